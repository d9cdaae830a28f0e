"""`temporal_vote` on hand-made observations: k of the last n frames, the lower per-frame
threshold, the braking gate, and ranges that must shrink with the car's odometry."""

import pytest

from avsim.config import PolicyConfig
from avsim.control.policies import POLICIES, Observation
from avsim.control.temporal_vote import range_rate
from avsim.perception.base import Detection
from test_policies import CAM_TO_BUMPER_M, CTX, DT, F_PX

SPEED_MPS = 20.0  # 1 m driven per control step


def make(**cfg):
    return POLICIES.get("temporal_vote")(PolicyConfig(name="temporal_vote", **cfg), CTX)


def sign_at(stop_line_m: float, conf: float = 0.4, truncated: bool = False) -> Detection:
    """A front stop-sign box whose pinhole estimate puts the stop line `stop_line_m` ahead of the bumper."""
    h = 0.762 * F_PX / (stop_line_m + 1.0 + CAM_TO_BUMPER_M)
    return Detection("stop_sign", conf, (400.0, 150.0, 400.0 + h, 150.0 + h), "front", truncated)


def drive(policy, boxes, speed=SPEED_MPS):
    """Feed one observation per entry (a Detection, or None for an empty frame); the brake levels."""
    return [policy.decide(Observation(k * DT, speed, {"front": [] if b is None else [b]})).brake
            for k, b in enumerate(boxes)]


def approaching(start_m: float, frames: int, conf: float = 0.4):
    """A real sign: its stop line 1 m closer each frame (SPEED_MPS * DT)."""
    return [sign_at(start_m - k * SPEED_MPS * DT, conf) for k in range(frames)]


def test_it_brakes_on_the_kth_consistent_vote_and_holds_the_brake():
    brakes = drive(make(baseline_brake=0.85), [*approaching(35.0, 3), None, None, None])
    assert brakes[:2] == [0.0, 0.0]
    assert brakes[2:] == [0.85] * 4


def test_a_confident_single_frame_does_not_brake():
    assert drive(make(), [sign_at(30.0, conf=0.99), None, None, None, None]) == [0.0] * 5


def test_votes_count_from_the_lower_per_frame_threshold_only():
    assert drive(make(vote_conf_threshold=0.3), approaching(35.0, 4, conf=0.29)) == [0.0] * 4
    assert drive(make(vote_conf_threshold=0.3), approaching(35.0, 4, conf=0.3))[-1] > 0.0


def test_k_of_n_votes_may_skip_frames_but_not_too_many():
    real = approaching(35.0, 6)
    assert drive(make(vote_k=3, vote_n=5), [real[0], None, real[2], None, real[4]])[-1] > 0.0
    assert drive(make(vote_k=3, vote_n=5), [real[0], None, None, None, real[4], None])[-1] == 0.0


def test_a_box_whose_range_does_not_shrink_with_the_odometry_gets_no_vote_through():
    # The same box, frame after frame, while the car drives 1 m a frame: a large far object
    # read as a near sign, or a texture that holds its box, not a sign the car approaches.
    assert drive(make(), [sign_at(20.0)] * 8) == [0.0] * 8
    # A range that shrinks at a fifth of the speed the car drives (a 3.8 m tall tree crown read as a 0.76 m sign).
    assert drive(make(), [sign_at(20.0 - 0.2 * k) for k in range(8)]) == [0.0] * 8


def test_it_acts_only_inside_the_braking_gate():
    far = approaching(60.0, 5)  # 60 .. 56 m, beyond the 40 m gate
    assert drive(make(trigger_dist_m=40.0), far) == [0.0] * 5
    assert drive(make(trigger_dist_m=None), far)[-1] > 0.0


def test_truncated_boxes_and_other_classes_do_not_vote():
    truncated = [sign_at(30.0 - k, truncated=True) for k in range(5)]
    assert drive(make(), truncated) == [0.0] * 5
    yields = [Detection("yield", 0.9, b.box_xyxy_px, "front") for b in approaching(30.0, 5)]
    assert drive(make(), yields) == [0.0] * 5


def test_a_standing_car_gathers_no_evidence_from_odometry():
    # Votes need vote_min_travel_m of driving between them: at rest nothing can be checked.
    assert drive(make(), [sign_at(30.0)] * 6, speed=0.0) == [0.0] * 6


def test_the_vote_follows_the_track_past_a_more_confident_stray_box():
    # Frame 1 also holds a more confident box 10 m ahead. Had it been the frame's vote, the three
    # votes would not shrink with the odometry and the car would not brake at frame 2.
    real = approaching(35.0, 3)
    frames = [[real[0]], [real[1], sign_at(10.0, conf=0.9)], [real[2]]]
    policy = make()
    brakes = [policy.decide(Observation(k * DT, SPEED_MPS, {"front": f})).brake for k, f in enumerate(frames)]
    assert brakes == [0.0, 0.0, 0.85]


def test_range_rate_is_minus_one_for_a_sign_the_car_drives_towards():
    assert range_rate([(0.0, 30.0), (1.0, 29.0), (2.0, 28.0)]) == pytest.approx(-1.0)
    assert range_rate([(0.0, 30.0), (0.0, 29.0)]) is None


def test_vote_settings_are_checked():
    from avsim.errors import ConfigError

    with pytest.raises(ConfigError, match="vote_k"):
        PolicyConfig(vote_k=6, vote_n=5)
    with pytest.raises(ConfigError, match="vote_range_rate_tol"):
        PolicyConfig(vote_range_rate_tol=0.0)
