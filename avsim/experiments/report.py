"""`report.md` of `avsim reproduce`: our measurements beside the study's, with the differences.

Every number in the report is computed from the run records (`runs.jsonl`); the study's come
from `avsim.experiments.study`. Cells report mean ± sample standard deviation over seeds, and
how many runs stopped before the sign.

Conventions, as in the study: "before the sign" is along the road from the car's origin (the
middle of the car, as CARLA's actor location) to the sign post, positive before it. avsim's
own result keys measure from the front bumper, 2.3 m ahead of the origin; the per-experiment
tables give those too.
"""

from __future__ import annotations

import statistics
from collections import defaultdict
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from avsim.attacks import success as attack_success
from avsim.config import SimConfig, VehicleConfig, with_overrides
from avsim.experiments import study
from avsim.experiments.spec import Experiment
from avsim.metrics import STOPPED_BEFORE_SIGN, write_text_atomic
from avsim.stats import rate_with_interval
from avsim.vehicle.brake_test import full_brake_decel_mps2
from avsim.vehicle.physics import FRONT_BUMPER_X_M

Record = dict[str, Any]
# Frames where the sign is within the perception's range (16 px) in every placement: the clean
# sign is first detected about 40 m ahead (`avsim attack eval`).
CONFIDENCE_WINDOW_M = (10.0, 40.0)


def origin_before_sign_m(result: dict[str, Any]) -> float:
    """Car origin to sign post along the road at the end of the run [m]; > 0 before the sign."""
    return result["sign_position_m"][0] - result["stop_position_m"][0]


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


def _diff(ours: Sequence[float | None], theirs: float, digits: int = 1) -> str:
    present = [v for v in ours if v is not None]
    return f"{statistics.fmean(present) - theirs:+.{digits}f}" if present else "–"


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
        return self.results.get((experiment, cell), [])

    def values(self, experiment: str, cell: str, key: str | Callable[[dict[str, Any]], float | None]) -> list[float | None]:
        get = key if callable(key) else (lambda r: r[key])
        return [get(r) for r in self.of(experiment, cell)]

    def stopped(self, experiment: str, cell: str) -> str:
        """"k/n" of the finished runs, with the failed ones counted beside: "3/4 (1 failed)"."""
        results = self.of(experiment, cell)
        failed = self.failed.get((experiment, cell), 0)
        return f"{sum(r['outcome'] in STOPPED_BEFORE_SIGN for r in results)}/{len(results)}" + (f" ({failed} failed)" if failed else "")


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    return ["| " + " | ".join(header) + " |", "|" + "---|" * len(header), *("| " + " | ".join(r) + " |" for r in rows), ""]


def _cell_table(cells: Cells, experiment: Experiment) -> list[str]:
    """Every experiment's own table: outcomes and avsim's result keys per cell."""
    stem = experiment.path.stem
    rows = []
    for cell in experiment.cells:
        c = cell.config
        rows.append([
            cell.name, c.policy.name, c.scenario.sign, cells.stopped(stem, cell.name),
            fmt(cells.values(stem, cell.name, "sign_margin_m")),
            fmt(cells.values(stem, cell.name, "time_to_stop_s"), 2),
            fmt(cells.values(stem, cell.name, "dist_at_brake_m")),
            fmt(cells.values(stem, cell.name, "first_detection_dist_m")),
            fmt(cells.values(stem, cell.name, lambda r: r["peak_speed_mps"] * 3.6)),
        ])
    return _table(["cell", "policy", "sign", "stopped before sign", "bumper before sign [m]", "time to stop [s]",
                   "braking began, bumper to sign [m]", "first detection [m]", "peak speed [km/h]"], rows)


