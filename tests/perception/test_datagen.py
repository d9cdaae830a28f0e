"""Detector data generation: labels, the held-out split, determinism, no half-written output."""

import json

import pytest

from avsim.errors import ConfigError
from avsim.perception.base import SIGN_CLASSES
from avsim.perception.datagen import VAL_LAYOUT_SEED, VAL_SUN_ELEVATION_DEG, DataGenConfig, make_dataset
from avsim.realism.settings import SETTINGS

TINY = DataGenConfig(n_train=6, n_val=4, images_per_scene=3, seed=7, workers=1)


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory):
    return make_dataset(tmp_path_factory.mktemp("data") / "signs", TINY)


def _records(root, split):
    return [json.loads(line) for line in (root / f"{split}.jsonl").read_text().splitlines()]


def test_every_image_has_a_record_with_valid_boxes(tiny_dataset):
    for split, count in (("train", 6), ("val", 4)):
        records = _records(tiny_dataset, split)
        assert len(records) == count
        for record in records:
            assert (tiny_dataset / record["image"]).is_file()
            assert len(record["boxes"]) == len(record["classes"])
            for (x0, y0, x1, y1), cls in zip(record["boxes"], record["classes"]):
                assert cls in SIGN_CLASSES
                assert 0 <= x0 < x1 <= 640 and 0 <= y0 < y1 <= 480
                assert y1 - y0 >= 4.0


def test_validation_split_is_held_out_by_town_seed_and_lighting(tiny_dataset):
    low, high = VAL_SUN_ELEVATION_DEG
    for record in _records(tiny_dataset, "val"):
        assert record["meta"]["layout_seed"] == VAL_LAYOUT_SEED
        assert low <= record["meta"]["sun_elevation_deg"] < high
    for record in _records(tiny_dataset, "train"):
        assert record["meta"]["layout_seed"] != VAL_LAYOUT_SEED
        assert not low <= record["meta"]["sun_elevation_deg"] < high


def test_same_seed_gives_the_same_dataset(tiny_dataset, tmp_path):
    again = make_dataset(tmp_path / "again", TINY)
    assert (again / "train.jsonl").read_text() == (tiny_dataset / "train.jsonl").read_text()
    first = _records(tiny_dataset, "train")[0]["image"]
    assert (again / first).read_bytes() == (tiny_dataset / first).read_bytes()


def test_existing_output_is_refused_and_nothing_partial_is_left(tiny_dataset):
    with pytest.raises(ConfigError, match="already exists"):
        make_dataset(tiny_dataset, TINY)
    assert not tiny_dataset.with_name(tiny_dataset.name + ".partial").exists()


def test_bad_counts_are_config_errors():
    with pytest.raises(ConfigError):
        DataGenConfig(n_train=0, n_val=0)


def test_a_stop_mid_render_leaves_no_half_made_dataset(tmp_path, monkeypatch):
    """Ctrl-C or SIGTERM (the boundary's exception) after the first scene: no OUT, no OUT.partial."""
    from avsim.perception import datagen

    rendered = []

    def first_scene_then_stop(args):
        if rendered:
            raise KeyboardInterrupt
        rendered.append(args)
        return args[0], []  # a scene's records: none needed to reach the stop

    monkeypatch.setattr(datagen, "_render_job", first_scene_then_stop)
    with pytest.raises(KeyboardInterrupt):
        make_dataset(tmp_path / "signs", TINY)
    assert rendered and list(tmp_path.iterdir()) == []


def test_a_setting_renders_the_same_views_with_other_pixels(tiny_dataset, tmp_path):
    overrides = SETTINGS["textured"].config_overrides()
    textured = make_dataset(tmp_path / "textured", DataGenConfig(**{**TINY.__dict__, "setting": "textured",
                                                                   "setting_overrides": overrides}))
    assert json.loads((textured / "generation.json").read_text())["setting"] == "textured"
    for split in ("train", "val"):
        base, under = _records(tiny_dataset, split), _records(textured, split)
        assert [r["meta"] for r in under] == [r["meta"] for r in base]  # same scenes, poses and lighting
        assert [r["classes"] for r in under] == [r["classes"] for r in base]
    changed = [r["image"] for r in _records(textured, "train")
               if (textured / r["image"]).read_bytes() != (tiny_dataset / r["image"]).read_bytes()]
    assert len(changed) == 6


def test_a_setting_that_changes_the_image_size_is_refused():
    with pytest.raises(ConfigError, match="renders 1920x1080"):
        DataGenConfig(setting="automotive_1080p", setting_overrides=SETTINGS["automotive_1080p"].config_overrides())


def test_an_unknown_setting_is_one_line_and_exit_2_before_anything_is_written(tmp_path, capsys):
    from avsim import cli

    assert cli.main(["detector", "make-data", "--out", str(tmp_path / "signs"), "--setting", "texturd"]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "invalid choice: 'texturd'" in err, err
    assert list(tmp_path.iterdir()) == []
