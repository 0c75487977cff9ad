"""Dynamixel servo buses: the driver (:mod:`.bus`), its packet codec (:mod:`.protocol`), servo
control tables (:mod:`.models`) and a byte-level emulator on a pseudo-terminal
(:mod:`.emulator`)."""