def _table3(cells: Cells, stem: str) -> list[str]:
    rows = []
    for name, theirs in study.TABLE3.items():
        ours = cells.values(stem, name, origin_before_sign_m)
        rows.append([name, cells.stopped(stem, name), fmt(ours), f"{theirs.before_sign_m:+.1f}", _diff(ours, theirs.before_sign_m)])
    return ["Car origin before the sign at rest [m] (negative: past it).", "",
            *_table(["cell", "stopped before sign (ours)", "ours", "study", "ours − study"], rows)]


def _defended(cells: Cells, stem: str, reference: dict[str, study.DefendedStop]) -> list[str]:
    rows = []
    for name, theirs in reference.items():
        times = cells.values(stem, name, "time_to_stop_s")
        dists = cells.values(stem, name, lambda r: None if r["dist_at_brake_m"] is None else r["dist_at_brake_m"] + FRONT_BUMPER_X_M)
        rows.append([name, cells.stopped(stem, name), fmt(times, 2), f"{theirs.time_to_stop_s:.2f}", _diff(times, theirs.time_to_stop_s, 2),
                     fmt(dists), f"{theirs.dist_at_brake_m:.2f}", _diff(dists, theirs.dist_at_brake_m)])
    return ["Time from the first brake command to a full stop, and car origin to sign when braking began.", "",
            *_table(["cell", "stopped before sign (ours)", "time to stop, ours [s]", "study [s]", "ours − study [s]",
                     "dist at brake, ours [m]", "study [m]", "ours − study [m]"], rows)]


def mean_confidence(trace: dict[str, list[float]], camera: str, window_m: tuple[float, float] = CONFIDENCE_WINDOW_M) -> float | None:
    """Mean of the camera's best stop-sign confidence per frame (0 for a miss) over frames with the
    bumper `window_m` from the sign; None if the camera was not rendered or no frame is in the window."""
    series = trace.get(f"{camera}_conf")
    if series is None:
        return None
    lo, hi = window_m
    values = [conf for dist, conf in zip(trace["sign_dist_m"], series) if lo <= dist <= hi]
    return statistics.fmean(values) if values else None


def _fig3(cells: Cells, experiment: Experiment) -> list[str]:
    stem = experiment.path.stem
    rows, means = [], {}
    for cell in experiment.cells:
        confs = [mean_confidence(t, "front") for t in cells.traces.get((stem, cell.name), [])]
        present = [c for c in confs if c is not None]
        if present:
            means[cell.name] = statistics.fmean(present)
        rows.append([cell.name, fmt(confs, 2), fmt(cells.values(stem, cell.name, "first_detection_dist_m")),
                     cells.stopped(stem, cell.name)])
    lo, hi = CONFIDENCE_WINDOW_M
    lines = [f"Front camera: the detector's best stop-sign confidence per frame (0 for a miss), averaged over the "
             f"frames {lo:g}–{hi:g} m from the sign, then over seeds. The study: the clean sign scores about "
             f"{study.CLEAN_CONFIDENCE}, every attack lower, {study.LOWEST_CONFIDENCE_ATTACK} lowest.", "",
             *_table(["sign", "mean confidence", "first detection [m]", "baseline stopped before sign"], rows)]
    if means:
        lowest = min(means, key=means.get)
        clean = means.get("clean")
        lower = [name for name, m in means.items() if name != "clean" and clean is not None and m < clean]
        lines += [f"Lowest confidence here: **{lowest}** ({means[lowest]:.2f}); the study's lowest: "
                  f"{study.LOWEST_CONFIDENCE_ATTACK}. Attacks scoring below the clean sign: {len(lower)} of "
                  f"{len(means) - (clean is not None)}.", ""]
    return lines


DEFENCES = ("adjusted", "side_camera", "combined")


