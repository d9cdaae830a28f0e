"""Closed-loop attack success, as the attack literature reports it, from run results.

A run is an attack success when the car ends past the sign: outcome `ran_past_sign` (it braked,
too late) or `never_braked` (`avsim.metrics`). Per group of runs:
- the success rate with its Wilson 95 % interval;
- the overrun, front bumper past the sign at the end of each successful run [m], mean and
  worst. The loop ends a run 40 m past the sign (`avsim.loop.RAN_PAST_SIGN_M`), so a car that is
  still rolling there counts 40 m: the mean is then a lower bound;
- where braking began (bumper to sign [m]) and its delay against the clean sign, paired by seed
  (seed k has the same start, lighting and sensor noise with either sign).
"""

from __future__ import annotations

import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from avsim.stats import wilson_interval

SUCCESS_OUTCOMES = ("ran_past_sign", "never_braked")


@dataclass(frozen=True)
class Success:
    """One group of runs (a cell, or cells pooled)."""

    runs: int
    past: int
    rate: float
    ci95: tuple[float, float]
    overrun_mean_m: float | None
    overrun_worst_m: float | None
    brake_dist_mean_m: float | None  # where braking began, bumper to sign; runs that braked
    brake_delay_mean_m: float | None  # clean's braking distance minus this one's, paired by seed
    never_braked: int


def is_success(result: Mapping[str, Any]) -> bool:
    """Whether a run's result is an attack success: the car ended past the sign (`SUCCESS_OUTCOMES`)."""
    return result["outcome"] in SUCCESS_OUTCOMES


def overrun_m(result: Mapping[str, Any]) -> float:
    """Front bumper past the sign at the end of the run [m] (> 0 past it)."""
    return -float(result["sign_margin_m"])


def success(results: Sequence[Mapping[str, Any]], seeds: Sequence[int] | None = None,
            clean_by_seed: Mapping[int, Mapping[str, Any]] | None = None) -> Success:
    """Success figures of `results` (result dicts, as `avsim run --json` writes them).

    seeds: each result's seed, to pair it with `clean_by_seed` (the clean sign's result at that
    seed, same cell otherwise) for the braking delay.
    """
    past = [r for r in results if is_success(r)]
    overruns = [overrun_m(r) for r in past]
    brakes = [r["dist_at_brake_m"] for r in results if r["dist_at_brake_m"] is not None]
    delays = []
    if seeds is not None and clean_by_seed:
        for seed, result in zip(seeds, results):
            clean = clean_by_seed.get(seed)
            if clean is not None and clean["dist_at_brake_m"] is not None and result["dist_at_brake_m"] is not None:
                delays.append(clean["dist_at_brake_m"] - result["dist_at_brake_m"])
    return Success(
        runs=len(results), past=len(past), rate=len(past) / len(results) if results else float("nan"),
        ci95=wilson_interval(len(past), len(results)),
        overrun_mean_m=statistics.fmean(overruns) if overruns else None,
        overrun_worst_m=max(overruns) if overruns else None,
        brake_dist_mean_m=statistics.fmean(brakes) if brakes else None,
        brake_delay_mean_m=statistics.fmean(delays) if delays else None,
        never_braked=sum(r["outcome"] == "never_braked" for r in results))


def _fmt(value: float | None, digits: int = 1) -> str:
    return "–" if value is None else f"{value:.{digits}f}"


def success_row(s: Success) -> list[str]:
    """Table cells: runs past / runs, rate (95 % CI), overrun mean / worst, braking began, delay."""
    low, high = s.ci95
    rate = "–" if s.runs == 0 else f"{s.rate:.2f} ({low:.2f}–{high:.2f})"
    never = f" ({s.never_braked} never braked)" if s.never_braked else ""
    return [f"{s.past}/{s.runs}{never}", rate, _fmt(s.overrun_mean_m), _fmt(s.overrun_worst_m),
            _fmt(s.brake_dist_mean_m), _fmt(s.brake_delay_mean_m)]


SUCCESS_HEADER = ["ran past the sign", "success rate (Wilson 95%)", "overrun mean [m]", "overrun worst [m]",
                  "braking began, bumper to sign [m]", "braking delay vs clean [m]"]
