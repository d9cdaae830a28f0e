"""One-off probe: do detectors trained on photographs find the stop sign better in MuJoCo 4's Filament
renders (`mujoco.mjrf`: physically based, tone-mapped) than in the classic OpenGL renders avsim uses?
Issue 28 asks for `render.backend = filament` if it measures better; this measures it before building it.

Every frame of `avsim realism`'s set (the `baseline` setting, towns town07, town03 and town10, two scene
draws each, out to 60 m, both cameras) is rendered again from the same state and camera by Filament at the
same size, given the very sensor-noise draw the classic frame got, and scored by the benchmark's own
`score_frame` (threshold 0.5, labels from the classic segmentation, with which Filament's geometry agrees to
within half a pixel). Filament runs as MuJoCo ships it, on avsim's unchanged scene (classic materials, which
Filament approximates; its fallback light, the scene's sun, a 40,000 lux headlight), in three looks fixed
beforehand by what a camera does, none searched for a score:

- `filament_default`: post-processing on (its default tone mapper, FXAA, ambient occlusion);
- `filament_post_off_srgb`: post-processing off, the linear 8-bit read-back put through the sRGB transfer
  function (IEC 61966-2-1) in numpy, as a camera's encoder would;
- `filament_filmic`: post-processing on, with Filament's filmic tone curve (`filament.cg.tone_mapping`).

`filament_default` is rendered twice per state: with post-processing on, Filament's frame depends on the
frames before it, not on the state alone (measured: most pixels move by 1-2 levels, thin far edges by up
to ~110), and the second render counts how often that flips a detection.

Needs Vulkan on the CPU, which avsim's install does not bring: Debian's `libvulkan1` and
`mesa-vulkan-drivers` (lavapipe). Filament leaks about 1.2 MB a frame that nothing gives back, so each
town runs in a child process. About 8 minutes on this 2-core machine.

    MUJOCO_GL=egl LP_NUM_THREADS=1 nice -n 5 python experiments/probes/filament_recall.py results/filament_recall

Writes rows.jsonl (the benchmark's row per frame, network and renderer, plus `renderer` and `render_ms`) in
the folder and prints the tables. Measured here: docs/realism_scene.md, "The Filament renderer, measured".
"""

from __future__ import annotations

import ctypes.util
import dataclasses
import glob
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

TOWNS = ("town07", "town03", "town10")
DRAWS_PER_TOWN = 2
SEED = 0  # `avsim realism --seed`'s default
THRESHOLD = 0.5  # `avsim realism --threshold`'s default
MAX_DIST_M = 60
NETWORKS = ("coco", "nanodet", "yolo", "detector")
RENDERERS = ("classic", "filament_default", "filament_post_off_srgb", "filament_filmic")
REPEAT = "filament_default_repeat"
# The headlight's intensity [lux]: `filament.fallback.head_light_intensity`'s documented default, which
# MuJoCo Studio also reported for these towns. The Python bindings cannot read it from the model.
HEADLIGHT_LUX = 40000.0
SPANS_M = ((10.0, 40.0), (40.0, 60.0))


def vulkan_missing() -> str | None:
    """Why Filament cannot start here, or None. Filament ends the process on a missing device instead of
    raising, so this is checked first."""
    if ctypes.util.find_library("vulkan") is None:
        return "no Vulkan loader"
    if not glob.glob("/usr/share/vulkan/icd.d/lvp_icd*.json"):
        return "no lavapipe (Mesa's CPU Vulkan driver)"
    return None


def srgb_table() -> np.ndarray:
    """(256,) uint8: linear 8-bit level -> sRGB-encoded level (IEC 61966-2-1)."""
    linear = np.arange(256) / 255.0
    encoded = np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * np.power(linear, 1 / 2.4) - 0.055)
    return np.clip(np.rint(encoded * 255), 0, 255).astype(np.uint8)


