"""The safety map of a sweep: for each policy and sign, the highest speed at which the car stops.

    smap = safety_map(records, SimConfig())
    smap.max_safe_kmh("baseline", "yang")       # 40.0, or None when no speed is safe

A speed is *safe* for (policy, sign) when every run there is `ok` and stopped before the
sign (outcome `stopped_before_line` or `stopped_past_line`): every seed, and every value
of any other grid key. A failed run makes its speed not safe (it is not known to stop).
Everything is computed from the records alone; a run's policy, sign and speed come from
its grid point, or from the sweep's base config when the grid does not vary them.

`write_sweep_report` writes `summary.md` (tables) and `safety_map.png`: highest safe speed
against attack strength per policy, and one panel per policy of every (speed, sign) outcome.
The attack strength of a sign is its budget, read from the JSON record beside the texture
(`textures/yang_eps0.09.json`: hyperparameters.eps_peak = 0.09); the clean sign is 0. Beside
it, what the attack did in the sweep's own runs (`front_measures`, from the traces): the front
camera's peak confidence and the distance of its first frame at the braking threshold.
"""

from __future__ import annotations

import json
import math
import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from avsim.config import SimConfig
from avsim.errors import ConfigError
from avsim.metrics import BEYOND_GATE_CAUSE, STOPPED_BEFORE_SIGN, record_rested_beyond_gate, write_text_atomic
from avsim.software import versions_sentence

SPEED_KEY, SIGN_KEY, POLICY_KEY = "scenario.speed_kmh", "scenario.sign", "policy.name"
FIGURE_FILE = "safety_map.png"


@dataclass(frozen=True)
class SpeedOutcome:
    """The runs of one (policy, sign, speed): how many, how many stopped before the sign, how many failed.

    sign_margins_m: bumper to sign at the end of each ok run [m]; > 0 is before the sign.
    """

    runs: int
    stopped: int
    failed: int
    sign_margins_m: tuple[float, ...]
    outcomes: tuple[str, ...]
    # Of the stops, how many came to rest farther before the line than the braking gate reaches
    # (`avsim.metrics.record_rested_beyond_gate`): braking began outside the gate, on a range read far too near.
    beyond_gate: int = 0

    @property
    def safe(self) -> bool:
        """Whether every run at this speed ran and stopped before the sign (and there was at least one)."""
        return self.runs > 0 and self.failed == 0 and self.stopped == self.runs


@dataclass(frozen=True)
class SafetyMap:
    """Outcomes per (policy, sign, speed [km/h]); policies and signs in order of first appearance."""

    speeds_kmh: tuple[float, ...]
    policies: tuple[str, ...]
    signs: tuple[str, ...]
    cells: dict[tuple[str, str, float], SpeedOutcome]

    def max_safe_kmh(self, policy: str, sign: str) -> float | None:
        """The highest speed at which every run stopped before the sign; None if there is none."""
        safe = [s for s in self.speeds_kmh if self._safe(policy, sign, s)]
        return max(safe) if safe else None

    def safe_up_to_kmh(self, policy: str, sign: str) -> float | None:
        """The highest speed with every speed up to it safe; below `max_safe_kmh` when a lower speed failed."""
        last = None
        for speed in self.speeds_kmh:
            if not self._safe(policy, sign, speed):
                break
            last = speed
        return last

    def _safe(self, policy: str, sign: str, speed: float) -> bool:
        cell = self.cells.get((policy, sign, speed))
        return cell is not None and cell.safe


def coordinates(record: Mapping[str, Any], base: SimConfig) -> tuple[str, str, float]:
    """(policy, sign, speed [km/h]) of a record: its grid point, else the sweep's base config."""
    point = record.get("point") or {}
    return (str(point.get(POLICY_KEY, base.policy.name)), str(point.get(SIGN_KEY, base.scenario.sign)),
            float(point.get(SPEED_KEY, base.scenario.speed_kmh)))


