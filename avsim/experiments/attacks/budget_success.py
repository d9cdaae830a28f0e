"""Closed-loop attack success against the camouflage budget: the budget sweep's textures driven past.

`avsim attack sweep --closed-loop FILE` takes an attack-success experiment file as the protocol
(e.g. `experiments/attacks/success_town07.toml`: baseline, Town07 standard, 85 km/h from 150 m,
sensor noise and lighting drawn per seed) and runs its cell named "clean" once with the clean
sign and once with each budget's texture in its place, at the file's seeds. Only the sign
differs between a texture's runs and the clean ones, so seed k meets the same start, noise
and light with every sign, and the braking delay is paired by seed (`avsim.experiments.attacks.success`).
Every run is `avsim run`'s closed loop: the stop position comes from the physics, the
detections from the detector on the rendered frames.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from avsim.experiments.attacks.success import Success, success
from avsim.config import with_overrides
from avsim.experiments.batch import run_batch
from avsim.experiments.plan import Plan
from avsim.experiments.recordings import with_recordings
from avsim.experiments.results_file import JsonlWriter
from avsim.experiments.run_task import RunSpec
from avsim.experiments.spec import Cell, Experiment, check_networks, check_renderer, load_experiment

CLEAN_CELL = "clean"


def load_protocol(path: str | Path) -> Experiment:
    """The experiment file whose "clean" cell is the protocol; a one-line ConfigError if it has none."""
    experiment = load_experiment(path)
    protocol = experiment.cell(CLEAN_CELL).config  # the cell raises, naming the cells it has
    check_networks(protocol)
    check_renderer(protocol)
    return experiment


def protocol_specs(protocol: Experiment, signs: Mapping[str, str]) -> Plan:
    """One RunSpec per (label, sign) and seed: the clean cell with `scenario.sign` = sign, each
    built only as a batch draws on it (`avsim.experiments.plan`).

    signs: label -> a --sign value (a texture name or a PNG path), in the order to run them.
    """
    clean = protocol.cell(CLEAN_CELL)
    cells = [Cell(label, with_overrides(clean.config, {"scenario": {"sign": sign}})) for label, sign in signs.items()]
    return Plan(len(cells) * protocol.seeds,
                lambda: (RunSpec("attack_sweep", cell.name, seed, protocol.config_for(cell, seed))
                         for cell in cells for seed in range(protocol.seeds)))


def closed_loop_success(protocol: Experiment, signs: Mapping[str, str], runs_jsonl: Path,
                        workers: int = 1, progress: bool = True, rrd: str = "none",
                        mcap: str = "none") -> dict[str, Success]:
    """Run the protocol past every sign (and the clean one, labelled "clean"); label -> Success.

    Every run's record is written to `runs_jsonl` (replaced) as it finishes, in the batch format
    of `avsim reproduce`. A failed run raises RuntimeError naming it: a rate over the runs that
    happened to finish would not be the rate.
    """
    all_signs = {CLEAN_CELL: "clean", **{label: sign for label, sign in signs.items() if label != CLEAN_CELL}}
    plan = protocol_specs(protocol, all_signs).then(
        lambda specs: with_recordings(specs, runs_jsonl.parent, rrd=rrd, mcap=mcap))
    runs_jsonl.unlink(missing_ok=True)  # this sweep's runs only, never appended to an earlier sweep's
    writer = JsonlWriter(runs_jsonl)
    records = run_batch(plan, workers=workers, on_record=writer.append, progress=progress,
                        description="closed-loop runs", root=runs_jsonl.parent)
    failed = [f"{r['cell']} seed {r['seed']}: {r['error']}" for r in records if r["status"] != "ok"]
    if failed:
        raise RuntimeError(f"{len(failed)} closed-loop runs failed, e.g. {failed[0]} (records in {runs_jsonl})")
    by_label: dict[str, list[dict[str, Any]]] = {}
    for record in records:
        by_label.setdefault(record["cell"], []).append(record)
    clean_by_seed = {r["seed"]: r["result"] for r in by_label[CLEAN_CELL]}
    return {label: success([r["result"] for r in rows], [r["seed"] for r in rows],
                           clean_by_seed if label != CLEAN_CELL else None)
            for label, rows in by_label.items()}
