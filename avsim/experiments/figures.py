"""Figures of `avsim reproduce`, drawn from the run traces (PNG, matplotlib's Agg backend).

- `speed_vs_distance.png`: speed against bumper-to-sign distance for each Table III cell;
- `confidence_vs_distance.png`: the best stop-sign confidence per frame against distance,
  front camera (the Fig. 3 signs) and side camera (clean, attacked and adaptive signs);
- `stop_positions.png`: seen from above along the road, where the car stopped relative to
  the sign and the stop line in each Table III cell, ours over seeds beside the study's.

Each figure is drawn only when the experiment it needs was run.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from avsim.experiments import study_figures
from avsim.experiments.report_cells import Cells, origin_before_sign_m
from avsim.experiments.spec import Experiment

# The figures' files in the results folder, which `avsim reproduce` checks can be written before its first run.
SPEED_FIGURE, STOPS_FIGURE, CONFIDENCE_FIGURE = "speed_vs_distance.png", "stop_positions.png", "confidence_vs_distance.png"
FIGURE_FILES = (SPEED_FIGURE, STOPS_FIGURE, CONFIDENCE_FIGURE)
_STOP_LINE_BEFORE_SIGN_M = 1.0  # the towns' road convention (docs/architecture.md: the sign stands 1 m past the line)
_DIST_BIN_M = 2.0
_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#17becf")


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path)
    _pyplot().close(fig)
    return path


def make_figures(out_dir: Path, experiments: Sequence[Experiment], cells: Cells) -> dict[str, Path]:
    """Draw every figure whose experiments were run; returns {caption: path}."""
    by_kind: dict[str, list[Experiment]] = {}
    for experiment in experiments:
        by_kind.setdefault(experiment.report, []).append(experiment)
    figures: dict[str, Path] = {}
    if "table3" in by_kind:
        table3 = by_kind["table3"][0]
        figures["Speed against distance to the sign, Table III cells"] = _speed_vs_distance(out_dir, table3, cells)
        figures["Where the car stopped, Table III cells"] = _stop_positions(out_dir, table3, cells)
    series = _confidence_series(by_kind, cells)
    if any(series.values()):
        figures["Stop-sign confidence against distance, front and side camera"] = _confidence_vs_distance(out_dir, series)
    return figures


def _speed_vs_distance(out_dir: Path, experiment: Experiment, cells: Cells) -> Path:
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.5), dpi=120)
    stem = experiment.path.stem
    for colour, cell in zip(_COLOURS, experiment.cells):
        for k, trace in enumerate(cells.traces.get((stem, cell.name), [])):
            ax.plot(trace["sign_dist_m"], np.asarray(trace["speed_mps"]) * 3.6, color=colour, lw=1.0, alpha=0.8,
                    label=cell.name if k == 0 else None)
    ax.axvline(0.0, color="red", lw=1.2, label="stop sign")
    ax.axvline(_STOP_LINE_BEFORE_SIGN_M, color="black", lw=0.8, ls="--", label="stop line")
    ax.set_xlim(80, -20)  # the car drives left to right, towards the sign
    ax.set_ylim(bottom=0)
    ax.set_xlabel("front bumper to stop sign [m] (negative: past the sign)")
    ax.set_ylabel("speed [km/h]")
    ax.set_title(f"{experiment.title}: one line per seed")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower left")
    return _save(fig, out_dir / SPEED_FIGURE)


def _stop_positions(out_dir: Path, experiment: Experiment, cells: Cells) -> Path:
    """One row per cell, seen from above along the road: where the car's origin stopped relative to the
    sign and the stop line, one filled point per seed (avsim) and a hollow diamond for the study."""
    plt = _pyplot()
    names = [cell.name for cell in experiment.cells]
    fig, ax = plt.subplots(figsize=(8, 0.9 + 0.55 * len(names)), dpi=120)
    stem = experiment.path.stem
    for row, (colour, name) in enumerate(zip(_COLOURS, names)):
        along = [origin_before_sign_m(r) for r in cells.of(stem, name)]
        ax.scatter(along, [row] * len(along), color=colour, s=30, zorder=3, label="avsim, one point per seed" if row == 0 else None)
        theirs = study_figures.TABLE3.get(name)
        if theirs is not None:
            ax.scatter([theirs.before_sign_m], [row], facecolors="none", edgecolors="black", s=70, marker="D", zorder=4,
                       label="the study (Table III)" if row == 0 else None)
    ax.axvline(0.0, color="red", lw=2.0, label="stop sign")
    ax.axvline(_STOP_LINE_BEFORE_SIGN_M, color="black", lw=0.8, ls="--", label="stop line")
    ax.set_yticks(range(len(names)), names, fontsize=8)
    ax.set_ylim(len(names) - 0.5, -0.5)
    ax.set_xlim(20, -15)  # the car drives left to right
    ax.set_xlabel("car origin (middle of the car) before the sign at rest [m]; negative: past it")
    ax.set_title(f"{experiment.title}: where the car stopped", fontsize=9)
    ax.grid(alpha=0.3, axis="x")
    ax.legend(fontsize=7, loc="lower right")
    return _save(fig, out_dir / STOPS_FIGURE)


def _confidence_series(by_kind: dict[str, list[Experiment]], cells: Cells) -> dict[str, list[tuple[str, list[dict]]]]:
    """{camera: [(label, traces)]}: front from the Fig. 3 cells, side from the defended tables."""
    series: dict[str, list[tuple[str, list[dict]]]] = {"front": [], "side": []}
    for experiment in by_kind.get("fig3", [])[:1]:
        for cell in experiment.cells:
            series["front"].append((cell.name, cells.traces.get((experiment.name, cell.name), [])))
    side_sources = [(e, label) for kind, label in (("table1", "clean (Table I)"), ("table2", "attacked (Table II)"),
                                                   ("adaptive", "adaptive experiment")) for e in by_kind.get(kind, [])[:1]]
    for experiment, label in side_sources:
        by_sign: dict[str, list[dict]] = {}
        for cell in experiment.cells:
            traces = [t for t in cells.traces.get((experiment.name, cell.name), []) if "side_conf" in t]
            if traces:
                by_sign.setdefault(cell.config.scenario.sign, []).extend(traces)
        series["side"].extend((f"{label}: {sign}", traces) for sign, traces in by_sign.items())
    return series


def _binned(traces: list[dict], camera: str) -> tuple[np.ndarray, np.ndarray]:
    """Mean confidence (0 for a miss) per 2 m distance bin over all frames of the traces."""
    dist = np.concatenate([t["sign_dist_m"] for t in traces])
    conf = np.concatenate([t[f"{camera}_conf"] for t in traces])
    bins = np.floor(dist / _DIST_BIN_M).astype(int)
    centres, means = [], []
    for b in np.unique(bins):
        centres.append((b + 0.5) * _DIST_BIN_M)
        means.append(conf[bins == b].mean())
    return np.asarray(centres), np.asarray(means)


def _confidence_vs_distance(out_dir: Path, series: dict[str, list[tuple[str, list[dict]]]]) -> Path:
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), dpi=120, sharey=True)
    for ax, camera in zip(axes, ("front", "side")):
        for colour, (label, traces) in zip(_COLOURS, series[camera]):
            traces = [t for t in traces if f"{camera}_conf" in t]
            if traces:
                x, y = _binned(traces, camera)
                ax.plot(x, y, color=colour, lw=1.4, label=f"{label} ({len(traces)} runs)")
        ax.axhline(0.5, color="grey", ls=":", lw=0.8, label="braking threshold")
        ax.set_xlim(60, 0)
        ax.set_ylim(0, 1)
        ax.set_xlabel("front bumper to stop sign [m]")
        ax.set_title(f"{camera} camera", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    axes[0].set_ylabel(f"best stop-sign confidence, mean per {_DIST_BIN_M:g} m (0 = missed)")
    return _save(fig, out_dir / CONFIDENCE_FIGURE)
