"""Kinematic trees (from a platform profile or a URDF), forward kinematics to the camera pose,
the camera model and pixel -> ground-plane projection.

Frames follow SPEC §3: the robot's ground frame has x forward, y left, z up; the camera frame has
x along the optical axis, y left, z up. The one conversion to and from OpenCV's camera frame lives
in :mod:`percept.kinematics.camera`.
"""
