"""Sign face textures: maker geometry, PNG loading/saving, and the committed clean PNGs."""

from pathlib import Path

import cv2
import numpy as np
import pytest

from avsim.errors import AvsimError, TextureError
from avsim.world.textures import (
    CLEAN_TEXTURE_FILES,
    SIGN_TEXTURE_MAKERS,
    TEXTURE_DIR,
    load_texture_png,
    make_speed_limit_sign,
    make_stop_sign,
    make_yield_sign,
    save_texture_png,
    write_clean_textures,
)


def _is_red(px) -> bool:
    return px[0] > 150 and px[1] < 60 and px[2] < 90


def _assert_one_line_error(excinfo, path) -> None:
    msg = str(excinfo.value)
    assert "\n" not in msg
    assert str(path) in msg
    assert isinstance(excinfo.value, AvsimError)


@pytest.mark.parametrize("maker, shape", [
    (make_stop_sign, (512, 512, 3)),
    (make_yield_sign, (512, 512, 3)),
    (make_speed_limit_sign, (500, 400, 3)),
    (lambda: make_stop_sign(256), (256, 256, 3)),
    (lambda: make_speed_limit_sign(100, 200, 250), (250, 200, 3)),
])
def test_makers_return_rgb_uint8_of_documented_shape(maker, shape):
    img = maker()
    assert img.dtype == np.uint8
    assert img.shape == shape


