"""Run the realism benchmark: every render setting's frames through every network, in worker processes.

One job is one (setting, scene draw): the scene is compiled under the setting, its frames rendered
and each scored by every network. Jobs run on `workers` processes (each with its own GL context and
networks, one torch thread); rows come back in job order, so the same arguments give the same rows.
"""

from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from avsim.realism.frame_set import DEFAULT_MAX_DIST_M, SceneDraw, render_scene, scene_draws
from avsim.realism.scoring import build_networks, score_frame
from avsim.realism.settings import RenderSetting
from avsim.sensors.gl import check_offscreen_rendering, check_texture_anisotropy
from avsim.workers import init_worker, terminate_workers

_WORKER: dict = {}


@dataclass(frozen=True)
class BenchmarkPlan:
    """What to run: settings in order, towns, scene draws per town (`--frames`), networks, the
    detection threshold, the seed of the frame set and its farthest distance bin's end [m]."""

    settings: tuple[RenderSetting, ...]
    towns: tuple[str, ...]
    draws_per_town: int
    networks: tuple[str, ...]
    threshold: float = 0.5
    seed: int = 0
    max_dist_m: int = DEFAULT_MAX_DIST_M
    overrides: Mapping[str, Any] = field(default_factory=dict)  # `--set` values (nested), under every frame

    def jobs(self) -> list[tuple[RenderSetting, SceneDraw]]:
        """Every (setting, scene) pair to render: each setting over the same seeded scene draws."""
        return [(setting, scene) for setting in self.settings for scene in scene_draws(self.towns, self.draws_per_town, self.seed)]


def _start_worker(env: dict[str, str], parent_pid: int, networks: tuple[str, ...]) -> None:
    init_worker(env, parent_pid)
    _WORKER["networks"] = build_networks(networks)


def run_job(job: tuple[RenderSetting, SceneDraw, float, int, Mapping[str, Any]]) -> list[dict]:
    """Rows of one scene under one setting: one per frame and network. job: (setting, scene, detection
    threshold, farthest bin's end [m], --set values)."""
    setting, scene, threshold, max_dist_m, overrides = job
    rows = []
    for index, (frame, model, data, rig) in enumerate(render_scene(scene, setting, max_dist_m, overrides)):
        segmentation: dict = {}
        common = {"setting": setting.name, "town": scene.town, "placement": scene.placement, "scene": scene.index,
                  "frame": index, "camera": frame.camera, "dist_m": None if frame.dist_m is None else round(frame.dist_m, 3),
                  "render_cpu_ms": round(frame.render_cpu_s * 1000, 3)}
        for name, detector in _WORKER["networks"].items():
            rows.append({**common, "network": name, **score_frame(frame, detector, threshold, model, data, rig, segmentation)})
    return rows


def run_benchmark(plan: BenchmarkPlan, workers: int) -> list[dict]:
    """Every job's rows, in job order, with a progress bar."""
    from tqdm import tqdm

    check_offscreen_rendering()  # no EGL: one line, before the progress bar and the workers
    for setting in plan.settings:  # so is a GL that filters less than a setting asks
        check_texture_anisotropy(setting.config(plan.overrides).camera.texture_anisotropy)
    jobs = [(setting, scene, plan.threshold, plan.max_dist_m, plan.overrides) for setting, scene in plan.jobs()]
    rows: list[dict] = []
    # Built here first, whatever the workers: missing or corrupt weights are refused in one line
    # before anything renders, not inside a worker.
    _WORKER["networks"] = build_networks(plan.networks)
    if workers == 1:
        for job in tqdm(jobs, desc="realism", unit="scene"):
            rows.extend(run_job(job))
        return rows
    pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"), initializer=_start_worker,
                               initargs=({}, os.getpid(), plan.networks))
    finished = False
    try:
        for job_rows in tqdm(pool.map(run_job, jobs), total=len(jobs), desc="realism", unit="scene"):
            rows.extend(job_rows)
        finished = True
    finally:
        if finished:
            pool.shutdown()
        else:
            terminate_workers(pool)
    return rows
