"""Braking policies on hand-made observations (no simulation)."""

import math

import pytest

from avsim.config import PolicyConfig
from avsim.control.policies import POLICIES, CameraModel, Observation, PolicyContext
from avsim.perception.base import Detection
from avsim.world.hd_map import HdMap, MapHandle

F_PX = 895.69
CAM_TO_BUMPER_M = 1.75
SIDE_YAW_RAD = math.radians(20.0)
SIDE_CAM_TO_BUMPER_M = 1.45
DT = 0.05
FULL_BRAKE_MPS2 = 8.2  # a measured full-brake deceleration (avsim.vehicle.brake_test)
CTX = PolicyContext(cameras={"front": CameraModel(F_PX, 320.0, 0.0, CAM_TO_BUMPER_M),
                             "side": CameraModel(F_PX, 320.0, SIDE_YAW_RAD, SIDE_CAM_TO_BUMPER_M)},
                    control_dt_s=DT, full_brake_decel_mps2=FULL_BRAKE_MPS2)


class FakeBumper:
    """The car's bumper x for a map handle, set by the test."""

    x_m = -100.0

    def __call__(self) -> float:
        return self.x_m


BUMPER = FakeBumper()


def make(name: str, **cfg):
    factory = POLICIES.get(name)
    extra = {"map_handle": MapHandle(HdMap((0.0,)), BUMPER)} if factory.uses_map else {}
    return factory(PolicyConfig(name=name, **cfg), CTX, **extra)


def det(h_px: float = 30.0, conf: float = 0.9, cls: str = "stop_sign", camera: str = "front", truncated: bool = False) -> Detection:
    y0 = 200.0
    return Detection(cls, conf, (300.0, y0, 300.0 + h_px, y0 + h_px), camera, truncated)


def obs(speed: float = 20.0, front=(), side=(), stop_line: float = 100.0, t: float = 0.0) -> Observation:
    """An observation; `stop_line` is where the map-reading autopilot's bumper is (perceiving
    policies never see it)."""
    BUMPER.x_m = -stop_line
    return Observation(t, speed, {"front": list(front), "side": list(side)})


def expected_estimate(h_px: float, cfg: PolicyConfig = PolicyConfig()) -> float:
    return 0.762 * F_PX / h_px - cfg.stop_line_before_sign_m - CAM_TO_BUMPER_M


# ---- baseline --------------------------------------------------------------------------

def test_baseline_no_brake_before_detection():
    p = make("baseline")
    for _ in range(5):
        assert p.decide(obs()).brake == 0.0


def test_baseline_latches_brake_after_detection():
    p = make("baseline", baseline_brake=0.85)
    assert p.decide(obs()).brake == 0.0
    d = p.decide(obs(front=[det(conf=0.6)]))
    assert d.brake == 0.85
    assert d.est_stop_line_dist_m == pytest.approx(expected_estimate(30.0))
    # detection gone: keeps braking
    for _ in range(5):
        assert p.decide(obs(speed=10.0)).brake == 0.85


def test_baseline_uses_configured_brake_level():
    p = make("baseline", baseline_brake=0.6)
    assert p.decide(obs(front=[det()])).brake == 0.6


def test_baseline_ignores_detection_below_threshold():
    p = make("baseline", conf_threshold=0.5)
    assert p.decide(obs(front=[det(conf=0.49)])).brake == 0.0
    assert p.decide(obs()).brake == 0.0


def test_baseline_threshold_is_inclusive():
    p = make("baseline", conf_threshold=0.5)
    assert p.decide(obs(front=[det(conf=0.5)])).brake > 0.0


def test_baseline_ignores_other_classes():
    p = make("baseline")
    assert p.decide(obs(front=[det(cls="yield"), det(cls="speed_limit")])).brake == 0.0
    assert p.decide(obs()).brake == 0.0


def test_baseline_ignores_side_camera():
    p = make("baseline")
    assert p.cameras == ("front",)
    assert p.decide(obs(side=[det(camera="side")])).brake == 0.0


def test_baseline_finds_stop_sign_behind_other_class():
    p = make("baseline")
    assert p.decide(obs(front=[det(cls="yield", conf=0.99), det(conf=0.7)])).brake > 0.0


# ---- adjusted --------------------------------------------------------------------------

def test_adjusted_no_brake_before_detection():
    p = make("adjusted")
    d = p.decide(obs())
    assert d.brake == 0.0
    assert d.est_stop_line_dist_m is None