def safety_map(records: Sequence[Mapping[str, Any]], base: SimConfig) -> SafetyMap:
    """Group the records by (policy, sign, speed); see the module docstring for what is safe."""
    groups: dict[tuple[str, str, float], list[Mapping[str, Any]]] = {}
    for record in records:
        groups.setdefault(coordinates(record, base), []).append(record)
    cells = {}
    for key, group in groups.items():
        ok = [r for r in group if r["status"] == "ok"]
        cells[key] = SpeedOutcome(
            runs=len(group), failed=len(group) - len(ok),
            stopped=sum(1 for r in ok if r["result"]["outcome"] in STOPPED_BEFORE_SIGN),
            sign_margins_m=tuple(r["result"]["sign_margin_m"] for r in ok),
            outcomes=tuple(r["result"]["outcome"] for r in ok),
            beyond_gate=sum(record_rested_beyond_gate(r["result"]) for r in ok))
    return SafetyMap(speeds_kmh=tuple(sorted({s for _, _, s in groups})),
                     policies=tuple(dict.fromkeys(p for p, _, _ in groups)),
                     signs=tuple(dict.fromkeys(s for _, s, _ in groups)), cells=cells)


# ---- attack strength ------------------------------------------------------------------------

@dataclass(frozen=True)
class Strength:
    """A sign's attack: method and budget from its texture's JSON record (clean: budget 0)."""

    sign: str
    method: str | None
    budget_key: str | None
    budget: float | None

    @property
    def label(self) -> str:
        """How the report names the sign: the texture, or "method budget_key=budget" for a budget-sweep texture."""
        if self.method is None:
            return self.sign if self.budget is None else "clean"
        return f"{self.method} {self.budget_key}={self.budget:g}" if self.budget is not None else self.sign


def sign_strength(sign: str) -> Strength:
    """Read the budget of `sign` from the JSON record beside its PNG; unknown budgets stay None."""
    from avsim.experiments.attacks.budget_sweep import BUDGET_KEY
    from avsim.world.scene import resolve_sign_texture

    if sign == "clean":
        return Strength(sign, None, None, 0.0)
    try:
        record = json.loads(resolve_sign_texture(sign).with_suffix(".json").read_text())
    except (ConfigError, OSError, ValueError):  # texture gone since the run, or no record beside it
        return Strength(sign, None, None, None)
    method = record.get("method")
    key = BUDGET_KEY.get(method)
    budget = record.get("hyperparameters", {}).get(key) if key else None
    return Strength(sign, method, key, float(budget) if isinstance(budget, (int, float)) else None)


def ordered_by_strength(strengths: Sequence[Strength]) -> list[Strength]:
    """Clean first, then by method and budget; signs of unknown budget last, in their given order."""
    known = sorted((s for s in strengths if s.budget is not None), key=lambda s: (s.method or "", s.budget))
    return known + [s for s in strengths if s.budget is None]


@dataclass(frozen=True)
class FrontMeasure:
    """What the front camera made of one sign, over the sign's ok runs in the sweep.

    peak_conf: the highest stop-sign confidence in a run, mean over runs.
    range_m: bumper-to-sign distance [m] of the first frame scored at or above the policy's
    conf_threshold, mean over the runs that had one (`reached` of `runs`); None if none did.
    """

    runs: int
    peak_conf: float
    reached: int
    range_m: float | None


def front_measures(records: Sequence[Mapping[str, Any]], base: SimConfig) -> dict[str, FrontMeasure]:
    """Per sign, from the run traces: see `FrontMeasure`."""
    peaks: dict[str, list[float]] = {}
    ranges: dict[str, list[float]] = {}
    for record in records:
        trace = record.get("trace") or {}
        if record["status"] != "ok" or not trace.get("front_conf"):
            continue
        sign = coordinates(record, base)[1]
        threshold = record["result"]["config"]["policy"]["conf_threshold"]
        peaks.setdefault(sign, []).append(max(trace["front_conf"]))
        first = next((d for d, c in zip(trace["sign_dist_m"], trace["front_conf"]) if c >= threshold), None)
        if first is not None:
            ranges.setdefault(sign, []).append(first)
    return {sign: FrontMeasure(len(values), statistics.fmean(values), len(ranges.get(sign, [])),
                               statistics.fmean(ranges[sign]) if sign in ranges else None)
            for sign, values in peaks.items()}


