"""Labelled sign images rendered by the simulator, for training and evaluating the detector.

Boxes come from segmentation rendering (2x supersampled, so edges fall on half
pixels). Each "scene" is one compiled town with randomised scenery, lighting, fog,
a target sign of a random kind at the stop line and red distractor props; several
images are rendered from random car poses in it.

Held out: the validation split uses town layout seed 0 (the seed every driving
scenario uses) and sun elevations in [40, 55) deg; no training image comes from
either.

Output, in DIR (written to DIR.partial and renamed when complete):
  images/{train,val}/NNNNNN.png   640x480 RGB
  {train,val}.jsonl               {"image", "boxes": [[x0, y0, x1, y1]], "classes", "meta"}
  generation.json                 the generation settings
With `label_format` "coco" or "yolo", the labels are written in that format instead of the
JSON lines (`avsim.perception.dataset_formats`).

`setting_overrides` renders every image under one of `avsim realism`'s render settings (textured surfaces,
sheeting, see-through crowns, shadows, the photographic stages; the command line resolves `--setting NAME`
to them), to train or score a detector on those renders. The scenes, poses and lighting are drawn from the
seed alone, so two datasets of one seed under two settings show the same views.
"""

from __future__ import annotations

import json
import math
import os
import shutil
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from types import MappingProxyType
from typing import Any, Mapping
from pathlib import Path

import cv2
import mujoco
import numpy as np

from avsim.config import MAX_SEED, CameraConfig, SimConfig, with_overrides
from avsim.errors import ConfigError
from avsim.validation import check_ranges, ranged
from avsim.outputs import write_image, write_text
from avsim.perception.dataset_formats import FORMATS, SPLITS, write_labels
from avsim.sensors.camera import CameraRig
from avsim.sensors.gl import check_offscreen_rendering
from avsim.vehicle.physics import Vehicle
from avsim.workers import init_worker, terminate_workers
from avsim.world import props
from avsim.world.scene import SceneInfo, compose_scene
from avsim.world.towns import PLACEMENTS, TOWNS

VAL_LAYOUT_SEED = 0
VAL_SUN_ELEVATION_DEG = (40.0, 55.0)
TARGET_KINDS = ("stop_sign", "yield", "speed_limit")
TARGET_KIND_WEIGHTS = (0.55, 0.2, 0.25)
MIN_LABEL_HEIGHT_PX = 4.0
# Every image is rendered at the default camera's resolution: `_scene_config` changes the scenario and a setting's
# camera stages, and DataGenConfig refuses a setting that changes the size.
IMAGE_SIZE_PX = (CameraConfig().width_px, CameraConfig().height_px)
DEFAULT_RENDERS: Mapping[str, Mapping[str, Any]] = MappingProxyType({})  # no setting's overrides


@dataclass(frozen=True)
class DataGenConfig:
    """`avsim detector make-data`'s settings: how many train and validation images, rendered in
    scenes of `images_per_scene` views each, the dataset `seed`, the worker processes, the farthest
    target sign [m] and the label format (jsonl, coco or yolo)."""

    n_train: int = ranged(6000, 0, 10_000_000)
    n_val: int = ranged(1000, 0, 10_000_000)
    images_per_scene: int = ranged(25, 1, 1000)
    seed: int = ranged(0, 0, MAX_SEED, note="2**32 - 1")
    workers: int = ranged(2, 1, 64)
    # Farthest target sign [m]. 80 m covers the braking range; the perception-range
    # measurement (docs/perception.md) renders out to 160 m, where the sign is 4 px tall.
    max_dist_m: float = ranged(80.0, 10, 300, unit="m", note="the approach road is 320 m long")
    # How the labels are written: "jsonl" (avsim's own), "coco" or "yolo" (dataset_formats).
    label_format: str = "jsonl"
    # The render setting every image is drawn under: its name (recorded in generation.json) and its config
    # overrides, {section: {key: value}} (avsim.realism.settings; "baseline" and {}: the default renders).
    setting: str = "baseline"
    setting_overrides: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.label_format not in FORMATS:
            raise ConfigError(f"--format must be one of {', '.join(FORMATS)}, got {self.label_format!r}")
        camera = with_overrides(SimConfig(), self.setting_overrides).camera
        if (camera.width_px, camera.height_px) != IMAGE_SIZE_PX:
            raise ConfigError(f"--setting {self.setting} renders {camera.width_px}x{camera.height_px}, but make-data "
                              f"renders at the study camera's {IMAGE_SIZE_PX[0]}x{IMAGE_SIZE_PX[1]}; choose a setting "
                              "that keeps the camera's size")
        check_ranges(self, "make-data")
        if self.n_train + self.n_val == 0:
            raise ConfigError(f"need a positive number of images, got train={self.n_train}, val={self.n_val}")


