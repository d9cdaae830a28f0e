"""The offscreen renderer: each one draws into a framebuffer of its own size, a region read back
alone is rasterised alone, with the whole frame's pixels, and the rasteriser's thread count moves no pixel."""

import os
import subprocess
import sys

import mujoco
import numpy as np
import pytest

from avsim.loop import ClosedLoop
from avsim.errors import RenderError
from avsim.sensors import gl
from avsim.sensors.gl import OffscreenRenderer, check_offscreen_rendering, check_texture_anisotropy
from avsim.vehicle.physics import FRONT_BUMPER_X_M
from avsim.world.signs import set_texture_data
from helpers import PROCESS_TIMEOUT_S, make_config

# A red box filling the view of a camera looking down the x axis, before a grey plane.
SCENE = """
<mujoco>
  <visual><global offwidth="1280" offheight="960"/></visual>
  <worldbody>
    <light pos="0 0 10" dir="0 0 -1"/>
    <camera name="cam" pos="0 0 1" xyaxes="0 -1 0 0 0 1" fovy="40"/>
    <geom type="plane" size="50 50 1" rgba="0.5 0.5 0.5 1"/>
    <geom type="box" pos="6 0 1" size="0.1 1 0.6" rgba="0.9 0.1 0.1 1"/>
  </worldbody>
</mujoco>
"""


