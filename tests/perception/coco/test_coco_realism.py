"""The realism table runs either COCO network on make-data frames and reports both recall criteria."""

import json

import pytest

from avsim import cli
from avsim.perception.coco import realism


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("data") / "eval"
    assert cli.main(["detector", "make-data", "--out", str(out), "--train", "6", "--val", "0", "--seed", "13"]) == 0
    return out


@pytest.mark.parametrize("network", ["coco", "yolo"])
def test_realism_scores_every_frame_and_writes_its_report(tiny_dataset, tmp_path, capsys, network):
    out = tmp_path / "out"
    code = realism.main(["--network", network, "--data", str(tiny_dataset), "--modes", "crop", "--precisions", "fp32",
                         "--workers", "1", "--out", str(out)])
    assert code == 0
    rows = [json.loads(line) for line in (out / "frames.jsonl").read_text().splitlines()]
    assert len(rows) == 6 and {r["setting"] for r in rows} == {"crop fp32"}
    # a box that overlaps the sign with IoU >= 0.5 is centred on it, so "centred" finds at least as many
    assert all(r["found_centred"] or not r["found"] for r in rows)
    report = (out / "report.md").read_text()
    assert report.startswith(f"# {realism.NETWORKS[network]} on avsim renders (6 frames)")
    assert "`crop fp32`, centred" in report and f"perception.{network}_input" in report
    capsys.readouterr()
