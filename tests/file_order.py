"""The order in which the test files go out to pytest-xdist's processes (used by `conftest.py`).

pytest-xdist's loadfile hands each process whole files, by default in order of their test count. In the slow
pass that put the one-test files (the TF.js reference, then about 220 s) last, and one process sat idle for
about two minutes at the end. `make test` passes --no-loadscope-reorder to the slow pass, so its files go
out in the order below: the longest first (longest-processing-time-first scheduling), then every other file
as collected. The seconds are each file's test time in the slow pass (the wall column of `--cpu-durations`,
on a quiet 2-core machine, 2026-11-27; the five largest re-measured on the 2-core AVX2 machine, 2026-12-02);
they decide only the order, never what runs. A file left out of the
table, or one that grows, costs time, not correctness.

The default pass keeps xdist's order: it ends within about 20 s of even either way, and its longest files,
run side by side, cost more CPU time (506 s and 965 CPU-s in this order against 480 s and 916 CPU-s in
xdist's, back to back on the same quiet machine).
"""

LONGEST_FILES_S = {
    "tests/perception/detector/test_perception.py": 403,  # 700 (AVX2, 2026-12-02) before its policy runs started at 150 m
    "tests/test_lockstep.py": 217,  # 420 (AVX2, 2026-12-02) before the COCO and ensemble batches went to two cars
    "tests/experiments/test_study_outcomes.py": 313,
    "tests/control/test_defences_in_the_loop.py": 236,
    "tests/test_loop.py": 83,  # 177 (AVX2, 2026-12-02) before its two-camera runs started at 150 m
    "tests/perception/coco/test_coco_reference.py": 104,
    "tests/experiments/test_sweep_backends.py": 93,
    "tests/cli/test_cli_signals.py": 168,  # AVX2, 2026-12-02, with Ctrl-C during reproduce
    "tests/experiments/attacks/test_texture_eval.py": 64,
    "tests/test_termination.py": 64,
    "tests/experiments/test_sweep_resume.py": 48,
    "tests/perception/nanodet/test_nanodet_reference.py": 44,
    "tests/test_validation.py": 40,
    "tests/control/test_policies_in_the_loop.py": 70,  # 39 measured, before the side camera's map checks moved here
    "tests/experiments/test_output_lock.py": 33,
    "tests/experiments/test_disk_full.py": 32,
    "tests/experiments/test_leaderboard.py": 50,  # the small board (about 49 s), moved here from the default pass
    "tests/experiments/test_ray_backend.py": 20,  # a sweep at an address: as the local-cluster sweep, estimated
    "tests/experiments/test_sweep.py": 60,  # the failed-run and --set sweeps with the smoke sweep they use (2026-12-02)
    "tests/gym/test_gym_vector.py": 60,  # both vector checks, moved here 2026-12-02: about 30 s each, estimated
}


def longest_files_first(items: list) -> None:
    """Sorts pytest's collected items in place: the files of LONGEST_FILES_S first, longest first. The sort is
    stable, so each file's tests stay together and in order, and every other file stays where it was."""
    rank = {path: i for i, path in enumerate(sorted(LONGEST_FILES_S, key=lambda path: -LONGEST_FILES_S[path]))}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::")[0], len(rank)))
