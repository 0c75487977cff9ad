"""Every threshold of the perception core (SPEC §4.1-4.4), with its default and what it does.

The ``[perception]`` table of an experiment file fills :class:`PerceptionParams`; a preset file
(``config/presets/perception-<name>.toml``) holds the same table on its own. The preset
``chapter`` reproduces the chapter's literal values (k = 1, Q = 1e-5 I, R = 1e-1 I, ...); the
defaults here were picked by measurement against ground truth (README, "Perception").

Units: grey levels (0-255) for intensities, pixels for image lengths, image fractions for areas
(so that one setting works at 176x144 and at 640x480), seconds for time. The Kalman filter steps
once per frame, so its noise terms are per frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

MIB = 1 << 20

ColourModel = Literal["marginals", "joint_chroma"]
"""How regions, percepts and anchors hold their colours
(:class:`percept.perception.colour.Coding`)."""


@dataclass(frozen=True)
class BackgroundParams:
    """Background calibration and the foreground test of §4.1."""

    calibration_frames: int = field(
        default=30,
        metadata={
            "min": 1,
            "max": 100000,
            "doc": "frames the background statistics are taken over",
        },
    )
    calibration_memory: float = field(
        default=2048.0,
        metadata={
            "min": 1.0,
            "max": 1048576.0,
            "doc": "MiB the calibration may hold: it keeps every frame, calibration_frames x "
            "width x height x 3 bytes, which must fit",
        },
    )
    estimator: Literal["clipped", "mean"] = field(
        default="clipped",
        metadata={
            "doc": "clipped: per-pixel median and MAD, then mean and deviation of the samples "
            "within `clip` robust sigmas, so that people or objects passing during calibration "
            "are left out; mean: plain mean and deviation of all frames (the chapter)"
        },
    )
    clip: float = field(
        default=2.5,
        metadata={
            "min": 0.5,
            "max": 100.0,
            "doc": "clipped estimator: samples farther than this many robust sigmas from the "
            "per-pixel median are outliers",
        },
    )
    k: float = field(
        default=5.0,
        metadata={
            "min": 0.0,
            "max": 100.0,
            "doc": "foreground when |i - mu| > k * max(sigma, sigma_min) in any channel",
        },
    )
    sigma_min: float = field(
        default=3.0,
        metadata={
            "min": 0.0,
            "max": 255.0,
            "doc": "grey levels: floor of the deviation (a still or simulated camera has 0)",
        },
    )

    def memory_problem(self, width: int, height: int) -> str | None:
        """Why calibrating on ``width`` x ``height`` frames would exceed the memory budget, or
        None when it fits (the frames are kept as one uint8 YCrCb stack)."""
        need = self.calibration_frames * width * height * 3
        if need <= self.calibration_memory * MIB:
            return None
        return (
            f"{self.calibration_frames} frames of {width}x{height} need {need / MIB:.0f} MiB "
            f"to calibrate (frames x width x height x 3 bytes), more than calibration_memory = "
            f"{self.calibration_memory:g} MiB; use at most "
            f"{int(self.calibration_memory * MIB // (width * height * 3))} frames or raise "
            "calibration_memory"
        )


@dataclass(frozen=True)
class MotionParams:
    """Frame-to-frame motion of §4.3."""

    k: float = field(
        default=4.0,
        metadata={
            "min": 0.0,
            "max": 100.0,
            "doc": "a pixel moved when |i_t - i_t-1| > k * max(sigma, sigma_min) in any channel",
        },
    )


@dataclass(frozen=True)
class RegionParams:
    """Noise reduction and connected regions of §4.1."""

    opening: int = field(
        default=3,
        metadata={
            "min": 1,
            "max": 31,
            "doc": "side of the square erosion-then-dilation kernel (applied to foreground "
            "and motion); 1 switches noise reduction off",
        },
    )
    min_area: float = field(
        default=0.0005,
        metadata={
            "min": 0.0,
            "max": 1.0,
            "doc": "fraction of the image: smaller foreground regions are noise and dropped",
        },
    )
    grid_pixels: int = field(
        default=320 * 240,
        metadata={
            "min": 0,
            "max": 8192 * 8192,
            "doc": "regions, histograms and the colour split look at every s-th pixel of every "
            "s-th row of the foreground, s the smallest step leaving at most this many pixels "
            "(s = 2 at 640x480: a quarter of the work, boxes within a pixel); 0: every pixel",
        },
    )
    bins: int = field(
        default=16,
        metadata={
            "min": 2,
            "max": 32,
            "doc": "histogram bins m per channel (Y, Cr, Cb); a power of two, so that every "
            "bin covers as many of the 256 intensities",
        },
    )

    colour_model: ColourModel = field(
        default="marginals",
        metadata={
            "doc": "how regions, percepts and anchors hold their colours. marginals: a histogram "
            "each of Y, Cr and Cb, whose product is a pixel's probability (the chapter's); "
            "joint_chroma: a histogram of Y and one of Cr and Cb together (m x m bins), so that "
            "a model does not also explain the colours between those it has seen (an orange "
            "model a yellow neighbour)"
        },
    )

    def __post_init__(self) -> None:
        if self.bins & (self.bins - 1):
            raise ValueError(f"bins must be a power of two (2, 4, 8, 16 or 32), got {self.bins}")


@dataclass(frozen=True)
class SplitParams:
    """Splitting foreground regions with the anchors' colour models (§4.2)."""

    enabled: bool = field(
        default=True, metadata={"doc": "split regions by colour model; false: one percept each"}
    )
    threshold: float = field(
        default=2e-4,
        metadata={
            "min": 0.0,
            "max": 1.0,
            "doc": "t: a pixel whose best p_j = M_Y * M_Cr * M_Cb is below this has no model",
        },
    )
    min_area: float = field(
        default=0.0003,
        metadata={
            "min": 0.0,
            "max": 1.0,
            "doc": "fraction of the image: a class needs this many pixels in a region to split "
            "it off, and smaller split pieces are dropped",
        },
    )
    margin: float = field(
        default=0.1,
        metadata={
            "min": 0.0,
            "max": 1000.0,
            "doc": "a model takes part in splitting a region when its predicted box, grown by "
            "this fraction of its size on each side, overlaps the region's box",
        },
    )


