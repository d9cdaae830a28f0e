"""The per-step record of a run and the typed result computed from it.

Result keys are stable: later features add keys, never rename these. Distances
"to the sign" are longitudinal, from the front bumper to the sign post (world x).
"""

from __future__ import annotations

import json
import math
import os
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

    @property
    def stopped_before_sign(self) -> bool:
        """Whether the car stopped with its bumper at or before the sign (either of STOPPED_BEFORE_SIGN)."""
        return self.outcome in STOPPED_BEFORE_SIGN

    def to_json_dict(self) -> dict[str, Any]:
        return asdict(self)


def summarise(records: list[StepRecord], last: StepRecord, sign_xy_m: tuple[float, float], stopped: bool,
              config: dict[str, Any]) -> RunResult:
    """Compute the run's result.

    records: one per control step, each with the state at sensing time;
    last: the state when the run ended.
    """
    brake_start = next((r for r in records if r.brake > 0), None)
    detected = next((r for r in records if r.top_stop_conf > 0), None)
    time_to_stop = last.time_s - brake_start.time_s if (stopped and brake_start) else None
    margin = last.stop_line_dist_m
    outcome = classify_outcome(stopped=stopped, braked=brake_start is not None, line_dist_m=margin,
                               sign_dist_m=last.sign_dist_m)
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
    )


def classify_outcome(*, stopped: bool, braked: bool, line_dist_m: float, sign_dist_m: float) -> str:
    """The run's outcome (see OUTCOMES) from how it ended: bumper to line and to sign [m], > 0 before them."""
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
    return value if value is not None and math.isfinite(value) else None
