"""Perception while the head moves: the background over viewing directions (a mosaic that holds
for every head pose), brought into each frame's view, and motion without the camera's own."""