@dataclass(frozen=True)
class AnchorParams:
    """Kalman-filtered object anchors of §4.4."""

    t_space: float = field(
        default=0.9,
        metadata={
            "min": 0.0,
            "max": 1.0,
            "doc": "s_space = 1 - distance / image diagonal counts only above this",
        },
    )
    t_color: float = field(
        default=0.4,
        metadata={
            "min": 0.0,
            "max": 1.0,
            "doc": "s_color = product of the Bhattacharyya coefficients of the colour model's "
            "histograms (Y, Cr, Cb; or Y and CrCb) counts only above",
        },
    )
    t_space_motion: float = field(
        default=0.8,
        metadata={"min": 0.0, "max": 1.0, "doc": "t_space for a model in motion (looser)"},
    )
    t_color_motion: float = field(
        default=0.2,
        metadata={"min": 0.0, "max": 1.0, "doc": "t_color for a model in motion (looser)"},
    )
    q: float = field(
        default=1e-2,
        metadata={"min": 0.0, "max": 1e6, "doc": "process noise Q = q I_8 (pixels^2 per frame)"},
    )
    r: float = field(
        default=1.0,
        metadata={"min": 1e-9, "max": 1e6, "doc": "measurement noise R = r I_4 (pixels^2)"},
    )
    p0_position: float = field(
        default=1.0,
        metadata={"min": 1e-9, "max": 1e6, "doc": "initial variance of x, y, w, h (pixels^2)"},
    )
    p0_velocity: float = field(
        default=1.0,
        metadata={
            "min": 0.0,
            "max": 1e6,
            "doc": "initial variance of their rates (pixels^2 per frame^2)",
        },
    )
    alpha: float = field(
        default=0.1,
        metadata={"min": 0.0, "max": 1.0, "doc": "histogram update M = (1-alpha) M + alpha M_P"},
    )
    max_absence: float = field(
        default=1.0,
        metadata={
            "min": 0.0,
            "max": 86400.0,
            "doc": "seconds without a percept after which a model is deleted (with a camera "
            "pose: one whose place is in view, not hidden and empty)",
        },
    )
    memory: float = field(
        default=60.0,
        metadata={
            "min": 0.0,
            "max": 86400.0,
            "doc": "with a camera pose: seconds an anchor out of view or hidden behind a nearer "
            "one is remembered (not visible) before it is forgotten",
        },
    )
    reacquire_distance: float = field(
        default=0.15,
        metadata={
            "min": 0.0,
            "max": 100.0,
            "doc": "metres on the ground: an object coming back into view this near a "
            "remembered anchor's place, in its colour, gets that anchor's id back",
        },
    )
    out_of_sight: float = field(
        default=0.5,
        metadata={
            "min": 0.0,
            "max": 1.0,
            "doc": "an unseen anchor is out of view when less than this fraction of its box is "
            "inside the image, hidden when at least this fraction lies under a nearer anchor",
        },
    )
    max_seed_motion: float = field(
        default=0.0,
        metadata={
            "min": 0.0,
            "max": 1.0,
            "doc": "a new model is created only when at most this fraction of its box moved "
            "(0: nowhere, as in the chapter; 1: creation regardless of motion)",
        },
    )
    min_seed_area: float = field(
        default=0.002,
        metadata={"min": 0.0, "max": 1.0, "doc": "fraction of the image: smallest new model"},
    )

    def __post_init__(self) -> None:
        if self.t_space_motion > self.t_space or self.t_color_motion > self.t_color:
            raise ValueError("the thresholds under motion must be looser (<=) than the others")


