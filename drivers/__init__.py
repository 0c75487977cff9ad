"""Hardware and its stand-ins: cameras, Dynamixel servo buses, the servo emulator and the
simulated world that feeds them.

Each driver defines the typed settings it needs; ``runtime`` builds them from config.
"""