# ---- summary and figure ---------------------------------------------------------------------

def write_sweep_report(out_dir: Path, sweep, records: Sequence[Mapping[str, Any]], manifest: Mapping[str, Any]) -> Path:
    """Write `summary.md` and `safety_map.png` into `out_dir`; returns the summary's path."""
    smap = safety_map(records, sweep.base)
    strengths = ordered_by_strength([sign_strength(s) for s in smap.signs])
    front = front_measures(records, sweep.base)
    figure = draw_safety_map(out_dir / FIGURE_FILE, smap, strengths, front, sweep.title)
    path = out_dir / "summary.md"
    write_text_atomic(path, summary_markdown(sweep, smap, strengths, front, records, manifest, figure.name))
    return path


def summary_markdown(sweep, smap: SafetyMap, strengths: Sequence[Strength], front: Mapping[str, FrontMeasure],
                     records: Sequence[Mapping[str, Any]], manifest: Mapping[str, Any], figure_name: str) -> str:
    """The sweep's summary.md: runs and time, the safety map (highest safe speed per policy and sign),
    the attack strengths and the figure `figure_name`.
    """
    signs = [s.sign for s in strengths]
    lowest = smap.speeds_kmh[0] if smap.speeds_kmh else None
    lines = [
        f"# {sweep.title}", "",
        f"{manifest['runs']} runs ({manifest['failed']} failed), {sweep.seeds} seed(s) per grid point; "
        f"{manifest['ran']} run now and {manifest['reused']} reused, in {manifest['wall_s']:.0f} s {_ran_on(manifest)}"
        + (f" ({len(manifest['history'])} earlier invocation(s) in manifest.json)" if manifest.get("history") else "")
        + f"; the runs' own wall times add up to {_run_seconds(records):.0f} s. "
        f"Grid speeds [km/h]: {', '.join(f'{s:g}' for s in smap.speeds_kmh)}. "
        + versions_sentence(manifest["versions"], manifest.get("cluster_nodes")), "",
        "## Highest speed at which the car stops before the sign [km/h]", "",
        "A speed counts when every run at it stopped before the sign (outcome stopped_before_line or "
        f"stopped_past_line). \"none\": not even at {lowest:g} km/h. A `*` marks a gap: some lower speed did not stop "
        "(the value in brackets is the highest speed with every speed up to it safe)." if lowest is not None else "", "",
        "| policy | " + " | ".join(s.label for s in strengths) + " |",
        "|---|" + "---:|" * len(strengths),
    ]
    for policy in smap.policies:
        lines.append(f"| {policy} | " + " | ".join(_safe_cell(smap, policy, sign) for sign in signs) + " |")
    lines += ["", f"![safety map]({figure_name})", "",
              "## Attack strength", "",
              "Budget: from the texture's JSON record. Measured in this sweep's runs, front camera: the "
              "highest stop-sign score in a run (mean over the sign's runs), and the distance from the bumper "
              "to the sign of the first frame scored at or above the policy's threshold "
              f"({sweep.base.policy.conf_threshold:g}; mean over the runs that reached it).", "",
              "| sign | texture | budget | peak front confidence | front camera sure at [m] |", "|---|---|---:|---:|---:|"]
    for s in strengths:
        budget = "0 (clean)" if s.method is None and s.budget == 0 else (f"{s.budget_key} = {s.budget:g}" if s.budget is not None else "unknown")
        m = front.get(s.sign)
        peak = f"{m.peak_conf:.3f}" if m else "n/a"
        sure = "n/a" if m is None else ("never" if m.range_m is None else f"{m.range_m:.1f}")
        if m is not None and 0 < m.reached < m.runs:
            sure += f" ({m.runs - m.reached} of {m.runs} runs never)"
        lines.append(f"| {s.label} | `{s.sign}` | {budget} | {peak} | {sure} |")
    lines += ["", "## Every run", "",
              "Bumper to sign at the end [m] (> 0: before the sign; `line`: before the stop line too); "
              "`past`: braked but ran past the sign; `never braked`: ran past without braking; `timed out`: the time "
              "limit ended the run before the sign; with several runs, how many stopped before the sign, and how many of "
              "those stops came to rest farther before the stop line than the braking gate reaches (\"beyond the gate\": "
              f"{BEYOND_GATE_CAUSE}; a stop all the same).", "",
              "| policy | sign | " + " | ".join(f"{s:g}" for s in smap.speeds_kmh) + " |",
              "|---|---|" + "---:|" * len(smap.speeds_kmh)]
    for policy in smap.policies:
        for s in strengths:
            cells = [run_cell_text(smap.cells.get((policy, s.sign, speed))) for speed in smap.speeds_kmh]
            lines.append(f"| {policy} | {s.label} | " + " | ".join(cells) + " |")
    lines += ["", "## Speed reached", "",
              "The car starts from rest; the highest speed it reached in each run, lowest and highest over the runs "
              "at that target [km/h].", "",
              "| target | " + " | ".join(f"{s:g}" for s in smap.speeds_kmh) + " |",
              "|---|" + "---:|" * len(smap.speeds_kmh)]
    reached: dict[float, list[float]] = {}
    for record in records:
        if record["status"] == "ok":
            reached.setdefault(coordinates(record, sweep.base)[2], []).append(record["result"]["peak_speed_mps"] * 3.6)
    lines.append("| reached | " + " | ".join(
        f"{min(reached[s]):.0f}–{max(reached[s]):.0f}" if s in reached else "n/a" for s in smap.speeds_kmh) + " |")
    failed = [r for r in records if r["status"] == "failed"]
    if failed:
        lines += ["", f"## Failed runs ({len(failed)})", ""]
        lines += [f"- {r['cell']}, seed {r['seed']}: {r['error']}" for r in failed]
    return "\n".join(lines) + "\n"