def test_adjusted_brake_matches_v2_over_2d_law_exactly():
    m, margin, a_max = 0.8, 0.5, 9.81
    p = make("adjusted", brake_multiplier=m, stop_margin_m=margin, a_max_mps2=a_max)
    h, v = 30.0, 10.0
    d_est = 0.762 * F_PX / h - 1.0 - CAM_TO_BUMPER_M
    expected = min(v**2 / (2 * (d_est - margin)) / a_max * m, 1.0)
    assert 0.0 < expected < 1.0  # the numbers exercise the unclamped branch
    d = p.decide(obs(speed=v, front=[det(h_px=h)]))
    assert d.est_stop_line_dist_m == pytest.approx(d_est, rel=1e-12)
    assert d.required_decel_mps2 == pytest.approx(v**2 / (2 * (d_est - margin)), rel=1e-12)
    assert d.brake == pytest.approx(expected, rel=1e-12)


def test_adjusted_brake_saturates_at_one_when_close_and_fast():
    p = make("adjusted")
    # 100 px box: sign ~6.8 m away, 4 m to the line at 25 m/s
    assert p.decide(obs(speed=25.0, front=[det(h_px=100.0)])).brake == 1.0


def test_adjusted_uses_stop_line_offset_from_config():
    p = make("adjusted", stop_line_before_sign_m=3.0)
    d = p.decide(obs(speed=10.0, front=[det(h_px=30.0)]))
    assert d.est_stop_line_dist_m == pytest.approx(0.762 * F_PX / 30.0 - 3.0 - CAM_TO_BUMPER_M)


def test_adjusted_ignores_truncated_boxes():
    p = make("adjusted")
    d = p.decide(obs(front=[det(h_px=30.0, truncated=True)]))
    assert d.brake == 0.0
    assert d.est_stop_line_dist_m is None


def test_adjusted_dead_reckons_when_detection_disappears():
    p = make("adjusted")
    first = p.decide(obs(speed=10.0, front=[det(h_px=30.0)])).est_stop_line_dist_m
    second = p.decide(obs(speed=10.0)).est_stop_line_dist_m
    third = p.decide(obs(speed=8.0)).est_stop_line_dist_m
    assert second == pytest.approx(first - 10.0 * DT)
    assert third == pytest.approx(first - 10.0 * DT - 8.0 * DT)


def test_adjusted_dead_reckons_through_truncated_box():
    p = make("adjusted")
    first = p.decide(obs(speed=10.0, front=[det(h_px=30.0)])).est_stop_line_dist_m
    # a truncated box (here deceptively tall) must not replace the estimate
    second = p.decide(obs(speed=10.0, front=[det(h_px=200.0, truncated=True)])).est_stop_line_dist_m
    assert second == pytest.approx(first - 10.0 * DT)


def test_adjusted_brakes_fully_once_estimate_passes_margin():
    p = make("adjusted", stop_margin_m=0.5)
    p.decide(obs(speed=10.0, front=[det(h_px=200.0)]))  # est ~0.66 m
    assert p.decide(obs(speed=10.0)).brake == 1.0  # dead-reckoned to ~0.16 m < margin


def test_adjusted_updates_estimate_from_new_detection():
    p = make("adjusted")
    p.decide(obs(speed=10.0, front=[det(h_px=30.0)]))
    d = p.decide(obs(speed=10.0, front=[det(h_px=40.0)]))
    assert d.est_stop_line_dist_m == pytest.approx(expected_estimate(40.0))


# ---- side camera -----------------------------------------------------------------------

def test_side_camera_full_brake_from_side_detection_alone():
    p = make("side_camera")
    assert set(p.cameras) == {"front", "side"}
    assert p.decide(obs()).brake == 0.0
    assert p.decide(obs(side=[det(camera="side")])).brake == 1.0
    # latched
    assert p.decide(obs()).brake == 1.0


def test_side_camera_front_detection_gives_baseline_brake():
    p = make("side_camera", baseline_brake=0.85)
    assert p.decide(obs(front=[det()])).brake == 0.85


def test_side_camera_ignores_side_detection_below_threshold():
    p = make("side_camera")
    assert p.decide(obs(side=[det(camera="side", conf=0.2)])).brake == 0.0


def test_combined_side_detection_overrides_adjusted():
    p = make("combined")
    d = p.decide(obs(speed=10.0, front=[det(h_px=30.0)], side=[det(camera="side")]))
    assert d.brake == 1.0
    assert d.est_stop_line_dist_m == pytest.approx(expected_estimate(30.0))