@dataclass(frozen=True)
class LightParams:
    """A background that lasts a lab session (:mod:`percept.perception.light`): photometric
    compensation, shadows, sudden light changes, ghosts and selective maintenance.

    Off (``enabled = false``) the model is the chapter's: learned once, then frozen.
    """

    enabled: bool = field(
        default=True,
        metadata={"doc": "adapt the background to the light; false: the fixed calibration"},
    )
    compensation: bool = field(
        default=True,
        metadata={
            "doc": "per frame, a gain and offset per channel (Y, Cr, Cb) fitted on pixels that "
            "are background with confidence, mapping the frame back to the calibration's light"
        },
    )
    samples: int = field(
        default=600,
        metadata={
            "min": 100,
            "max": 1_000_000,
            "doc": "pixels (on a fixed sparse grid) the gain and offset are fitted on",
        },
    )
    shadows: bool = field(
        default=True,
        metadata={"doc": "a pixel darker in Y with its chroma kept is shadow, not foreground"},
    )
    shadow_darkest: float = field(
        default=0.4,
        metadata={
            "min": 0.0,
            "max": 1.0,
            "doc": "shadow only when Y is at least this fraction of the background's (darker "
            "is an object)",
        },
    )
    shadow_chroma: float = field(
        default=1.0,
        metadata={
            "min": 0.0,
            "max": 100.0,
            "doc": "shadow only when Cr and Cb are within this many max(sigma, sigma_min) of "
            "the background's chroma scaled by the darkening",
        },
    )
    switch_gain: float = field(
        default=0.12,
        metadata={
            "min": 0.0,
            "max": 10.0,
            "doc": "a sudden change: the fitted Y gain moves by more than this fraction "
            "within `switch_window` seconds or since the last frame",
        },
    )
    switch_window: float = field(
        default=0.25,
        metadata={"min": 0.0, "max": 60.0, "doc": "seconds a sudden gain change happens in"},
    )
    switch_fraction: float = field(
        default=0.35,
        metadata={
            "min": 0.0,
            "max": 1.0,
            "doc": "a sudden change the compensation cannot explain: this fraction of the "
            "pixels outside anchors becomes foreground from one frame to the next; once "
            "the view has been still for `confirm` seconds the background is re-learned "
            "from the current view outside the anchors",
        },
    )
    confirm: float = field(
        default=0.3,
        metadata={
            "min": 0.0,
            "max": 60.0,
            "doc": "seconds the view must stay still after a jump of `switch_fraction` before "
            "the jump is taken for light and the background re-learned (a person walking "
            "past keeps moving); meanwhile no new anchor is made outside the anchors",
        },
    )
    settle: float = field(
        default=1.0,
        metadata={
            "min": 0.0,
            "max": 600.0,
            "doc": "seconds the gain must stay steady after a change before the light is "
            "reported steady again",
        },
    )
    ghosts: bool = field(
        default=True,
        metadata={
            "doc": "re-learn a foreground region whose current image matches its surroundings "
            "while the model does not (someone stood there during calibration)"
        },
    )
    ghost_match: float = field(
        default=10.0,
        metadata={
            "min": 0.0,
            "max": 255.0,
            "doc": "grey levels: a region matches its surroundings when its mean colour is "
            "this close to theirs (Euclidean in Y, Cr, Cb; or a quarter of the model's "
            "distance); the model inside must be at least twice as far from the model around",
        },
    )
    maintain_time: float = field(
        default=20.0,
        metadata={
            "min": 0.01,
            "max": 86400.0,
            "doc": "seconds: time constant with which quiet background pixels follow the light",
        },
    )
    quiet: float = field(
        default=2.0,
        metadata={
            "min": 0.0,
            "max": 86400.0,
            "doc": "seconds a pixel must have been background, still and outside every anchor "
            "before it is maintained",
        },
    )
    maintain_every: float = field(
        default=0.5,
        metadata={
            "min": 0.0,
            "max": 3600.0,
            "doc": "seconds between maintenance steps (each step catches up on the time since)",
        },
    )


