"""A background that lasts a lab session.

The chapter learns the background once and keeps it; a session of an hour sees daylight drift,
lamps switched, the camera adjust its exposure, shadows of hands and people walking through
while the robot calibrates. This package keeps the learned model valid through that, without
giving up the chapter's premise that whatever was not there before is an object:

- :mod:`.photometry.photometric`: each frame is mapped back to the calibration's light by a gain and
  offset per channel, fitted on pixels that are background with confidence;
- :mod:`.foreground`: the frame mapped, its foreground test, and shadows dropped (a pixel darker
  in Y with its chroma kept is shadow, not foreground), in one pass over the pixels;
- :mod:`.photometry.change`: a sudden change (a switch, an exposure step) is detected and reported;
- :mod:`.maintenance`: quiet background pixels follow slow drift, regions left by people who
  stood there during calibration (ghosts) are re-learned, and after a change the compensation
  cannot explain the background is re-learned outside the anchors; an anchored object is
  never learned into the background;
- :mod:`.adaptation`: the per-frame state that ties them together for :class:`Perception`.

Everything works on a :class:`~percept.perception.segmentation.background.BackgroundModel` (mean,
sigma, bounds) and a YCrCb frame of the same size, so the same code serves any view of a model.
"""
