"""docs/foxglove_screenshot/screenshot.js, the command that makes docs/ros.md's Foxglove screenshot:
its refusals of bad input (which come before its npm packages or a browser are needed), and the
one change it makes to the layout for Foxglove Studio 1.48. Taking a screenshot needs Chromium and
`npm ci` there, so it is not tested here; docs/ros.md says how the picture was made."""

import json
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "docs" / "foxglove_screenshot" / "screenshot.js"
LAYOUT = ROOT / "docs" / "foxglove_layout.json"

pytestmark = pytest.mark.skipif(shutil.which("node") is None, reason="needs node")


def _screenshot(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["node", str(SCRIPT), *args], capture_output=True, text=True, timeout=60)


def test_bad_input_is_one_line_exit_2_and_writes_nothing(tmp_path):
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not a bag")
    bag = tmp_path / "bag.mcap"
    bag.write_bytes(b"\x89MCAP0\r\n" + bytes(16))  # the magic is all it checks before the browser
    (tmp_path / "a_file").write_text("")
    cases = [((str(tmp_path / "missing.mcap"), str(tmp_path / "out.png")), "is not a file"),
             ((str(junk), str(tmp_path / "out.png")), "is not an MCAP file"),
             ((str(bag), str(tmp_path / "a_file" / "out.png")), "is not a writable folder"),
             ((str(bag), str(tmp_path / "out.jpg")), "must end in .png"),
             ((str(bag), str(tmp_path / "out.png"), "--time", "-1"), "--time"),
             ((str(bag), str(tmp_path / "out.png"), "--colour", "red"), "unknown option --colour")]
    for args, message in cases:
        done = _screenshot(*args)
        assert done.returncode == 2, (args, done.stderr)
        assert len(done.stderr.splitlines()) == 1 and message in done.stderr, done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file", "bag.mcap", "junk.mcap"]


def test_image_panels_become_148s_image_panel_on_the_same_topics():
    converted = json.loads(subprocess.run(
        ["node", "-e", f"const {{layoutFor148}} = require({json.dumps(str(SCRIPT))});"
                       f"console.log(JSON.stringify(layoutFor148(require({json.dumps(str(LAYOUT))}))))"],
        capture_output=True, text=True, check=True, timeout=60).stdout)
    layout = json.loads(LAYOUT.read_text())
    image_panels = {name: config for name, config in layout["configById"].items() if name.startswith("Image!")}
    assert len(image_panels) == 2
    for name, config in image_panels.items():
        old = converted["configById"][name.replace("Image!", "ImageViewPanel!")]
        assert old["cameraTopic"] == config["imageMode"]["imageTopic"]
        assert old["enabledMarkerTopics"] == list(config["imageMode"]["annotations"])
    others = {name: config for name, config in layout["configById"].items() if name not in image_panels}
    assert {name: converted["configById"][name] for name in others} == others

    def leaves(node):
        return [node] if isinstance(node, str) else leaves(node["first"]) + leaves(node["second"])

    assert sorted(leaves(converted["layout"])) == sorted(converted["configById"])
