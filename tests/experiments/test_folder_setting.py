"""A results folder's render setting (`setting.json`): written for a setting other than the default renders,
read back, and a resume under another setting refused in one line."""

from __future__ import annotations

import pytest

from avsim.errors import ConfigError
from avsim.experiments.folder_setting import SETTING_FILE, check_resumed_setting, folder_setting, record_setting


def test_a_setting_is_kept_and_the_default_renders_leave_no_file(tmp_path):
    record_setting(tmp_path, "textured_aniso16")
    assert folder_setting(tmp_path) == "textured_aniso16"
    record_setting(tmp_path, "baseline")  # a resume allowed under the default renders: the file goes
    assert not (tmp_path / SETTING_FILE).exists() and folder_setting(tmp_path) == "baseline"


def test_a_resume_under_the_folders_setting_passes_and_under_another_is_refused(tmp_path):
    record_setting(tmp_path, "sheeting")
    check_resumed_setting(tmp_path, "sheeting", "avsim sweep")
    with pytest.raises(ConfigError, match=r"--setting sheeting and this avsim sweep under --setting baseline.*give "
                                          r"--setting sheeting to finish it, or another --out"):
        check_resumed_setting(tmp_path, "baseline", "avsim sweep")


@pytest.mark.parametrize("text", ["{not json", '{"set": 1}', '{"setting": 3}'])
def test_a_setting_file_avsim_did_not_write_is_named(tmp_path, text):
    (tmp_path / SETTING_FILE).write_text(text)
    with pytest.raises(ConfigError, match=f"its {SETTING_FILE} (cannot be read|is not one avsim wrote)") as caught:
        folder_setting(tmp_path)
    assert "\n" not in str(caught.value)
