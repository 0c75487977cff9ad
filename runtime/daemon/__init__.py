"""The onboard daemon: its devices, its per-frame pipeline, its loop, status and threads."""
