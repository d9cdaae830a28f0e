"""Cameras: intrinsics, poses, segmentation boxes against geometry, and rendered pixels."""

import hashlib
import math

import cv2
import mujoco
import numpy as np
import pytest

from avsim.config import ORACLE_MIN_BOX_HEIGHT_PX, CameraConfig
from avsim.sensors.pinhole import pinhole_distance_m
from avsim.errors import RenderError
from avsim.loop import ClosedLoop
from avsim.sensors import gl
from avsim.sensors.camera import Intrinsics
from helpers import make_config


@pytest.fixture(scope="module")
def near_scene():
    """town07 with the sign at the `near` placement, so it stays in view down to 10 m."""
    loop = ClosedLoop(make_config(scenario={"placement": "near"}))
    yield loop
    loop.close()


def _put_camera_at_depth(loop: ClosedLoop, depth_m: float, camera: str = "front") -> None:
    """Place the car so the sign face is `depth_m` ahead of the camera along the road."""
    cam_x = float(loop.model.cam_pos[loop.model.camera(f"car/{camera}").id][0])
    face_x = loop.scene.stop_sign.face_center_m[0]
    loop.vehicle.place(face_x - depth_m - cam_x, loop.scene.layout.lane_center_y_m, 0.0, 0.0)


def _stop_box(loop, camera="front"):
    sign = loop.scene.stop_sign
    faces = {sign.name: (loop.model.geom(sign.face_geom).id, sign.corners_m())}
    return loop.rig.sign_boxes(loop.data, camera, faces).get(sign.name)


def test_intrinsics_follow_the_pinhole_formula():
    intr = Intrinsics(640, 480, 30.0)
    assert intr.f_px == pytest.approx(240 / math.tan(math.radians(15)))
    assert intr.principal_point_px == (320.0, 240.0)
    assert np.allclose(intr.matrix(), [[intr.f_px, 0, 320], [0, intr.f_px, 240], [0, 0, 1]])


def test_default_camera_sees_a_stop_sign_at_least_15_px_tall_at_40_m():
    intr = Intrinsics(640, 480, make_config().camera.fovy_deg)
    assert 0.762 * intr.f_px / 40.0 >= 15.0


def test_front_camera_sits_behind_the_windscreen_at_1_4_to_1_5_m(near_scene):
    pose = near_scene.rig.pose(near_scene.data, "front")
    assert 1.4 <= pose.position_m[2] <= 1.5


def test_side_camera_is_yawed_towards_the_right_roadside(near_scene):
    pose = near_scene.rig.pose(near_scene.data, "side")
    forward = -pose.rotation[:, 2]
    yaw_right_deg = math.degrees(math.atan2(-forward[1], forward[0]))
    assert yaw_right_deg == pytest.approx(near_scene.config.camera.side_yaw_deg, abs=1e-6)


@pytest.mark.parametrize("depth_m", [10.0, 15.0, 20.0, 30.0, 40.0, 50.0, 60.0])
def test_pinhole_distance_from_ground_truth_box_is_within_5_percent(near_scene, depth_m):
    _put_camera_at_depth(near_scene, depth_m)
    box = _stop_box(near_scene)
    assert box is not None
    f_px = near_scene.rig.intrinsics("front").f_px
    true_depth = near_scene.rig.pose(near_scene.data, "front").depth_m(near_scene.scene.stop_sign.face_center_m)
    estimate = pinhole_distance_m(0.762, f_px, box[3] - box[1])
    assert estimate == pytest.approx(true_depth, rel=0.05)


@pytest.mark.parametrize("camera", ["front", "side"])
@pytest.mark.parametrize("depth_m", [15.0, 30.0, 50.0])
def test_projected_sign_corners_land_within_2_px_of_segmentation_box(near_scene, camera, depth_m):
    _put_camera_at_depth(near_scene, depth_m, camera)
    box = _stop_box(near_scene, camera)
    assert box is not None
    pose = near_scene.rig.pose(near_scene.data, camera)
    rvec, tvec = pose.opencv_extrinsics()
    corners = near_scene.scene.stop_sign.corners_m()
    pixels, _ = cv2.projectPoints(corners, rvec, tvec, near_scene.rig.intrinsics(camera).matrix(), None)
    pixels = pixels.reshape(-1, 2)
    projected = (pixels[:, 0].min(), pixels[:, 1].min(), pixels[:, 0].max(), pixels[:, 1].max())
    assert np.allclose(projected, box, atol=2.0)


