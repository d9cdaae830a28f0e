"""docs/yolo.md cannot rot: its avsim commands parse, and its config keys exist."""

import re
import shlex
from dataclasses import fields
from pathlib import Path

import pytest

from avsim.cli.command import build_parser
from avsim.config import PerceptionConfig

DOC = (Path(__file__).resolve().parents[3] / "docs" / "yolo.md").read_text()


def _commands() -> list[list[str]]:
    blocks = re.findall(r"```bash\n(.*?)```", DOC, flags=re.S)
    return [shlex.split(line)[1:] for block in blocks for line in block.splitlines() if line.startswith("avsim ")]


@pytest.mark.parametrize("argv", _commands(), ids=lambda argv: " ".join(argv[:3]))
def test_doc_commands_parse(argv):
    build_parser().parse_args(argv)


def test_every_perception_key_the_doc_names_exists():
    named = set(re.findall(r"`perception\.(\w+)`", DOC))
    assert named and named <= {f.name for f in fields(PerceptionConfig)}
