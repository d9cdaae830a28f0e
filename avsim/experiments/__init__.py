"""Experiment files: a table or figure of the study as named cells over seeds.

`load_experiment("experiments/table3_stop_positions.toml")` resolves every cell to a
full `SimConfig`; `Experiment.runs()` expands the cells over the seeds.
"""

from avsim.experiments.spec import Cell, Experiment, Run, load_experiment

__all__ = ["Cell", "Experiment", "Run", "load_experiment"]
