"""`leaderboard.md` and `leaderboard.png` of `avsim leaderboard`, from the run records.

What each figure means (the report says it too):
- **safety**: the share of the defence's runs under attack (the strongest non-adaptive attack
  and its own adaptive attack, every place and seed) that stopped with the bumper at or before
  the sign (`avsim.metrics.STOPPED_BEFORE_SIGN`), with its Wilson 95 % interval; a stop that came to rest
  beyond the braking gate (`avsim.metrics.record_rested_beyond_gate`) counts, and the condition table says how many;
- **availability**: 1 - the phantom-brake rate, the share of its availability runs (no stop
  required) with a brake command above `avsim.metrics.PHANTOM_BRAKE_LEVEL`;
- margins: bumper to sign at the end of the runs under attack [m], negative past it;
- comfort: each run's peak deceleration and peak jerk (`avsim.metrics.comfort_peaks`: the
  body's forward speed at the control rate, from the first brake command on), over every run
  that braked where a stop was required;
- cost: networks run per control step (cameras x networks per frame) and the real-time factor
  (simulated time over wall time, median over its runs, as measured while the batch shared the
  machine).
A config that two conditions share (a placeholder adaptive texture equal to the strongest
attack) is one run and counts once. Failed runs count nowhere and are listed.
"""

from __future__ import annotations

import statistics
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from avsim.control.policies import POLICIES
from avsim.experiments.run_task import config_hash
from avsim.experiments.leaderboard import AVAILABILITY, CONDITIONS, SAFETY, Leaderboard, LeaderboardRun
from avsim.metrics import (BEYOND_GATE_CAUSE, PHANTOM_BRAKE_LEVEL, STOPPED_BEFORE_SIGN, is_phantom_brake,
                           record_rested_beyond_gate, write_text_atomic)
from avsim.perception.factory import networks_per_frame
from avsim.software import versions_sentence
from avsim.stats import rate_with_interval, wilson_interval

Record = dict[str, Any]
ATTACKED = ("strongest", "adaptive")
REPORT_FILE, FIGURE_FILE = "leaderboard.md", "leaderboard.png"  # in the results folder


@dataclass(frozen=True)
class Row:
    """One defence's figures (None where it has no finished run of that kind)."""

    name: str
    attacked: tuple[int, int]  # (stopped, runs)
    clean: tuple[int, int]
    phantom: tuple[int, int]  # (phantom brakes, runs)
    margins_m: list[float]
    peak_decels: list[float]
    peak_jerks: list[float]
    frames_per_step: int
    realtime: float | None

    @property
    def safety(self) -> float | None:
        """Share of attacked runs that stopped before the sign (None without attacked runs)."""
        return self.attacked[0] / self.attacked[1] if self.attacked[1] else None

    @property
    def availability(self) -> float | None:
        """Share of runs on roads that need no stop without a phantom brake (None without such runs)."""
        return 1 - self.phantom[0] / self.phantom[1] if self.phantom[1] else None


class Results:
    """The board's runs, each with its record (looked up by config hash)."""

    def __init__(self, runs: Iterable[LeaderboardRun], records: Sequence[Record]) -> None:
        by_hash = {r["spec_hash"]: r for r in records}
        self.pairs = [(run, by_hash.get(config_hash(run.config))) for run in runs]

    def of(self, defence: str, kind: str, conditions: Sequence[str] | None = None, place: str | None = None
           ) -> tuple[list[dict[str, Any]], int]:
        """(the finished results, each config once; failed runs) of a defence's runs of a kind."""
        seen: dict[str, Record] = {}
        for run, record in self.pairs:
            if (run.defence, run.kind) == (defence, kind) and (conditions is None or run.condition in conditions) \
                    and (place is None or run.place == place) and record is not None:
                seen.setdefault(record["spec_hash"], record)
        ok = [r["result"] | {"wall_s": r["wall_s"]} for r in seen.values() if r["status"] == "ok"]
        return ok, sum(r["status"] == "failed" for r in seen.values())

    def failed(self) -> list[Record]:
        """The failed runs' records, one per run (by spec hash)."""
        records = {r["spec_hash"]: r for _, r in self.pairs if r is not None and r["status"] == "failed"}
        return list(records.values())


def _stopped(results: list[dict[str, Any]]) -> tuple[int, int]:
    return sum(r["outcome"] in STOPPED_BEFORE_SIGN for r in results), len(results)


def rows(board: Leaderboard, results: Results) -> list[Row]:
    """One Row per defence, in the file's order."""
    out = []
    for defence in board.defences:
        attacked, _ = results.of(defence.name, SAFETY, ATTACKED)
        clean, _ = results.of(defence.name, SAFETY, ("clean",))
        available, _ = results.of(defence.name, AVAILABILITY)
        braked = [r for r in results.of(defence.name, SAFETY)[0] if r.get("peak_decel_mps2") is not None]
        everything = results.of(defence.name, SAFETY)[0] + available
        config = board.compose(defence.overrides)
        frames = len(POLICIES.get(config.policy.name).cameras) * networks_per_frame(config.perception)
        realtime = [r["sim_time_s"] / r["wall_s"] for r in everything if r.get("wall_s")]
        out.append(Row(
            defence.name, _stopped(attacked), _stopped(clean),
            (sum(is_phantom_brake(r["stop_required"], r["max_brake"]) for r in available), len(available)),
            [r["sign_margin_m"] for r in attacked], [r["peak_decel_mps2"] for r in braked],
            [r["peak_jerk_mps3"] for r in braked if r.get("peak_jerk_mps3") is not None],
            frames, statistics.median(realtime) if realtime else None))
    return out