@dataclass(frozen=True)
class SceneJob:
    """One scene to render: everything random about it is drawn from `seed`."""

    split: str
    first_index: int
    n_images: int
    seed: int


def _scene_config(rng: np.random.Generator, split: str,
                  setting_overrides: Mapping[str, Mapping[str, Any]] = DEFAULT_RENDERS) -> SimConfig:
    if split == "val":
        layout_seed = VAL_LAYOUT_SEED
        elevation = float(rng.uniform(*VAL_SUN_ELEVATION_DEG))
    else:
        layout_seed = int(rng.integers(1, 1_000_000))
        low, high = VAL_SUN_ELEVATION_DEG
        # Uniform over [15, 85) minus the held-out band.
        elevation = float(rng.uniform(15.0, 85.0 - (high - low)))
        elevation = elevation + (high - low) if elevation >= low else elevation
    fog = rng.random() < 0.3
    fog_end = float(rng.uniform(90.0, 300.0)) if fog else 0.0
    drawn = with_overrides(SimConfig(), {"scenario": {
        "town": str(rng.choice(TOWNS.names())),
        "placement": str(rng.choice(PLACEMENTS.names())),
        "layout_seed": layout_seed,
        "sun_elevation_deg": elevation,
        "sun_azimuth_deg": float(rng.uniform(-180, 180)),
        "sun_intensity": float(rng.uniform(0.5, 1.4)),
        "fog_start_m": float(rng.uniform(0, 20)) if fog else 0.0,
        "fog_end_m": fog_end,
    }})
    return with_overrides(drawn, setting_overrides)


def _add_red_distractors(rng: np.random.Generator):
    """Red props (boxes, drums, a red car) near the road: a detector must not fire on them."""

    def add(spec: mujoco.MjSpec, info: SceneInfo) -> None:
        edge = info.layout.lane_edge_y_m
        for k in range(int(rng.integers(1, 6))):
            x = float(rng.uniform(-90, 30))
            side = -1 if rng.random() < 0.7 else 1
            y = edge - float(rng.uniform(0.8, 7.0)) if side < 0 else -edge + float(rng.uniform(0.8, 7.0))
            kind = rng.random()
            if kind < 0.5:
                size = (float(rng.uniform(0.3, 2.5)), float(rng.uniform(0.3, 2.0)), float(rng.uniform(0.4, 3.0)))
                props.add_red_distractor(spec, f"distractor_{k}", x, y, size)
            elif kind < 0.8:
                radius, height = float(rng.uniform(0.2, 0.6)), float(rng.uniform(0.5, 2.8))
                spec.worldbody.add_geom(name=f"distractor_{k}", type=mujoco.mjtGeom.mjGEOM_CYLINDER, pos=[x, y, height / 2],
                                        size=[radius, height / 2], rgba=[0.8, 0.07, 0.08, 1], contype=0, conaffinity=0)
            else:
                props.add_parked_car(spec, f"distractor_{k}", x, y, float(rng.uniform(-0.2, 0.2)), (0.75, 0.06, 0.08))

    return add


def _camera_jitter(model: mujoco.MjModel, cam_id: int, base_pos: np.ndarray, base_quat: np.ndarray, rng: np.random.Generator) -> None:
    """Mount height +-0.1 m and pitch +-2 deg, as different cars and loads would give."""
    model.cam_pos[cam_id] = base_pos + np.array([0.0, 0.0, rng.uniform(-0.1, 0.1)])
    pitch = math.radians(rng.uniform(-2.0, 2.0))
    q_pitch = np.array([math.cos(pitch / 2), math.sin(pitch / 2), 0.0, 0.0])  # about the camera's x axis
    q = np.zeros(4)
    mujoco.mju_mulQuat(q, base_quat, q_pitch)
    model.cam_quat[cam_id] = q


