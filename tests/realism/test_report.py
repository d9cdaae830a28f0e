"""The realism report on hand-made rows: Wilson cells, AP, false stop signs and what they sit on, the figure."""

import math

import pytest

from avsim.realism.report import (ap_table, false_stop_by_distance_table, false_stop_table, paired_table, recall_table,
                                  report, summary_table, threshold_table, write_figure)
from avsim.stats import rate_with_interval


def _row(setting="baseline", network="coco", town="town07", camera="front", dist_m=12.0, found=True, frame=0,
         false=(), detections=((0.9, True),), n_truth=1):
    return {"setting": setting, "network": network, "town": town, "placement": "standard", "scene": 0, "frame": frame,
            "camera": camera, "dist_m": dist_m, "render_cpu_ms": 7.0, "found": found, "found_centred": found,
            "best_score": 0.9 if found else 0.0, "false_stop_signs": [list(f) for f in false],
            "ap_detections": [list(d) for d in detections], "n_truth": n_truth}


def test_recall_cells_count_signs_per_bin_with_wilson_intervals():
    rows = [_row(dist_m=11.0, frame=0), _row(dist_m=13.0, found=False, frame=1, detections=()), _row(dist_m=52.0, frame=2),
            _row(dist_m=None, frame=3, n_truth=0, detections=())]  # a roadside view is not in the recall population
    table = recall_table(rows, "coco", "front")
    town07 = next(line for line in table if line.startswith("| baseline | town07"))
    cells = [c.strip() for c in town07.split("|")[3:-1]]
    assert cells[0] == "1/2 (0.09–0.91)"  # 10-15 m
    assert cells[8] == "1/1 (0.21–1.00)"  # 50-55 m
    assert cells[-1] == "1/2 (0.09–0.91)"  # pooled 10-40 m leaves out 52 m
    assert cells[1] == "–"


def test_false_stop_signs_per_frame_name_what_they_sit_on_and_how_many_cover_a_sign():
    rows = [_row(frame=0, false=[(0.8, 0, 0, 5, 5, "tree_right/crown", 0.2), (0.6, 0, 0, 5, 5, "tree_right/crown", 0.0)]),
            _row(frame=1, false=[(0.7, 0, 0, 5, 5, "sky", 0.0)]), _row(frame=2), _row(frame=3, town="town10")]
    table = false_stop_table(rows)
    assert table[0].endswith("| sits on | over a sign |")
    line = next(line for line in table if line.startswith("| coco | baseline"))
    assert "1.000 (3/3)" in line and "0.000 (0/1)" in line and "0.750 (3/4)" in line
    assert line.endswith("tree_right/crown 2, sky 1 | 1 of 3 |")
    assert next(line for line in false_stop_table([_row()]) if line.startswith("| coco")).endswith("| – | – |")


def test_a_set_beyond_60_m_gets_its_own_bins_and_span():
    rows = [_row(dist_m=12.0, frame=0), _row(dist_m=57.0, frame=1), _row(dist_m=83.0, found=False, frame=2, detections=(),
            false=[(0.5, 0, 0, 5, 5, "tree_right/crown", 0.0), (0.6, 0, 0, 5, 5, "tree_right/crown", 0.0)]),
            _row(dist_m=None, frame=3, n_truth=0, detections=())]
    header = summary_table(rows)[0]
    assert "| front 10–40 m | front 40–60 m | front 60–85 m | side 10–40 m |" in header
    assert recall_table(rows, "coco", "front")[0].split(" | ")[-2] == "80–85"  # the last bin, before the pooled column
    by_distance = false_stop_by_distance_table(rows)
    assert by_distance[0] == "| network | setting | 10–40 m | 40–60 m | 60–85 m | roadside views |"
    # Frames with at least one false stop sign: the 83 m frame's two boxes count once.
    assert by_distance[2] == (f"| coco | baseline | {rate_with_interval(0, 1)} | {rate_with_interval(0, 1)} | "
                              f"{rate_with_interval(1, 1)} | {rate_with_interval(0, 1)} |")