class FilamentCamera:
    """Renders one model's fixed cameras with Filament into an (H, W, 3) uint8 array, row 0 at the top.

    Uses the `mujoco.mjrf` bindings directly: MuJoCo's own wrapper module needs Python 3.12. One context
    serves one model (a second model's camera in the same context fails at its first render)."""

    def __init__(self, model, width_px: int, height_px: int, option) -> None:
        import mujoco
        from mujoco import mjrf

        self._mujoco, self._mjrf, self._model = mujoco, mjrf, model
        self._size = (width_px, height_px)
        self._context = mjrf.Context(mjrf.ContextConfig(graphics_api=mjrf.GraphicsApi.GRAPHICS_API_VULKAN,
                                                        software_rendering=True))
        self._scene = self._context.create_scene(mjrf.SceneParams())
        self._scene.configure_from_model(model)  # reads the model's filament.* custom fields
        resources = mjrf.ModelResources(self._context, model)
        self._lights = mjrf.ModelLights(self._scene, resources)
        self._renderables = mjrf.ModelRenderables(self._scene, resources)
        self._renderables.set_options(option)
        self._target = self._context.create_render_target(
            mjrf.RenderTargetConfig(color_format=mjrf.PixelFormat.PIXEL_FORMAT_RGB8))
        self._target.resize(width_px, height_px)
        self._pixels = np.empty((height_px, width_px, 3), np.uint8)
        self._read = mjrf.ReadRequest(target=self._target)
        self._read.set_buffer(self._pixels)
        self._camera = mujoco.MjvCamera()
        self._camera.type = int(mujoco.mjtCamera.mjCAMERA_FIXED)
        self._resources = resources  # kept alive: the lights and renderables draw from it
        self.post_processing = True

    def render(self, data, camera_id: int) -> np.ndarray:
        """A fresh (H, W, 3) uint8 frame of camera `camera_id` at the state `data` holds."""
        mujoco, mjrf = self._mujoco, self._mjrf
        self._lights.update(data)
        self._renderables.update(data)
        self._camera.fixedcamid = camera_id
        gl = mujoco.mjv_camera2GLCamera(self._model, data, self._camera)
        request = mjrf.RenderRequest()
        request.scene, request.target = self._scene, self._target
        request.camera = mjrf.Camera(pos=gl.pos, forward=gl.forward, up=gl.up, frustum_bottom=gl.frustum_bottom,
                                     frustum_top=gl.frustum_top, frustum_near=gl.frustum_near, frustum_far=gl.frustum_far)
        request.viewport.left, request.viewport.bottom = 0, 0
        request.viewport.width, request.viewport.height = self._size
        request.draw_mode = mjrf.DrawMode.DRAW_MODE_DEFAULT
        request.post_processing = self.post_processing
        request.reflections = request.shadows = request.skybox = request.haze = True
        request.headlight = bool(self._model.vis.headlight.active)
        request.headlight_color = tuple(float(c) for c in self._model.vis.headlight.diffuse)
        request.headlight_intensity = HEADLIGHT_LUX
        self._context.wait_for_frame(self._context.render([request], [self._read]))
        return self._pixels.copy()


def score_town(town: str, out_path: Path) -> None:
    """Every frame of `town`'s draws under every renderer, as rows in out_path (jsonl)."""
    import mujoco
    import mujoco.studio  # noqa: F401  registers Filament's material assets; without it the first render ends the process

    from avsim.realism.frame_set import SENSOR_NOISE_STD_LEVELS, render_scene, scene_config, scene_draws
    from avsim.realism.scoring import build_networks, score_frame
    from avsim.realism.settings import SETTINGS
    from avsim.sensors.camera import camera_view_option
    from avsim.sensors.noise import SensorNoise
    from avsim.world.scene import compose_scene

    setting = SETTINGS["baseline"]
    networks = build_networks(NETWORKS)
    option = camera_view_option()
    encode = srgb_table()
    rows = []
    for scene in scene_draws((town,), DRAWS_PER_TOWN, SEED):
        # The filmic look is a field of the model, so it is a second compile of the same scene, posed each frame.
        spec, _ = compose_scene(scene_config(scene, setting))
        spec.add_text(name="filament.cg.tone_mapping", data="filmic")
        filmic_model = spec.compile()
        filmic_data = mujoco.MjData(filmic_model)
        # One generator per renderer, seeded as the benchmark's: frame k of each gets the classic frame k's noise.
        noises = {name: SensorNoise(SENSOR_NOISE_STD_LEVELS, scene.seed) for name in (*RENDERERS[1:], REPEAT, "check")}
        cameras = None
        for index, (frame, model, data, rig) in enumerate(render_scene(scene, setting, MAX_DIST_M)):
            if cameras is None:
                size = (rig.config.width_px, rig.config.height_px)
                cameras = {"default": FilamentCamera(model, *size, option), "filmic": FilamentCamera(filmic_model, *size, option)}
            assert np.array_equal(noises["check"].apply(rig.render_rgb(data, frame.camera)), frame.image), "noise out of step"
            filmic_data.qpos[:] = data.qpos
            mujoco.mj_forward(filmic_model, filmic_data)
            assert np.array_equal(filmic_data.cam_xmat, data.cam_xmat), "the filmic model is posed elsewhere"
            camera_id = model.camera(f"car/{frame.camera}").id
            default, filmic = cameras["default"], cameras["filmic"]
            draws = {
                "filament_default": lambda: default.render(data, camera_id),
                REPEAT: lambda: default.render(data, camera_id),
                "filament_post_off_srgb": lambda: encode[_without_post(default, data, camera_id)],
                "filament_filmic": lambda: filmic.render(filmic_data, camera_id),
            }
            images, render_ms = {"classic": frame.image}, {"classic": frame.render_cpu_s * 1000}
            for name, draw in draws.items():
                start = time.perf_counter()
                image = draw()
                render_ms[name] = (time.perf_counter() - start) * 1000
                images[name] = noises[name].apply(image)
            segmentation: dict = {}  # the geom-id image depends on the state only: shared by every renderer
            common = {"town": town, "scene": scene.index, "frame": index, "camera": frame.camera,
                      "dist_m": None if frame.dist_m is None else round(frame.dist_m, 3)}
            for renderer, image in images.items():
                scored = dataclasses.replace(frame, image=image)
                for name, detector in networks.items():
                    rows.append({"renderer": renderer, **common, "network": name, "render_ms": round(render_ms[renderer], 2),
                                 **score_frame(scored, detector, THRESHOLD, model, data, rig, segmentation)})
        del cameras
    out_path.write_text("".join(json.dumps(row) + "\n" for row in rows))


