"""The README's front door cannot rot: its example commands run, and its printed summary
has the shape `avsim run` really prints."""

import re
import shlex
from pathlib import Path

import pytest

from avsim.cli import build_parser, main

README = Path(__file__).resolve().parents[1] / "README.md"
TEXT = README.read_text()


# A python block right after this marker is run by the test below, which compares what it prints
# with the ```text block that follows it.
TESTED_MARKER = "<!-- tested by tests/test_readme.py -->"


def _tested_python_examples() -> list[tuple[str, str]]:
    """(code, documented output) of every marked python block."""
    return re.findall(re.escape(TESTED_MARKER) + r"\n```python\n(.*?)```\n[^`]*?```text\n(.*?)```", TEXT, flags=re.S)


def _example_commands() -> list[list[str]]:
    blocks = re.findall(r"```bash\n(.*?)```", TEXT, flags=re.S)
    lines = [line.split("#")[0].strip() for block in blocks for line in block.splitlines()]
    return [shlex.split(line)[1:] for line in lines if line.startswith("avsim ")]


def test_readme_has_the_two_front_door_commands_and_ci_calls_the_test_one():
    assert "make run" in TEXT and "make test" in TEXT
    assert "make test" in (README.parent / ".ci" / "run").read_text()


@pytest.mark.parametrize("argv", _example_commands(), ids=lambda argv: " ".join(argv[:3]))
def test_readme_example_commands_parse(argv):
    build_parser().parse_args(argv)


def test_readme_run_command_runs_and_prints_the_documented_summary(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    argv = next(a for a in _example_commands() if a[0] == "run" and "--json" in a)
    assert main(argv) == 0
    printed = capsys.readouterr().out.splitlines()
    documented = re.search(r"```\n(avsim run: .*?)```", TEXT, flags=re.S).group(1).splitlines()
    # Same lines, same labels; the numbers are the machine's own.
    assert [line.split()[0] for line in printed[:8]] == [line.split()[0] for line in documented[:8]]
    assert printed[0] == documented[0]
    assert printed[1] == documented[1]  # the outcome is physics, identical on every machine
    assert (tmp_path / "out.json").is_file()


def test_readme_error_example_is_what_the_cli_prints(capsys):
    assert main(["run", "--town", "town99"]) == 2
    documented = re.search(r"\$ avsim run --town town99\n(.*)\n", TEXT).group(1)
    assert capsys.readouterr().err.strip() == documented


def test_readme_has_a_tested_python_example_of_under_15_lines():
    examples = _tested_python_examples()
    assert len(examples) == TEXT.count(TESTED_MARKER) >= 1
    assert all(len(code.splitlines()) < 15 for code, _ in examples)


@pytest.mark.parametrize("code,documented", _tested_python_examples(),
                         ids=[f"python example {i + 1}" for i in range(len(_tested_python_examples()))])
def test_readme_python_examples_run_and_print_what_is_documented(code, documented, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    exec(compile(code, str(README), "exec"), {"__name__": "__readme_example__"})
    printed = capsys.readouterr().out.splitlines()
    # The same lines with the same first word (an outcome is physics, identical on every machine).
    assert [line.split()[0] for line in printed] == [line.split()[0] for line in documented.splitlines()]