def _ran_on(manifest: Mapping[str, Any]) -> str:
    """Where the runs ran: e.g. 'with 2 workers', 'with 2 Ray workers', 'on the Ray cluster at HOST:6379'."""
    workers, backend, address = manifest["workers"], manifest.get("backend", "local"), manifest.get("address")
    if backend == "ray" and address is not None:
        cap = f" (at most {workers} run{'s' if workers != 1 else ''} at once)" if workers is not None else ""
        return f"on the Ray cluster at {address}{cap}"
    kind = "Ray worker" if backend == "ray" else "worker"
    return f"with {workers} {kind}{'s' if workers != 1 else ''}"


def _run_seconds(records: Sequence[Mapping[str, Any]]) -> float:
    return sum(r.get("wall_s") or 0.0 for r in records)


def _tick(strength: Strength, measure: FrontMeasure | None) -> str:
    if measure is None:
        return strength.label
    sure = "never" if measure.range_m is None else f"{measure.range_m:.1f} m"
    return f"{strength.label}\nfront sure at {sure}"


def _safe_cell(smap: SafetyMap, policy: str, sign: str) -> str:
    best, up_to = smap.max_safe_kmh(policy, sign), smap.safe_up_to_kmh(policy, sign)
    if best is None:
        return "none"
    if up_to == best:
        return f"{best:g}"
    return f"{best:g}* ({'none' if up_to is None else f'{up_to:g}'})"


def run_cell_text(cell: SpeedOutcome | None, beyond_gate_note: bool = True) -> str:
    """What the "Every run" table shows for one (policy, sign, speed): the one run's end, or the stop count
    (with `beyond_gate_note`, and how many of those stops came to rest beyond the gate)."""
    if cell is None:
        return ""
    if cell.runs == 1:
        if cell.failed:
            return "failed"
        outcome, margin = cell.outcomes[0], cell.sign_margins_m[0]
        return {"stopped_before_line": f"{margin:.1f} line", "stopped_past_line": f"{margin:.1f}",
                "ran_past_sign": "past", "never_braked": "never braked", "timed_out_before_sign": "timed out"}[outcome]
    note = f"; {cell.beyond_gate} beyond the gate" if beyond_gate_note and cell.beyond_gate else ""
    return (f"{cell.stopped}/{cell.runs}" + note
            + (f" ({cell.failed} failed)" if cell.failed else ""))


