"""Perception: background model, foreground and motion, regions, colour-model splitting, Kalman
object anchors, sensory experiences and marker landmarks (chapter 5.2-5.3).

Data flows one way: frame -> percepts -> anchors -> sensory experiences. One subpackage per
stage, each with its compiled loops beside the module they serve (``X.py`` and
``X_kernels.py``): :mod:`.segmentation`, :mod:`.tracking`, :mod:`.light`, :mod:`.view`,
:mod:`.landmarks`, :mod:`.features`; :mod:`.pipeline` ties them together, :mod:`.backgrounds`
holds the backgrounds a frame is told from, :mod:`.compiled` what every kernel shares.
"""
