"""The one-screen text summary `avsim run` prints."""

from __future__ import annotations

from avsim.metrics import RunResult

_OUTCOME = {
    "stopped_before_line": "STOPPED {line:.1f} m before the stop line ({sign:.1f} m before the sign)",
    "stopped_before_sign": "STOPPED past the stop line, {sign:.1f} m before the sign",
    "stopped_past_sign": "RAN PAST the sign: stopped {past:.1f} m beyond it",
    "did_not_stop": "RAN PAST the sign without stopping",
}


def _dist(value: float | None, what: str) -> str:
    return f"{value:.1f} m before the sign" if value is not None else f"never ({what})"


def format_summary(result: RunResult, wall_s: float) -> str:
    cfg = result.config
    sc = cfg["scenario"]
    outcome = _OUTCOME[result.outcome].format(line=result.margin_m, sign=result.sign_margin_m, past=-result.sign_margin_m)
    tts = f"{result.time_to_stop_s:.2f} s (mean deceleration {result.mean_decel_mps2:.2f} m/s^2)" if result.time_to_stop_s else "n/a"
    brake = (f"{result.dist_at_brake_m:.1f} m before the sign, at {result.speed_at_brake_mps * 3.6:.1f} km/h"
             if result.dist_at_brake_m is not None else "never")
    lines = [
        f"avsim run: {sc['town']} / {sc['placement']} / policy {cfg['policy']['name']} / perception {cfg['perception']['kind']}"
        f" / sign {sc['sign']} / {sc['speed_kmh']:g} km/h / seed {sc['seed']}",
        f"  outcome          {outcome}",
        f"  time to stop     {tts}",
        f"  braking began    {brake}",
        f"  first detection  {_dist(result.first_detection_dist_m, 'no stop sign seen')}",
        f"  peak speed       {result.peak_speed_mps * 3.6:.1f} km/h",
        f"  stop position    ({result.stop_position_m[0]:.2f}, {result.stop_position_m[1]:.2f}) m;"
        f" sign at ({result.sign_position_m[0]:.2f}, {result.sign_position_m[1]:.2f}) m",
        f"  simulated        {result.sim_time_s:.2f} s in {wall_s:.2f} s wall ({result.sim_time_s / wall_s:.1f}x real time)",
    ]
    return "\n".join(lines)
