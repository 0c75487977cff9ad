"""Finding markers in an image: the quad search, reading each candidate's id, sub-pixel corners
from its edges (:mod:`.detector`, :mod:`.decoding`, :mod:`.edges` and their compiled loops), or
cv2.aruco's or the AprilTag C library's detectors instead."""
