"""Issue 44: learning from a picture works in bounded memory, and says so before reading one it cannot;
a picture without straight lines, or lines beyond the circle found, gets one line saying what was found.

The edges of a large image circle are searched at a bounded working resolution (its smoothing is wider
than a pixel already), as precisely; the memory of the line and board search is estimated from the
images' headers before any is decoded, and refused beyond 3/4 of the machine's (as ``video`` does).
"""

from __future__ import annotations

import math
import tracemalloc
from pathlib import Path

import cv2
import numpy as np
import pytest

from panomap.calibrate.circles import Circle, ImageCircles
from panomap.calibrate.lines.arcs import EdgeArc, find_arcs, working_factor
from panomap.calibrate.lines.budget import check_line_search_memory, line_search_memory
from panomap.calibrate.lines.fit import fit_lines
from panomap.errors import PanomapError
from test_line_fit import _scene

from helpers import assert_one_line_error, run, true_circles

SIZE = 2400


def slanted_edges(size: int = SIZE) -> tuple[np.ndarray, list[tuple[np.ndarray, float]]]:
    """A grey image crossed by two straight edges (box-filtered steps of 110 grey levels) and the edges
    as (unit normal, offset): a pixel centre p is on an edge where normal . p = offset."""
    v, u = np.mgrid[0:size, 0:size].astype(np.float64)
    image = np.full((size, size), 20.0)
    edges = []
    for angle_deg, offset in ((30.0, 0.37 * size), (-70.0, 0.11 * size)):
        normal = np.array([math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))])
        image += 110.0 * np.clip(normal[0] * u + normal[1] * v - offset + 0.5, 0.0, 1.0)
        edges.append((normal, offset))
    grey = np.rint(image).astype(np.uint8)
    return np.repeat(grey[..., None], 3, axis=2), edges


def circles_of(size: int, radius: float) -> ImageCircles:
    centre = ((size - 1) / 2, (size - 1) / 2)
    return ImageCircles(centre, Circle(centre, radius, 0.0, 0, 0), None, None)


def distance_to_edges(points: np.ndarray, edges: list[tuple[np.ndarray, float]]) -> np.ndarray:
    return np.min([np.abs(points @ normal - offset) for normal, offset in edges], axis=0)


@pytest.mark.parametrize(("sigma", "k"), [(1.2, 1), (6.0, 2), (9.0, 4)])
def test_edges_stay_precise_at_the_working_resolution(sigma: float, k: int) -> None:
    # Found at the image's own resolution (k = 1): median 0.009 px, 0.017 at sigma 6; measured at k = 2:
    # 0.028 px, at k = 4: 0.054 px (95 %: 0.10), a small part of a line fit's residuals (0.3 px and more).
    assert working_factor(sigma) == k
    image, edges = slanted_edges()
    arcs = find_arcs(image, circles_of(SIZE, 1150.0), sigma=sigma)
    points = np.concatenate([arc.pixels for arc in arcs])
    assert sum(arc.length_px for arc in arcs) > 2600  # both edges, most of their length inside the circle
    distance = distance_to_edges(points, edges)
    assert np.median(distance) < 0.015 * k + 0.01 and np.percentile(distance, 95) < 0.03 * k + 0.01
    # The contrast is in grey levels per image px at any k: a step of 110 over a Gaussian of sigma px.
    assert np.median([arc.contrast for arc in arcs]) == pytest.approx(110 / math.sqrt(2 * math.pi) / sigma, rel=0.2)


def test_a_wide_circle_is_searched_in_a_fraction_of_the_memory() -> None:
    image, _ = slanted_edges()
    circles = circles_of(SIZE, 1150.0)
    tracemalloc.start()
    try:
        find_arcs(image, circles, sigma=9.0)  # k = 4
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    # At the image's own resolution: float grey, blur, two gradients, magnitude (20 bytes a pixel and more).
    assert peak < 4 * SIZE * SIZE, f"{peak / SIZE / SIZE:.1f} bytes a pixel"


def test_the_search_memory_is_estimated_from_the_sizes() -> None:
    assert line_search_memory([(16000, 16000)]) > 3e9
    assert check_line_search_memory([(2000, 2000)], memory_limit=8 << 30) == line_search_memory([(2000, 2000)])
    assert check_line_search_memory([(16000, 16000)] * 100, memory_limit=None) > 3e11
    with pytest.raises(PanomapError, match=r"needs about 4\.1 GB of memory, more than the 2\.1 GB"):
        check_line_search_memory([(16000, 16000)], memory_limit=2 << 30)


