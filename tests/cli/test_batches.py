"""`avsim.cli.batches`: what a batch command says it wrote."""

from pathlib import Path

from avsim.cli.batches import _recordings_written
from avsim.experiments.recordings import KINDS


def test_the_closing_line_names_only_the_recordings_asked_for():
    out = Path("results/x")
    assert _recordings_written(out, "failed", "none") == "; recordings (--rrd failed) under results/x/rrd/"
    assert _recordings_written(out, "none", "all") == "; recordings (--mcap all) under results/x/mcap/"
    assert _recordings_written(out, "all", "failed") == ("; recordings (--rrd all, --mcap failed) under results/x/rrd/ "
                                                          "and results/x/mcap/")
    assert _recordings_written(out, "none", "none") == ""


def test_the_folders_it_names_are_the_ones_the_recordings_go_to():
    assert {kind: folder for kind, (folder, _) in KINDS.items()} == {"rrd": "rrd", "mcap": "mcap"}
