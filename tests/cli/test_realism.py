"""`avsim realism`: names refused in one line before any work, and a small run end to end."""

import json

import pytest

from avsim import cli


@pytest.mark.parametrize("flag, value, named", [("--settings", "baseline,fancy", "fancy"), ("--networks", "coco,ssd", "ssd"),
                                                ("--frames", "0", "--frames"), ("--threshold", "1", "--threshold"),
                                                ("--max-dist-m", "62", "multiple of 5"), ("--max-dist-m", "155", "--max-dist-m")])
def test_bad_names_and_numbers_are_refused_in_one_line(flag, value, named, capsys):
    assert cli.main(["realism", flag, value]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and named in lines[0]


def test_an_unknown_town_is_refused_before_anything_renders(capsys, tmp_path):
    assert cli.main(["realism", "--towns", "town99", "--out", str(tmp_path / "out")]) == 2
    assert "town99" in capsys.readouterr().err and not (tmp_path / "out").exists()


@pytest.mark.slow  # 2 x 28 frames through the own detector: about 15 s here
def test_a_small_run_writes_its_report_figure_and_rows_with_the_set_value(tmp_path, capsys):
    out = tmp_path / "realism"
    assert cli.main(["realism", "--towns", "town07", "--frames", "1", "--networks", "detector",
                     "--settings", "baseline,ss2", "--workers", "1", "--max-dist-m", "70", "--out", str(out),
                     "--set", "scenario.sign_materials=sheeting"]) == 0
    rows = [json.loads(line) for line in (out / "frames.jsonl").read_text().splitlines()]
    assert len(rows) == 2 * 2 * (12 + 2)  # settings x cameras x (bins out to 70 m + roadside views)
    assert max(r["dist_m"] for r in rows if r["dist_m"] is not None) > 65
    assert {r["setting"] for r in rows} == {"baseline", "ss2"}
    near = [r for r in rows if r["dist_m"] is not None and r["dist_m"] < 40 and r["camera"] == "front"]
    assert sum(r["found"] for r in near) >= 0.8 * len(near)  # the own detector's trained range
    assert (out / "recall.png").stat().st_size > 10_000
    text = (out / "report.md").read_text()
    assert "# Render realism benchmark (56 frames)" in text and "| front 60–70 m |" in text and "65–70 |" in text
    assert "Every frame drawn with --set scenario.sign_materials=sheeting" in text


def test_a_set_key_no_frame_reads_is_refused_in_one_line_before_anything_renders(capsys, tmp_path):
    assert cli.main(["realism", "--towns", "town07", "--set", "policy.conf_threshold=0.6", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "policy" in err[0] and not (tmp_path / "out").exists()
