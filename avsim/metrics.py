"""The per-step record of a run and the typed result computed from it.

Result keys are stable: later features add keys, never rename these. Distances
"to the sign" are longitudinal, from the front bumper to the sign post (world x).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

from avsim.outputs import write_bytes_atomic
from avsim.perception.base import Detection

STOPPED_SPEED_MPS = 0.1

# How a run ended; `summarise` gives exactly one, and `avsim run` prints the same word.
# "Stopped" means braked to below STOPPED_SPEED_MPS (the loop only stops a car that braked).
#   stopped_before_line     stopped, front bumper at or before the stop line
#   stopped_past_line       stopped past the line, bumper at or before the sign
#   ran_past_sign           braked, but ended with the bumper past the sign (stopped there, or still rolling)
#   never_braked            ran past the sign without ever braking
#   timed_out_before_sign   loop.max_time_s ended the run before the sign, not stopped (braked or not)
# The loop ends a run only when the car stopped, ran well past the sign, or timed out, so
# these five cover every end.
OUTCOMES = ("stopped_before_line", "stopped_past_line", "ran_past_sign", "never_braked", "timed_out_before_sign")
STOPPED_BEFORE_SIGN = ("stopped_before_line", "stopped_past_line")
# A run where no stop is required (`stop_required` false: no stop sign for this car at the junction,
# see `avsim.world.scene.SceneInfo`) ends in one of these; "the sign" is then whatever stands at
# the junction's sign post, and the stop line is where a stop line would be:
#   drove_through           passed 40 m beyond the junction: correct, whether or not it braked on the way
#   phantom_stop            braked to a stop although nothing required it
#   timed_out_before_sign   loop.max_time_s ended the run before the junction, not stopped
# How hard a car braked for nothing is `max_brake` (PHANTOM_BRAKE_LEVEL), not the outcome.
NO_STOP_OUTCOMES = ("drove_through", "phantom_stop", "timed_out_before_sign")
ALL_OUTCOMES = (*OUTCOMES, *(o for o in NO_STOP_OUTCOMES if o not in OUTCOMES))
# A brake command above this where no stop is required is a phantom brake (the 0.3: a
# firm brake a passenger notices, well above a light touch).
PHANTOM_BRAKE_LEVEL = 0.3


@dataclass(frozen=True)
class StepRecord:
    """State after one control step (world frame, SI units)."""

    time_s: float
    x_m: float
    y_m: float
    yaw_rad: float
    speed_mps: float
    throttle: float
    brake: float
    steer_rad: float
    stop_line_dist_m: float  # true, front bumper to stop line
    sign_dist_m: float  # true, front bumper to sign
    est_stop_line_dist_m: float | None
    required_decel_mps2: float | None
    top_stop_conf: float  # best stop-sign confidence over the policy's cameras, 0 if none
    detections: tuple[Detection, ...]
    pitch_rad: float = 0.0  # body pitch, nose down +
    # Largest wheel slip during the step's physics while braking above 5 m/s (None: no such moment).
    max_brake_slip: float | None = None


@dataclass(frozen=True)
class RunResult:
    """Outcome of one closed-loop run; `to_json_dict` gives the JSON written by `avsim run`."""

    stop_position_m: list[float]  # car body origin [x, y] at the end of the run
    sign_position_m: list[float]
    margin_m: float  # bumper to stop line at the end; > 0: stopped before the line
    time_to_stop_s: float | None  # first brake command to speed < 0.1 m/s
    dist_at_brake_m: float | None
    first_detection_dist_m: float | None
    peak_speed_mps: float
    config: dict[str, Any]
    outcome: str  # one of OUTCOMES
    sign_margin_m: float  # bumper to sign at the end; > 0: stopped before the sign
    mean_decel_mps2: float | None  # speed at brake / time to stop
    speed_at_brake_mps: float | None
    sim_time_s: float
    # Largest longitudinal slip of any wheel while braking above 5 m/s; None if the car never did.
    max_brake_slip: float | None = None
    peak_pitch_deg: float = 0.0  # largest nose-down pitch of the body over the run
    max_brake: float = 0.0  # largest brake command of the run, in [0, 1]
    # Whether the junction required this car to stop (a stop sign facing it); false in the
    # availability scenarios (no stop sign, a stop sign turned to the cross street).
    stop_required: bool = True
    # Comfort, from the first brake command to the end (None if the car never braked), measured
    # from the body's forward speed at the control rate (`comfort_peaks`): the largest deceleration
    # over one control step [m/s^2] and the largest change of it between two steps [m/s^3].
    peak_decel_mps2: float | None = None
    peak_jerk_mps3: float | None = None

    @property
    def stopped_before_sign(self) -> bool:
        """Whether the car stopped with its bumper at or before the sign (either of STOPPED_BEFORE_SIGN)."""
        return self.outcome in STOPPED_BEFORE_SIGN

    @property
    def phantom_brake(self) -> bool:
        """Whether it braked above PHANTOM_BRAKE_LEVEL where no stop was required."""
        return is_phantom_brake(self.stop_required, self.max_brake)

    @property
    def rested_beyond_gate(self) -> bool:
        """Whether a required stop came to rest farther before the line than its policy's braking gate
        (`rested_beyond_gate`); a config without a policy gate never did."""
        return rested_beyond_gate(self.stop_required, self.outcome, self.margin_m,
                                  self.config.get("policy", {}).get("trigger_dist_m"))

    def to_json_dict(self) -> dict[str, Any]:
        """The record as a JSON-ready dict, one key per field (the keys of `avsim run --json` and results.jsonl)."""
        return asdict(self)


def is_phantom_brake(stop_required: bool, max_brake: float) -> bool:
    """A brake command above PHANTOM_BRAKE_LEVEL in a run where no stop was required."""
    return not stop_required and max_brake > PHANTOM_BRAKE_LEVEL


def rested_beyond_gate(stop_required: bool, outcome: str, margin_m: float | None, trigger_dist_m: float | None) -> bool:
    """A required stop that ended farther before the stop line (`margin_m`, bumper to line [m]) than the
    braking gate reaches (`policy.trigger_dist_m` [m]; None: no gate, never).

    Every perceiving policy brakes for a stop sign only once its range estimate to the line is inside the
    gate, and the car travels on while it stops, so coming to rest beyond the gate means braking began
    outside it: the range read nearer than the line by more than the car's stopping distance (a false stop
    sign, or the sign's box stretched over what stands behind it). Such a run counts as a stop
    (STOPPED_BEFORE_SIGN), as in the study; reports name it beside the stop rates."""
    return (stop_required and outcome in STOPPED_BEFORE_SIGN and trigger_dist_m is not None
            and margin_m is not None and margin_m > trigger_dist_m)


# What such a stop means, as the reports that count it say it.
BEYOND_GATE_CAUSE = ("braking began outside the gate, on a range that read nearer than the line by more than the car's "
                     "stopping distance (a false stop sign, or the sign's box stretched over what stands behind it)")


def record_rested_beyond_gate(result: Mapping[str, Any]) -> bool:
    """`rested_beyond_gate` of a run's result record (`RunResult.to_json_dict`, as runs.jsonl keeps it), at the
    gate of the policy in its own config. A record without `margin_m` (no stop position) never did."""
    if result.get("margin_m") is None:
        return False
    return rested_beyond_gate(result.get("stop_required", True), result["outcome"], result["margin_m"],
                              result["config"]["policy"]["trigger_dist_m"])


def comfort_peaks(records: list[StepRecord], last: StepRecord) -> tuple[float | None, float | None]:
    """(peak deceleration [m/s^2], peak jerk [m/s^3]) from the first brake command to the end;
    (None, None) if the car never braked.

    Measured from the body's forward speed at sensing time, at the control rate: the
    deceleration over step k is (v_k - v_k+1) / dt, the speed lost over that control period
    (a 50 ms average, which smooths the anti-lock controller's cycling at the physics rate,
    as a passenger's body does); the jerk is the change of that deceleration from one step to
    the next, over dt. The step before the first brake command anchors the onset, and the end
    of braking counts too: a car that stops sheds its deceleration at once, and that lurch is
    the jerk a passenger feels at standstill.
    """
    start = next((k for k, r in enumerate(records) if r.brake > 0), None)
    if start is None:
        return None, None
    states = [*records[max(start - 1, 0):], last]
    steps = [((a.speed_mps - b.speed_mps) / (b.time_s - a.time_s), (a.time_s + b.time_s) / 2)
             for a, b in zip(states, states[1:]) if b.time_s > a.time_s]
    braking = steps[1:] if start > 0 else steps  # the step before braking only anchors the jerk
    if not braking:
        return None, None
    jerks = [abs(a2 - a1) / (t2 - t1) for (a1, t1), (a2, t2) in zip(steps, steps[1:])]
    return max(a for a, _ in braking), max(jerks, default=None)


def summarise(records: list[StepRecord], last: StepRecord, sign_xy_m: tuple[float, float], stopped: bool,
              config: dict[str, Any], stop_required: bool = True) -> RunResult:
    """Compute the run's result.

    records: one per control step, each with the state at sensing time;
    last: the state when the run ended; stop_required: whether the junction required a stop.
    """
    brake_start = next((r for r in records if r.brake > 0), None)
    detected = next((r for r in records if r.top_stop_conf > 0), None)
    time_to_stop = last.time_s - brake_start.time_s if (stopped and brake_start) else None
    margin = last.stop_line_dist_m
    outcome = classify_outcome(stopped=stopped, braked=brake_start is not None, line_dist_m=margin,
                               sign_dist_m=last.sign_dist_m, stop_required=stop_required)
    peak_decel, peak_jerk = comfort_peaks(records, last)
    return RunResult(
        stop_position_m=[last.x_m, last.y_m],
        sign_position_m=list(sign_xy_m),
        margin_m=margin,
        time_to_stop_s=time_to_stop,
        dist_at_brake_m=brake_start.sign_dist_m if brake_start else None,
        first_detection_dist_m=detected.sign_dist_m if detected else None,
        peak_speed_mps=max(r.speed_mps for r in (*records, last)),
        config=config,
        outcome=outcome,
        sign_margin_m=last.sign_dist_m,
        mean_decel_mps2=(brake_start.speed_mps / time_to_stop) if time_to_stop else None,
        speed_at_brake_mps=brake_start.speed_mps if brake_start else None,
        sim_time_s=last.time_s,
        max_brake_slip=max((r.max_brake_slip for r in records if r.max_brake_slip is not None), default=None),
        peak_pitch_deg=math.degrees(max(r.pitch_rad for r in (*records, last))),
        max_brake=max((r.brake for r in records), default=0.0),
        stop_required=stop_required,
        peak_decel_mps2=peak_decel,
        peak_jerk_mps3=peak_jerk,
    )


def classify_outcome(*, stopped: bool, braked: bool, line_dist_m: float, sign_dist_m: float,
                     stop_required: bool = True) -> str:
    """The run's outcome from how it ended: bumper to line and to sign [m], > 0 before them. One of
    OUTCOMES where a stop was required, of NO_STOP_OUTCOMES where none was."""
    if not stop_required:
        if stopped:
            return "phantom_stop"
        return "drove_through" if sign_dist_m < 0 else "timed_out_before_sign"
    if stopped:
        if line_dist_m >= 0:
            return "stopped_before_line"
        return "stopped_past_line" if sign_dist_m >= 0 else "ran_past_sign"
    if sign_dist_m < 0:
        return "ran_past_sign" if braked else "never_braked"
    return "timed_out_before_sign"  # not stopped, before the sign: only the time limit ends such a run


def write_json_atomic(path: str | os.PathLike, payload: dict[str, Any]) -> None:
    """Write JSON via a temporary file and rename, so a crash leaves no half-written file."""
    write_text_atomic(path, json.dumps(payload, indent=2, allow_nan=False) + "\n")


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write `text` to a temporary file beside `path`, fsync it, and rename it over `path`
    (`avsim.outputs.write_bytes_atomic`: a failed write is an OutputError naming the file)."""
    write_bytes_atomic(path, text.encode())


def finite_or_none(value: float | None) -> float | None:
    """`value` if it is a finite number, else None (JSON has no NaN or infinity)."""
    return value if value is not None and math.isfinite(value) else None