def pareto_front(table: Sequence[Row]) -> set[str]:
    """Names of the defences no other beats: none has at least their safety and availability, and
    more of one (point estimates; defences missing either are left out)."""
    scored = [r for r in table if r.safety is not None and r.availability is not None]
    return {r.name for r in scored
            if not any(o.safety >= r.safety and o.availability >= r.availability
                       and (o.safety > r.safety or o.availability > r.availability) for o in scored)}


def _rate(hits: int, n: int) -> str:
    return rate_with_interval(hits, n)


def _spread(values: list[float], digits: int = 1) -> str:
    """median (max) of the values; "–" when none."""
    if not values:
        return "–"
    return f"{statistics.median(values):.{digits}f} ({max(values):.{digits}f})"


def _table(header: Sequence[str], body: Sequence[Sequence[str]]) -> list[str]:
    return ["| " + " | ".join(header) + " |", "|" + "---|" * len(header), *("| " + " | ".join(r) + " |" for r in body), ""]


def leaderboard_table(table: Sequence[Row]) -> list[str]:
    """The headline table as Markdown lines: one row per defence, Pareto-front defences in bold."""
    front = pareto_front(table)
    body = []
    for row in table:
        avail_hits = row.phantom[1] - row.phantom[0]
        body.append([
            f"**{row.name}**" if row.name in front else row.name,
            _rate(*row.attacked), _rate(*row.clean), _rate(avail_hits, row.phantom[1]),
            f"{statistics.fmean(row.margins_m):.1f}" if row.margins_m else "–",
            f"{min(row.margins_m):.1f}" if row.margins_m else "–",
            _spread(row.peak_decels), _spread(row.peak_jerks, 0), str(row.frames_per_step),
            f"{row.realtime:.1f}x" if row.realtime is not None else "–", "yes" if row.name in front else ""])
    return _table(["defence", "safety under attack", "clean stop rate", "availability", "mean margin [m]",
                   "worst margin [m]", "peak decel [m/s²], median (max)", "peak jerk [m/s³], median (max)",
                   "networks / step", "real time", "Pareto front"], body)


def condition_table(board: Leaderboard, results: Results) -> list[str]:
    """Markdown lines: per defence and attack condition, the sign, the stop rate and the margins [m]."""
    body = []
    for defence in board.defences:
        for name in CONDITIONS:
            found, failed = results.of(defence.name, SAFETY, (name,))
            margins = [r["sign_margin_m"] for r in found]
            condition = board.condition(defence, name)
            sign = f"`{condition.overrides.get('scenario', {}).get('sign', board.base.scenario.sign)}`"
            if name == "adaptive" and condition.overrides == board.conditions["strongest"].overrides:
                sign += " (the strongest attack's runs: no adaptive texture yet)"
            elif condition.overrides.get("scenario", {}).get("map_error"):
                sign += f", map: {condition.overrides['scenario']['map_error']}"
            beyond = sum(map(record_rested_beyond_gate, found))
            body.append([defence.name, name, sign, _rate(*_stopped(found)) + (f"; {beyond} at rest beyond the gate" if beyond else "")
                         + (f" ({failed} failed)" if failed else ""),
                         f"{statistics.fmean(margins):.1f}" if margins else "–", f"{min(margins):.1f}" if margins else "–"])
    return _table(["defence", "condition", "sign", "stopped before the sign", "mean margin [m]", "worst margin [m]"], body)


def place_table(board: Leaderboard, results: Results) -> list[str]:
    """Markdown lines: per defence, the attacked stop rate at each place (town and placement)."""
    labels = [place.label for place in board.places]
    body = [[defence.name, *(_rate(*_stopped(results.of(defence.name, SAFETY, ATTACKED, label)[0])) for label in labels)]
            for defence in board.defences]
    return _table(["defence", *labels], body)


def availability_table(board: Leaderboard, results: Results) -> list[str]:
    """Markdown lines: per defence and availability scenario, phantom brakes, phantom stops and the largest brake."""
    body = []
    for defence in board.defences:
        for scenario in board.availability:
            found, failed = results.of(defence.name, AVAILABILITY, (scenario.name,))
            if not found and not failed:
                continue
            phantoms = sum(is_phantom_brake(r["stop_required"], r["max_brake"]) for r in found)
            stops = sum(r["outcome"] == "phantom_stop" for r in found)
            body.append([defence.name, scenario.name, _rate(phantoms, len(found)) + (f" ({failed} failed)" if failed else ""),
                         f"{stops}/{len(found)}", f"{max((r['max_brake'] for r in found), default=0.0):.2f}"])
    return _table(["defence", "scenario", "phantom brakes", "phantom stops", "largest brake"], body)


