"""A measurement command's --set scope: whole sections and single keys it reads pass; anything else, its own keys and
a setting's keys are refused in one line."""

import pytest

from avsim.cli.overrides import parse_set
from avsim.errors import ConfigError
from avsim.realism.set_scope import SetScope
from avsim.realism.settings import SETTINGS

SCOPE = SetScope(reads=("camera.", "policy.conf_threshold"), reads_in_words="camera keys and policy.conf_threshold",
                 own_keys=("camera.preset",), own_fix="choose it with --preset", command="a measurement")


def test_a_read_section_and_a_read_key_pass_under_every_setting():
    SCOPE.check(parse_set(["camera.fovy_deg=40", "policy.conf_threshold=0.6"]), (SETTINGS["baseline"], SETTINGS["textured"]))


@pytest.mark.parametrize("item, named", [
    ("policy.vote_k=3", "--set policy.vote_k: a measurement reads camera keys and policy.conf_threshold only"),
    ("camera.preset=study", "--set camera.preset: a measurement sets it itself; choose it with --preset"),
    ("camera.supersample=3", "--set camera.supersample: --setting photo sets it too"),
    ("camera.fovy_deg=-1", "--set under --setting baseline: "),
])
def test_what_the_command_does_not_read_or_sets_itself_and_bad_values_are_refused(item, named):
    with pytest.raises(ConfigError) as caught:
        SCOPE.check(parse_set([item]), (SETTINGS["baseline"], SETTINGS["photo"]))
    assert str(caught.value).startswith(named) and "\n" not in str(caught.value), str(caught.value)