def _degrade(image: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Motion blur, sensor noise and JPEG re-encoding, each with some probability."""
    out = image
    if rng.random() < 0.3:
        length = int(rng.integers(3, 8))
        kernel = np.zeros((length, length), np.float32)
        kernel[length // 2, :] = 1.0 / length
        rot = cv2.getRotationMatrix2D((length / 2 - 0.5, length / 2 - 0.5), float(rng.uniform(0, 180)), 1.0)
        kernel = cv2.warpAffine(kernel, rot, (length, length))
        out = cv2.filter2D(out, -1, kernel / max(kernel.sum(), 1e-6))
    if rng.random() < 0.6:
        noise = rng.normal(0.0, rng.uniform(1.0, 6.0), out.shape)
        out = np.clip(out.astype(np.float32) + noise, 0, 255).astype(np.uint8)
    if rng.random() < 0.3:
        ok, buf = cv2.imencode(".jpg", out[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, int(rng.integers(50, 95))])
        out = cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1]
    return np.ascontiguousarray(out)


def render_scene(job: SceneJob, out_dir: str, max_dist_m: float = 80.0,
                 setting_overrides: Mapping[str, Mapping[str, Any]] = DEFAULT_RENDERS) -> list[dict]:
    """Render one scene's images into out_dir/images/<split>/ under a render setting's config overrides
    and return their label records."""
    rng = np.random.default_rng(job.seed)
    config = _scene_config(rng, job.split, setting_overrides)
    target_kind = str(rng.choice(TARGET_KINDS, p=TARGET_KIND_WEIGHTS))
    spec, info = compose_scene(config, target_kind, _add_red_distractors(rng))
    model = spec.compile()
    data = mujoco.MjData(model)
    vehicle = Vehicle(model, data, config.vehicle)
    rig = CameraRig(model, config.camera, fog=config.scenario.fog_end_m > 0)
    faces = {s.name: (model.geom(s.face_geom).id, s.corners_m()) for s in info.signs}
    kinds = {s.name: s.kind for s in info.signs}
    layout = info.layout
    records = []
    try:
        for k in range(job.n_images):
            camera = "front" if rng.random() < 0.75 else "side"
            cam_id = model.camera(f"car/{camera}").id
            base_pos, base_quat = model.cam_pos[cam_id].copy(), model.cam_quat[cam_id].copy()
            _camera_jitter(model, cam_id, base_pos, base_quat, rng)
            lane = int(rng.integers(layout.lanes_per_direction))
            y = layout.lane_center_y_m + lane * layout.lane_width_m + float(rng.uniform(-0.6, 0.6))
            if rng.random() < 0.85:  # looking down the road at the target sign
                # Square-root spacing puts more samples far away, where signs are small and hard.
                dist_m = 5.0 + (max_dist_m - 5.0) * math.sqrt(rng.random())
                x = info.stop_sign.face_center_m[0] - dist_m - float(base_pos[0])
                yaw = math.radians(rng.uniform(-3, 3))
            else:  # elsewhere: past the junction, or turned towards the roadside
                dist_m = -1.0
                x = float(rng.uniform(-250, 40))
                yaw = math.radians(rng.choice([-1, 1]) * rng.uniform(15, 75))
            vehicle.place(x, y, yaw, 0.0)
            image = _degrade(rig.render_rgb(data, camera), rng)
            boxes = rig.sign_boxes(data, camera, faces)
            labels = [(kinds[name], box) for name, box in boxes.items() if box[3] - box[1] >= MIN_LABEL_HEIGHT_PX]
            model.cam_pos[cam_id], model.cam_quat[cam_id] = base_pos, base_quat
            rel = f"images/{job.split}/{job.first_index + k:06d}.png"
            # Not atomic: the whole dataset is written to a .partial folder, renamed when complete.
            write_image(os.path.join(out_dir, rel), image[..., ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 1], atomic=False)
            records.append({
                "image": rel,
                "boxes": [[round(float(v), 3) for v in box] for _, box in labels],
                "classes": [kind for kind, _ in labels],
                "meta": {"town": config.scenario.town, "placement": config.scenario.placement,
                         "layout_seed": config.scenario.layout_seed, "camera": camera,
                         "target_kind": target_kind, "dist_m": round(dist_m, 3),
                         "sun_elevation_deg": round(config.scenario.sun_elevation_deg, 2),
                         "sun_azimuth_deg": round(config.scenario.sun_azimuth_deg, 2),
                         "sun_intensity": round(config.scenario.sun_intensity, 3),
                         "fog_start_m": round(config.scenario.fog_start_m, 1),
                         "fog_end_m": round(config.scenario.fog_end_m, 1)},
            })
    finally:
        rig.close()
    return records


def _jobs(config: DataGenConfig) -> list[SceneJob]:
    seeds = np.random.SeedSequence(config.seed)
    jobs = []
    for split, count in (("train", config.n_train), ("val", config.n_val)):
        for first in range(0, count, config.images_per_scene):
            child = seeds.spawn(1)[0]
            jobs.append(SceneJob(split, first, min(config.images_per_scene, count - first), int(child.generate_state(1)[0])))
    return jobs


def _render_job(args: tuple[SceneJob, str, float, Mapping]) -> tuple[SceneJob, list[dict]]:
    job, out_dir, max_dist_m, setting_overrides = args
    return job, render_scene(job, out_dir, max_dist_m, setting_overrides)


def make_dataset(out_dir: str | os.PathLike, config: DataGenConfig, overwrite: bool = False) -> Path:
    """Render the dataset into `out_dir`. Same config, same images and labels."""
    out = Path(out_dir)
    if out.exists() and not overwrite:
        raise ConfigError(f"{out} already exists; choose another --out or pass --overwrite")
    check_offscreen_rendering()  # no EGL: one line, before the progress bar and the workers
    partial = out.with_name(out.name + ".partial")
    shutil.rmtree(partial, ignore_errors=True)
    # A stop before the rename (Ctrl-C, SIGTERM, a worker that died, a full disk) leaves no half-made dataset.
    try:
        _render_dataset(partial, config, out)
        if out.exists():
            shutil.rmtree(out)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    os.replace(partial, out)
    return out


def _render_dataset(partial: Path, config: DataGenConfig, out: Path) -> None:
    """Render every image and write the labels and generation.json into `partial` (the labels name `out`)."""
    from tqdm import tqdm

    for split in SPLITS:
        (partial / "images" / split).mkdir(parents=True)
    jobs = _jobs(config)
    results: dict[int, list[dict]] = {}
    work = [(job, str(partial), config.max_dist_m, config.setting_overrides) for job in jobs]
    with tqdm(total=config.n_train + config.n_val, desc="rendering", unit="img") as bar:
        if config.workers == 1:
            outputs = map(_render_job, work)
            pool = None
        else:
            import multiprocessing

            # Each worker builds its own renderers: GL contexts are never shared across processes.
            # The workers die with this process and leave Ctrl-C to it (`avsim.workers`).
            pool = ProcessPoolExecutor(config.workers, mp_context=multiprocessing.get_context("spawn"),
                                       initializer=init_worker, initargs=({}, os.getpid()))
            outputs = pool.map(_render_job, work)
        finished = False
        try:
            for job, records in outputs:
                results[jobs.index(job)] = records
                bar.update(job.n_images)
            finished = True
        finally:
            if pool is not None and finished:
                pool.shutdown()
            elif pool is not None:
                terminate_workers(pool)
    records = {split: [record for i, job in enumerate(jobs) if job.split == split for record in results[i]] for split in SPLITS}
    write_labels(partial, config.label_format, records, IMAGE_SIZE_PX, out)
    write_text(partial / "generation.json", json.dumps({**asdict(config), "val_layout_seed": VAL_LAYOUT_SEED,
                                                        "val_sun_elevation_deg": VAL_SUN_ELEVATION_DEG}, indent=2), atomic=False)
