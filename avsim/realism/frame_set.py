"""The benchmark's fixed, seeded frames: per town, scene draw, camera and 5-m distance bin.

A scene draw is one compiled town (layout seed 0, as every driving scenario) with the clean stop
sign at a placement (standard, near, far in turn) under daylight drawn from the experiment files'
ranges (`EXPERIMENT_LIGHTING`, the `[vary]` of experiments/coco_detector.toml; a test holds them
equal). In it, each camera sees the sign from one distance drawn uniformly inside each bin, from the
car's lane with a small lateral offset, plus `ROADSIDE_FRAMES` views turned towards the roadside
(no sign meant to be in view: where false stop signs show). Every draw comes from
numpy's generator seeded by (seed, town, draw), and none depends on the render setting, so every
setting sees the same poses and lighting.

Labels are the visible part of each sign face (segmentation, `CameraRig.sign_boxes`), kept from
`MIN_LABEL_HEIGHT_PX` up as in the detector's data.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from avsim.config import SimConfig, with_overrides
from avsim.perception.datagen import MIN_LABEL_HEIGHT_PX
from avsim.realism.settings import RenderSetting
from avsim.sensors.camera import CAMERA_NAMES, CameraRig
from avsim.sensors.noise import SensorNoise
from avsim.vehicle.physics import Vehicle
from avsim.world.scene import compose_scene
from avsim.world.towns import PLACEMENTS, TOWNS

# experiments/coco_detector.toml [vary] and [defaults] (tests/realism/test_frame_set.py checks them).
EXPERIMENT_LIGHTING = {"sun_elevation_deg": (30.0, 70.0), "sun_azimuth_deg": (-180.0, 180.0), "sun_intensity": (0.8, 1.2)}
SENSOR_NOISE_STD_LEVELS = 2.0
# 5-m distance bins from the camera to the sign face along the road [m]: 10-15, ..., 55-60 by default.
# `--max-dist-m` runs them out to 150 m, where the closed-loop files start the car: false stop signs that
# open a braking gate 60-100 m out (docs/realism_foliage.md) are outside the default set.
NEAREST_DIST_M = 10
BIN_WIDTH_M = 5
DEFAULT_MAX_DIST_M = 60
MAX_DIST_LIMIT_M = 150


def bin_edges_m(max_dist_m: int = DEFAULT_MAX_DIST_M) -> tuple[int, ...]:
    """The bins' edges [m] from NEAREST_DIST_M to max_dist_m (a multiple of BIN_WIDTH_M)."""
    return tuple(range(NEAREST_DIST_M, max_dist_m + BIN_WIDTH_M, BIN_WIDTH_M))


BIN_EDGES_M = bin_edges_m()
ROADSIDE_FRAMES = 2  # per scene draw and camera
PLACEMENT_ORDER = ("standard", "near", "far")  # scene draw k of a town uses PLACEMENT_ORDER[k % 3]
LATERAL_JITTER_M = 0.3  # about the lane centre, as a driver holds a lane


@dataclass(frozen=True)
class SceneDraw:
    """One scene of the set; `index` counts draws within the town."""

    town: str
    index: int
    placement: str
    seed: int
    sun_elevation_deg: float
    sun_azimuth_deg: float
    sun_intensity: float


@dataclass
class Frame:
    """One rendered frame and what is in it: image (H, W, 3) uint8 RGB; stop_boxes (N, 4) and
    other_boxes (M, 4) xyxy [px] of the visible sign faces; dist_m the distance bin's draw (None for a
    roadside view); render_cpu_s the CPU time of the render (`time.process_time`, GL threads included)."""

    scene: SceneDraw
    camera: str
    dist_m: float | None
    image: np.ndarray
    stop_boxes: np.ndarray
    other_boxes: np.ndarray
    render_cpu_s: float


def scene_draws(towns: tuple[str, ...], draws_per_town: int, seed: int) -> list[SceneDraw]:
    """The set's scenes: `draws_per_town` per town, placements in turn, lighting drawn per scene."""
    placements = [p for p in PLACEMENT_ORDER if p in PLACEMENTS] + [p for p in PLACEMENTS.names() if p not in PLACEMENT_ORDER]
    scenes = []
    for town in towns:
        for k in range(draws_per_town):
            rng = np.random.default_rng((seed, TOWNS.names().index(town), k))
            light = {key: float(rng.uniform(*span)) for key, span in EXPERIMENT_LIGHTING.items()}
            scenes.append(SceneDraw(town, k, placements[k % len(placements)], int(rng.integers(2**31)), **light))
    return scenes


