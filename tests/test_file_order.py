"""The order of the test files under pytest-xdist (`tests/file_order.py`): the longest go out first."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from file_order import LONGEST_FILES_S, longest_files_first

REPO = Path(__file__).resolve().parent.parent


def test_every_file_the_schedule_names_exists():
    # A renamed file would silently lose its place at the front and lengthen the slow pass.
    missing = [path for path in LONGEST_FILES_S if not (REPO / path).is_file()]
    assert missing == []


def test_the_longest_files_come_first_and_every_file_stays_together_in_order():
    longest, second = sorted(LONGEST_FILES_S, key=lambda path: -LONGEST_FILES_S[path])[:2]
    nodeids = ["tests/a.py::one", f"{second}::x", "tests/a.py::two", "tests/b.py::one", f"{longest}::y",
               f"{second}::z", f"{longest}::w"]
    items = [SimpleNamespace(nodeid=nodeid) for nodeid in nodeids]
    longest_files_first(items)
    assert [item.nodeid for item in items] == [f"{longest}::y", f"{longest}::w", f"{second}::x", f"{second}::z",
                                               "tests/a.py::one", "tests/a.py::two", "tests/b.py::one"]
