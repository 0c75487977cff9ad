"""The pictures of "How the perception works" (docs/assets/), made from the simulated world:

    MUJOCO_GL=egl python docs/_hooks/pictures.py

Robot a's camera in the ``tabletop-busy`` scene, perceived as the daemon perceives it (a still
head: calibrated on the empty floor, then every frame at 30 fps), drawn as the chapter's Fig. 5.2
and 5.3 at a few moments of the scene: objects being put down, touching, one hiding another. Not
run when the site is built (it needs MuJoCo and a minute of CPU); its pictures are committed.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from percept.perception.debug import panel
from percept.perception.params import PerceptionParams
from percept.perception.pipeline import Perception
from percept.runtime.settings.scene import open_world

ASSETS = Path(__file__).resolve().parents[1] / "assets"
SCENE, ROBOT, FPS = "tabletop-busy", "a", 30.0
EMPTY_UNTIL = 2.0  # seconds of the scene with the floor empty: the calibration
MOMENTS = {"pipeline-put-down.png": 4.0, "pipeline-hidden.png": 13.0}


def main() -> None:
    params = PerceptionParams()
    world = open_world(SCENE)
    try:
        calibration = [
            world.render(ROBOT, 0.0) for _ in range(params.background.calibration_frames)
        ]
        height, width = calibration[0].shape[:2]
        perception = Perception(params, width=width, height=height)
        perception.calibrate(calibration)
        frame = 0
        for name, at in sorted(MOMENTS.items(), key=lambda item: item[1]):
            image: np.ndarray | None = None
            while frame / FPS <= at - EMPTY_UNTIL:
                image = world.render(ROBOT, EMPTY_UNTIL + frame / FPS)
                result = perception.process(image, frame / FPS)
                frame += 1
            assert image is not None
            cv2.imwrite(str(ASSETS / name), panel(image, result))
            print(ASSETS / name)
    finally:
        world.close()


if __name__ == "__main__":
    main()
