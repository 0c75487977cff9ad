"""The commands of a robot's bring-up: its servos read, moved and emulated, its camera and head
calibrated, its pose and markers checked."""
