"""Braking policies on hand-made observations (no simulation)."""

import pytest

from avsim.config import PolicyConfig
from avsim.control.policies import POLICIES, Observation, PolicyContext
from avsim.perception.base import Detection

F_PX = 895.69
CAM_TO_BUMPER_M = 1.75
DT = 0.05
FULL_BRAKE_MPS2 = 8.2  # a measured full-brake deceleration (avsim.vehicle.brake_test)
CTX = PolicyContext(front_f_px=F_PX, cam_to_bumper_m=CAM_TO_BUMPER_M, control_dt_s=DT, full_brake_decel_mps2=FULL_BRAKE_MPS2)


def make(name: str, **cfg):
    return POLICIES.get(name)(PolicyConfig(name=name, **cfg), CTX)


def det(h_px: float = 30.0, conf: float = 0.9, cls: str = "stop_sign", camera: str = "front", truncated: bool = False) -> Detection:
    y0 = 200.0
    return Detection(cls, conf, (300.0, y0, 300.0 + h_px, y0 + h_px), camera, truncated)


def obs(speed: float = 20.0, front=(), side=(), stop_line: float = 100.0, t: float = 0.0) -> Observation:
    return Observation(t, speed, {"front": list(front), "side": list(side)}, stop_line)


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
