"""The per-step record of a run and the typed result computed from it.

Result keys are stable: later features add keys, never rename these. Distances
"to the sign" are longitudinal, from the front bumper to the sign post (world x).
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from avsim.perception.base import Detection

STOPPED_SPEED_MPS = 0.1


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
    outcome: str  # stopped_before_line | stopped_before_sign | stopped_past_sign | did_not_stop
    sign_margin_m: float  # bumper to sign at the end; > 0: stopped before the sign
    mean_decel_mps2: float | None  # speed at brake / time to stop
    speed_at_brake_mps: float | None
    sim_time_s: float
    # Largest longitudinal slip of any wheel while braking above 5 m/s; None if the car never did.
    max_brake_slip: float | None = None
    peak_pitch_deg: float = 0.0  # largest nose-down pitch of the body over the run

    @property
    def stopped_before_sign(self) -> bool:
        return self.outcome in ("stopped_before_line", "stopped_before_sign")

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
    if not stopped:
        outcome = "did_not_stop"
    elif margin >= 0:
        outcome = "stopped_before_line"
    elif last.sign_dist_m >= 0:
        outcome = "stopped_before_sign"
    else:
        outcome = "stopped_past_sign"
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


def write_json_atomic(path: str | os.PathLike, payload: dict[str, Any]) -> None:
    """Write JSON via a temporary file and rename, so a crash leaves no half-written file."""
    write_text_atomic(path, json.dumps(payload, indent=2, allow_nan=False) + "\n")


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write `text` to a temporary file beside `path`, fsync it, and rename it over `path`."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(tmp, 0o644)  # mkstemp makes it private; results are meant to be shared
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def finite_or_none(value: float | None) -> float | None:
    return value if value is not None and math.isfinite(value) else None
