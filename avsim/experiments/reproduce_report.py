"""`report.md` of `avsim reproduce`: our measurements beside the study's, with the differences.

Every number in the report is computed from the run records (`runs.jsonl`); the study's come
from `avsim.experiments.study_figures`. Cells report mean ± sample standard deviation over seeds, and
how many runs stopped before the sign.

Conventions, as in the study: "before the sign" is along the road from the car's origin (the
middle of the car, as CARLA's actor location) to the sign post, positive before it. avsim's
own result keys measure from the front bumper, 2.3 m ahead of the origin; the per-experiment
tables give those too.
"""

from __future__ import annotations

import statistics
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from avsim.experiments import study_figures
from avsim.experiments.figures import make_figures
from avsim.experiments.report_cells import (Cells, Record, beyond_gate, fmt, markdown_table, origin_before_sign_m,
                                            run_full_brake_decel_mps2)
from avsim.experiments.report_sections import (adaptive_answer, attack_success_section, compare_section,
                                               sensitivity_section, stop_rates)
from avsim.experiments.spec import Experiment
from avsim.metrics import BEYOND_GATE_CAUSE, STOPPED_BEFORE_SIGN, write_text_atomic
from avsim.software import versions_sentence
from avsim.vehicle.physics import FRONT_BUMPER_X_M

# Frames where the sign is within the perception's range (16 px) in every placement: the clean
# sign is first detected about 40 m ahead (`avsim attack eval`).
CONFIDENCE_WINDOW_M = (10.0, 40.0)


def _diff(ours: Sequence[float | None], theirs: float, digits: int = 1) -> str:
    present = [v for v in ours if v is not None]
    return f"{statistics.fmean(present) - theirs:+.{digits}f}" if present else "–"


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
    return markdown_table(["cell", "policy", "sign", "stopped before sign", "bumper before sign [m]", "time to stop [s]",
                   "braking began, bumper to sign [m]", "first detection [m]", "peak speed [km/h]"], rows)


def _table3(cells: Cells, stem: str) -> list[str]:
    rows = []
    for name, theirs in study_figures.TABLE3.items():
        ours = cells.values(stem, name, origin_before_sign_m)
        rows.append([name, cells.stopped(stem, name), fmt(ours), f"{theirs.before_sign_m:+.1f}", _diff(ours, theirs.before_sign_m)])
    return ["Car origin before the sign at rest [m] (negative: past it).", "",
            *markdown_table(["cell", "stopped before sign (ours)", "ours", "study", "ours − study"], rows)]


