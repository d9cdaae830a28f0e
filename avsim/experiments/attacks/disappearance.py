"""Per-frame metrics of an attacked sign over drive-bys, as the attack literature reports them.

A drive-by here is the front camera's frames of one approach at the closed loop's frame
spacing (speed x control period: 1.18 m at 85 km/h), from `FAR_M` down to where the sign
leaves the view, the car level in its lane. Drives differ in their lighting (drawn from the
experiment files' ranges, `view_bank.CLOSED_LOOP_LIGHTING`), their first frame's phase and
the seeded sensor noise (`perception.sensor_noise_std`, the experiment files' 2 levels); drive
k is the same for every texture and detector, so textures compare in pairs.

Per frame: the confidence of the detection matching the sign (IoU >= 0.3 with its ground-truth
box; 0 if none), that box's height, and the braking policy's pinhole estimate of the distance to
the stop line from it (`avsim.control.policy_base`). From these:
- the disappearance rate (Armory's term; RP2's "% of frames where the sign is missed"): the
  share of frames with no matching detection at or above the braking threshold, per 5-m bin;
- the first confident detection of each drive, at any range and inside the braking gate (the
  pinhole estimate at most `policy.trigger_dist_m`): the frame `baseline` brakes on;
- the predicted box height over the true one (what range inflation moves).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from avsim.attacks.view_bank import CLOSED_LOOP_LIGHTING, frame_spacing_m
from avsim.config import PerceptionConfig, SimConfig, with_overrides
from avsim.loop import ClosedLoop
from avsim.perception.ap import box_iou
from avsim.perception.evaluation import wilson_interval
from avsim.perception.factory import build_perception
from avsim.vehicle.physics import FRONT_BUMPER_X_M

FAR_M = 60.0
NEAR_M = 4.0
BIN_M = 5.0
MATCH_IOU = 0.3
SENSOR_NOISE_STD_LEVELS = 2.0
# Second word of the lighting generator's seed (independent of the sensor noise's stream).
_LIGHTING_STREAM = 7


@dataclass(frozen=True)
class Frame:
    """One camera frame of a drive-by. Distances: front bumper to the sign [m]."""

    drive: int
    dist_m: float
    confidence: float  # of the detection matching the sign; 0 if none
    box_height_px: float  # of that detection; 0 if none
    true_height_px: float
    estimate_m: float | None  # the policy's pinhole estimate of the stop line from that box


@dataclass
class DriveBys:
    """Every frame of one texture's drive-bys under one detector."""

    sign: str
    detector: str
    town: str
    placement: str
    threshold: float
    trigger_dist_m: float | None
    frames: list[Frame] = field(default_factory=list)

    @property
    def drives(self) -> list[int]:
        """The drive indices that have frames, ascending."""
        return sorted({f.drive for f in self.frames})

    def detected(self, frame: Frame, gated: bool = False) -> bool:
        """Reported at or above the threshold (and, gated, with its estimate inside the trigger distance)."""
        if frame.confidence < self.threshold:
            return False
        return not gated or self.trigger_dist_m is None or (frame.estimate_m is not None and frame.estimate_m <= self.trigger_dist_m)

    def bins(self, bin_m: float = BIN_M) -> list[tuple[float, float]]:
        """Distance bins (lo, hi) [m] of width `bin_m` from below `NEAR_M` to `FAR_M`, near to far."""
        edges = np.arange(math.floor(NEAR_M / bin_m) * bin_m, FAR_M + bin_m, bin_m)
        return [(float(lo), float(hi)) for lo, hi in zip(edges[:-1], edges[1:])]

    def in_range(self, lo_m: float, hi_m: float) -> list[Frame]:
        """The frames whose bumper-to-sign distance is in [lo_m, hi_m) [m]."""
        return [f for f in self.frames if lo_m <= f.dist_m < hi_m]

    def disappearance(self, lo_m: float, hi_m: float) -> tuple[int, int, float, tuple[float, float]]:
        """(frames, missed, rate, Wilson 95% interval) over frames at lo <= distance < hi."""
        frames = self.in_range(lo_m, hi_m)
        missed = sum(not self.detected(f) for f in frames)
        rate = missed / len(frames) if frames else float("nan")
        return len(frames), missed, rate, wilson_interval(missed, len(frames))

    def first_confident_m(self, drive: int, gated: bool) -> float | None:
        """The farthest frame of a drive detected at the threshold (inside the gate, if gated); None if none."""
        hits = [f.dist_m for f in self.frames if f.drive == drive and self.detected(f, gated)]
        return max(hits) if hits else None

    def mean_confidence(self, lo_m: float, hi_m: float) -> float:
        """Mean confidence of the sign's detection (0 where missed) over the frames in [lo_m, hi_m); NaN if none."""
        frames = self.in_range(lo_m, hi_m)
        return float(np.mean([f.confidence for f in frames])) if frames else float("nan")

    def height_ratio(self, lo_m: float, hi_m: float) -> float:
        """Median predicted / true box height of the detected frames at lo <= distance < hi (nan if none)."""
        ratios = [f.box_height_px / f.true_height_px for f in self.in_range(lo_m, hi_m) if f.confidence >= self.threshold]
        return float(np.median(ratios)) if ratios else float("nan")