# ---- autopilot -------------------------------------------------------------------------

def test_autopilot_uses_no_cameras():
    assert make("autopilot").cameras == ()


def test_autopilot_no_brake_when_far():
    p = make("autopilot")
    d = p.decide(obs(speed=20.0, stop_line=200.0))
    assert d.brake == 0.0
    assert d.required_decel_mps2 == pytest.approx(400.0 / (2 * (200.0 - 0.5)))


def test_autopilot_brakes_when_required_decel_reaches_threshold():
    cfg = PolicyConfig(name="autopilot")
    p = make("autopilot")
    v = 20.0
    trigger = cfg.autopilot_decel_fraction * FULL_BRAKE_MPS2
    far = v * v / (2 * trigger) + cfg.autopilot_stop_margin_m + 0.1  # needs slightly less than the trigger
    assert p.decide(obs(speed=v, stop_line=far)).brake == 0.0
    dist = v * v / (2 * trigger) + cfg.autopilot_stop_margin_m - 0.1  # needs slightly more
    d = p.decide(obs(speed=v, stop_line=dist))
    a = v * v / (2 * (dist - cfg.autopilot_stop_margin_m))
    assert a >= trigger
    assert d.brake == pytest.approx(a / FULL_BRAKE_MPS2)  # calibrated to the measured full brake
    assert d.brake > 0.0


def test_autopilot_keeps_braking_once_started():
    p = make("autopilot")
    assert p.decide(obs(speed=20.0, stop_line=30.0)).brake > 0.0
    # slower now: required decel below the trigger, but it keeps tracking v^2/2d
    d = p.decide(obs(speed=5.0, stop_line=25.0))
    assert d.brake > 0.0


def test_autopilot_ignores_detections():
    p = make("autopilot")
    close = [det(h_px=200.0)]
    assert p.decide(obs(speed=20.0, stop_line=200.0, front=close, side=[det(camera="side")])).brake == 0.0


# ---- the braking gate --------------------------------------------------------------------

def _h_px_at(stop_line_m: float, cam_to_bumper_m: float = CAM_TO_BUMPER_M) -> float:
    """Front box height of a stop sign whose stop line is `stop_line_m` ahead of the bumper."""
    return 0.762 * F_PX / (stop_line_m + 1.0 + cam_to_bumper_m)


@pytest.mark.parametrize("name", ["baseline", "adjusted", "side_camera", "combined"])
def test_perceiving_policies_ignore_a_stop_sign_beyond_the_trigger_distance(name):
    p = make(name, trigger_dist_m=40.0)
    far = det(h_px=_h_px_at(60.0), conf=0.95)
    for _ in range(3):
        assert p.decide(obs(speed=20.0, front=[far])).brake == 0.0
    assert p.decide(obs(speed=20.0, front=[det(h_px=_h_px_at(39.0))])).brake > 0.0


@pytest.mark.parametrize("name", ["baseline", "adjusted", "side_camera", "combined"])
def test_with_no_gate_a_far_stop_sign_is_acted_on_at_once(name):
    p = make(name, trigger_dist_m=None)
    assert p.decide(obs(speed=20.0, front=[det(h_px=_h_px_at(90.0))])).brake > 0.0


def test_trigger_none_and_inf_mean_no_gate():
    from avsim.config import SimConfig, with_overrides

    assert with_overrides(SimConfig(), {"policy": {"trigger_dist_m": "none"}}).policy.trigger_dist_m is None
    assert with_overrides(SimConfig(), {"policy": {"trigger_dist_m": math.inf}}).policy.trigger_dist_m is None
    assert SimConfig().policy.trigger_dist_m == 40.0


def test_the_gate_picks_a_gated_box_behind_a_more_confident_far_one():
    p = make("baseline", trigger_dist_m=40.0)
    assert p.decide(obs(front=[det(h_px=_h_px_at(80.0), conf=0.99), det(h_px=_h_px_at(30.0), conf=0.6)])).brake > 0.0


