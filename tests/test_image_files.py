"""Image sizes read from file headers before decoding (`avsim.image_files`)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from avsim.image_files import MAX_IMAGE_PIXELS, ImageError, check_image_file, decode_image, header_size_px


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
