"""Whether the CPU runs bf16, and what each network's precision setting becomes on a CPU without it."""

from __future__ import annotations

import pytest
import torch

from avsim.errors import ConfigError
from avsim.perception.cpu_bf16 import (arithmetic, arithmetics_here, auto_arithmetic, detector_arithmetic,
                                       onednn_runs_bf16, require_bf16)

SETTINGS = ("perception.detector_precision", "perception.coco_precision", "perception.yolo_precision")


@pytest.fixture
def no_bf16(monkeypatch):
    monkeypatch.setattr(torch.ops.mkldnn, "_is_mkldnn_bf16_supported", lambda: False)


@pytest.fixture
def with_bf16(monkeypatch):
    monkeypatch.setattr(torch.ops.mkldnn, "_is_mkldnn_bf16_supported", lambda: True)


def test_the_answer_is_onednns():
    assert onednn_runs_bf16() is bool(torch.ops.mkldnn._is_mkldnn_bf16_supported())


@pytest.mark.parametrize("setting", SETTINGS)
def test_auto_is_bf16_where_the_cpu_runs_it(with_bf16, setting):
    assert arithmetic("auto", setting) == "bf16" == auto_arithmetic()
    assert arithmetics_here() == ("fp32", "bf16")


@pytest.mark.parametrize("setting", SETTINGS)
def test_auto_is_fp32_where_it_does_not(no_bf16, setting):
    assert arithmetic("auto", setting) == "fp32" == auto_arithmetic()
    assert arithmetics_here() == ("fp32",)


def test_fp32_is_fp32_on_any_cpu(no_bf16):
    assert detector_arithmetic("fp32") == "fp32"


@pytest.mark.parametrize("setting", SETTINGS)
def test_bf16_without_the_cpu_names_the_setting_and_the_fix(no_bf16, setting):
    with pytest.raises(ConfigError, match=rf"{setting} = bf16 .*set {setting}=auto or fp32$"):
        arithmetic("bf16", setting)


def test_require_names_the_setting_it_was_given(no_bf16):
    with pytest.raises(ConfigError, match="set perception.yolo_precision=auto or fp32"):
        require_bf16("perception.yolo_precision")


def test_an_unknown_precision_is_refused():
    with pytest.raises(ValueError, match="precision must be one of auto, fp32, bf16"):
        detector_arithmetic("fp16")
