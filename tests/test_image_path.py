"""The image path follows the map: depth, channels, interpolation and fill."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from panomap.errors import PanomapError
from panomap.io.images import read_image, write_image
from panomap.remap import Remapper

WIDTH, HEIGHT = 640, 480
# 16-bit codes of a coordinate: 64 codes per pixel, so 0..639 px fits in 0..40960.
SCALE = 64.0


def coordinate_image() -> np.ndarray:
    """(H, W, 3) uint16: channel 0 encodes u, channel 1 encodes v, channel 2 a constant."""
    v, u = np.mgrid[0:HEIGHT, 0:WIDTH].astype(np.float64)
    image = np.empty((HEIGHT, WIDTH, 3), np.uint16)
    image[..., 0] = np.round(u * SCALE)
    image[..., 1] = np.round(v * SCALE)
    image[..., 2] = 1000
    return image


def random_map(rng: np.random.Generator, shape: tuple[int, int]) -> np.ndarray:
    map_uv = np.empty((*shape, 2), np.float32)
    map_uv[..., 0] = rng.uniform(0, WIDTH - 1, shape)
    map_uv[..., 1] = rng.uniform(0, HEIGHT - 1, shape)
    map_uv[rng.random(shape) < 0.1] = np.nan
    return map_uv


def test_16_bit_coordinate_image_comes_out_as_the_map_predicts() -> None:
    rng = np.random.default_rng(7)
    map_uv = random_map(rng, (120, 200))
    out = Remapper(map_uv, (WIDTH, HEIGHT), "linear")(coordinate_image())
    assert out.dtype == np.uint16 and out.shape == (120, 200, 3)
    valid = np.all(np.isfinite(map_uv), axis=2)
    decoded = out[..., :2].astype(np.float64) / SCALE
    # OpenCV's bilinear weights are quantised to 1/32 px, and the codes round to 1/128 px.
    np.testing.assert_allclose(decoded[valid], map_uv[valid], atol=1 / 32 + 1 / 128)
    assert np.all(out[valid][:, 2] == 1000)
    # No source: the fill value.
    assert np.all(out[~valid] == 0)


def test_nearest_reads_the_nearest_pixel() -> None:
    map_uv = np.array([[[10.4, 20.6], [10.6, 20.4]]], np.float32)
    out = Remapper(map_uv, (WIDTH, HEIGHT), "nearest")(coordinate_image())
    np.testing.assert_array_equal(out[0, :, :2] / SCALE, [[10, 21], [11, 20]])


def test_edge_half_pixel_reads_the_edge_pixel_not_the_fill() -> None:
    map_uv = np.array([[[-0.4, 100.0], [WIDTH - 0.6, HEIGHT - 0.6]]], np.float32)
    out = Remapper(map_uv, (WIDTH, HEIGHT), "linear")(coordinate_image())
    np.testing.assert_allclose(out[0, :, :2] / SCALE, [[0, 100], [WIDTH - 1, HEIGHT - 1]], atol=1 / 32)


@settings(max_examples=25, deadline=None)
@given(
    depth=st.sampled_from([np.uint8, np.uint16]),
    channels=st.sampled_from([1, 3, 4, None]),
    interpolation=st.sampled_from(["nearest", "linear", "cubic"]),
)
def test_depth_and_channels_are_kept(depth: type, channels: int | None, interpolation: str) -> None:
    rng = np.random.default_rng(1)
    shape = (HEIGHT, WIDTH) if channels is None else (HEIGHT, WIDTH, channels)
    image = rng.integers(0, np.iinfo(depth).max, shape, dtype=depth)
    map_uv = random_map(rng, (30, 40))
    out = Remapper(map_uv, (WIDTH, HEIGHT), interpolation)(image)
    assert out.dtype == depth
    assert out.shape == (30, 40) + (() if channels is None else (channels,))
    invalid = ~np.all(np.isfinite(map_uv), axis=2)
    assert np.all(out[invalid] == 0)  # black, and alpha 0 for four channels


def test_constant_image_stays_constant_under_cubic() -> None:
    image = np.full((HEIGHT, WIDTH), 40000, np.uint16)
    out = Remapper(random_map(np.random.default_rng(2), (50, 50)), (WIDTH, HEIGHT), "cubic")(image)
    values = np.unique(out)
    assert set(values.tolist()) <= {0, 40000}


def test_wrong_frame_size_or_type_is_refused() -> None:
    remapper = Remapper(random_map(np.random.default_rng(3), (4, 4)), (WIDTH, HEIGHT))
    with pytest.raises(PanomapError, match="the table is for 640 x 480"):
        remapper(np.zeros((10, 10), np.uint8))
    with pytest.raises(PanomapError, match="8- or 16-bit"):
        remapper(np.zeros((HEIGHT, WIDTH), np.int32))


@pytest.mark.parametrize("channels", [None, 3])
def test_remap_into_a_strided_output_equals_a_fresh_one(channels: int | None) -> None:
    """``out=`` (a video frame's padded plane, say) gets the same pixels and fill; its padding is untouched."""
    rng = np.random.default_rng(5)
    shape = (HEIGHT, WIDTH) if channels is None else (HEIGHT, WIDTH, channels)
    image = rng.integers(0, 255, shape, dtype=np.uint8)
    map_uv = random_map(rng, (30, 40))
    remapper = Remapper(map_uv, (WIDTH, HEIGHT), "linear", fill=9.0)
    padded = np.full((30, 53) + (() if channels is None else (channels,)), 77, np.uint8)
    out = padded[:, :40]
    assert not out.flags.c_contiguous
    returned = remapper(image, out=out)
    assert returned is out
    fresh = remapper(image)
    np.testing.assert_array_equal(out, fresh)
    assert np.all(out[~np.all(np.isfinite(map_uv), axis=2)] == 9)
    assert np.all(padded[:, 40:] == 77)
    with pytest.raises(PanomapError, match="the output must be"):
        remapper(image, out=np.zeros((30, 41, *out.shape[2:]), np.uint8))
    with pytest.raises(PanomapError, match="the output must be"):
        remapper(image, out=np.zeros(out.shape, np.uint16))


@pytest.mark.parametrize(
    ("suffix", "depth", "channels"), [(".png", np.uint16, 4), (".tif", np.uint16, 1), (".png", np.uint8, 3)]
)
def test_image_files_keep_depth_and_channels(tmp_path: Path, suffix: str, depth: type, channels: int) -> None:
    rng = np.random.default_rng(4)
    image = rng.integers(0, np.iinfo(depth).max, (12, 16, channels), dtype=depth)
    path = tmp_path / f"x{suffix}"
    write_image(path, image.squeeze() if channels == 1 else image)
    back = read_image(path)
    np.testing.assert_array_equal(back.reshape(image.shape), image)


def test_16_bit_into_jpeg_is_refused_and_nothing_is_written(tmp_path: Path) -> None:
    with pytest.raises(PanomapError, match="16-bit images need PNG"):
        write_image(tmp_path / "x.jpg", np.zeros((4, 4), np.uint16))
    assert list(tmp_path.iterdir()) == []


def test_unreadable_image(tmp_path: Path) -> None:
    path = tmp_path / "x.png"
    path.write_bytes(b"\x89PNG not really")
    with pytest.raises(PanomapError, match=r"x\.png: cannot read it as an image"):
        read_image(path)
    with pytest.raises(PanomapError, match=r"y\.png: no such image file"):
        read_image(tmp_path / "y.png")
