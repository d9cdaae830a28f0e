"""Resuming a results folder: which folders hold runs a resume would add to."""

from avsim.experiments.resumable import RESULTS_FILE, holds_runs


def test_only_a_results_file_with_something_in_it_holds_runs(tmp_path):
    results = tmp_path / RESULTS_FILE
    assert not holds_runs(results)  # a first command under --resume: nothing to mix its runs with
    results.write_text("")
    assert not holds_runs(results)
    results.write_text('{"status": "ok"}\n')
    assert holds_runs(results)