def _defended(cells: Cells, stem: str, reference: dict[str, study_figures.DefendedStop]) -> list[str]:
    rows = []
    for name, theirs in reference.items():
        times = cells.values(stem, name, "time_to_stop_s")
        dists = cells.values(stem, name, lambda r: None if r["dist_at_brake_m"] is None else r["dist_at_brake_m"] + FRONT_BUMPER_X_M)
        rows.append([name, cells.stopped(stem, name), fmt(times, 2), f"{theirs.time_to_stop_s:.2f}", _diff(times, theirs.time_to_stop_s, 2),
                     fmt(dists), f"{theirs.dist_at_brake_m:.2f}", _diff(dists, theirs.dist_at_brake_m)])
    return ["Time from the first brake command to a full stop, and car origin to sign when braking began.", "",
            *markdown_table(["cell", "stopped before sign (ours)", "time to stop, ours [s]", "study [s]", "ours − study [s]",
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
             f"{study_figures.CLEAN_CONFIDENCE}, every attack lower, {study_figures.LOWEST_CONFIDENCE_ATTACK} lowest.", "",
             *markdown_table(["sign", "mean confidence", "first detection [m]", "baseline stopped before sign"], rows)]
    if means:
        lowest = min(means, key=means.get)
        clean = means.get("clean")
        lower = [name for name, m in means.items() if name != "clean" and clean is not None and m < clean]
        lines += [f"Lowest confidence here: **{lowest}** ({means[lowest]:.2f}); the study's lowest: "
                  f"{study_figures.LOWEST_CONFIDENCE_ATTACK}. Attacks scoring below the clean sign: {len(lower)} of "
                  f"{len(means) - (clean is not None)}.", ""]
    return lines


DEFENCES = ("adjusted", "side_camera", "combined")


def findings(cells: Cells, experiments: Sequence[Experiment]) -> list[str]:
    """Where a defended run (or an undefended one at the clean sign) ran past the sign, with the
    deceleration stopping before the sign needed when braking began; then what each attacked sign
    did to the undefended `baseline` rule, beside the study's."""
    failures, attacks, unknown, short = [], [], [], []
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
                               f"{_needed(past)} (the study's attacked car ran {-study_figures.TABLE3['attacked sign, baseline'].before_sign_m:g} m past).")
            elif past:
                kind = "defence" if config.policy.name in DEFENCES else "undefended run at the clean sign"
                failures.append(f"- {where} ({kind}): {_did_not_stop(past)} in {len(past)} of {len(results)} finished runs{_needed(past)}.")
            if beyond := beyond_gate(results):
                short.append(f"- {where}: {len(beyond)} of {len(results)} finished runs came to rest "
                             f"{_span([r['margin_m'] for r in beyond])} m before the stop line, beyond the "
                             f"{config.policy.trigger_dist_m:g} m gate; braking began "
                             f"{_span([r['dist_at_brake_m'] for r in beyond])} m before the sign.")
    finished = sum(len(results) for results in cells.results.values())
    lines = ["Defended runs (and clean-sign runs) that did not stop before the sign:", ""]
    if not finished:
        lines += ["- no run finished, so there is no outcome to report (see Failed runs)."]
    else:
        lines += failures or [f"- none: every finished defended run stopped before the sign"
                              f"{' (the failed runs below have no outcome)' if unknown else ''}."]
    if short:
        lines += ["", "Runs counted as stopped that came to rest farther before the stop line than the braking gate "
                  f"reaches: {BEYOND_GATE_CAUSE}. `--rrd failed` (the default) records them, as failed cars:", "", *short]
    if unknown:
        lines += ["", f"Runs that failed, and have no outcome: {'; '.join(unknown)}."]
    if attacks:
        lines += ["", "What each attacked sign did to the undefended `baseline` rule:", "", *attacks]
    return lines


def _span(values: Sequence[float]) -> str:
    """"12.3" for one value or equal ones, else "12.3–45.6" (lowest to highest, one decimal)."""
    low, high = f"{min(values):.1f}", f"{max(values):.1f}"
    return low if low == high else f"{low}–{high}"


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


_SECTIONS: dict[str, Callable[[Cells, Experiment, dict[str, Experiment]], list[str]]] = {
    "cells": lambda cells, experiment, by_name: [],
    "table3": lambda cells, experiment, by_name: _table3(cells, experiment.name),
    "table1": lambda cells, experiment, by_name: _defended(cells, experiment.name, study_figures.TABLE1),
    "table2": lambda cells, experiment, by_name: _defended(cells, experiment.name, study_figures.TABLE2),
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
    cells = Cells(records)
    figures = figures if figures is not None else make_figures(out_dir, experiments, cells)
    failed = [r for r in records if r["status"] == "failed"]
    lines = [
        "# avsim: the study, reproduced", "",
        f"`{manifest['command']}`, started {manifest['started_at']}: {manifest['runs']} runs ({manifest['failed']} failed) "
        f"with {manifest['workers']} worker(s) in {manifest['wall_s'] / 60:.1f} min. "
        + versions_sentence(manifest["versions"], manifest.get("cluster_nodes")), "",
        "Each cell is run over its seeds (start position and lighting vary) and reported as mean ± std. "
        "Every run has a line in `runs.jsonl`; its `rrd` key names its rerun recording where one was asked for "
        "(`--rrd`, by default the runs whose car failed), and any run is recorded afterwards, bit for bit, with "
        "`avsim run --config experiments/FILE.toml --cell CELL --seed K --rrd RUN.rrd` (docs/recording.md).", "",
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
        lines += ["## Failed runs", "", *markdown_table(["experiment", "cell", "seed", "error"],
                                               [[r["experiment"], r["cell"], str(r["seed"]), r["error"]] for r in failed])]
    if figures:
        lines += ["## Figures", ""] + [f"![{title}]({path.name})\n" for title, path in figures.items()]
    path = out_dir / "report.md"
    write_text_atomic(path, "\n".join(lines))
    return path