def test_each_renderer_gets_a_framebuffer_of_its_own_size_and_the_model_keeps_its_settings():
    model = mujoco.MjModel.from_xml_string(SCENE)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    frames = {}
    for width_px, height_px in ((640, 480), (1600, 1200)):  # smaller and larger than the model's 1280x960
        renderer = OffscreenRenderer(model, width_px, height_px, segmentation=False)
        try:
            assert (renderer._con.offWidth, renderer._con.offHeight) == (width_px, height_px)
            frames[width_px] = renderer.render(data, 0, mujoco.MjvOption()).copy()
        finally:
            renderer.close()
        assert (model.vis.global_.offwidth, model.vis.global_.offheight) == (1280, 960)
    for width_px, frame in frames.items():
        height_px = frame.shape[0]
        centre = frame[height_px // 2, width_px // 2].astype(int)
        # The bottom-right pixel is the plane; in a framebuffer of the model's 1280x960 it would be off the
        # buffer at 1600x1200.
        corner = frame[height_px - 1, width_px - 1].astype(int)
        assert centre[0] - centre[1] > 80, (width_px, centre)  # the red box
        assert corner.min() > 40 and abs(corner[0] - corner[1]) < 10, (width_px, corner)


def _place(loop, dist_m: float) -> None:
    """The car's bumper `dist_m` before the stop line, on its lane."""
    loop.vehicle.place(loop.scene.stop_line_x_m - dist_m - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
    mujoco.mj_forward(loop.model, loop.data)


# (x0, y0, x1, y1) [px] in a 640x480 frame: the front camera's deployed region, the detector's crop around
# it, a sign-sized box inside the frame, and a strip along the bottom edge.
REGIONS_PX = ((288, 0, 640, 256), (160, 0, 640, 384), (301, 117, 333, 151), (0, 400, 640, 480))


def _render(renderer: OffscreenRenderer, loop, camera_id: int, region=None) -> np.ndarray:
    """The render's pixels; for segmentation, the model geom under each pixel (scene indices depend on
    which geoms were culled, which depends on the region)."""
    frame = renderer.render(loop.data, camera_id, mujoco.MjvOption(), region).astype(np.int32)
    if renderer._scene.flags[mujoco.mjtRndFlag.mjRND_SEGMENT]:
        frame = renderer.geom_id_lookup()[frame[..., 0] | (frame[..., 1] << 8) | (frame[..., 2] << 16)]
    return frame


@pytest.mark.parametrize("segmentation, overrides", [
    (False, {"scenario": {"town": "town07"}}),
    (False, {"scenario": {"town": "town10", "materials": "textured", "sun_shadow_map_px": 1024}}),
    (False, {"scenario": {"town": "town03"}, "camera": {"offsamples": 4}}),
    (True, {"scenario": {"town": "town10"}}),
])
def test_a_region_rasterised_alone_has_the_whole_frames_pixels(segmentation, overrides):
    loop = ClosedLoop(make_config(**overrides))
    masked = OffscreenRenderer(loop.model, 640, 480, segmentation=segmentation)
    whole = OffscreenRenderer(loop.model, 640, 480, segmentation=segmentation)
    whole.rasterise_region_only = False
    try:
        for dist_m in (60.0, 12.0):
            _place(loop, dist_m)
            for camera in ("car/front", "car/side"):
                camera_id = loop.model.camera(camera).id
                frame = _render(whole, loop, camera_id)
                for x0, y0, x1, y1 in REGIONS_PX:
                    region = _render(masked, loop, camera_id, (x0, y0, x1, y1))
                    assert masked._stencil_region == (x0, y0, x1, y1)  # the mask was in use
                    assert np.array_equal(region, frame[y0:y1, x0:x1]), (overrides, dist_m, camera, (x0, y0, x1, y1))
                # After region renders, a whole frame is drawn whole again.
                assert np.array_equal(_render(masked, loop, camera_id), frame), (overrides, dist_m, camera)
    finally:
        masked.close()
        whole.close()
        loop.close()


def test_a_reflective_material_keeps_the_stencil_buffer_for_mujoco_and_draws_the_whole_frame():
    # MuJoCo draws reflections through the stencil buffer, so the region's mask must stay out of its way.
    model = mujoco.MjModel.from_xml_string(SCENE.replace(
        "<worldbody>", '<asset><material name="mirror" reflectance="0.5"/></asset><worldbody>').replace(
        'rgba="0.5 0.5 0.5 1"', 'material="mirror"'))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    option = mujoco.MjvOption()
    renderer = OffscreenRenderer(model, 640, 480, segmentation=False)
    try:
        frame = renderer.render(data, 0, option).copy()
        region = renderer.render(data, 0, option, (100, 200, 400, 480))
        assert renderer._stencil_region is None
        assert np.array_equal(region, frame[200:480, 100:400])
    finally:
        renderer.close()


# Renders a few frames and prints their digest; run once per llvmpipe thread count, which Mesa reads when
# the process's first GL context starts.
_FRAMES_DIGEST = """
import hashlib, mujoco
from avsim.config import SimConfig, with_overrides
from avsim.loop import ClosedLoop
from avsim.sensors.gl import OffscreenRenderer
from avsim.vehicle.physics import FRONT_BUMPER_X_M
digest = hashlib.sha256()
for town in ("town07", "town10"):
    loop = ClosedLoop(with_overrides(SimConfig(), {"scenario": {"town": town}, "perception": {"kind": "oracle"}}))
    renderer = OffscreenRenderer(loop.model, 640, 480, segmentation=False)
    for dist_m in (60.0, 15.0):
        loop.vehicle.place(loop.scene.stop_line_x_m - dist_m - FRONT_BUMPER_X_M, loop.scene.layout.lane_center_y_m, 0.0, 0.0)
        mujoco.mj_forward(loop.model, loop.data)
        for camera in ("car/front", "car/side"):
            camera_id = loop.model.camera(camera).id
            digest.update(renderer.render(loop.data, camera_id, mujoco.MjvOption()).tobytes())
            digest.update(renderer.render(loop.data, camera_id, mujoco.MjvOption(), (288, 0, 640, 256)).tobytes())
    renderer.close()
    loop.close()
print(digest.hexdigest())
"""


def test_the_rasteriser_thread_count_changes_no_pixel():
    # A batch worker rasterises on its share of the cores (`run_task.worker_env`), a lone run on a thread per
    # core, and 0 draws in the run's own thread. A run's result must not depend on which: every frame the same.
    digests = {}
    for threads in ("0", "1", "2"):
        env = {**os.environ, "LP_NUM_THREADS": threads, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
        done = subprocess.run([sys.executable, "-c", _FRAMES_DIGEST], env=env, capture_output=True, text=True,
                              timeout=PROCESS_TIMEOUT_S, check=True)
        digests[threads] = done.stdout.strip()
    assert len(digests["0"]) == 64 and len(set(digests.values())) == 1, digests


def _no_egl(*args, **kwargs):
    raise RuntimeError("Cannot initialize a EGL device display\nsecond line")


def test_offscreen_rendering_is_checked_with_a_one_line_fix(monkeypatch):
    check_offscreen_rendering()  # this machine renders
    monkeypatch.setattr("avsim.sensors.gl.mujoco.GLContext", _no_egl)
    monkeypatch.delenv("MUJOCO_EGL_DEVICE_ID", raising=False)
    with pytest.raises(RenderError, match="install Mesa's EGL") as err:
        check_offscreen_rendering()
    assert "\n" not in str(err.value) and "Cannot initialize a EGL device display" in str(err.value)
    # A device number the machine lacks is named as the fault, not a missing EGL.
    monkeypatch.setenv("MUJOCO_EGL_DEVICE_ID", "99")
    with pytest.raises(RenderError, match=r"unset MUJOCO_EGL_DEVICE_ID \(=99\)"):
        check_offscreen_rendering()


def _striped_road() -> mujoco.MjModel:
    """SCENE with its plane painted in 12.5-cm stripes along the camera's view (x)."""
    spec = mujoco.MjSpec.from_string(SCENE)
    stripes = np.zeros((64, 64, 3), np.uint8)
    stripes[(np.arange(64) // 8) % 2 == 1] = 230  # rows alternate: the texture varies along v only
    set_texture_data(spec.add_texture(name="stripes", type=mujoco.mjtTexture.mjTEXTURE_2D), stripes)
    road = spec.add_material(name="road", texrepeat=[1, 1], texuniform=True)
    road.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "stripes"
    spec.geoms[0].material = "road"
    return spec.compile()


def _striped_road_frames(ratios: tuple[int, ...]) -> dict[int, np.ndarray]:
    """The striped road's 640x480 frame (H, W, 3) uint8 at each texture anisotropy ratio."""
    model = _striped_road()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    frames = {}
    for ratio in ratios:
        renderer = OffscreenRenderer(model, 640, 480, segmentation=False, texture_anisotropy=ratio)
        try:
            frames[ratio] = renderer.render(data, 0, mujoco.MjvOption()).copy()
        finally:
            renderer.close()
    return frames


def test_anisotropic_filtering_sharpens_a_texture_seen_edge_on_and_leaves_untextured_pixels_alone():
    # Far off, a pixel's footprint on the road is long along it and narrow across it; trilinear filtering
    # blurs the texture by the footprint's length, so stripes along the road grey out, but anisotropic
    # filtering keeps them.
    frames = {ratio: frame.astype(int) for ratio, frame in _striped_road_frames((1, 16)).items()}
    box = frames[1][200:280, 300:340]  # the red box, untextured
    assert box[..., 0].min() - box[..., 1].max() > 80
    assert np.array_equal(frames[16][200:280, 300:340], box)
    # Left of the box, 15-70 m ahead of a camera 1 m above the road (rows 258-290), where a footprint is
    # 10-70 times longer than wide.
    contrast = {ratio: frame[258:290, :200].std(axis=1).mean() for ratio, frame in frames.items()}  # across each row
    assert contrast[16] > 2 * contrast[1], contrast


def _llvmpipe_of_mesa_22_3() -> bool:
    info = gl._gl_info()
    return info is not None and info.renderer.startswith("llvmpipe") and "Mesa 22.3" in info.version


@pytest.mark.skipif(not _llvmpipe_of_mesa_22_3(), reason="what docs/realism_filtering.md measured on llvmpipe of Mesa 22.3")
def test_llvmpipe_of_mesa_22_3_filters_the_whole_footprint_whatever_ratio_is_asked():
    # docs/realism_filtering.md and camera.texture_anisotropy's docs rest on this: Mesa 22.3's llvmpipe takes any
    # ratio above 1 as one filter (every texel of the footprint's ellipse, Gaussian-weighted), so 2 and 16
    # draw the same pixels, even where a footprint is 10-70 times longer than wide. A GL that honours the
    # ratio fails here, and those docs then need measuring again on it.
    frames = _striped_road_frames((2, 16))
    assert np.array_equal(frames[2], frames[16])


def test_more_anisotropy_than_the_gl_offers_is_refused_in_one_line(monkeypatch):
    monkeypatch.setattr("avsim.sensors.gl.GL.glGetFloatv", lambda name: 8.0)
    model = _striped_road()
    with pytest.raises(RenderError, match=r"filters at most 8:1 .*set camera.texture_anisotropy to 1") as err:
        OffscreenRenderer(model, 64, 48, segmentation=False, texture_anisotropy=16)
    assert "\n" not in str(err.value)


def test_a_batch_checks_the_gl_anisotropy_limit_once_before_any_renderer(monkeypatch):
    gl._gl_info.cache_clear()
    check_texture_anisotropy(16)  # llvmpipe, like most GPUs, filters up to 16:1
    monkeypatch.setattr("avsim.sensors.gl.GL.glGetFloatv", lambda name: 4.0)
    gl._gl_info.cache_clear()
    try:
        check_texture_anisotropy(4)
        with pytest.raises(RenderError, match=r"camera.texture_anisotropy = 8 but this GL filters at most 4:1") as err:
            check_texture_anisotropy(8)
        assert "\n" not in str(err.value)
    finally:
        gl._gl_info.cache_clear()
    # 1 is MuJoCo's own filtering: no context is started to check it, and a machine without one is left to
    # the offscreen check (a Ray cluster's runs render on its machines).
    monkeypatch.setattr("avsim.sensors.gl.mujoco.GLContext", _no_egl)
    check_texture_anisotropy(1)
    check_texture_anisotropy(16)
    gl._gl_info.cache_clear()