# The scenario keys every scene draw sets itself (`_scene_keys`; tests/realism/test_frame_set.py holds the two
# equal): a `--set` of one is refused (`avsim.realism.set_values`).
FRAME_SET_KEYS = ("scenario.town", "scenario.placement", "scenario.sign", "scenario.seed", "scenario.sun_elevation_deg",
                  "scenario.sun_azimuth_deg", "scenario.sun_intensity")


def _scene_keys(scene: SceneDraw) -> dict[str, object]:
    """The scenario keys a scene draw sets (its town, placement, clean sign, seed and sun)."""
    # The scene's seed draws its clouds, where the setting has them; nothing else in a scene reads it.
    return {"town": scene.town, "placement": scene.placement, "sign": "clean", "seed": scene.seed,
            "sun_elevation_deg": scene.sun_elevation_deg, "sun_azimuth_deg": scene.sun_azimuth_deg,
            "sun_intensity": scene.sun_intensity}


def scene_config(scene: SceneDraw, setting: RenderSetting, overrides: Mapping[str, Any] | None = None) -> SimConfig:
    """The `SimConfig` that renders `scene` (its town, placement, clean sign and sun) under the
    render `setting`'s overrides (camera, scenario materials, ...), and then `overrides` (`avsim realism --set`:
    nested, camera and scenario keys none of the others sets)."""
    return with_overrides(setting.config(overrides or {}), {"scenario": _scene_keys(scene)})


def render_scene(scene: SceneDraw, setting: RenderSetting, max_dist_m: int = DEFAULT_MAX_DIST_M,
                 overrides: Mapping[str, Any] | None = None) -> Iterator[tuple[Frame, mujoco.MjModel, mujoco.MjData, CameraRig]]:
    """Each frame of `scene` under `setting`, with the model, data and rig it was drawn by (for a
    segmentation look-up while the pose holds): every camera at every bin out to max_dist_m [m], then
    the roadside views. A longer set draws its poses from the same generator in another order, so its
    frames are not a superset of the default set's. overrides: as `scene_config`'s."""
    config = scene_config(scene, setting, overrides)
    spec, info = compose_scene(config)
    model = spec.compile()
    data = mujoco.MjData(model)
    vehicle = Vehicle(model, data, config.vehicle)
    rig = CameraRig(model, config.camera)
    noise = SensorNoise(SENSOR_NOISE_STD_LEVELS, scene.seed)
    faces = {s.name: (model.geom(s.face_geom).id, s.corners_m()) for s in info.signs}
    is_stop = {s.name: s.kind == "stop_sign" for s in info.signs}
    rng = np.random.default_rng(scene.seed)
    layout = info.layout
    try:
        for camera in CAMERA_NAMES:
            cam_x_m = float(model.cam_pos[model.camera(f"car/{camera}").id][0])
            poses = [(lo + BIN_WIDTH_M * float(rng.random()), None) for lo in bin_edges_m(max_dist_m)[:-1]]
            poses += [(None, math.radians(float(rng.choice([-1, 1]) * rng.uniform(15, 75)))) for _ in range(ROADSIDE_FRAMES)]
            for dist_m, yaw in poses:
                y_m = layout.lane_center_y_m + float(rng.uniform(-LATERAL_JITTER_M, LATERAL_JITTER_M))
                if dist_m is not None:
                    vehicle.place(info.stop_sign.face_center_m[0] - dist_m - cam_x_m, y_m, 0.0, 0.0)
                else:
                    vehicle.place(float(rng.uniform(-250, 40)), y_m, yaw, 0.0)
                start = time.process_time()
                image = rig.render_rgb(data, camera, noise=noise)
                cpu_s = time.process_time() - start
                boxes = {name: box for name, box in rig.sign_boxes(data, camera, faces).items()
                         if box[3] - box[1] >= MIN_LABEL_HEIGHT_PX}
                stop = np.asarray([b for n, b in boxes.items() if is_stop[n]], float).reshape(-1, 4)
                other = np.asarray([b for n, b in boxes.items() if not is_stop[n]], float).reshape(-1, 4)
                yield Frame(scene, camera, dist_m, image, stop, other, cpu_s), model, data, rig
    finally:
        rig.close()
