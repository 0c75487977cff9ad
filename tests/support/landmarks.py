"""The box and camera the marker tests draw and read: a 16 cm carton with a 10 cm marker on each
side face, seen by a 640x480 camera of 60 x 47 degrees."""

from __future__ import annotations

from percept.kinematics.camera import CameraModel
from percept.perception.landmarks.settings import BoxSettings, MarkerSettings

BOX = BoxSettings(
    1,
    (0.16, 0.16, 0.16),
    tuple(MarkerSettings(i, 0.1, f) for i, f in enumerate(("front", "left", "back", "right"))),
)
CAMERA = CameraModel.from_opening_angles(1.0472, 0.8172, 640, 480)
