"""The README and every docs page cannot rot: their `avsim` commands parse, the `python -m`
modules they name exist and run as scripts, their tested python examples run and print what is
documented, their error examples are what the CLI prints, and every relative link (a page, a
figure, an anchor) resolves. README-only checks (the front door's run example) are in
tests/test_readme.py."""

import importlib.util
import re
import shlex
from pathlib import Path

import pytest

from avsim.cli import main
from avsim.cli.command import build_parser

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
TEXTS = {page: page.read_text() for page in PAGES}

# A python block right after this marker is run by the test below, which compares what it prints
# with the ```text block that follows it.
TESTED_MARKER = "<!-- tested by tests/test_docs_commands.py -->"


def _name(page: Path) -> str:
    return str(page.relative_to(ROOT))


def _command_lines(prefix: str) -> list[tuple[str, str]]:
    """(page, line) of every line of a ```bash block that starts with `prefix`, comments cut."""
    found = []
    for page, text in TEXTS.items():
        for block in re.findall(r"```bash\n(.*?)```", text, flags=re.S):
            for line in block.splitlines():
                line = line.split(" #")[0].strip()
                if line.startswith(prefix):
                    found.append((_name(page), line))
    return found


def _tested_python_examples() -> list[tuple[str, str, str]]:
    """(page, code, documented output) of every marked python block."""
    return [(_name(page), code, out) for page, text in TEXTS.items()
            for code, out in re.findall(re.escape(TESTED_MARKER) + r"\n```python\n(.*?)```\n[^`]*?```text\n(.*?)```", text, flags=re.S)]


def _error_examples() -> list[tuple[str, str, str]]:
    """(page, command, the one line documented under it) of every `$ avsim ...` line in a text block."""
    return [(_name(page), command, line) for page, text in TEXTS.items()
            for command, line in re.findall(r"^\$ avsim (.*)\n(.*)\n", text, flags=re.M)]


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def _anchors(text: str) -> set[str]:
    without_code = re.sub(r"```.*?```", "", text, flags=re.S)
    return {_slug(h) for h in re.findall(r"^#{1,6} (.*)$", without_code, flags=re.M)}


def _relative_links() -> list[tuple[str, str]]:
    """(page, target) of every markdown link or image that is not a URL."""
    return [(_name(page), target) for page, text in TEXTS.items()
            for target in re.findall(r"\]\(([^)\s]+)\)", re.sub(r"```.*?```", "", text, flags=re.S))
            if not re.match(r"[a-z]+://|mailto:", target)]


@pytest.mark.parametrize(("page", "line"), _command_lines("avsim "), ids=lambda x: x if x.endswith(".md") else x[:60])
def test_avsim_commands_parse(page, line):
    build_parser().parse_args(shlex.split(line)[1:])


@pytest.mark.parametrize(("page", "line"), _command_lines("python -m avsim"), ids=lambda x: x if x.endswith(".md") else x[:60])
def test_python_m_modules_exist_and_run_as_scripts(page, line):
    module = shlex.split(line)[2]
    spec = importlib.util.find_spec(module)
    assert spec is not None and spec.origin, f"{page}: no module {module}"
    source = Path(spec.origin)
    if spec.submodule_search_locations:  # a package runs its __main__.py
        source = source.parent / "__main__.py"
    assert source.is_file() and "__main__" in source.read_text(), f"{page}: {module} does not run with python -m"


@pytest.mark.parametrize(("page", "target"), _relative_links(), ids=lambda x: x)
def test_relative_links_resolve(page, target):
    path, _, anchor = target.partition("#")
    resolved = (ROOT / page).parent / path if path else ROOT / page
    assert resolved.exists(), f"{page}: link to missing {target}"
    if anchor:
        assert anchor in _anchors(resolved.read_text()), f"{page}: {target}: no heading with that anchor"


def test_pages_have_a_tested_python_example_of_under_15_lines():
    examples = _tested_python_examples()
    assert len(examples) == sum(text.count(TESTED_MARKER) for text in TEXTS.values()) >= 1
    assert all(len(code.splitlines()) < 15 for _, code, _ in examples)


@pytest.mark.parametrize(("page", "code", "documented"), _tested_python_examples(),
                         ids=[f"{page} python example {i + 1}" for i, (page, _, _) in enumerate(_tested_python_examples())])
def test_python_examples_run_and_print_what_is_documented(page, code, documented, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    exec(compile(code, page, "exec"), {"__name__": "__docs_example__"})
    printed = capsys.readouterr().out.splitlines()
    # The same lines with the same first word (an outcome is physics, identical on every machine).
    assert [line.split()[0] for line in printed] == [line.split()[0] for line in documented.splitlines()]


def test_pages_have_an_error_example():
    assert _error_examples()


@pytest.mark.parametrize(("page", "command", "documented"), _error_examples(), ids=lambda x: x[:60])
def test_error_examples_are_what_the_cli_prints(page, command, documented, capsys):
    assert main(shlex.split(command)) == 2
    assert capsys.readouterr().err.strip() == documented
