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


def keys_weights(t: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Weights (..., 4) of the 4 taps at ``offsets`` (-1, 0, 1, 2) for fractions ``t`` (...): Keys'
    cubic convolution with a = -0.75, the kernel OpenCV's INTER_CUBIC documents."""
    a = -0.75
    x = np.abs(t[..., None] - offsets)
    near = (a + 2) * x**3 - (a + 3) * x**2 + 1
    far = a * x**3 - 5 * a * x**2 + 8 * a * x - 4 * a
    return np.where(x <= 1, near, far)


def expected_remap(image: np.ndarray, map_uv: np.ndarray, interpolation: str, fixed_point: bool) -> np.ndarray:
    """The remap in closed form, (H, W, C) float64 before rounding: the pixel nearest each map
    position, the bilinear mix of the 4 around it, or Keys' cubic mix of the 16; edge pixels
    replicated. Fixed-point maps hold positions in 1/32 px; float maps are exact (OpenCV 5)."""
    source = (image[..., None] if image.ndim == 2 else image).astype(np.float64)
    height, width = source.shape[:2]
    position = np.nan_to_num(map_uv.astype(np.float64))  # (entries with no source: the caller's to mask)
    if fixed_point and interpolation != "nearest":  # (nearest: convertMaps rounds to whole pixels)
        position = np.round(position * 32) / 32
    u, v = position[..., 0], position[..., 1]
    if interpolation == "nearest":
        return source[
            np.clip(np.floor(v + 0.5).astype(int), 0, height - 1), np.clip(np.floor(u + 0.5).astype(int), 0, width - 1)
        ]
    u0, v0 = np.floor(u).astype(int), np.floor(v).astype(int)
    if interpolation == "linear":
        offsets = np.array([0, 1])
        weights_u = np.stack([1 - (u - u0), u - u0], axis=-1)
        weights_v = np.stack([1 - (v - v0), v - v0], axis=-1)
    else:
        offsets = np.array([-1, 0, 1, 2])
        weights_u, weights_v = keys_weights(u - u0, offsets), keys_weights(v - v0, offsets)
    out = np.zeros(map_uv.shape[:2] + source.shape[2:])
    for j, dv in enumerate(offsets):
        for i, du in enumerate(offsets):
            tap = source[np.clip(v0 + dv, 0, height - 1), np.clip(u0 + du, 0, width - 1)]
            out += (weights_v[..., j] * weights_u[..., i])[..., None] * tap
    return out


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
    fixed_point=st.booleans(),
)
def test_depth_and_channels_are_kept(depth: type, channels: int | None, interpolation: str, fixed_point: bool) -> None:
    rng = np.random.default_rng(1)
    shape = (HEIGHT, WIDTH) if channels is None else (HEIGHT, WIDTH, channels)
    image = rng.integers(0, np.iinfo(depth).max, shape, dtype=depth)
    map_uv = random_map(rng, (30, 40))
    out = Remapper(map_uv, (WIDTH, HEIGHT), interpolation, fixed_point=fixed_point)(image)
    assert out.dtype == depth
    assert out.shape == (30, 40) + (() if channels is None else (channels,))
    invalid = ~np.all(np.isfinite(map_uv), axis=2)
    assert np.all(out[invalid] == 0)  # black, and alpha 0 for four channels
    # Every channel's value where the map has a source, against the closed form: within one level
    # (OpenCV's fixed-point weights and float rounding; measured: at most 1, exact for nearest).
    expected = np.clip(np.rint(expected_remap(image, map_uv, interpolation, fixed_point)), 0, np.iinfo(depth).max)
    got = out.reshape(expected.shape).astype(np.float64)
    np.testing.assert_allclose(got[~invalid], expected[~invalid], atol=0 if interpolation == "nearest" else 1)


def test_cubic_is_keys_cubic_convolution_and_keeps_a_constant() -> None:
    """INTER_CUBIC against Keys' kernel (a = -0.75) in closed form on a random image, within one
    level (measured 1); linear interpolation misses it by hundreds. A constant image stays exactly
    constant (the weights sum to 1), with 0 only where the map has no source."""
    rng = np.random.default_rng(2)
    image = rng.integers(0, 60000, (HEIGHT, WIDTH), dtype=np.uint16)
    map_uv = random_map(rng, (50, 50))
    valid = np.all(np.isfinite(map_uv), axis=2)
    expected = np.clip(np.rint(expected_remap(image, map_uv, "cubic", False)[..., 0]), 0, 65535)
    cubic = Remapper(map_uv, (WIDTH, HEIGHT), "cubic")(image).astype(np.float64)
    np.testing.assert_allclose(cubic[valid], expected[valid], atol=1)
    linear = Remapper(map_uv, (WIDTH, HEIGHT), "linear")(image).astype(np.float64)
    assert np.median(np.abs(linear[valid] - expected[valid])) > 100
    constant = Remapper(map_uv, (WIDTH, HEIGHT), "cubic")(np.full((HEIGHT, WIDTH), 40000, np.uint16))
    np.testing.assert_array_equal(constant, np.where(valid, 40000, 0))


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
