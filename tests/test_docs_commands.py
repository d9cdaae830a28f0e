"""The avsim commands in the docs pages parse, as the README's do (tests/test_readme.py)."""

import re
import shlex
from pathlib import Path

import pytest

from avsim.cli import build_parser

DOCS = Path(__file__).resolve().parents[1] / "docs"


def _commands() -> list[tuple[str, list[str]]]:
    found = []
    for page in sorted(DOCS.glob("*.md")):
        for block in re.findall(r"```bash\n(.*?)```", page.read_text(), flags=re.S):
            for line in block.splitlines():
                line = line.split(" #")[0].strip()
                if line.startswith("avsim "):
                    found.append((page.name, shlex.split(line)[1:]))
    return found


@pytest.mark.parametrize(("page", "argv"), _commands(), ids=lambda x: x if isinstance(x, str) else " ".join(x[:2]))
def test_docs_commands_parse(page, argv):
    build_parser().parse_args(argv)
