"""The one-screen text summary `avsim run` prints."""

from __future__ import annotations

from avsim.config import SimConfig, with_overrides
from avsim.metrics import RunResult
from avsim.perception.factory import network_arithmetics

# What each outcome adds after its own word, the JSON's `outcome` (one entry per ALL_OUTCOMES).
_OUTCOME_DETAIL = {
    "stopped_before_line": "{line:.1f} m before the stop line ({sign:.1f} m before the sign)",
    "stopped_past_line": "{past_line:.1f} m past the stop line, {sign:.1f} m before the sign",
    "ran_past_sign": "{past:.1f} m beyond the sign, {state}; braking began {braked_at:.1f} m before it",
    "never_braked": "{past:.1f} m beyond the sign, never braked",
    "timed_out_before_sign": "the {limit:g} s time limit ended the run {sign:.1f} m before the sign; {braked}",
    # No stop required: "the sign" is the junction's sign post, whatever stands there.
    "drove_through": "{past:.1f} m beyond the junction's sign post, no stop required; largest brake {max_brake:.2f}",
    "phantom_stop": "stopped {sign:.1f} m before the junction's sign post where no stop was required; braking began {braked_at:.1f} m before it",
}


def outcome_line(result: RunResult) -> str:
    """The outcome's own word, then where the car ended, e.g. "stopped_before_line: 2.9 m before the stop line (...)"."""
    braked_at = result.dist_at_brake_m
    detail = _OUTCOME_DETAIL[result.outcome].format(
        line=result.margin_m, past_line=-result.margin_m, sign=result.sign_margin_m, past=-result.sign_margin_m,
        limit=result.config["loop"]["max_time_s"], braked_at=braked_at if braked_at is not None else float("nan"),
        state="stopped" if result.time_to_stop_s is not None else "still rolling", max_brake=result.max_brake,
        braked=f"still rolling, braking since {braked_at:.1f} m before the sign" if braked_at is not None else "never braked")
    return f"{result.outcome}: {detail}"


def _dist(value: float | None, what: str) -> str:
    return f"{value:.1f} m before the sign" if value is not None else f"never ({what})"


def _perception(perception: dict) -> str:
    """The perception's kind, with the arithmetic each network that has one ran in, e.g. "detector (bf16)",
    "coco (fp32)" or "ensemble (detector bf16, coco bf16)"."""
    config = with_overrides(SimConfig(), {"perception": perception}).perception
    ran = network_arithmetics(config)
    if not ran:
        return config.kind
    if list(ran) == [config.kind]:
        return f"{config.kind} ({ran[config.kind]})"
    return f"{config.kind} ({', '.join(f'{network} {how}' for network, how in ran.items())})"


def format_summary(result: RunResult, wall_s: float) -> str:
    """`avsim run`'s printed summary of one run: the scenario, outcome, time to stop, where braking
    began, first detection, peak speed, stop position [m, world] and simulated time against `wall_s` [s].
    """
    cfg = result.config
    sc = cfg["scenario"]
    tts = f"{result.time_to_stop_s:.2f} s (mean deceleration {result.mean_decel_mps2:.2f} m/s^2)" if result.time_to_stop_s else "n/a"
    brake = (f"{result.dist_at_brake_m:.1f} m before the sign, at {result.speed_at_brake_mps * 3.6:.1f} km/h"
             if result.dist_at_brake_m is not None else "never")
    lines = [
        f"avsim run: {sc['town']} / {sc['placement']} / policy {cfg['policy']['name']} / perception {_perception(cfg['perception'])}"
        f" / sign {sc['sign']} / {sc['speed_kmh']:g} km/h / seed {sc['seed']}",
        f"  outcome          {outcome_line(result)}",
        f"  time to stop     {tts}",
        f"  braking began    {brake}",
        f"  first detection  {_dist(result.first_detection_dist_m, 'no stop sign seen')}",
        f"  peak speed       {result.peak_speed_mps * 3.6:.1f} km/h",
        f"  stop position    ({result.stop_position_m[0]:.2f}, {result.stop_position_m[1]:.2f}) m;"
        f" sign at ({result.sign_position_m[0]:.2f}, {result.sign_position_m[1]:.2f}) m",
        f"  simulated        {result.sim_time_s:.2f} s in {wall_s:.2f} s wall ({result.sim_time_s / wall_s:.1f}x real time)",
    ]
    return "\n".join(lines)