def findings(cells: Cells, experiments: Sequence[Experiment]) -> list[str]:
    """Where a defended run (or an undefended one at the clean sign) ran past the sign, with the
    deceleration stopping before the sign needed when braking began; then what each attacked sign
    did to the undefended `baseline` rule, beside the study's."""
    failures, attacks, unknown = [], [], []
    for experiment in experiments:
        stem = experiment.path.stem
        for cell in experiment.cells:
            # A run with no stop to make (scenario.sign = none, a sign for the cross street) did not fail to stop.
            results = [r for r in cells.of(stem, cell.name) if r.get("stop_required", True)]
            past = [r for r in results if r["outcome"] not in STOPPED_BEFORE_SIGN]
            config = cell.config
            where = f"{experiment.title} / {cell.name}"
            failed = cells.failed.get((stem, cell.name), 0)
            if failed:
                unknown.append(f"{where} ({failed} of {failed + len(results)})")
            if not results:
                continue  # no run finished: nothing is known of this cell's outcome
            if config.policy.name == "baseline" and config.scenario.sign != "clean":
                attacks.append(f"- {where}: {_did_not_stop(past)} in {len(past)} of {len(results)} finished runs"
                               f"{_needed(past)} (the study's attacked car ran {-study.TABLE3['attacked sign, baseline'].before_sign_m:g} m past).")
            elif past:
                kind = "defence" if config.policy.name in DEFENCES else "undefended run at the clean sign"
                failures.append(f"- {where} ({kind}): {_did_not_stop(past)} in {len(past)} of {len(results)} finished runs{_needed(past)}.")
    finished = sum(len(results) for results in cells.results.values())
    lines = ["Defended runs (and clean-sign runs) that did not stop before the sign:", ""]
    if not finished:
        lines += ["- no run finished, so there is no outcome to report (see Failed runs)."]
    else:
        lines += failures or [f"- none: every finished defended run stopped before the sign"
                              f"{' (the failed runs below have no outcome)' if unknown else ''}."]
    if unknown:
        lines += ["", f"Runs that failed, and have no outcome: {'; '.join(unknown)}."]
    if attacks:
        lines += ["", "What each attacked sign did to the undefended `baseline` rule:", "", *attacks]
    return lines


def _did_not_stop(results: Sequence[dict[str, Any]]) -> str:
    """"ran past the sign", or what else the runs that did not stop before the sign did."""
    timed_out = sum(r["outcome"] == "timed_out_before_sign" for r in results)
    if not timed_out:
        return "ran past the sign"
    if timed_out == len(results):
        return "timed out before the sign"
    return f"ran past the sign or timed out before it ({timed_out} timed out)"


def _needed(past: Sequence[dict[str, Any]]) -> str:
    """Why, in physics: the deceleration each run that ran past needed when braking began, beside
    what the car's full brake gives on that run's road (measured, `avsim.vehicle.brake_test`)."""
    if not past:
        return ""
    needed = [_needed_decel(r) for r in past]
    why = ", ".join(f"{n:.1f} m/s²" if n is not None else "never braked (no stop sign seen above the threshold)"
                    for n in needed)
    full = sorted({round(run_full_brake_decel_mps2(r["config"]), 1) for r in past})
    roads = sorted({r["config"]["scenario"]["road_friction"] for r in past})
    return (f"; stopping before the sign from where braking began needed {why}, against "
            f"{' / '.join(f'{f:.1f}' for f in full)} m/s² at full brake (measured, road friction "
            f"{' / '.join(f'{mu:g}' for mu in roads)})")


def run_full_brake_decel_mps2(config: dict[str, Any]) -> float:
    """The car's full-brake deceleration for a run's saved config: its vehicle, road and speed [m/s²]."""
    return full_brake_decel_mps2(with_overrides(VehicleConfig(), config["vehicle"]), config["scenario"]["road_friction"],
                                 config["scenario"]["speed_kmh"] / 3.6, config["loop"]["physics_dt_s"])