def _aim_car_at_sign(loop: ClosedLoop, x_m: float, y_m: float) -> None:
    sign = loop.scene.stop_sign.base_pos_m
    loop.vehicle.place(x_m, y_m, math.atan2(sign[1] - y_m, sign[0] - x_m), 0.0)


@pytest.mark.parametrize("town", ["town07", "town10"])  # the stop sign alone; a town with more signs
def test_a_minimum_height_leaves_out_only_boxes_shorter_than_it_and_skips_the_far_renders(town, monkeypatch):
    loop = ClosedLoop(make_config(scenario={"town": town}, camera={"seg_supersample": CameraConfig().seg_supersample}))
    faces = {s.name: (loop.model.geom(s.face_geom).id, s.corners_m()) for s in loop.scene.signs}
    min_px = ORACLE_MIN_BOX_HEIGHT_PX
    renders = []
    real = gl.OffscreenRenderer.render
    monkeypatch.setattr(gl.OffscreenRenderer, "render", lambda self, *a, **k: renders.append(1) or real(self, *a, **k))
    skipped = 0
    # from where the stop sign is a few pixels tall to where it first passes the height, in steps of a few pixels' rows
    for depth_m in np.arange(60.0, 190.0, 2.5):
        _put_camera_at_depth(loop, depth_m)
        mujoco.mj_forward(loop.model, loop.data)
        every = loop.rig.sign_boxes(loop.data, "front", faces)
        before = len(renders)
        tall = loop.rig.sign_boxes(loop.data, "front", faces, min_height_px=min_px)
        skipped += len(renders) == before
        assert {k: v for k, v in tall.items() if v[3] - v[1] >= min_px} == {k: v for k, v in every.items() if v[3] - v[1] >= min_px}
    loop.close()
    if town == "town07":
        assert skipped >= 20, "beyond the oracle's range the front camera should render nothing"


def test_segmentation_box_respects_occlusion_by_buildings():
    loop = ClosedLoop(make_config(scenario={"town": "town03"}))
    sign_x, edge_y = loop.scene.stop_sign.base_pos_m[0], loop.scene.layout.lane_edge_y_m
    _aim_car_at_sign(loop, sign_x - 25.0, edge_y - 3.0)  # on the sidewalk: clear view
    assert _stop_box(loop) is not None
    _aim_car_at_sign(loop, sign_x - 25.0, edge_y - 60.0)  # behind the right-hand block
    assert _stop_box(loop) is None
    loop.close()


def test_rgb_render_shows_a_red_sign_inside_its_box(near_scene):
    _put_camera_at_depth(near_scene, 20.0)
    image = near_scene.rig.render_rgb(near_scene.data, "front")
    assert image.shape == (480, 640, 3) and image.dtype == np.uint8
    x0, y0, x1, y1 = (int(round(v)) for v in _stop_box(near_scene))
    patch = image[y0:y1, x0:x1].reshape(-1, 3).astype(int)
    red = (patch[:, 0] > 120) & (patch[:, 1] < 80) & (patch[:, 2] < 90)
    assert red.mean() > 0.4


def test_ego_car_shell_is_not_in_its_own_camera(near_scene):
    _put_camera_at_depth(near_scene, 200.0)
    seg = near_scene.rig.render_segmentation(near_scene.data, "front")
    ego = {g for g in range(near_scene.model.ngeom) if near_scene.model.geom(g).name.startswith("car/") or near_scene.model.geom_bodyid[g] != 0 and near_scene.model.body(near_scene.model.geom_bodyid[g]).name.startswith("car/")}
    assert not np.isin(seg, list(ego)).any()


def test_missing_gl_backend_gives_a_one_line_render_error(monkeypatch):
    def no_gl(*args, **kwargs):
        raise RuntimeError("eglInitialize failed\nsecond line")
    monkeypatch.setattr(gl.mujoco, "GLContext", no_gl)
    loop = ClosedLoop(make_config())
    with pytest.raises(RenderError) as err:
        loop.rig.render_rgb(loop.data, "front")
    assert "\n" not in str(err.value) and "MUJOCO_GL" in str(err.value) and "osmesa" in str(err.value)


