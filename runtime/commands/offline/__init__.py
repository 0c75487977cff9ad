"""The commands on recorded frames: tracking, foreground masks and their scores against ground
truth, a recording replayed, exported or summed up."""
