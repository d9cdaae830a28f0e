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


def _copy_with_first_line(dataset, tmp_path, edit):
    """The dataset's labels in a new folder (images shared), its first line changed by `edit(record)`."""
    copy = tmp_path / "copy"
    copy.mkdir()
    (copy / "images").symlink_to(dataset / "images")
    lines = (dataset / "train.jsonl").read_text().splitlines()
    first = json.loads(lines[0])
    edit(first)
    (copy / "train.jsonl").write_text("\n".join([json.dumps(first), *lines[1:]]) + "\n")
    return copy


@pytest.mark.parametrize("edit, named", [
    (lambda r: r.update(image="images/missing.png"), "does not exist"),
    (lambda r: r.pop("meta"), "meta.camera"),
    (lambda r: r["meta"].pop("town"), "meta.town"),
])
def test_a_bad_labels_line_or_image_is_one_line_before_any_frame_is_scored(tiny_dataset, tmp_path, capsys, edit, named):
    data = _copy_with_first_line(tiny_dataset, tmp_path, edit)
    code = realism.main(["--data", str(data), "--modes", "crop", "--precisions", "fp32", "--workers", "1",
                         "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1 and "train.jsonl:1" in err[0] and named in err[0], err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("out, named", [("/proc/x", "cannot write in /proc"), ("held", "already holds report.md")])
def test_an_output_folder_that_cannot_take_the_report_is_refused_before_scoring(tiny_dataset, tmp_path, capsys, out, named):
    (tmp_path / "held").mkdir()
    (tmp_path / "held" / "report.md").write_text("mine")
    target = out if out.startswith("/") else str(tmp_path / out)
    code = realism.main(["--data", str(tiny_dataset), "--modes", "crop", "--precisions", "fp32", "--workers", "1",
                         "--out", target])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1 and named in err[0], err
    assert (tmp_path / "held" / "report.md").read_text() == "mine"
