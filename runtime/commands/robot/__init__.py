"""The commands of a robot at work: its daemon, the lab's router and certificates, the monitor of
joint attention, and the profiles and experiments they read (``init``, ``config``)."""