@dataclass(frozen=True)
class ViewParams:
    """Following a moving head: the background over viewing directions and motion without the
    camera's own motion (used only when the frames come with camera poses)."""

    refine: bool = field(
        default=True,
        metadata={
            "doc": "refine the alignment that the camera pose predicts against the image (phase "
            "correlation of the model's brightness with the frame's); false: trust the pose",
        },
    )
    max_shift: float = field(
        default=3.0,
        metadata={
            "min": 0.0,
            "max": 45.0,
            "doc": "degrees: the largest pose error the refinement corrects; a larger shift "
            "found by the correlation is not believed",
        },
    )
    spread: int = field(
        default=1,
        metadata={
            "min": 0,
            "max": 5,
            "doc": "map cells: the background bounds of a direction take in those of the cells "
            "this close to it (erosion of the lower, dilation of the upper bound), so that what "
            "remains of the alignment error after the refinement is not foreground",
        },
    )
    learn_time: float = field(
        default=2.0,
        metadata={
            "min": 0.0,
            "max": 3600.0,
            "doc": "seconds: a direction that no calibration frame saw (unknown: never "
            "foreground) is learned once it was seen this long without motion and outside "
            "every anchor's box",
        },
    )
    compensate: bool = field(
        default=True,
        metadata={
            "doc": "bring the previous frame into the current view before the motion test; "
            "false: difference the frames as they are (for comparison)",
        },
    )


@dataclass(frozen=True)
class PerceptionParams:
    """The perception core's parameters: one nested table per stage."""

    background: BackgroundParams = field(
        default_factory=BackgroundParams, metadata={"doc": "calibration and foreground (§4.1)"}
    )
    motion: MotionParams = field(default_factory=MotionParams, metadata={"doc": "motion (§4.3)"})
    regions: RegionParams = field(
        default_factory=RegionParams, metadata={"doc": "noise reduction, regions, histograms"}
    )
    split: SplitParams = field(
        default_factory=SplitParams, metadata={"doc": "colour-model splitting (§4.2)"}
    )
    anchors: AnchorParams = field(
        default_factory=AnchorParams, metadata={"doc": "Kalman object anchors (§4.4)"}
    )
    light: LightParams = field(
        default_factory=LightParams,
        metadata={"doc": "compensation, shadows, light changes, ghosts, maintenance"},
    )
    view: ViewParams = field(
        default_factory=ViewParams,
        metadata={"doc": "background and motion while the head moves"},
    )