def drive_lighting(drive: int, seed: int) -> dict[str, float]:
    """Drive k's lighting, uniform in the experiment files' ranges."""
    rng = np.random.default_rng((seed, _LIGHTING_STREAM, drive))
    return {key: round(float(rng.uniform(*bounds)), 3) for key, bounds in CLOSED_LOOP_LIGHTING.items()}


def drive_by_frames(sign: str, detector: str = "detector", town: str = "town07", placement: str = "standard",
                    drives: int = 6, seed: int = 0, speed_kmh: float = 85.0, base: SimConfig | None = None) -> DriveBys:
    """Drive `drives` approaches past `sign` (a `--sign` value) and record every front frame
    (see the module docstring). detector: a perception kind that runs on pixels (detector, coco, yolo, nanodet)."""
    base = base or SimConfig()
    spacing_m = frame_spacing_m(speed_kmh, base.loop.control_dt_s)
    result = DriveBys(sign, detector, town, placement, base.policy.conf_threshold, base.policy.trigger_dist_m)
    for drive in range(drives):
        config = with_overrides(base, {
            "scenario": {"town": town, "placement": placement, "sign": sign, "seed": seed * 1000 + drive,
                         **drive_lighting(drive, seed)},
            "perception": {"kind": detector, "min_confidence": 0.05, "sensor_noise_std": SENSOR_NOISE_STD_LEVELS,
                           "threads": 1}})
        loop = ClosedLoop(config)
        try:
            oracle = build_perception(PerceptionConfig(kind="oracle", oracle_min_box_height_px=1.0), loop.config.camera, loop.model, loop.scene)
            phase = np.random.default_rng((seed, _LIGHTING_STREAM + 1, drive)).random() * spacing_m
            for dist_m in np.arange(FAR_M - phase, NEAR_M, -spacing_m):
                frame = _frame(loop, oracle, drive, float(dist_m))
                if frame is not None:
                    result.frames.append(frame)
        finally:
            loop.close()
    return result


def _frame(loop: ClosedLoop, oracle, drive: int, dist_m: float) -> Frame | None:
    """The front camera's frame with the bumper `dist_m` before the sign; None if the sign is out of view."""
    bumper_x = loop.scene.stop_sign.base_pos_m[0] - dist_m
    loop.vehicle.place(bumper_x - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
    truth = [d for d in oracle.detect(loop.rig, loop.data, "front") if d.class_name == "stop_sign"]
    if not truth:
        return None
    found = [d for d in loop.perception.detect(loop.rig, loop.data, "front") if d.class_name == "stop_sign"]
    ious = box_iou(np.array([d.box_xyxy_px for d in found]).reshape(-1, 4), np.array([truth[0].box_xyxy_px]))[:, 0]
    matched = [d for d, iou in zip(found, ious) if iou >= MATCH_IOU]
    if not matched:
        return Frame(drive, dist_m, 0.0, 0.0, truth[0].height_px, None)
    best = max(matched, key=lambda d: d.confidence)
    return Frame(drive, dist_m, best.confidence, best.height_px, truth[0].height_px, loop.policy.stop_line_estimate_m(best))