def draw_safety_map(path: Path, smap: SafetyMap, strengths: Sequence[Strength], front: Mapping[str, FrontMeasure],
                    title: str) -> Path:
    """Left: highest safe speed against attack strength, a line per policy. Right: a panel per policy."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    n_policies = max(1, len(smap.policies))
    cols = 2 if n_policies > 1 else 1
    rows = math.ceil(n_policies / cols)
    fig = plt.figure(figsize=(6 + 3.6 * cols, max(5.0, 3.2 * rows)), dpi=120)
    grid = fig.add_gridspec(rows, cols + 2, width_ratios=[1.5, 0.15] + [1.0] * cols)
    ax = fig.add_subplot(grid[:, 0])

    # x: the budget when every sign has one of the same kind, else evenly spaced in strength order.
    keys = {s.budget_key for s in strengths if s.method is not None}
    numeric = all(s.budget is not None for s in strengths) and len(keys) <= 1
    xs = [s.budget if numeric else float(i) for i, s in enumerate(strengths)]
    span = (max(xs) - min(xs)) or 1.0
    top = max(smap.speeds_kmh) if smap.speeds_kmh else 1.0
    bottom = min(smap.speeds_kmh) if smap.speeds_kmh else 0.0
    none_y = bottom - 0.1 * ((top - bottom) or top)  # "no speed was safe", just below the grid
    for k, policy in enumerate(smap.policies):
        # A small sideways offset per policy keeps equal values from hiding each other.
        offset = (k - (n_policies - 1) / 2) * 0.012 * span
        ys = [smap.max_safe_kmh(policy, s.sign) for s in strengths]
        line = ax.plot([x + offset for x in xs], [np.nan if y is None else y for y in ys], "o-", lw=1.5, label=policy)[0]
        none_x = [x + offset for x, y in zip(xs, ys) if y is None]
        ax.plot(none_x, [none_y] * len(none_x), "x", color=line.get_color(), ms=8, mew=2)
    ax.set_xticks(xs, [_tick(s, front.get(s.sign)) for s in strengths], fontsize=7)
    ax.set_xlim(min(xs) - 0.12 * span, max(xs) + 0.12 * span)
    ax.set_yticks([none_y, *smap.speeds_kmh], ["none", *(f"{s:g}" for s in smap.speeds_kmh)])
    ax.set_ylim(none_y - 0.05 * (top - none_y), top + 0.05 * (top - none_y))
    ax.set_xlabel("attack budget (front sure at: mean distance of the first confident front frame)", fontsize=8)
    ax.set_ylabel("highest speed that stops before the sign [km/h]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    ax.set_title("Highest safe speed (every run stopped)", fontsize=10)

    cmap = matplotlib.colormaps["RdYlGn"].with_extremes(bad="#bbbbbb")
    for k, policy in enumerate(smap.policies):
        panel = fig.add_subplot(grid[k // cols, 2 + k % cols])
        frac = np.full((len(smap.speeds_kmh), len(strengths)), np.nan)
        for i, speed in enumerate(smap.speeds_kmh):
            for j, s in enumerate(strengths):
                cell = smap.cells.get((policy, s.sign, speed))
                if cell is not None and not cell.failed:
                    frac[i, j] = cell.stopped / cell.runs
                if cell is not None:
                    panel.text(j, i, run_cell_text(cell, beyond_gate_note=False).replace(" line", ""), ha="center", va="center", fontsize=6)
        panel.imshow(np.ma.masked_invalid(frac), cmap=cmap, vmin=0, vmax=1, origin="lower", aspect="auto")
        panel.set_xticks(range(len(strengths)), [s.label.replace(" ", "\n", 1) for s in strengths], fontsize=6)
        panel.set_yticks(range(len(smap.speeds_kmh)), [f"{s:g}" for s in smap.speeds_kmh], fontsize=7)
        panel.set_title(policy, fontsize=9)
        if k % cols == 0:
            panel.set_ylabel("speed [km/h]", fontsize=8)
    fig.suptitle(f"{title}\npanels: green stopped before the sign (text: metres to the sign), red not, grey failed",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path