def adaptive_answer(cells: Cells, experiment: Experiment) -> list[str]:
    """Whether defence 2 holds: every side-camera cell's outcome, the adaptive sign and the front-only attack."""
    stem = experiment.path.stem
    lines = []
    for cell in experiment.cells:
        if cell.config.policy.name in ("side_camera", "combined"):
            margins = cells.values(stem, cell.name, "sign_margin_m")
            lines.append(f"- {cell.name}: stopped before the sign in {cells.stopped(stem, cell.name)} runs, "
                         f"bumper {fmt(margins)} m before it (smallest {min(margins):.1f} m)." if margins else f"- {cell.name}: no run finished.")
    return ["Does defence 2 (the side camera) hold when the attack also targets the side camera?", "", *lines, ""]


def compare_section(cells: Cells, experiment: Experiment, other: Experiment | None) -> list[str]:
    """Each cell beside the same-named cell of `other` (e.g. the wet road beside the dry one), with
    the car's measured full-brake deceleration on each road."""
    if other is None:
        return [f"(Run `experiments/{experiment.compare_with}.toml` in the same reproduction to compare with it.)", ""]
    rows = []
    for cell in experiment.cells:
        row = [cell.name]
        for exp in (other, experiment):
            results = cells.of(exp.name, cell.name)
            full = [run_full_brake_decel_mps2(r["config"]) for r in results[:1]]
            row += [cells.stopped(exp.name, cell.name), fmt(cells.values(exp.name, cell.name, "sign_margin_m")),
                    fmt(cells.values(exp.name, cell.name, "dist_at_brake_m")), f"{full[0]:.2f}" if full else "–"]
        rows.append(row)
    a, b = other.name, experiment.name
    return [f"Each cell beside the same-named cell of `{a}`: stopped before the sign, bumper before the sign at rest "
            f"[m], bumper to sign when braking began [m], and the car's full-brake deceleration on that road "
            f"[m/s²] (measured on a test track, `python -m avsim.vehicle.brake_test`).", "",
            *_table(["cell", f"{a}: stopped", "bumper before sign", "braking began", "full brake",
                     f"{b}: stopped", "bumper before sign", "braking began", "full brake"], rows)]


def sensitivity_section(cells: Cells, experiment: Experiment, by_name: dict[str, Experiment]) -> list[str]:
    """One table per policy or perception constant that varies across the cells: rows (policy,
    sign), one column per value of the constant, the other varied constants at their defaults.
    Each entry: stopped before the sign, with its Wilson 95 % interval, and the mean bumper-to-sign
    margin [m] at rest (negative: past it)."""
    flat = {cell.name: _tunable_values(cell.config) for cell in experiment.cells}
    defaults = _tunable_values(SimConfig())
    varied = sorted(k for k in defaults if k != "policy.name" and len({values[k] for values in flat.values()}) > 1)
    lines = []
    for key in varied:
        others = [k for k in varied if k != key]
        chosen = [c for c in experiment.cells if all(flat[c.name][k] == defaults[k] for k in others)]
        values = sorted({flat[c.name][key] for c in chosen}, key=lambda v: (v is None, v))
        rows: dict[tuple[str, str], dict[Any, str]] = {}
        for cell in chosen:
            results = cells.of(experiment.name, cell.name)
            stopped = sum(r["outcome"] in STOPPED_BEFORE_SIGN for r in results)
            margin = fmt(cells.values(experiment.name, cell.name, "sign_margin_m"))
            row = rows.setdefault((cell.config.policy.name, cell.config.scenario.sign), {})
            row[flat[cell.name][key]] = f"{rate_with_interval(stopped, len(results))}, {margin} m"
        header = ["policy", "sign", *(f"{key} = {'none' if v is None else f'{v:g}'}" for v in values)]
        table_rows = [[policy, sign, *(row.get(v, "–") for v in values)] for (policy, sign), row in rows.items()]
        default = defaults[key]
        lines += [f"`{key}` (default {'none' if default is None else f'{default:g}'}): stopped before the sign with its "
                  f"Wilson 95 % interval, and the bumper's mean margin to the sign at rest [m].", "",
                  *_table(header, table_rows)]
    return lines or ["(No policy or perception constant varies across these cells.)", ""]