def test_fit_refuses_images_beyond_the_memory_before_reading_them(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    image = tmp_path / "omni.png"
    cv2.imwrite(str(image), np.full((3000, 3000, 3), 90, np.uint8))  # 131 kB on disk, 9 megapixels
    import panomap.cli.lines
    import panomap.video.unwarp

    monkeypatch.setattr(panomap.video.unwarp, "machine_memory", lambda: 1_400_000_000)  # 1.05 GB usable

    def no_read(*args: object, **kwargs: object) -> None:
        raise AssertionError("the images were read before the memory was checked")

    monkeypatch.setattr(panomap.cli.lines, "_read_all", no_read)
    out = tmp_path / "cam.npz"
    result = run("fit", "--image", image, "-o", out)
    assert_one_line_error(result, "needs about 1.1 GB of memory", "give fewer or smaller images")
    assert not out.exists()


# ----------------------------------------------------------------------------- what the line fit says


def curved_arcs(centre: tuple[float, float]) -> list[EdgeArc]:
    """24 half circles of 25 px about the image: edges that no camera makes straight (a pattern of short
    curved edges all over the frame, as a checkerboard tiled over a fisheye's frame gives)."""
    arcs = []
    for k in range(24):
        a = 2 * math.pi * k / 24
        r = 120 + 100 * (k % 3)
        t = np.linspace(0, math.pi, 120) + a
        x, y = centre[0] + r * math.cos(a) + 25 * np.cos(t), centre[1] + r * math.sin(a) + 25 * np.sin(t)
        arcs.append(EdgeArc(np.stack([x, y], 1), 0, 50.0))
    return arcs


def test_no_straight_arc_under_any_start_is_one_clear_error() -> None:
    centre = (399.5, 399.5)
    # Before: a ValueError from the objective (no line left to concatenate).
    with pytest.raises(PanomapError, match=r"only 0 of 24 edge arcs are straight under any starting camera"):
        fit_lines(curved_arcs(centre), circles_of(800, 390.0))


def test_a_camera_learned_from_lines_names_the_lines_not_landmarks() -> None:
    camera, lines, _ = _scene("equisolid", 0.0, seed=5)
    fit = fit_lines(lines, true_circles(camera))
    with pytest.raises(PanomapError) as caught:
        fit.camera_range(0.0, 100.0)  # an image circle found far inside the lines
    message = str(caught.value)
    assert "landmark" not in message
    assert "the straight lines' points (under the fitted camera, about its centre (" in message
    assert "outside the annulus 0.0..100.0 px between the cut-off disc and the image circle found" in message


def large_video(path: Path, frames: int, side: int = 4000, distinct: bool = False) -> Path:
    """A ``side`` x ``side`` H.264 video of ``frames`` black frames (a white square at another place in each
    where ``distinct``): tens of kB on disk, 16 megapixels a frame."""
    import av

    with av.open(str(path), "w") as container:
        stream = container.add_stream("libx264", rate=4)
        stream.width = stream.height = side
        stream.pix_fmt = "yuv420p"
        for k in range(frames):
            image = np.zeros((side, side, 3), np.uint8)
            if distinct:
                image[k * side // 8 : (k + 2) * side // 8, k * side // 8 : (k + 2) * side // 8] = 255
            for packet in stream.encode(av.VideoFrame.from_ndarray(image, format="bgr24")):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)
    return path


def test_fit_refuses_a_videos_frames_beyond_the_memory_before_decoding_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before: every frame asked for was decoded at full size, then the memory checked (64 frames of
    # 4000 x 4000: 3.42 GB peak).
    video = large_video(tmp_path / "big.mp4", 3)
    import panomap.video.sample
    import panomap.video.unwarp

    monkeypatch.setattr(panomap.video.unwarp, "machine_memory", lambda: 1_400_000_000)  # 1.05 GB usable

    def no_decode(*args: object, **kwargs: object) -> None:
        raise AssertionError("a frame was decoded before the memory was checked")

    monkeypatch.setattr(panomap.video.sample, "first_frame", no_decode)
    out = tmp_path / "cam.npz"
    result = run("fit", "--video", video, "--video-frames", 3, "-o", out)
    assert_one_line_error(result, "1 image(s) of 16,000,000 pixels", "needs about 1.2 GB of memory")
    assert not out.exists()


@pytest.mark.slow
def test_fit_takes_only_the_video_frames_the_memory_holds(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    video = large_video(tmp_path / "big.mp4", 4, distinct=True)
    import panomap.cli.lines
    import panomap.video.unwarp

    # 1 GB and 12 bytes a pixel a frame (calibrate/lines/budget.py): two frames fit in 1.45 GB, not three.
    monkeypatch.setattr(panomap.video.unwarp, "machine_memory", lambda: 1_450_000_000 * 4 // 3)
    given: list[int] = []

    def learn(images: list[np.ndarray], **kwargs: object) -> None:
        given.append(len(images))
        raise PanomapError("stopped here")

    monkeypatch.setattr(panomap.cli.lines, "learn_from_images", learn)
    result = run("fit", "--video", video, "--video-frames", 4, "-o", tmp_path / "cam.npz")
    assert result.exit_code == 1 and "stopped here" in result.stderr
    assert given == [2]
    assert "learning from 4 frames of 4000 x 4000 would need about 1.8 GB" in result.stderr
    assert "taking at most 2 frames showing distinct views" in result.stderr
    assert "2 frames taken, 2 showing a view" in result.stderr