def test_stop_sign_geometry_and_colours():
    s = 512
    img = make_stop_sign(s)
    # Just inside the left flat, past the rim and the white band: red face (RGB order).
    assert _is_red(img[s // 2, int(0.06 * s)])
    # The flats touch the image edges: the rim is red at the middle of every edge.
    for px in (img[s // 2, 1], img[s // 2, s - 2], img[1, s // 2], img[s - 2, s // 2]):
        assert _is_red(px)
    # Corners are outside the octagon.
    for px in (img[0, 0], img[0, -1], img[-1, 0], img[-1, -1], img[20, 20]):
        assert tuple(px) == (128, 128, 128)
    # The white border band sits between the rim and the red face.
    assert (img[s // 2, int(0.03 * s)] > 240).all()
    # The STOP legend is white, centred, and spans about 70 % of the width.
    centre = img[int(0.4 * s):int(0.6 * s), int(0.2 * s):int(0.8 * s)]
    assert ((centre > 240).all(axis=2)).mean() > 0.2
    white_cols = np.nonzero((img[int(0.4 * s):int(0.6 * s)] > 240).all(axis=2).any(axis=0))[0]
    inner = white_cols[(white_cols > 0.1 * s) & (white_cols < 0.9 * s)]
    assert abs((inner.min() + inner.max()) / 2 - s / 2) < 0.02 * s
    assert 0.65 * s < inner.max() - inner.min() < 0.75 * s


def test_yield_sign_geometry_and_colours():
    s = 512
    img = make_yield_sign(s)
    apex_y = s * np.sqrt(3) / 2
    assert _is_red(img[2, s // 2 - 200]) and _is_red(img[2, s // 2 + 200])  # top edge, full width
    assert _is_red(img[int(apex_y) - 4, s // 2])  # apex at the bottom centre
    assert tuple(img[int(apex_y) + 10, s // 2]) == (128, 128, 128)
    assert tuple(img[s // 2, 10]) == (128, 128, 128)
    assert (img[int(0.4 * apex_y), s // 2] > 240).all()  # white interior
    legend = img[int(0.15 * s):int(0.3 * s), int(0.3 * s):int(0.7 * s)]
    assert np.mean([_is_red(px) for px in legend.reshape(-1, 3)]) > 0.1


def test_speed_limit_sign_colours():
    img = make_speed_limit_sign()
    assert (img[0, 0] == 255).all() and (img[250, 12] < 20).all()  # white edge, black border
    number = img[int(0.5 * 500):int(0.85 * 500), 80:320]
    assert ((number < 30).all(axis=2)).mean() > 0.2


@pytest.mark.parametrize("kind", sorted(SIGN_TEXTURE_MAKERS))
def test_generation_is_deterministic(kind):
    make = SIGN_TEXTURE_MAKERS[kind]
    assert np.array_equal(make(), make())


def test_registries_cover_the_same_kinds():
    kinds = {"stop_sign", "yield", "speed_limit"}
    assert set(SIGN_TEXTURE_MAKERS) == set(CLEAN_TEXTURE_FILES) == kinds


def test_save_then_load_round_trips(tmp_path):
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, size=(40, 64, 3), dtype=np.uint8)
    path = tmp_path / "face.png"
    save_texture_png(path, rgb)
    assert np.array_equal(load_texture_png(path), rgb)
    assert np.array_equal(load_texture_png(path, expected_aspect=64 / 40), rgb)
    assert [p.name for p in tmp_path.iterdir()] == ["face.png"]  # no temp file left behind


def test_load_drops_alpha_expands_grey_and_scales_16_bit(tmp_path):
    bgra = np.zeros((32, 32, 4), np.uint8)
    bgra[..., 2], bgra[..., 3] = 200, 7  # red in BGR order, arbitrary alpha
    cv2.imwrite(str(tmp_path / "a.png"), bgra)
    rgba_loaded = load_texture_png(tmp_path / "a.png")
    assert rgba_loaded.shape == (32, 32, 3) and tuple(rgba_loaded[0, 0]) == (200, 0, 0)
    cv2.imwrite(str(tmp_path / "g.png"), np.full((32, 32), 77, np.uint8))
    assert (load_texture_png(tmp_path / "g.png") == 77).all()
    cv2.imwrite(str(tmp_path / "w.png"), np.full((32, 32, 3), 257 * 100, np.uint16))
    wide = load_texture_png(tmp_path / "w.png")
    assert wide.dtype == np.uint8 and (wide == 100).all()


def test_save_refuses_wrong_dtype_or_shape(tmp_path):
    with pytest.raises(TextureError):
        save_texture_png(tmp_path / "x.png", np.zeros((32, 32, 3), np.float32))
    with pytest.raises(TextureError):
        save_texture_png(tmp_path / "x.png", np.zeros((32, 32), np.uint8))
    assert not list(tmp_path.iterdir())


def test_load_refuses_missing_file(tmp_path):
    path = tmp_path / "nope.png"
    with pytest.raises(TextureError) as excinfo:
        load_texture_png(path)
    _assert_one_line_error(excinfo, path)


def test_load_refuses_jpeg_renamed_png(tmp_path):
    ok, buf = cv2.imencode(".jpg", np.zeros((64, 64, 3), np.uint8))
    assert ok
    path = tmp_path / "photo.png"
    path.write_bytes(buf.tobytes())
    with pytest.raises(TextureError) as excinfo:
        load_texture_png(path)
    _assert_one_line_error(excinfo, path)
    assert "not a PNG" in str(excinfo.value)


@pytest.mark.parametrize("cut", [0.5, 0.9, 30])
def test_load_refuses_truncated_png(tmp_path, cut):
    path = tmp_path / "full.png"
    save_texture_png(path, make_stop_sign(128))
    data = path.read_bytes()
    n = int(len(data) * cut) if cut < 1 else cut
    broken = tmp_path / "broken.png"
    broken.write_bytes(data[:n])
    with pytest.raises(TextureError) as excinfo:
        load_texture_png(broken)
    _assert_one_line_error(excinfo, broken)


def test_load_refuses_corrupt_image_data(tmp_path):
    path = tmp_path / "full.png"
    save_texture_png(path, make_stop_sign(128))
    data = bytearray(path.read_bytes())
    idat = data.index(b"IDAT")
    data[idat + 4:idat + 200] = b"\x00" * 196  # zlib stream destroyed, IEND still there
    broken = tmp_path / "corrupt.png"
    broken.write_bytes(bytes(data))
    with pytest.raises(TextureError) as excinfo:
        load_texture_png(broken)
    _assert_one_line_error(excinfo, broken)


@pytest.mark.parametrize("shape", [(16, 16, 3), (64, 31, 3), (4097, 40, 3)])
def test_load_refuses_bad_size(tmp_path, shape):
    path = tmp_path / "odd.png"
    cv2.imwrite(str(path), np.zeros(shape, np.uint8))
    with pytest.raises(TextureError) as excinfo:
        load_texture_png(path)
    _assert_one_line_error(excinfo, path)


def test_load_refuses_wrong_aspect(tmp_path):
    path = tmp_path / "square.png"
    save_texture_png(path, np.zeros((100, 100, 3), np.uint8))
    assert load_texture_png(path, expected_aspect=1.015).shape == (100, 100, 3)  # within 2 %
    with pytest.raises(TextureError) as excinfo:
        load_texture_png(path, expected_aspect=0.8)
    _assert_one_line_error(excinfo, path)
    assert "100x100" in str(excinfo.value)


def test_write_clean_textures(tmp_path):
    paths = write_clean_textures(tmp_path)
    assert sorted(p.name for p in paths) == sorted(CLEAN_TEXTURE_FILES.values())
    for kind, name in CLEAN_TEXTURE_FILES.items():
        assert np.array_equal(load_texture_png(tmp_path / name), SIGN_TEXTURE_MAKERS[kind]())


def test_texture_dir_is_repo_top_level():
    assert TEXTURE_DIR == Path(__file__).resolve().parents[2] / "textures"


@pytest.mark.parametrize("kind", sorted(CLEAN_TEXTURE_FILES))
def test_committed_textures_match_the_makers(kind):
    # If this fails, the drawing code changed: run `python -m avsim.world.textures`.
    committed = load_texture_png(TEXTURE_DIR / CLEAN_TEXTURE_FILES[kind])
    assert np.array_equal(committed, SIGN_TEXTURE_MAKERS[kind]())


def test_a_device_or_a_pipe_as_a_texture_is_refused_without_reading_it(tmp_path):
    import os

    pipe = tmp_path / "sign.png"
    os.mkfifo(pipe)
    for path, kind in (("/dev/zero", "a device"), (pipe, r"a pipe \(FIFO\)")):
        with pytest.raises(TextureError, match=f"is {kind}, not a regular file"):
            load_texture_png(path)