def _tunable_values(config: SimConfig) -> dict[str, Any]:
    """The policy and perception constants of a config, by dotted key."""
    data = config.to_dict()
    return {f"{section}.{key}": value for section in ("policy", "perception") for key, value in data[section].items()
            if not isinstance(value, (list, tuple, dict))}


def stop_rates(cells: Cells, experiment: Experiment) -> list[str]:
    """Per town and placement (rows) and policy (columns): runs stopped before the sign, with the
    Wilson 95% interval of the rate, and the bumper's mean distance before the sign at rest;
    then each policy over all its cells."""
    stem = experiment.name
    places = list(dict.fromkeys((c.config.scenario.town, c.config.scenario.placement) for c in experiment.cells))
    policies = list(dict.fromkeys(c.config.policy.name for c in experiment.cells))
    by_place = {(c.config.scenario.town, c.config.scenario.placement, c.config.policy.name): c.name for c in experiment.cells}
    pooled: dict[str, list[dict[str, Any]]] = defaultdict(list)

    def rate(results: list[dict[str, Any]]) -> str:
        return rate_with_interval(sum(r["outcome"] in STOPPED_BEFORE_SIGN for r in results), len(results))

    rows = []
    for town, placement in places:
        row = [f"{town} {placement}"]
        for policy in policies:
            name = by_place.get((town, placement, policy))
            if name is None:  # no such cell
                row.append("–")
                continue
            results = cells.of(stem, name)
            pooled[policy] += results
            failed = cells.failed.get((stem, name), 0)
            row.append(f"{rate(results)}; {fmt([r['sign_margin_m'] for r in results])} m"
                       + (f"; {failed} failed" if failed else ""))
        rows.append(row)
    rows.append(["all cells"] + [f"{rate(pooled[p])}; {fmt([r['sign_margin_m'] for r in pooled[p]])} m" for p in policies])
    return ["Runs stopped before the sign (95% Wilson interval of the rate); the front bumper's distance before the "
            "sign at rest, mean ± std over the runs [m] (negative: past it).", "",
            *_table(["town, placement", *policies], rows)]


def attack_success_section(cells: Cells, experiment: Experiment) -> list[str]:
    """Closed-loop attack success per cell (`avsim.attacks.success`), each attacked cell paired
    with the clean cell of the same town, placement, policy and perception; then pooled over
    towns and placements per sign, perception and policy."""
    stem = experiment.path.stem

    def situation(config) -> tuple:
        return config.scenario.town, config.scenario.placement, config.policy.name, config.perception.kind

    clean_cells = {situation(c.config): c.name for c in experiment.cells if c.config.scenario.sign == "clean"}
    rows, pooled = [], defaultdict(list)
    for cell in experiment.cells:
        c = cell.config
        clean_name = clean_cells.get(situation(c))
        clean_by_seed = dict(zip(cells.seeds[stem, clean_name], cells.of(stem, clean_name))) if clean_name else {}
        results, seeds = cells.of(stem, cell.name), cells.seeds[stem, cell.name]
        s = attack_success.success(results, seeds, clean_by_seed if c.scenario.sign != "clean" else None)
        rows.append([cell.name, c.scenario.sign, c.perception.kind, f"{c.scenario.town} {c.scenario.placement}",
                     c.policy.name, *attack_success.success_row(s)])
        pooled[c.scenario.sign, c.perception.kind, c.policy.name].extend(results)
    lines = ["A run succeeds for the attacker when the car ends past the sign (ran_past_sign or never_braked). "
             "The overrun is the front bumper past the sign at the end; the loop ends a run 40 m past it, so "
             "a car still rolling there counts 40 m. The braking delay is the clean cell's braking distance "
             "minus this one's, paired by seed.", "",
             *_table(["cell", "sign", "perception", "town, placement", "policy", *attack_success.SUCCESS_HEADER], rows)]
    if len({situation(c.config)[:2] for c in experiment.cells}) > 1:
        pooled_rows = [[sign, kind, policy, *attack_success.success_row(attack_success.success(results))]
                       for (sign, kind, policy), results in pooled.items()]
        lines += ["Pooled over the towns and placements:", "",
                  *_table(["sign", "perception", "policy", *attack_success.SUCCESS_HEADER], pooled_rows)]
    return lines


