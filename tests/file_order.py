"""The order in which the test files go out to pytest-xdist's processes (used by `conftest.py`).

pytest-xdist's loadfile hands each process whole files, by default in order of their test count. That put
the slow pass's one-test files (the TF.js reference, then about 220 s) last, and one process sat idle for
about two minutes at the end. `make test` passes --no-loadscope-reorder, so the files go out in the order below: the longest
first (longest-processing-time-first scheduling), then every other file as collected. The seconds are each
file's test time in the default and slow passes together (the wall column of `--cpu-durations`, on a quiet
2-core machine, 2026-11-27); they decide only the order, never what runs. A file left out of the table, or
one that grows, costs time, not correctness.
"""

LONGEST_FILES_S = {
    "tests/perception/detector/test_perception.py": 494,
    "tests/test_loop.py": 257,
    "tests/test_lockstep.py": 250,
    "tests/experiments/test_study_outcomes.py": 174,
    "tests/control/test_defences_in_the_loop.py": 172,
    "tests/cli/test_cli_signals.py": 156,
    "tests/perception/coco/test_coco_reference.py": 95,
    "tests/experiments/test_sweep_backends.py": 82,
    "tests/test_termination.py": 82,
    "tests/control/test_policies_in_the_loop.py": 74,
    "tests/experiments/test_sweep_resume.py": 64,
    "tests/experiments/attacks/test_texture_eval.py": 59,
    "tests/perception/nanodet/test_nanodet_reference.py": 52,
    "tests/experiments/test_leaderboard.py": 50,
    "tests/attacks/test_driveby.py": 48,
    "tests/test_validation.py": 45,
    "tests/gym/test_gym_vector.py": 44,
    "tests/experiments/test_sweep.py": 42,
    "tests/experiments/test_output_lock.py": 40,
}


def longest_files_first(items: list) -> None:
    """Sorts pytest's collected items in place: the files of LONGEST_FILES_S first, longest first. The sort is
    stable, so each file's tests stay together and in order, and every other file stays where it was."""
    rank = {path: i for i, path in enumerate(sorted(LONGEST_FILES_S, key=lambda path: -LONGEST_FILES_S[path]))}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::")[0], len(rank)))
