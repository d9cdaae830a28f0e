"""`map_prior` on hand-made observations: it brakes for the mapped stop with no detection at all,
aims for the nearer of the map's line and the camera's estimate, and without a mapped stop acts
on the camera alone."""

import pytest

from avsim.config import PolicyConfig
from avsim.control.policies import POLICIES, Observation
from avsim.perception.base import Detection
from avsim.world.hd_map import HdMap, MapHandle
from test_policies import CAM_TO_BUMPER_M, CTX, F_PX, FULL_BRAKE_MPS2

CFG = PolicyConfig(name="map_prior")


class Bumper:
    x_m = -200.0

    def __call__(self) -> float:
        return self.x_m


def make(lines=(0.0,), **cfg):
    bumper = Bumper()
    policy = POLICIES.get("map_prior")(PolicyConfig(name="map_prior", **cfg), CTX, map_handle=MapHandle(HdMap(tuple(lines)), bumper))
    return policy, bumper


def sign_at(stop_line_m: float, conf: float = 0.9) -> Detection:
    h = 0.762 * F_PX / (stop_line_m + 1.0 + CAM_TO_BUMPER_M)
    return Detection("stop_sign", conf, (400.0, 150.0, 400.0 + h, 150.0 + h), "front")


def step(policy, bumper, line_m: float, speed: float = 23.6, front=()):
    bumper.x_m = -line_m
    return policy.decide(Observation(0.0, speed, {"front": list(front)}))


def onset_dist_m(speed: float, margin_m: float) -> float:
    """Where stopping at the aim first needs autopilot_decel_fraction of the full brake."""
    return speed**2 / (2 * CFG.autopilot_decel_fraction * FULL_BRAKE_MPS2) + margin_m


def test_it_brakes_for_the_mapped_stop_without_any_detection():
    policy, bumper = make()
    v = 23.6
    onset = onset_dist_m(v, CFG.autopilot_stop_margin_m)
    assert step(policy, bumper, onset + 0.5, v).brake == 0.0
    decision = step(policy, bumper, onset - 0.5, v)
    a = v**2 / (2 * (onset - 0.5 - CFG.autopilot_stop_margin_m))
    assert decision.brake == pytest.approx(a / FULL_BRAKE_MPS2)  # calibrated to the measured full brake
    assert step(policy, bumper, 20.0, 10.0).brake > 0.0  # keeps tracking once braking


def test_without_a_mapped_stop_only_the_camera_makes_it_brake():
    policy, bumper = make(lines=())
    assert step(policy, bumper, 35.0, 20.0).brake == 0.0
    decision = step(policy, bumper, 35.0, 20.0, front=[sign_at(35.0)])
    assert decision.est_stop_line_dist_m == pytest.approx(35.0)
    expected = 20.0**2 / (2 * (35.0 - CFG.stop_margin_m)) / FULL_BRAKE_MPS2
    assert 0.0 < expected < 1.0  # the unclamped branch
    assert decision.brake == pytest.approx(expected)


def test_it_aims_for_the_nearer_of_the_map_and_the_camera():
    # The map puts the line 15 m beyond the real one; the camera sees the real one.
    policy, bumper = make(lines=(15.0,))
    decision = step(policy, bumper, 30.0, front=[sign_at(30.0)])  # map: 45 m ahead, camera: 30 m
    assert decision.est_stop_line_dist_m == pytest.approx(30.0)
    assert decision.required_decel_mps2 == pytest.approx(23.6**2 / (2 * (30.0 - CFG.stop_margin_m)))
    # A camera estimate beyond the mapped line does not move the aim past it.
    policy, bumper = make(lines=(0.0,))
    decision = step(policy, bumper, 40.0, front=[sign_at(60.0)])
    assert decision.required_decel_mps2 == pytest.approx(23.6**2 / (2 * (40.0 - CFG.autopilot_stop_margin_m)))


def test_the_camera_estimate_is_dead_reckoned_when_the_sign_leaves_the_view():
    policy, bumper = make(lines=())
    first = step(policy, bumper, 35.0, 20.0, front=[sign_at(35.0)]).est_stop_line_dist_m
    assert step(policy, bumper, 34.0, 20.0).est_stop_line_dist_m == pytest.approx(first - 20.0 * CTX.control_dt_s)