_SECTIONS: dict[str, Callable[[Cells, Experiment, dict[str, Experiment]], list[str]]] = {
    "cells": lambda cells, experiment, by_name: [],
    "table3": lambda cells, experiment, by_name: _table3(cells, experiment.name),
    "table1": lambda cells, experiment, by_name: _defended(cells, experiment.name, study.TABLE1),
    "table2": lambda cells, experiment, by_name: _defended(cells, experiment.name, study.TABLE2),
    "fig3": lambda cells, experiment, by_name: _fig3(cells, experiment),
    "adaptive": lambda cells, experiment, by_name: adaptive_answer(cells, experiment),
    "compare": lambda cells, experiment, by_name: compare_section(cells, experiment, by_name.get(experiment.compare_with)),
    "sensitivity": sensitivity_section,
    "stop_rates": lambda cells, experiment, by_name: stop_rates(cells, experiment),
    "attack_success": lambda cells, experiment, by_name: attack_success_section(cells, experiment),
}


def _needed_decel(result: dict[str, Any]) -> float | None:
    """v²/(2d) at the first brake command, to stop with the bumper at the sign [m/s²]."""
    v, d = result["speed_at_brake_mps"], result["dist_at_brake_m"]
    if v is None or d is None:
        return None
    return float("inf") if d <= 0 else v * v / (2 * d)


def write_report(out_dir: Path, experiments: Sequence[Experiment], records: Sequence[Record], manifest: dict[str, Any],
                 figures: dict[str, Path] | None = None) -> Path:
    """Write `out_dir/report.md` (and its figures); returns its path."""
    from avsim.experiments.figures import make_figures

    cells = Cells(records)
    figures = figures if figures is not None else make_figures(out_dir, experiments, cells)
    failed = [r for r in records if r["status"] == "failed"]
    lines = [
        "# avsim: the study, reproduced", "",
        f"`{manifest['command']}`, started {manifest['started_at']}: {manifest['runs']} runs ({manifest['failed']} failed) "
        f"with {manifest['workers']} worker(s) in {manifest['wall_s'] / 60:.1f} min. Versions: "
        + ", ".join(f"{k} {v}" for k, v in manifest["versions"].items()) + ".", "",
        "Each cell is run over its seeds (start position and lighting vary) and reported as mean ± std. "
        "Every run has a rerun recording under `rrd/` and a line in `runs.jsonl`.", "",
    ]
    if records and len(failed) == len(records):
        lines += [f"**Every run failed** ({len(failed)} of {len(records)}): no table below states an outcome. "
                  "The errors are under Failed runs.", ""]
    by_name = {e.name: e for e in experiments}
    for experiment in experiments:
        lines += [f"## {experiment.title}", "", f"`experiments/{experiment.path.name}`, {experiment.seeds} seed(s) per cell.", ""]
        lines += _SECTIONS[experiment.report](cells, experiment, by_name)
        lines += ["All cells, avsim's own result keys (front bumper to sign):", "", *_cell_table(cells, experiment)]
    lines += ["## Findings", "", *findings(cells, experiments), ""]
    if failed:
        lines += ["## Failed runs", "", *_table(["experiment", "cell", "seed", "error"],
                                               [[r["experiment"], r["cell"], str(r["seed"]), r["error"]] for r in failed])]
    if figures:
        lines += ["## Figures", ""] + [f"![{title}]({path.name})\n" for title, path in figures.items()]
    path = out_dir / "report.md"
    write_text_atomic(path, "\n".join(lines))
    return path