def test_side_camera_gate_uses_the_side_cameras_own_pinhole_estimate():
    p = make("side_camera", trigger_dist_m=40.0)
    cam = CTX.cameras["side"]
    # A side-camera box whose centre sits on its optical axis: the sign is Z cos(20 deg) ahead.
    def side_det(ahead_m: float) -> Detection:
        depth = ahead_m / math.cos(SIDE_YAW_RAD)
        h = 0.762 * F_PX / depth
        return Detection("stop_sign", 0.9, (320.0 - h / 2, 100.0, 320.0 + h / 2, 100.0 + h), "side")
    beyond = side_det(40.0 + 1.0 + SIDE_CAM_TO_BUMPER_M + 2.0)  # stop line 42 m ahead of the bumper
    within = side_det(40.0 + 1.0 + SIDE_CAM_TO_BUMPER_M - 2.0)  # 38 m
    assert p.stop_line_estimate_m(beyond) == pytest.approx(42.0)
    assert cam.sign_ahead_m(within, 0.762) == pytest.approx(40.0 + 1.0 + SIDE_CAM_TO_BUMPER_M - 2.0)
    assert p.decide(obs(side=[beyond])).brake == 0.0
    assert p.decide(obs(side=[within])).brake == 1.0


def test_camera_model_turns_the_box_offset_into_distance_ahead():
    # A sign 30 m ahead and 5 m to the right of a camera yawed 20 deg right.
    cam = CameraModel(F_PX, 320.0, SIDE_YAW_RAD, 0.0)
    ahead, right = 30.0, 5.0
    depth = ahead * math.cos(SIDE_YAW_RAD) + right * math.sin(SIDE_YAW_RAD)  # along the optical axis
    across = -ahead * math.sin(SIDE_YAW_RAD) + right * math.cos(SIDE_YAW_RAD)  # right of it
    u = 320.0 + F_PX * across / depth
    h = 0.762 * F_PX / depth
    box = Detection("stop_sign", 0.9, (u - h / 2, 100.0, u + h / 2, 100.0 + h), "side")
    assert cam.sign_ahead_m(box, 0.762) == pytest.approx(ahead, rel=1e-9)


# ---- study_stack ---------------------------------------------------------------------------

def _study_det(d_m: float, camera: str = "front", u_px: float = 400.0, conf: float = 0.9) -> Detection:
    """A box whose pinhole depth with the stack's assumed 1.0 m sign is `d_m`."""
    h = 1.0 * F_PX / d_m
    return Detection("stop_sign", conf, (u_px - h / 2, 100.0, u_px + h / 2, 100.0 + h), camera)


def test_study_stack_brakes_by_its_literal_front_rule_below_40_m():
    p = make("study_stack")
    assert p.decide(obs(speed=20.0, front=[_study_det(45.0)])).brake == 0.0
    d = p.decide(obs(speed=20.0, front=[_study_det(30.0)]))
    assert d.brake == pytest.approx(min(20.0**2 / (2 * 30.0) / 9.81 * 0.6, 0.8))
    assert p.decide(obs(speed=23.0, front=[_study_det(8.0)])).brake == 0.8  # capped


def test_study_stack_counts_only_the_right_half_of_the_front_image():
    p = make("study_stack")
    assert p.decide(obs(speed=20.0, front=[_study_det(30.0, u_px=200.0)])).brake == 0.0


def test_study_stack_side_camera_acts_only_after_braking_began_with_the_last_front_estimate():
    p = make("study_stack")
    assert p.decide(obs(speed=20.0, side=[_study_det(10.0, camera="side")])).brake == 0.0
    p.decide(obs(speed=20.0, front=[_study_det(30.0)]))
    d = p.decide(obs(speed=18.0, side=[_study_det(10.0, camera="side")]))
    assert d.brake == pytest.approx(min(18.0**2 / (2 * 30.0) / 9.81 * 0.8, 1.0))


def test_study_stack_coasts_when_neither_camera_sees_the_sign():
    p = make("study_stack")
    assert p.decide(obs(speed=20.0, front=[_study_det(30.0)])).brake > 0.0
    assert p.decide(obs(speed=19.0)).brake == 0.0


def test_study_stack_sign_height_is_a_parameter():
    p = make("study_stack", study_sign_height_m=0.762)
    box = _study_det(30.0)  # 1.0 m sign at 30 m = 0.762 m sign at 22.9 m
    d = p.decide(obs(speed=20.0, front=[box]))
    assert d.required_decel_mps2 == pytest.approx(20.0**2 / (2 * 30.0 * 0.762))


# ---- privileged data -----------------------------------------------------------------------

def test_only_the_autopilot_and_the_map_prior_are_built_with_the_map():
    assert [name for name in POLICIES.names() if POLICIES.get(name).uses_map] == ["autopilot", "map_prior"]


def test_an_observation_carries_no_map_data():
    import dataclasses

    assert {f.name for f in dataclasses.fields(Observation)} == {"time_s", "speed_mps", "detections"}