def test_asking_again_for_the_same_state_gives_the_same_frame_and_a_new_state_a_new_one():
    """render_rgb keeps each camera's last frame; it must never hand back a stale one."""
    loop = ClosedLoop(make_config(scenario={"start_dist_m": 60.0}))
    fresh = ClosedLoop(make_config(scenario={"start_dist_m": 60.0}))
    loop.rig.reuse_last_frame = fresh.rig.reuse_last_frame = True
    try:
        first = loop.rig.render_rgb(loop.data, "front")
        again = loop.rig.render_rgb(loop.data, "front")
        assert np.array_equal(first, again) and first is not again
        again[:] = 0  # a caller's copy: changing it changes nothing kept
        assert np.array_equal(loop.rig.render_rgb(loop.data, "front"), first)
        side = loop.rig.render_rgb(loop.data, "side")
        assert not np.array_equal(side, first)
        for _ in range(3):
            loop.step()
            fresh.step()
            moved = loop.rig.render_rgb(loop.data, "front")
            # Drawn by a rig that draws this state for the first time: the same pixels, bit for bit.
            assert np.array_equal(moved, fresh.rig.render_rgb(fresh.data, "front"))
        assert not np.array_equal(moved, first)
        # A change of the model's appearance at the same state (the view bank hides the sign's face
        # this way) is a new frame, not the kept one.
        sign = loop.scene.stop_sign
        face = loop.model.geom(sign.face_geom).id
        group = int(loop.model.geom_group[face])
        loop.model.geom_group[face] = 5
        hidden = loop.rig.render_rgb(loop.data, "front")
        loop.model.geom_group[face] = group
        assert not np.array_equal(hidden, moved)
        assert np.array_equal(loop.rig.render_rgb(loop.data, "front"), moved)
    finally:
        loop.close()
        fresh.close()


# sha256 of the first front and side frames of a default run (town07, standard placement), as rendered
# at ed65e80, before camera.preset existed: the study preset keeps every existing result's pixels.
DEFAULT_RENDER_SHA256 = {"front": "c9344d252e107785c594ea5c7d6c678674af1edfa5f85a23aaa3ebbf9227bba2",
                         "side": "dddeabda3b9635198ace362a2011d1b8a43d77744bc608fa7f11b6e26573715f"}


def test_the_default_preset_renders_bit_identical_frames_to_before_presets():
    loop = ClosedLoop(make_config())
    try:
        for camera, digest in DEFAULT_RENDER_SHA256.items():
            assert hashlib.sha256(loop.rig.render_rgb(loop.data, camera).tobytes()).hexdigest() == digest
    finally:
        loop.close()


@pytest.fixture(scope="module")
def automotive_near_scene():
    """The near placement seen by the automotive preset's 1920x1080 cameras."""
    loop = ClosedLoop(make_config(scenario={"placement": "near"}, camera={"preset": "automotive_1080p"}))
    yield loop
    loop.close()


@pytest.mark.parametrize("depth_m", [20.0, 60.0])
def test_the_pinhole_range_follows_the_automotive_preset(automotive_near_scene, depth_m):
    loop = automotive_near_scene
    _put_camera_at_depth(loop, depth_m)
    box = _stop_box(loop)
    camera_model = loop.policy.context.cameras["front"]
    # The policies' camera model and the recorders' intrinsics are the preset's.
    assert camera_model.f_px == pytest.approx(loop.config.camera.f_px) and camera_model.cx_px == 960.0
    assert loop.rig.intrinsics("front").matrix()[:2, 2].tolist() == [960.0, 540.0]
    true_depth = loop.rig.pose(loop.data, "front").depth_m(loop.scene.stop_sign.face_center_m)
    assert pinhole_distance_m(0.762, camera_model.f_px, box[3] - box[1]) == pytest.approx(true_depth, rel=0.05)
    # At 2.06x the study's focal length the sign is 2.06x as tall as the study camera would see it.
    assert box[3] - box[1] == pytest.approx(0.762 * loop.config.camera.f_px / true_depth, rel=0.05)
    assert loop.rig.render_rgb(loop.data, "front").shape == (1080, 1920, 3)
