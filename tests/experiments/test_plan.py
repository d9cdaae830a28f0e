"""Plans are lazy: a command with 10^5+ runs starts its first run having built only a few specs."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from avsim import cli
from avsim.experiments import batch
from avsim.experiments.plan import SIBLING_WINDOW, Counted, Plan, count_of, in_flight, lockstep_groups
from avsim.experiments.results_file import read_records
from avsim.experiments.run_task import RunSpec, failed_record
from helpers import short_run_spec

REPO = Path(__file__).resolve().parents[2]
BATCH = 4  # runs per lock-step group in these tests

SWEEP = """title = "huge"
seeds = 200000
[defaults]
scenario = { town = "town07", placement = "standard", sign = "clean", start_dist_m = 60 }
perception = { kind = "oracle" }
[grid]
"scenario.speed_kmh" = [40, 60]
"""
EXPERIMENT = """title = "huge"
seeds = 200000
[defaults]
scenario = { town = "town07", placement = "standard", sign = "clean", start_dist_m = 60 }
perception = { kind = "oracle" }
[[cells]]
name = "baseline"
policy = { name = "baseline" }
"""


def _leaderboard_text() -> str:
    """The small board of test_leaderboard.py with 50,000 seeds at its place: 300,003 runs."""
    source = (REPO / "tests" / "experiments" / "test_leaderboard.py").read_text()
    tiny = re.search(r'TINY = """(.*?)"""', source, re.S).group(1)
    return tiny.replace("seeds = 2\nquick_seeds = 1", "seeds = 50000\nquick_seeds = 1", 1)


def _argv(command: str, tmp_path: Path) -> tuple[list[str], str]:
    """The command line of a 10^5+ run plan into tmp_path/out, and where its records land there (a glob)."""
    out = str(tmp_path / "out")
    if command == "sweep":
        (tmp_path / "huge.toml").write_text(SWEEP)
        return ["sweep", str(tmp_path / "huge.toml"), "--out", out], "results.jsonl"
    if command == "reproduce":
        (tmp_path / "huge.toml").write_text(EXPERIMENT)
        return ["reproduce", "--experiments", str(tmp_path / "huge.toml"), "--out", out, "--rrd", "none"], "*/runs.jsonl"
    (tmp_path / "board.toml").write_text(_leaderboard_text())
    return ["leaderboard", str(tmp_path / "board.toml"), "--out", out], "results.jsonl"


@pytest.mark.parametrize("command", ["sweep", "reproduce", "leaderboard"])
def test_a_plan_of_100k_runs_starts_its_first_run_after_building_only_a_few_specs(tmp_path, monkeypatch, capsys, command):
    built = []
    real_init = RunSpec.__init__
    monkeypatch.setattr(RunSpec, "__init__", lambda self, *args, **kwargs: (built.append(1), real_init(self, *args, **kwargs))[1])
    groups = []

    def first_group_then_ctrl_c(specs, root=None):
        """Stands in for the runs: the first group's records (no physics), then Ctrl-C."""
        groups.append(len(specs))
        if len(groups) > 1:
            raise KeyboardInterrupt
        return [failed_record(spec, "RuntimeError: stand-in") for spec in specs]

    monkeypatch.setattr(batch, "execute_group", first_group_then_ctrl_c)
    argv, results = _argv(command, tmp_path)
    flags = ["--workers", "1", "--batch", str(BATCH), "--no-progress"]
    assert cli.main([*argv, *flags]) == 2  # over 10,000 runs: refused without --yes
    assert "--yes" in capsys.readouterr().err and not (tmp_path / "out").exists()
    built.clear()

    assert cli.main([*argv, *flags, "--yes"]) == 130  # the stand-in's Ctrl-C, after the first group's records
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "finished run" in err, err
    (path,) = (tmp_path / "out").glob(results)
    assert len(read_records(path)) == BATCH == groups[0]
    # Only the specs among which the first groups' runs look for their siblings were built (one window,
    # `SIBLING_WINDOW`), each at most twice (its copy with recording paths, `--rrd failed`).
    assert len(built) <= 2 * SIBLING_WINDOW, f"{len(built)} specs built for a plan of 10^5+ runs"


def test_a_plan_is_built_lazily_and_again_on_each_pass():
    made = []

    def specs():
        for seed in range(5):
            made.append(seed)
            yield short_run_spec("lazy", seed)

    plan = Plan(5, specs)
    assert made == [] and count_of(plan) == 5 and count_of([1, 2]) == 2 and count_of(iter([1])) is None
    numbered = Counted(plan)
    first = next(lockstep_groups(numbered, 2, window=3))  # siblings are looked for 3 specs at a time
    assert [index for index, _ in first] == [0, 1] and made == [0, 1, 2] and not numbered.exhausted
    assert [spec.seed for spec in plan] == [0, 1, 2, 3, 4]  # a fresh pass, in the same order


def test_in_flight_keeps_at_most_its_limit_pending_and_draws_one_item_per_finished_one():
    drawn, pending = [], set()

    def items():
        for item in range(7):
            drawn.append(item)
            yield item

    def submit(item):
        pending.add(item)
        assert len(pending) <= 3
        return item

    def first_done(handles):
        done = min(handles)
        pending.discard(done)
        return done

    finished = []
    for item, handle in in_flight(items(), 3, submit, first_done, cancel=pending.discard):
        assert item == handle and len(drawn) <= len(finished) + 1 + 3
        finished.append(item)
    assert finished == list(range(7)) and not pending
