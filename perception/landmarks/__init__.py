"""Marker landmarks on carton boxes and the boxes' poses in the robot's ground frame (SPEC §4.6).

:mod:`.settings` holds the ``[landmarks]`` experiment table and imports no OpenCV, so config
loading stays light; the detector and estimators live in :mod:`.detector`, :mod:`.pose` and
:mod:`.boxes`.
"""
