"""What every section of `avsim reproduce`'s report reads: run results grouped by cell, and
their formatting (mean ± std, markdown tables).

Convention (as in the study): "before the sign" is along the road from the car's origin to the
sign post, positive before it; avsim's own result keys measure from the front bumper.
"""

from __future__ import annotations

import statistics
from collections import defaultdict
from collections.abc import Callable, Sequence
from typing import Any

from avsim.config import VehicleConfig, with_overrides
from avsim.metrics import STOPPED_BEFORE_SIGN, record_rested_beyond_gate
from avsim.vehicle.brake_test import full_brake_decel_mps2

Record = dict[str, Any]


def origin_before_sign_m(result: dict[str, Any]) -> float:
    """Car origin to sign post along the road at the end of the run [m]; > 0 before the sign."""
    return result["sign_position_m"][0] - result["stop_position_m"][0]


def beyond_gate(results: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The results whose required stop ended beyond their braking gate (`avsim.metrics.record_rested_beyond_gate`)."""
    return [r for r in results if record_rested_beyond_gate(r)]


def fmt(values: Sequence[float | None], digits: int = 1) -> str:
    """Mean ± sample std of the values that exist; "–" when none; the count when some are missing."""
    present = [v for v in values if v is not None]
    if not present:
        return "–"
    text = f"{statistics.fmean(present):.{digits}f}"
    if len(present) > 1:
        text += f" ± {statistics.stdev(present):.{digits}f}"
    if len(present) < len(values):
        text += f" ({len(present)}/{len(values)} runs)"
    return text


class Cells:
    """Successful results grouped by (experiment stem, cell name), in seed order."""

    def __init__(self, records: Sequence[Record]) -> None:
        self.results: dict[tuple[str, str], list[dict[str, Any]]] = defaultdict(list)
        self.traces: dict[tuple[str, str], list[dict[str, list[float]]]] = defaultdict(list)
        # Failed runs have no outcome; they are counted, never shown as stopped or run past.
        self.failed: dict[tuple[str, str], int] = defaultdict(int)
        self.seeds: dict[tuple[str, str], list[int]] = defaultdict(list)  # of the results, in their order
        for record in sorted(records, key=lambda r: r["seed"]):
            if record["status"] != "ok":
                self.failed[record["experiment"], record["cell"]] += 1
            else:
                self.results[record["experiment"], record["cell"]].append(record["result"])
                self.traces[record["experiment"], record["cell"]].append(record["trace"])
                self.seeds[record["experiment"], record["cell"]].append(record["seed"])

    def of(self, experiment: str, cell: str) -> list[dict[str, Any]]:
        """The run results of one cell of one experiment (empty if it has none)."""
        return self.results.get((experiment, cell), [])

    def values(self, experiment: str, cell: str, key: str | Callable[[dict[str, Any]], float | None]) -> list[float | None]:
        """`key` (a result field, or a function of a result) for each run of the cell."""
        get = key if callable(key) else (lambda r: r[key])
        return [get(r) for r in self.of(experiment, cell)]

    def stopped(self, experiment: str, cell: str) -> str:
        """"k/n" of the finished runs, with the failed ones counted beside: "3/4 (1 failed)"."""
        results = self.of(experiment, cell)
        failed = self.failed.get((experiment, cell), 0)
        return f"{sum(r['outcome'] in STOPPED_BEFORE_SIGN for r in results)}/{len(results)}" + (f" ({failed} failed)" if failed else "")


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    """A markdown table as lines, ending with a blank one."""
    return ["| " + " | ".join(header) + " |", "|" + "---|" * len(header), *("| " + " | ".join(r) + " |" for r in rows), ""]


def run_full_brake_decel_mps2(config: dict[str, Any]) -> float:
    """The car's full-brake deceleration for a run's saved config: its vehicle, road and speed [m/s²]."""
    return full_brake_decel_mps2(with_overrides(VehicleConfig(), config["vehicle"]), config["scenario"]["road_friction"],
                                 config["scenario"]["speed_kmh"] / 3.6, config["loop"]["physics_dt_s"])
