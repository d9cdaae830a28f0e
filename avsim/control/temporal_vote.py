"""`temporal_vote`: brake for a stop sign only once it has been seen, consistently, over several frames.

A single adversarial frame, or a flickering false alarm, should not decide a brake; a sign that is
really there is seen frame after frame, and its range shrinks as the car drives towards it.
Published anchors: two cameras with different fields of view plus voting across frames cut a
physical attack's success from 37.4 % to 18.2 % (REFERENCE.md, "Defences with published
numbers"); AdvIT (Xiao et al., ICCV 2019) flags over 95 % of adversarial video frames by their
inconsistency with neighbouring frames; production traffic-sign recognition memorises signs
across frames (NDSS 2025, four commercial cars). Assumptions: an attack cannot hold the sign
hidden for k of every n frames, and cannot fake a range that shrinks with the car's odometry.
"""

from __future__ import annotations

import statistics
from collections import deque

from avsim.config import PolicyConfig
from avsim.control.policy_base import POLICIES, STOP_CLASS, BrakeDecision, BrakingPolicy, Observation, PolicyContext
from avsim.perception.base import Detection


def range_rate(votes: list[tuple[float, float]]) -> float | None:
    """Least-squares slope of the range estimate against the distance driven, d(estimate)/d(odometer),
    over votes (odometer [m], estimate [m]); None when the odometer does not vary. A sign the car
    drives towards gives -1 (each metre driven takes a metre off its range)."""
    mean_s = statistics.fmean(s for s, _ in votes)
    mean_d = statistics.fmean(d for _, d in votes)
    var_s = sum((s - mean_s) ** 2 for s, _ in votes)
    if var_s == 0:
        return None
    return sum((s - mean_s) * (d - mean_d) for s, d in votes) / var_s


@POLICIES.register("temporal_vote")
class TemporalVotePolicy(BrakingPolicy):
    """Vote across frames, track with odometry, then brake as `baseline` does (the module docstring
    gives its source and assumptions).

    Every control step, the front camera's stop signs at or above `vote_conf_threshold` (lower
    than `conf_threshold`: the vote, not one frame, carries the decision), not cut by the image
    border, and inside the braking gate (`trigger_dist_m`) are candidates. The frame's vote is
    the candidate nearest to where the track's earlier votes put the sign along the road (its
    odometer reading plus its range estimate), or the most confident one when there is no track.
    The policy brakes once
    - at least `vote_k` of the last `vote_n` frames voted,
    - the votes span at least `vote_min_travel_m` of driving, and
    - their ranges shrink with the odometry: the least-squares slope of range against distance
      driven is -1 within `vote_range_rate_tol` (a sign the car approaches gives -1; a box that
      keeps its size as the car drives on, or a large far object read as a small near sign,
      gives about 0);
    and then, like `baseline`, holds `baseline_brake` until the car stops. The odometer is the
    car's own speed times the control period, summed, as `adjusted` dead-reckons.
    """

    config_keys = ("trigger_dist_m", "sign_height_m", "stop_line_before_sign_m", "baseline_brake", "vote_conf_threshold",
                   "vote_k", "vote_n", "vote_range_rate_tol", "vote_min_travel_m")

    def __init__(self, config: PolicyConfig, context: PolicyContext) -> None:
        super().__init__(config, context)
        self._odometer_m = 0.0
        # Per frame of the window: (odometer [m], range estimate [m]) of its vote, or None.
        self._window: deque[tuple[float, float] | None] = deque(maxlen=config.vote_n)
        self._triggered = False

    def candidates(self, obs: Observation) -> list[tuple[Detection, float]]:
        """The frame's front stop signs that may vote, with their stop-line estimates, most confident first."""
        trigger_m = self.config.trigger_dist_m
        found = []
        for det in obs.detections.get("front", []):
            if det.class_name != STOP_CLASS or det.confidence < self.config.vote_conf_threshold or det.truncated:
                continue
            estimate_m = self.stop_line_estimate_m(det)
            if trigger_m is None or estimate_m <= trigger_m:
                found.append((det, estimate_m))
        return found

    def votes(self) -> list[tuple[float, float]]:
        """The window's votes, oldest first: (odometer [m], stop-line estimate [m]) of each frame that voted."""
        return [vote for vote in self._window if vote is not None]

    def consistent(self) -> bool:
        """Whether the window's votes pass the rule (class docstring)."""
        votes = self.votes()
        if len(votes) < self.config.vote_k:
            return False
        if max(s for s, _ in votes) - min(s for s, _ in votes) < self.config.vote_min_travel_m:
            return False
        slope = range_rate(votes)
        return slope is not None and abs(slope + 1.0) <= self.config.vote_range_rate_tol

    def decide(self, obs: Observation) -> BrakeDecision:
        """Vote with this frame's best candidate (the one nearest where the earlier votes put the sign),
        and brake `baseline_brake` from the step the votes first agree (`consistent`) on.
        """
        found = self.candidates(obs)
        track = self.votes()
        if found and track:
            # The sign's position along the road, as the earlier votes put it.
            where_m = statistics.median(s + d for s, d in track)
            found = sorted(found, key=lambda c: abs(self._odometer_m + c[1] - where_m))
        estimate_m = found[0][1] if found else None
        self._window.append((self._odometer_m, estimate_m) if estimate_m is not None else None)
        self._triggered = self._triggered or self.consistent()
        self._odometer_m += obs.speed_mps * self.context.control_dt_s
        return BrakeDecision(self.config.baseline_brake if self._triggered else 0.0, estimate_m)
