"""A rig's video (issue 52, items 3 and 5): the fast blend equals RigRemapper's, the video's frames equal the
still command's, bad inputs are refused in one line before any work.

Ground truth as ``tests/test_rig.py``: ideal equidistant lenses chained in closed form (its helpers), the dual
fisheye back to back in one frame, the surround view four lenses turned by quarter turns, each its own picture.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path

import av
import cv2
import numpy as np
import pytest

from panomap.interop.rig_of_camchain import rig_of_camchain
from panomap.rig import CameraRig, RigRemapper, camera_maps, save_rig
from panomap.rig.fast import FastRigRemapper
from panomap.rig.seams import BLENDED, coarse_distances, seam_weights, video_seam_step
from panomap.video.frames import _chroma_map
from panomap.views import EquirectView, FloorView
from test_orientation import conventions_axes
from test_rig import BACK_TO_BACK, HALF_FOV, SIDE, camchain, chain_truth, render_lens, textured_world

from helpers import assert_one_line_error, run

QUARTER = [[0, 0, -1, 1.0], [0, 1, 0, 0], [1, 0, 0, 1.0], [0, 0, 0, 1]]
LOSSLESS_BGR = ["--codec", "ffv1", "--pix-fmt", "bgr0"]


def noisy(picture: np.ndarray, seed: int, gain: float = 1.0) -> np.ndarray:
    """``picture`` times ``gain`` with sensor noise (sigma 2), as uint8."""
    rng = np.random.default_rng(seed)
    return np.clip(picture.astype(np.float32) * gain + rng.normal(0, 2, picture.shape), 0, 255).astype(np.uint8)


@pytest.fixture(scope="module")
def dual(tmp_path_factory: pytest.TempPathFactory) -> tuple[CameraRig, Path, np.ndarray]:
    """The back-to-back pair (its rig file) and one frame of a world through it, lens 1 12% brighter."""
    folder = tmp_path_factory.mktemp("rig_video")
    rig = rig_of_camchain(camchain(folder / "dual.yaml", [BACK_TO_BACK]), side_by_side=True, fov_rad=2 * HALF_FOV)
    save_rig(rig, folder / "dual.npz")
    truth = chain_truth(conventions_axes(0, 0, 0), np.zeros(3), [BACK_TO_BACK])
    world = textured_world()
    lenses = [render_lens(world, axes).astype(np.float32) for axes, _ in truth]
    frame = noisy(np.concatenate([lenses[0], lenses[1] * 1.12], axis=1), 1)
    return rig, folder / "dual.npz", frame


@pytest.fixture(scope="module")
def surround(tmp_path_factory: pytest.TempPathFactory) -> tuple[CameraRig, Path, list[np.ndarray]]:
    """Four lenses by quarter turns, camera 0 pitched 40 deg down from 1.2 m (its rig file), and one picture
    each of the world, camera 2 10% darker."""
    folder = tmp_path_factory.mktemp("rig_surround")
    rig = rig_of_camchain(camchain(folder / "car.yaml", [QUARTER] * 3), orientation_rad=(0.0, math.radians(-40), 0.0),
                          camera_position=(1.0, 0.0, 1.2))  # fmt: skip
    save_rig(rig, folder / "car.npz")
    truth = chain_truth(conventions_axes(0, -40, 0), np.array([1.0, 0.0, 1.2]), [QUARTER] * 3)
    world = textured_world(2)
    pictures = [noisy(render_lens(world, axes), k, 0.9 if k == 2 else 1.0) for k, (axes, _) in enumerate(truth)]
    return rig, folder / "car.npz", pictures


def test_the_fast_blend_equals_the_rig_remapper_on_a_dual_fisheye_frame(dual: tuple) -> None:  # type: ignore[type-arg]
    """One frame holding both lenses, equirect (wrapping weights), colour and grey, with the gains found and
    with none: the fast blend (one remap, the band blended apart, gains as lookup tables) is RigRemapper's
    picture within 1 grey level (the same float maps and float32 sums: measured equal), and finds its gains."""
    rig, _, frame = dual
    remapper = RigRemapper(rig, camera_maps(rig, EquirectView(size=(512, 256))), wrap=True)
    fast = FastRigRemapper(remapper)
    gains = remapper.gains(frame)
    assert np.allclose(fast.gains(frame), gains, rtol=1e-5)
    assert 1.09 < float(np.mean(gains[0] / gains[1])) < 1.15
    for given in (gains, np.ones_like(gains)):
        assert np.abs(fast(frame, given).astype(int) - remapper(frame, given)).max() <= 1
    grey = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    fast_grey = FastRigRemapper(remapper, channels=1)
    assert np.abs(fast_grey(grey, gains[:, :1]).astype(int) - remapper(grey, gains[:, :1])).max() <= 1
    assert 0.05 < fast.plane.band_size / (512 * 256) < 0.3  # (the band: the 10 deg overlap, wider at the poles)


def formula_weights(maps: list[np.ndarray], wrap: bool) -> np.ndarray:
    """The feathered weights written out over every pixel (blend.py's formula): each camera's distance from the
    edge of what it sees (wrapping: across the wrap), less the largest plus 2 f (f = 1% of the diagonal), at
    least 0 and 0 where it does not see, over their sum."""
    seen = np.stack([np.all(np.isfinite(m), axis=-1) for m in maps])
    pad = seen.shape[2] // 4 if wrap else 0
    distances = []
    for mask in seen.astype(np.uint8):
        padded = cv2.copyMakeBorder(mask, 0, 0, pad, pad, cv2.BORDER_WRAP)
        distance = cv2.distanceTransform(padded, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        distances.append(distance[:, pad : pad + mask.shape[1]])
    weights = np.stack(distances)
    weights -= weights.max(axis=0) - 2 * max(8.0, 0.01 * float(np.hypot(*seen.shape[1:])))
    weights = np.where(seen, np.maximum(weights, 0), 0)
    total = weights.sum(axis=0)
    return np.divide(weights, total, out=np.zeros_like(weights), where=total > 0)


@pytest.mark.slow
@pytest.mark.parametrize("wrap", [True, False])
def test_the_seams_weights_are_the_formulas_over_every_pixel(dual: tuple, surround: tuple, wrap: bool) -> None:  # type: ignore[type-arg]
    """The weights kept sparse (each pixel's sole camera, the band where several weigh: seams.py) are the
    formula's over every pixel, for an equirect of the dual fisheye (wrapping) and a floor of four cameras; and a
    chroma plane's (each 2 x 2 block's sum, 0 where the camera's chroma map has none, over their sum) likewise.
    (Within 1e-6: OpenCV's distance transform varies in its last bits between calls.) The fast blend, copying
    the sole camera outside the band, is the picture blended densely with the formula's weights (every camera
    weighed at every pixel, as before the weights were kept sparse) within 1 grey level (float32 sums' rounding)."""
    rig, pictures = (dual[0], dual[2]) if wrap else (surround[0], surround[2])
    view = EquirectView(size=(256, 128)) if wrap else FloorView(0.0, (-3.0, 5.0), (-4.0, 4.0), (121, 97))
    maps = camera_maps(rig, view)
    expected = formula_weights(maps, wrap)
    seams = seam_weights(maps, wrap)
    assert np.abs(seams.dense() - expected).max() < 1e-6
    assert 0 < seams.band.size < expected[0].size  # (the band: not every pixel)
    assert np.array_equal(np.count_nonzero(expected > 1e-6, axis=0) >= 2, seams.owner == BLENDED)
    chroma = [_chroma_map(m, 1, 1) for m in maps]
    padded = np.pad(expected, ((0, 0), (0, expected.shape[1] % 2), (0, expected.shape[2] % 2)), mode="edge")
    blocks = padded[:, ::2, ::2] + padded[:, ::2, 1::2] + padded[:, 1::2, ::2] + padded[:, 1::2, 1::2]
    blocks = np.where(np.stack([np.all(np.isfinite(m), axis=-1) for m in chroma]), blocks, 0)
    total = blocks.sum(axis=0)
    blocks = np.divide(blocks, total, out=np.zeros_like(blocks), where=total > 0)
    assert np.abs(seams.subsampled(chroma, 1, 1).dense() - blocks).max() < 1e-6
    remapper = RigRemapper(rig, maps, wrap=wrap)
    layers = remapper.layers(pictures)
    gains = remapper.layer_gains(layers)
    dense = copy.copy(remapper)
    object.__setattr__(dense, "weights", expected)  # (the dense blend: every camera's weight at every pixel)
    assert np.abs(FastRigRemapper(remapper)(pictures, gains).astype(int) - dense.blend(layers, gains)).max() <= 1


def test_coarse_distances_are_the_distance_to_the_edge_within_their_bound() -> None:
    """Masks whose distance to the edge is known in closed form: a band of columns wrapping around the view (a
    seen pixel's distance: the columns to the nearest one not seen, across the wrap, or not) and a disc (R - r,
    within the pixel grid's 1 px). From every 2nd and 3rd row and column the distances are within sqrt(2) step px of
    the truth plus the grid's own (measured: 1.0 and 4.0 px on the band, 2.0 and 3.0 on the disc)."""
    height, width = 96, 301
    columns = np.arange(width)
    band = ((columns >= width - 40) | (columns < 57)).astype(np.uint8)  # (97 columns seen, across the wrap)
    mask = np.repeat(band[None, :] * np.uint8(255), height, axis=0)
    flat = np.flatnonzero(mask)
    x = flat % width
    inside = np.where(x >= width - 40, x - (width - 40), x + 40)  # (column within the band, 0..96)
    truth = np.minimum(inside + 1, 97 - inside).astype(np.float32)
    yy, xx = np.mgrid[:201, :203]
    radius = np.hypot(xx - 101.3, yy - 99.6)
    disc = ((radius < 90) * 255).astype(np.uint8)
    disc_flat = np.flatnonzero(disc)
    for step in (2, 3):
        off = np.abs(coarse_distances(mask, flat, step, wrap=True) - truth)
        assert off.max() <= math.sqrt(2) * step
        assert np.median(off) <= step - 1 + 1e-6  # (the nodes see the edge late by up to step - 1 columns)
        near = np.abs(coarse_distances(disc, disc_flat, step, wrap=False) - (90 - radius.reshape(-1)[disc_flat]))
        assert near.max() <= math.sqrt(2) * step + 1.0
    # Not wrapping, the band is two, each seen to the view's side (beyond it, OpenCV's transform sees no edge).
    apart = np.where(x < 57, 57 - x, x - (width - 41)).astype(np.float32)
    assert np.abs(coarse_distances(mask, flat, 2, wrap=False) - apart).max() <= math.sqrt(2) * 2


def test_a_videos_coarse_distances_move_its_blend_by_at_most_one_grey_level(dual: tuple) -> None:  # type: ignore[type-arg]
    """A video's view wide enough for a 40 px feather takes its distances on a 2 x 2 grid (4 x fewer pixels to
    transform; smaller views every pixel's). At that feather, the dual fisheye's equirect (lens 1 12% brighter,
    noise), 1024 x 512 with that feather: every weight within 0.03 of the exact one (measured 0.015; 0.016 at
    4K), and the fast blend's picture, with the gains found and with none, within 1 grey level of the exact
    weights' (measured: 1, at 0.1% and 0.9% of its pixels)."""
    assert video_seam_step((1920, 3840)) == 2 and video_seam_step((1080, 1920)) == 1
    rig, _, frame = dual
    maps = camera_maps(rig, EquirectView(size=(1024, 512)))
    exact = seam_weights(maps, True, feather_px=40.0)
    coarse = seam_weights(maps, True, feather_px=40.0, step=2)
    assert np.abs(exact.dense() - coarse.dense()).max() < 0.03
    remapper = RigRemapper(rig, maps, wrap=True)
    gains = remapper.gains(frame)
    pictures = []
    for seams in (exact, coarse):
        weighed = copy.copy(remapper)
        object.__setattr__(weighed, "seams", seams)
        fast = FastRigRemapper(weighed)
        pictures.append([fast(frame, given).astype(int) for given in (gains, np.ones_like(gains))])
    for a, b in zip(*pictures, strict=True):
        assert np.abs(a - b).max() <= 1


@pytest.mark.slow  # 3-4 s of set-up on two cores: the fast subset keeps within its 3 minutes
def test_the_fast_blend_equals_the_rig_remapper_on_a_surround_floor(surround: tuple) -> None:  # type: ignore[type-arg]
    """Four pictures, a floor map (its weights do not wrap), nearest and linear: within 1 grey level (nearest: but
    for the odd pixel whose entry lies a hair from a pixel's edge, where the fast buffer's offset, added in float32
    at u ~ 3000, rounds it across the tie: at most 0.2% of pixels)."""
    rig, _, pictures = surround
    maps = camera_maps(rig, FloorView(0.0, (-3.0, 5.0), (-4.0, 4.0), (160, 160)))
    for interpolation in ("linear", "nearest"):
        remapper = RigRemapper(rig, maps, interpolation)
        gains = remapper.gains(pictures)
        off = np.abs(FastRigRemapper(remapper)(pictures, gains).astype(int) - remapper(pictures, gains)).max(axis=-1)
        assert off.max() <= 1 if interpolation == "linear" else np.mean(off > 1) <= 0.002


def write_video(path: Path, frames: list[np.ndarray], lossless: bool = True) -> None:
    """``frames`` (BGR) as a video: FFV1 bgr0 (lossless) or H.264 yuv420p."""
    with av.open(str(path), "w") as container:
        stream = container.add_stream("ffv1" if lossless else "libx264", rate=25)
        stream.height, stream.width = frames[0].shape[:2]
        stream.pix_fmt = "bgr0" if lossless else "yuv420p"
        if not lossless:
            stream.options = {"preset": "ultrafast", "crf": "14"}
        for frame in frames:
            for packet in stream.encode(av.VideoFrame.from_ndarray(frame, format="bgr24")):
                container.mux(packet)
        for packet in stream.encode(None):
            container.mux(packet)


def frames_of(path: Path) -> list[np.ndarray]:
    with av.open(str(path)) as container:
        return [frame.to_ndarray(format="bgr24") for frame in container.decode(video=0)]


def test_the_videos_first_frame_is_the_still_commands_picture(dual: tuple, tmp_path: Path) -> None:  # type: ignore[type-arg]
    """A lossless dual-fisheye video of three frames: its first blended frame equals ``panomap equirect`` of that
    frame within 1 grey level (the same blend, BGR throughout); through H.264 and yuv420p (blended plane by plane,
    the luma's gain for all three), within 4 on average (the codecs' loss, and the chroma's gain about grey)."""
    _, rig_path, frame = dual
    write_video(tmp_path / "dual.mkv", [frame, np.roll(frame, 3, axis=0), frame])
    cv2.imwrite(str(tmp_path / "frame.png"), frame)
    still = run("equirect", rig_path, tmp_path / "frame.png", "-o", tmp_path / "still.png", "--size", "512x256")
    assert still.exit_code == 0, still.output
    expected = cv2.imread(str(tmp_path / "still.png")).astype(int)
    result = run("video", rig_path, tmp_path / "dual.mkv", "-o", tmp_path / "e.mkv", "--view",
                 "equirect:size=512x256", *LOSSLESS_BGR)  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "blended 2 cameras' view: 3 frames" in result.output
    blended = frames_of(tmp_path / "e.mkv")
    assert len(blended) == 3
    assert np.abs(blended[0] - expected).max() <= 1
    write_video(tmp_path / "dual.mp4", [frame, frame], lossless=False)
    assert run("video", rig_path, tmp_path / "dual.mp4", "-q", "-o", tmp_path / "e.mp4", "--view",
               "equirect:size=512x256").exit_code == 0  # fmt: skip
    assert float(np.abs(frames_of(tmp_path / "e.mp4")[0] - expected).mean()) < 4


@pytest.mark.slow
def test_four_videos_are_read_in_step_to_the_shortest(surround: tuple, tmp_path: Path) -> None:  # type: ignore[type-arg]
    """One video per camera, one of them a frame shorter: the floor map's video has the shortest's frames, and
    its first frame is the still command's."""
    _, rig_path, pictures = surround
    videos = []
    for k, picture in enumerate(pictures):
        videos.append(tmp_path / f"cam{k}.mkv")
        write_video(videos[-1], [picture] * (2 if k == 1 else 3))
        cv2.imwrite(str(tmp_path / f"cam{k}.png"), picture)
    spec = "floor:z=0,x=-3:5,y=-4:4,size=160x160"
    result = run("video", rig_path, *videos, "-o", tmp_path / "floor.mkv", "--view", spec, *LOSSLESS_BGR)
    assert result.exit_code == 0, result.output
    blended = frames_of(tmp_path / "floor.mkv")
    assert len(blended) == 2
    still = run("floor", rig_path, *(tmp_path / f"cam{k}.png" for k in range(4)), "-o", tmp_path / "floor.png",
                "--z", "0", "--x", "-3", "5", "--y", "-4", "4", "--size", "160x160")  # fmt: skip
    assert still.exit_code == 0, still.output
    assert np.abs(blended[0].astype(int) - cv2.imread(str(tmp_path / "floor.png"))).max() <= 1


def test_bad_inputs_are_refused_in_one_line_before_any_work(dual: tuple, surround: tuple, tmp_path: Path) -> None:  # type: ignore[type-arg]
    """Two videos for a rig whose cameras share one frame, three for four cameras, a video of the wrong size,
    cubic reading and two views: one line each, no output written."""
    _, rig_path, frame = dual
    _, car_path, _ = surround
    write_video(tmp_path / "dual.mkv", [frame])
    write_video(tmp_path / "half.mkv", [frame[:, :SIDE]])
    out = tmp_path / "out.mkv"
    view = ["--view", "equirect:size=256x128"]
    assert_one_line_error(run("video", rig_path, tmp_path / "dual.mkv", tmp_path / "dual.mkv", "-o", out, *view),
                          "share one frame", "not 2", exit_code=2)  # fmt: skip
    assert_one_line_error(run("video", car_path, *[tmp_path / "dual.mkv"] * 3, "-o", out, *view),
                          "one video per camera", "cam0, cam1, cam2, cam3", "not 3", exit_code=2)  # fmt: skip
    assert_one_line_error(run("video", rig_path, tmp_path / "half.mkv", "-o", out, *view),
                          "half.mkv", f"its frames are {SIDE} x {SIDE}", f"{2 * SIDE} x {SIDE}")  # fmt: skip
    assert_one_line_error(run("video", car_path, *[tmp_path / "dual.mkv"] * 4, "-o", out, *view),
                          "camera cam0 is 960 x 960")  # fmt: skip
    assert_one_line_error(run("video", rig_path, tmp_path / "dual.mkv", "-o", out, *view, "--interp", "cubic"),
                          "linear or nearest", exit_code=2)  # fmt: skip
    assert_one_line_error(run("video", rig_path, tmp_path / "dual.mkv", "-o", "o_{name}.mkv", *view, "--view",
                              "panorama:size=256x64"), "one view", exit_code=2)  # fmt: skip
    assert not out.exists() and not [p for p in tmp_path.iterdir() if ".part" in p.name]


def test_a_rig_videos_rotation_metadata_is_warned_of_and_not_on_a_refusal(dual: tuple, tmp_path: Path) -> None:  # type: ignore[type-arg]
    """The rotation metadata is read beside the rig (on a thread): its warning is printed once the rig is read
    and the inputs checked; a command refused meanwhile prints its one line alone."""
    _, rig_path, frame = dual
    clip = tmp_path / "turned.mp4"
    with av.open(str(clip), "w") as container:
        stream = container.add_stream("libx264", rate=10)
        stream.width, stream.height, stream.pix_fmt = frame.shape[1], frame.shape[0], "yuv420p"
        stream.set_display_rotation(90)
        for packet in [*stream.encode(av.VideoFrame.from_ndarray(frame, format="bgr24")), *stream.encode()]:
            container.mux(packet)
    view = ["--view", "equirect:size=64x32"]
    result = run("video", rig_path, clip, "-o", tmp_path / "out.mp4", *view)
    assert result.exit_code == 0, result.output + result.stderr
    assert result.stderr.count(f"panomap: warning: {clip}: it asks players to turn its frames by 90 deg") == 1
    assert_one_line_error(run("video", rig_path, clip, clip, "-o", tmp_path / "no.mp4", *view), "share one frame",
                          exit_code=2)  # fmt: skip
