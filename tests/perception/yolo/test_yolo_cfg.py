"""Darknet cfg parsing: sections in order, comments, and one-line errors naming file, line and key."""

import pytest

from avsim.perception.yolo.cfg import DarknetFileError, parse_cfg, parse_cfg_text
from avsim.perception.yolo.fetch import model_paths


def test_yolov3_tiny_cfg_has_net_then_24_layers_in_file_order():
    sections = parse_cfg(model_paths()[0])
    assert sections[0].kind == "net" and sections[0].int("width") == 416
    kinds = [s.kind for s in sections[1:]]
    assert len(kinds) == 24 and kinds.count("convolutional") == 13 and kinds.count("yolo") == 2
    assert kinds[11] == "maxpool" and sections[12].int("stride") == 1 and sections[12].int("size") == 2
    route = sections[1 + 20]
    assert route.kind == "route" and route.ints("layers") == (-1, 8)
    assert sections[1 + 16].ints("mask") == (3, 4, 5) and len(sections[1 + 16].floats("anchors")) == 12


def test_comments_blank_lines_and_spaces_around_equals_are_ignored():
    sections = parse_cfg_text("# top\n[net]\n width = 32 ; trailing\n\n[maxpool] \nsize= 3 # why\n")
    assert [(s.kind, s.options) for s in sections] == [("net", {"width": "32"}), ("maxpool", {"size": "3"})]
    assert sections[1].int("stride", 1) == 1 and sections[1].line == 5


@pytest.mark.parametrize("text, message", [
    ("[convolutional]\nfilters=8\n", "starts with a [net] section; this one starts with [convolutional]"),
    ("", "is empty"),
    ("[net]\nwidth\n", "line 2: 'width' is neither a [section] nor key=value"),
    ("[net\n", "line 1: '[net' is not a [section] header"),
])
def test_malformed_cfgs_are_refused_naming_the_line(text, message):
    with pytest.raises(DarknetFileError, match=message.replace("[", r"\[").replace("]", r"\]")):
        parse_cfg_text(text, "my.cfg")


def test_a_malformed_value_names_the_section_line_and_key():
    section = parse_cfg_text("[net]\n[convolutional]\nfilters=eight\n", "my.cfg")[1]
    with pytest.raises(DarknetFileError, match=r"my.cfg: \[convolutional\] at line 2, key 'filters': 'eight' is not an integer"):
        section.int("filters")
    with pytest.raises(DarknetFileError, match="key 'size' is required but missing"):
        section.int("size")


def test_a_missing_cfg_file_names_the_config_key(tmp_path):
    with pytest.raises(DarknetFileError, match="does not exist; check perception.yolo_cfg"):
        parse_cfg(tmp_path / "absent.cfg")