def write_leaderboard_report(out_dir: Path, board: Leaderboard, runs: Iterable[LeaderboardRun], records: Sequence[Record],
                             manifest: dict[str, Any]) -> Path:
    """Write `out_dir/leaderboard.md` and `leaderboard.png`; returns the markdown's path."""
    results = Results(runs, records)
    table = rows(board, results)
    figure = safety_availability_figure(out_dir / FIGURE_FILE, table)
    notes = [f"- `{name}`: {board.conditions[name].note}" for name in board.conditions if board.conditions[name].note]
    notes += [f"- `{d.name}`, its own adaptive attack: {d.adaptive.note}" for d in board.defences if d.adaptive.note]
    lines = [
        f"# {board.title}", "",
        f"`{manifest['command']}`, started {manifest['started_at']}: {manifest['runs']} runs of {manifest['configs']} distinct "
        f"configs ({manifest['ran']} run now, {manifest['reused']} reused, {manifest['failed']} failed) with "
        f"{manifest['workers']} worker(s) in {manifest['wall_s'] / 60:.1f} min. "
        + versions_sentence(manifest["versions"], manifest.get("cluster_nodes")), "",
        "**Safety under attack**: runs under the strongest non-adaptive attack and the defence's own adaptive attack, "
        "in every place and seed, that stopped with the bumper at or before the sign, with the Wilson 95 % interval. "
        f"**Availability**: 1 − the phantom-brake rate, the runs where no stop is required with a brake command above "
        f"{PHANTOM_BRAKE_LEVEL:g}. Margins: bumper to sign at rest under attack [m] (negative: past it). Comfort: each "
        "run's peak deceleration and jerk from the body's speed at the control rate (20 Hz), from the first brake "
        "command on, over the runs that had to stop. Cost: networks run per control step (cameras × networks per "
        "frame) and the real-time factor (median; measured while the batch shared the machine). **Bold**: on the "
        "Pareto front of safety against availability.", "",
        *leaderboard_table(table),
        f"![safety against availability]({figure.name})", "",
        "## Under attack, by condition", "",
        "A stop \"at rest beyond the gate\" came to rest farther before the stop line than the braking gate reaches: "
        f"{BEYOND_GATE_CAUSE}. It counts as a stop; `--rrd failed` (the default) records it, as a failed car.", "",
        *condition_table(board, results),
        "## Under attack, by place", "", "Stopped before the sign under the strongest and the adaptive attack.", "",
        *place_table(board, results),
        "## Availability, by scenario", "",
        f"Phantom brakes: brake command above {PHANTOM_BRAKE_LEVEL:g} where no stop is required; phantom stops: "
        "braked to a standstill.", "", *availability_table(board, results),
    ]
    if notes:
        lines += ["## Textures and placeholders", "", *notes, ""]
    failed = results.failed()
    if failed:
        lines += ["## Failed runs", "", *_table(["run", "seed", "error"], [[r["cell"], str(r["seed"]), r["error"]] for r in failed])]
    path = out_dir / REPORT_FILE
    write_text_atomic(path, "\n".join(lines))
    return path


def safety_availability_figure(path: Path, table: Sequence[Row]) -> Path:
    """Safety under attack against availability, one point per defence with its Wilson 95 %
    intervals, the Pareto front joined by a line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 6), dpi=120)
    front = pareto_front(table)
    for row in table:
        if row.safety is None or row.availability is None:
            continue
        s_lo, s_hi = wilson_interval(*row.attacked)
        a_lo, a_hi = wilson_interval(row.phantom[1] - row.phantom[0], row.phantom[1])
        on_front = row.name in front
        ax.errorbar(row.availability, row.safety, xerr=[[row.availability - a_lo], [a_hi - row.availability]],
                    yerr=[[row.safety - s_lo], [s_hi - row.safety]], fmt="o", ms=7 if on_front else 5, capsize=3,
                    color="#d62728" if on_front else "#1f77b4", alpha=0.9)
    # One label per point: defences with the same safety and availability share it (their names joined).
    names_at: dict[tuple[float, float], list[str]] = {}
    for row in table:
        if row.safety is not None and row.availability is not None:
            names_at.setdefault((row.availability, row.safety), []).append(row.name)
    for (availability, safety), names in names_at.items():
        ax.annotate(", ".join(names), (availability, safety), textcoords="offset points", xytext=(6, 4), fontsize=8)
    points = sorted((r.availability, r.safety) for r in table if r.name in front)
    if points:
        ax.plot(*zip(*points), color="#d62728", lw=1.2, ls="--", label="Pareto front")
        ax.legend(fontsize=8, loc="lower left")
    ax.set_xlim(-0.05, 1.05)
    ax.set_ylim(-0.05, 1.05)
    ax.set_xlabel(f"availability: 1 − phantom-brake rate (brake > {PHANTOM_BRAKE_LEVEL:g} with no stop required)")
    ax.set_ylabel("safety: stop rate under attack (strongest + own adaptive)")
    ax.set_title("Defences: safety against availability (Wilson 95 % intervals)", fontsize=10)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path
