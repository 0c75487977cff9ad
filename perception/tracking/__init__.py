"""Object anchors (§4.3-4.4): the percepts associated with Kalman-filtered models, motion
without the camera's own, known objects, and the memory of anchors out of view."""
