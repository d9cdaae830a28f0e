"""docs/config.md is generated from the code, and a stale page fails here."""

import dataclasses
from pathlib import Path

from avsim.config import SimConfig
from avsim.config_reference import COMMAND, generate, main
from avsim.validation import declared_ranges

PAGE = Path(__file__).resolve().parents[1] / "docs" / "config.md"


def test_docs_config_md_is_what_the_code_generates():
    assert PAGE.read_text() == generate(), f"docs/config.md is stale; write it again with {COMMAND}"


def test_every_key_has_a_row_with_its_default_range_and_readers():
    rows = {line.split("|")[1].strip().strip("`"): line for line in generate().splitlines() if line.startswith("| `")}
    config = SimConfig()
    for section in dataclasses.fields(config):
        instance = getattr(config, section.name)
        for f in dataclasses.fields(instance):
            cells = [cell.strip() for cell in rows[f"{section.name}.{f.name}"].split("|")]
            assert cells[5].strip("`") and cells[6]  # its default, and who reads it
        for name, spec in declared_ranges(instance).items():
            cells = [cell.strip() for cell in rows[f"{section.name}.{name}"].split("|")]
            assert (cells[3], cells[4]) == (spec.unit, dataclasses.replace(spec, unit="").describe())


def test_check_mode_fails_on_a_stale_page_and_passes_on_a_current_one(tmp_path, capsys):
    page = tmp_path / "config.md"
    page.write_text(generate().replace("policy.vote_k", "policy.votes_k"))
    assert main(["--check", str(page)]) == 1
    assert "stale" in capsys.readouterr().err
    assert main(["--out", str(page)]) == 0
    assert main(["--check", str(page)]) == 0