def test_higher_thresholds_are_recounted_from_the_kept_scores_per_town():
    # Two front signs found at 0.58 and 0.9; a crown's box at 0.52 and a sky's at 0.65; a side-camera sign and
    # a 45 m sign are outside the front 10-40 m column.
    rows = [_row(frame=0, false=[(0.52, 0, 0, 5, 5, "tree_right/crown", 0.3)]), _row(frame=1, dist_m=30.0),
            _row(frame=2, camera="side"), _row(frame=3, dist_m=45.0), _row(frame=4, town="town10", found=False)]
    rows[0]["best_score"] = 0.58
    rows[1]["false_stop_signs"] = [[0.65, 0, 0, 5, 5, "sky", 0.0]]
    table = threshold_table(rows, 0.5)
    assert table[0] == ("| network | setting | town | front 10–40 m at 0.5 | false at 0.5 | front 10–40 m at 0.55 | false at 0.55 "
                        "| front 10–40 m at 0.6 | false at 0.6 | front 10–40 m at 0.7 | false at 0.7 |")
    town07 = [c.strip() for c in table[2].split("|")[1:-1]]
    assert town07[:3] == ["coco", "baseline", "town07"]
    assert town07[3:] == [rate_with_interval(2, 2), "0.500 (2)", rate_with_interval(2, 2), "0.250 (1)",
                          rate_with_interval(1, 2), "0.250 (1)", rate_with_interval(1, 2), "0.000 (0)"]
    assert table[3].startswith("| coco | baseline | town10 | " + rate_with_interval(0, 1))
    # A run at 0.6 recounts only above it.
    assert threshold_table(rows, 0.6)[0].count("false at") == 2
    assert "## At higher thresholds" in report(rows, 0.5)


def test_a_default_set_keeps_the_default_columns():
    assert "60–" not in summary_table(_grid_rows())[0]


def test_ap_is_computed_over_every_frame_of_a_setting():
    rows = [_row(frame=0, detections=[(0.9, True), (0.8, False)]), _row(frame=1, detections=[(0.7, True)]),
            _row(frame=2, detections=[], n_truth=1)]
    line = ap_table(rows)[2]
    # Ranked: TP, FP, TP over 3 signs: AP = 1/3 * 1 + 1/3 * 2/3 = 0.556.
    assert line == f"| coco | {1 / 3 + (1 / 3) * (2 / 3):.3f} |"
    assert not math.isnan(float(line.split("|")[2]))


def _grid_rows():
    return [_row(setting=s, network=n, camera=c, dist_m=d, frame=k)
            for s in ("baseline", "photo") for n in ("coco", "detector") for c in ("front", "side")
            for k, d in enumerate((12.0, 33.0, 57.0))]


def test_the_report_covers_every_setting_and_network():
    text = report(_grid_rows(), 0.5)
    assert text.startswith("# Render realism benchmark (6 frames)")
    assert "| photo | camera.supersample=2" in text and "## own detector (detector), side camera" in text
    two, one = rate_with_interval(2, 2), rate_with_interval(1, 1)  # 12 and 33 m pooled, 57 m beyond 40 m
    assert f"| coco | photo | {two} | {one} | {two} | {one} | 0.000 (0/6) | 1.000 |" in text


def test_the_report_names_the_gl_that_drew_its_frames():
    # A frame's pixels are those of the GL that drew it: llvmpipe filters textures under
    # camera.texture_anisotropy in its own way (docs/realism_filtering.md), so a report says which GL it was.
    versions = {"mujoco": "4.0.0", "gl": "llvmpipe (LLVM 15.0.6, 256 bits), OpenGL 4.5 Mesa 22.3.6"}
    text = report(_grid_rows(), 0.5, versions)
    assert "\nDrawn by llvmpipe (LLVM 15.0.6, 256 bits), OpenGL 4.5 Mesa 22.3.6; mujoco 4.0.0.\n" in text
    assert "Drawn by" not in report(_grid_rows(), 0.5)


def test_the_paired_table_counts_signs_found_under_one_setting_only_frame_by_frame():
    # Frames 0-3 at 10-40 m: baseline finds 0 and 1, lens finds 1, 2 and 3 (gains 2 and 3, loses 0);
    # frame 4 at 45 m is found by both; frame 5 only by lens, but is a roadside view (not a sign frame).
    found = {"baseline": (True, True, False, False, True, False), "lens": (False, True, True, True, True, True)}
    rows = [_row(setting=setting, frame=k, dist_m=(12.0, 20.0, 30.0, 35.0, 45.0, None)[k], found=hit,
                 n_truth=0 if k == 5 else 1)
            for setting, hits in found.items() for k, hit in enumerate(hits)]
    line = next(line for line in paired_table(rows) if line.startswith("| coco | lens"))
    cells = [c.strip() for c in line.split("|")[3:-1]]
    assert cells[:2] == ["2 / 1 (p 1)", "0 / 0 (p 1)"]
    assert cells[2] == "–"  # no side-camera frames
    assert paired_table([r for r in rows if r["setting"] == "baseline"]) == []
    assert "## Paired against baseline" in report(rows, 0.5)


@pytest.mark.slow  # matplotlib's import and layout: about 5 s here
def test_the_figure_is_written(tmp_path):
    write_figure(_grid_rows(), tmp_path / "recall.png")
    assert (tmp_path / "recall.png").stat().st_size > 10_000
