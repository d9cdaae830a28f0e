"""The three-network board (`experiments/leaderboards/three_networks.toml`, issue 29): its plan, checked
without running it. Its runs took a median of 22 s of one core each here, so it is run by name only and never by the
quick test of the default board (tests/experiments/test_leaderboard.py)."""

import dataclasses
import json

import pytest

from avsim.experiments.leaderboard import DEFAULT_FILE, SAFETY, load_leaderboard, unique_specs
from avsim.experiments.run_task import config_hash
from avsim.world.textures import TEXTURE_DIR

THREE_NETWORKS = DEFAULT_FILE.parent / "three_networks.toml"
NEW_ROWS = ("ensemble3_or", "ensemble3_2of3")
REFERENCES = ("baseline", "ensemble_or")


@pytest.fixture(scope="module")
def boards():
    return load_leaderboard(THREE_NETWORKS), load_leaderboard(DEFAULT_FILE)


def test_the_new_rows_run_all_three_networks_each_fusion_against_the_texture_made_against_all_three(boards):
    board, _ = boards
    assert [d.name for d in board.defences] == [*REFERENCES, *NEW_ROWS]
    fusions, adaptive = {}, {}
    for run in board.runs(first_seed_only=True):
        if run.defence in NEW_ROWS:
            perception = run.config.perception
            assert perception.kind == "ensemble" and perception.ensemble_members == ("detector", "coco", "yolo")
            fusions[run.defence] = (perception.ensemble_fusion, perception.ensemble_k if perception.ensemble_fusion == "k_of_n" else None)
            if run.kind == SAFETY and run.condition == "adaptive":
                adaptive[run.defence] = run.config.scenario.sign
    assert fusions == {"ensemble3_or": ("or", None), "ensemble3_2of3": ("k_of_n", 2)}
    # Each fusion faces the texture made against its own rule: any of three, or two of three.
    assert adaptive == {"ensemble3_or": "driveby_ensemble_all", "ensemble3_2of3": "driveby_ensemble_all_2of3"}
    for texture, target in (("driveby_ensemble_all", "ensemble_all"), ("driveby_ensemble_all_2of3", "ensemble_all_2of3")):
        record = json.loads((TEXTURE_DIR / f"{texture}.json").read_text())
        assert record["detector"] == target and {"yolov3-tiny.weights", "centernet.bin"} <= set(record["weights_sha256"])


def test_the_references_are_the_default_boards_rows_run_for_run(boards):
    """Same configs, same seeds: the two boards' rows compare like for like (and share results by hash)."""
    board, default = boards

    board_runs, default_runs = board.runs(), default.runs()  # once each: a board builds its runs anew at each call

    def hashes(every_run, name):
        return sorted(config_hash(r.config) for r in every_run if r.defence == name)

    for name in REFERENCES:
        assert hashes(board_runs, name) == hashes(default_runs, name), name
    assert [p.label for p in board.places] == [p.label for p in default.places]
    assert board.size(quick=True) == 4 * 5 and len(list(unique_specs(board, board.runs(quick=True)))) == 20


def test_the_default_board_runs_no_three_network_ensemble(boards):
    """`avsim leaderboard` (and CI's quick test of it) keeps its cost: no run of it has YOLOv3-tiny."""
    _, default = boards
    def runs_yolo(perception) -> bool:
        return perception.kind == "yolo" or (perception.kind == "ensemble" and "yolo" in perception.ensemble_members)

    assert not any(runs_yolo(r.config.perception) for r in default.runs())


def test_the_clusters_board_is_the_three_network_board_with_see_through_crowns(boards):
    board, _ = boards
    clusters = load_leaderboard(THREE_NETWORKS.parent / "three_networks_clusters.toml")
    runs, cluster_runs = list(board.runs()), list(clusters.runs())
    assert len(runs) == len(cluster_runs) == 216
    for run, cluster_run in zip(runs, cluster_runs):
        assert (run.defence, run.condition, run.seed) == (cluster_run.defence, cluster_run.condition, cluster_run.seed)
        assert run.config.scenario.foliage == "solid" and cluster_run.config.scenario.foliage == "clusters"
        same = dataclasses.replace(cluster_run.config, scenario=dataclasses.replace(cluster_run.config.scenario, foliage="solid"))
        assert config_hash(same) == config_hash(run.config)
