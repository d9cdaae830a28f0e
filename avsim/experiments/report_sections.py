"""The report kinds beyond the study's own tables (an experiment file's `report` key): the
adaptive attacker's answer, a comparison with another experiment (the wet road), the
sensitivity tables, stop rates per town and placement, and closed-loop attack success.
Each takes the grouped results (`Cells`) and the experiment and returns markdown lines.
"""

from __future__ import annotations

from collections import defaultdict
from typing import Any

from avsim.experiments.attacks import success as attack_success
from avsim.config import SimConfig
from avsim.experiments.report_cells import Cells, beyond_gate, fmt, markdown_table, run_full_brake_decel_mps2
from avsim.experiments.spec import Experiment
from avsim.metrics import STOPPED_BEFORE_SIGN
from avsim.stats import rate_with_interval


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
            *markdown_table(["cell", f"{a}: stopped", "bumper before sign", "braking began", "full brake",
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
                  *markdown_table(header, table_rows)]
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
    pooled_beyond: dict[str, int] = defaultdict(int)

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
            beyond = len(beyond_gate(results))
            pooled_beyond[policy] += beyond
            row.append(f"{rate(results)}; {fmt([r['sign_margin_m'] for r in results])} m"
                       + _beyond_gate_note(beyond) + (f"; {failed} failed" if failed else ""))
        rows.append(row)
    rows.append(["all cells"] + [f"{rate(pooled[p])}; {fmt([r['sign_margin_m'] for r in pooled[p]])} m"
                                 + _beyond_gate_note(pooled_beyond[p]) for p in policies])
    return ["Runs stopped before the sign (95% Wilson interval of the rate); the front bumper's distance before the "
            "sign at rest, mean ± std over the runs [m] (negative: past it); how many of those stops came to rest "
            "farther before the stop line than the braking gate reaches, where there were any (braking began outside "
            "the gate: see Findings).", "",
            *markdown_table(["town, placement", *policies], rows)]


def _beyond_gate_note(count: int) -> str:
    return f"; {count} at rest beyond the gate" if count else ""


def attack_success_section(cells: Cells, experiment: Experiment) -> list[str]:
    """Closed-loop attack success per cell (`avsim.experiments.attacks.success`), each attacked cell paired
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
             *markdown_table(["cell", "sign", "perception", "town, placement", "policy", *attack_success.SUCCESS_HEADER], rows)]
    if len({situation(c.config)[:2] for c in experiment.cells}) > 1:
        pooled_rows = [[sign, kind, policy, *attack_success.success_row(attack_success.success(results))]
                       for (sign, kind, policy), results in pooled.items()]
        lines += ["Pooled over the towns and placements:", "",
                  *markdown_table(["sign", "perception", "policy", *attack_success.SUCCESS_HEADER], pooled_rows)]
    return lines
