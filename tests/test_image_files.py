"""Image sizes read from file headers before decoding (`avsim.image_files`)."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from avsim.image_files import MAX_IMAGE_BYTES, MAX_IMAGE_PIXELS, ImageError, check_image_file, decode_image, header_size_px


@pytest.mark.parametrize("suffix", [".png", ".jpg", ".bmp", ".webp"])
@pytest.mark.parametrize("width, height", [(17, 5), (320, 241)])
def test_the_header_size_is_the_decoded_size(suffix, width, height):
    image = np.random.default_rng(0).integers(0, 255, (height, width, 3), dtype=np.uint8)
    ok, encoded = cv2.imencode(suffix, image)
    assert ok
    assert header_size_px(encoded.tobytes()) == (width, height)


def test_unknown_or_cut_headers_give_no_size():
    assert header_size_px(b"not an image at all") is None
    assert header_size_px(b"\x89PNG\r\n\x1a\n") is None
    assert header_size_px(b"\xff\xd8\xff") is None


def test_a_declared_size_past_the_cap_is_refused_before_decoding(tmp_path):
    side = int(MAX_IMAGE_PIXELS ** 0.5) + 1
    gif = tmp_path / "big.gif"
    gif.write_bytes(b"GIF89a" + side.to_bytes(2, "little") + side.to_bytes(2, "little") + b"\x00\x00\x00;")
    with pytest.raises(ImageError, match="megapixels"):
        check_image_file(gif)


def test_a_truncated_png_is_one_line_without_libpngs_printout(tmp_path, capfd):
    ok, encoded = cv2.imencode(".png", np.full((64, 64, 3), 128, np.uint8))
    path = tmp_path / "cut.png"
    path.write_bytes(encoded.tobytes()[:60])
    with pytest.raises(ImageError) as refused:
        decode_image(check_image_file(path), path)
    assert "\n" not in str(refused.value)
    assert capfd.readouterr().err == ""


def test_a_device_or_a_pipe_is_refused_without_reading_it(tmp_path):
    pipe = tmp_path / "frame.png"
    os.mkfifo(pipe)  # opened for reading, it would block with no writer
    for path, kind in ((Path("/dev/zero"), "a device"), (pipe, r"a pipe \(FIFO\)")):
        with pytest.raises(ImageError, match=f"is {kind}, not a regular file"):
            check_image_file(path)


def test_a_format_whose_size_is_not_checked_is_refused_before_decoding(tmp_path):
    # A TIFF decodes in OpenCV, but its header, which may declare 30000 x 30000 in a few hundred bytes, is not read here.
    tiff = tmp_path / "frame.tif"
    cv2.imwrite(str(tiff), np.zeros((8, 8, 3), np.uint8))
    with pytest.raises(ImageError, match="not PNG, JPEG, BMP, GIF or WebP"):
        check_image_file(tiff)


def test_a_file_larger_than_any_image_is_refused_after_reading_its_header_only(tmp_path):
    big = tmp_path / "big.png"
    with big.open("wb") as file:
        file.truncate(MAX_IMAGE_BYTES + 1)  # sparse: no disk used
    with pytest.raises(ImageError, match="MB, more than"):
        check_image_file(big)
