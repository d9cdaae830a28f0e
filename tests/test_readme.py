"""The README is a front door: short, with the two commands, one `avsim run` example whose
printed summary has the shape `avsim run` really prints, and a link to every docs page. The
checks every page shares (commands parse, links resolve, examples run) are in
tests/test_docs_commands.py."""

import json
import re
import shlex
from pathlib import Path

from avsim.cli import main
from avsim.perception.cpu_bf16 import detector_arithmetic

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
TEXT = README.read_text()


def _run_example() -> list[str]:
    """The README's `avsim run ... --json` command line, as argv."""
    blocks = re.findall(r"```bash\n(.*?)```", TEXT, flags=re.S)
    lines = [line.split("#")[0].strip() for block in blocks for line in block.splitlines()]
    return next(shlex.split(line)[1:] for line in lines if line.startswith("avsim run ") and "--json" in line)


def test_readme_is_a_front_door_of_at_most_300_lines():
    assert len(TEXT.splitlines()) <= 300


def test_readme_links_every_docs_page():
    linked = set(re.findall(r"\]\(docs/([\w.-]+\.md)", TEXT))
    assert sorted(p.name for p in (ROOT / "docs").glob("*.md")) == sorted(linked)


def test_readme_has_the_two_front_door_commands_and_ci_calls_the_test_one():
    assert "make run" in TEXT and "make test" in TEXT
    assert "make test" in (ROOT / ".ci" / "run").read_text()


def test_readme_run_command_runs_and_prints_the_documented_summary(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(_run_example()) == 0
    printed = capsys.readouterr().out.splitlines()
    documented = re.search(r"```\n(avsim run: .*?)```", TEXT, flags=re.S).group(1).splitlines()
    # Same lines, same labels; the numbers are the machine's own.
    assert [line.split()[0] for line in printed[:8]] == [line.split()[0] for line in documented[:8]]
    # The README shows a bf16 CPU's run; a CPU without bf16 runs the detector in fp32 (docs/performance.md).
    assert printed[0] == documented[0].replace("(bf16)", f"({detector_arithmetic('auto')})")
    assert printed[1] == documented[1]  # the outcome is physics: this run's is the same in either arithmetic
    # The record's config keeps the precision as given; the printed header says what it ran as here.
    assert json.loads((tmp_path / "out.json").read_text())["config"]["perception"]["detector_precision"] == "auto"
    assert f"perception detector ({detector_arithmetic('auto')})" in printed[0]