def _without_post(camera: FilamentCamera, data, camera_id: int) -> np.ndarray:
    camera.post_processing = False
    try:
        return camera.render(data, camera_id)
    finally:
        camera.post_processing = True


def print_tables(rows: list[dict]) -> None:
    from avsim.stats import rate_with_interval

    def sign_rows(network, renderer, camera, span):
        return [r for r in rows if r["network"] == network and r["renderer"] == renderer and r["camera"] == camera
                and r["dist_m"] is not None and r["n_truth"] and span[0] <= r["dist_m"] < span[1]]

    print("front camera, the three towns pooled: recall (Wilson 95 %), median best score on the sign, false stop signs "
          "in all frames of both cameras")
    for network in NETWORKS:
        for renderer in RENDERERS:
            cells = [sign_rows(network, renderer, "front", span) for span in SPANS_M]
            recall = "   ".join(f"{lo:.0f}-{hi:.0f} m {rate_with_interval(sum(r['found'] for r in c), len(c))}"
                               for (lo, hi), c in zip(SPANS_M, cells))
            median = np.median([r["best_score"] for c in cells for r in c])
            every = [r for r in rows if r["network"] == network and r["renderer"] == renderer]
            false = sum(len(r["false_stop_signs"]) for r in every)
            print(f"  {network:8s} {renderer:24s} {recall}   median {median:.3f}   false {false}/{len(every)}")
    print("the same states paired, sign frames 10-60 m: found by classic only / by the Filament look only")
    keyed = {(r["renderer"], r["network"], r["town"], r["scene"], r["frame"]): r["found"] for r in rows}
    for network in NETWORKS:
        for camera in ("front", "side"):
            base = sign_rows(network, "classic", camera, (10.0, 60.0))
            parts = []
            for renderer in RENDERERS[1:]:
                other = [keyed[(renderer, network, r["town"], r["scene"], r["frame"])] for r in base]
                only_classic = sum(r["found"] and not o for r, o in zip(base, other))
                only_other = sum(o and not r["found"] for r, o in zip(base, other))
                parts.append(f"{renderer} {only_classic}/{only_other}")
            print(f"  {network:8s} {camera:5s} " + "   ".join(parts))
    flips = {n: sum(keyed[("filament_default", n, *k[2:])] != keyed[(REPEAT, n, *k[2:])]
                    for k in keyed if k[0] == "filament_default" and k[1] == n) for n in NETWORKS}
    print("filament_default rendered twice from the same state: frames whose outcome flipped "
          + ", ".join(f"{n} {k}" for n, k in flips.items()))
    for renderer in (*RENDERERS, REPEAT):
        times = [r["render_ms"] for r in rows if r["renderer"] == renderer and r["network"] == NETWORKS[0]]
        print(f"  render {renderer:24s} median {np.median(times):6.1f} ms a frame"
              + (" (CPU time)" if renderer == "classic" else " (wall time, read-back included)"))


def main(argv: list[str]) -> int:
    if len(argv) == 3 and argv[0] == "--town":  # a child: one town
        score_town(argv[1], Path(argv[2]))
        return 0
    if len(argv) != 1:
        print("usage: python experiments/probes/filament_recall.py OUT_DIR", file=sys.stderr)
        return 2
    missing = vulkan_missing()
    if missing:
        print(f"error: Filament needs Vulkan on the CPU and this machine has {missing}; install Debian's "
              "libvulkan1 and mesa-vulkan-drivers", file=sys.stderr)
        return 2
    out = Path(argv[0])
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for town in TOWNS:
        part = out / f"rows_{town}.jsonl"
        start = time.monotonic()
        subprocess.run([sys.executable, __file__, "--town", town, str(part)], check=True,
                       env={**os.environ, "LP_NUM_THREADS": os.environ.get("LP_NUM_THREADS", "1")})
        print(f"{town}: {time.monotonic() - start:.0f} s", flush=True)
        rows += [json.loads(line) for line in part.read_text().splitlines()]
        part.unlink()
    (out / "rows.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))
    print_tables(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
