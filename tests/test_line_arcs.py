"""Edge arcs (panomap.calibrate.lines.arcs) against ground truth: rendered rooms whose straight lines and
curved things are known in closed form (panomap.simulate.line_scenes), seen through a 190 deg fisheye
on a 16:9 sensor (image circle cut by the frame) and a tilted hyperbolic mirror on 4:3, with
vignetting, sensor noise and JPEG; and exact anti-aliased edges of known sub-pixel position.

Distances are from each arc point to the true image of the line (the projections of the line's
points through the true camera, joined as a polyline with steps under 0.5 px), computed here.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from panomap.calibrate.circles import Circle, ImageCircles
from panomap.calibrate.lines.arcs import EdgeArc, find_arcs
from panomap.simulate.cameras import SimulatedCamera
from panomap.simulate.line_scenes import LineScene, line_camera, render_line_scene

SCALE = 0.5  # half-size sensors: 960 x 540 fisheye, 800 x 600 mirror


def circles_of(camera: SimulatedCamera) -> ImageCircles:
    """The true image circle and cut-off disc."""
    outer = Circle(centre=camera.centre, radius=float(camera.outer_radius), rms_px=0.0, inliers=0, rays=0)
    cut = float(camera.cutoff_radius)
    cutoff = Circle(centre=camera.centre, radius=cut, rms_px=0.0, inliers=0, rays=0) if cut > 0 else None
    return ImageCircles(centre=camera.centre, outer=outer, cutoff=cutoff, ellipse=None)


def distance_to_polyline(
    points: NDArray[np.float64], line: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Distance (n,) of points (n, 2) to a polyline (m, 2) (its steps under 0.5 px; a gap over 2 px is no
    step), and the vector (n, 2) from the nearest point of the polyline to each point."""
    if len(line) == 0:
        return np.full(len(points), np.inf), np.full((len(points), 2), np.nan)
    tree = cKDTree(line)
    _, k = tree.query(points)
    best = np.full(len(points), np.inf)
    vec = np.zeros((len(points), 2))
    for step in (-1, 1):
        b = np.clip(k + step, 0, len(line) - 1)
        pa, pb = line[k], line[b]
        d = pb - pa
        joined = (b != k) & (np.hypot(d[:, 0], d[:, 1]) < 2.0)
        t = np.clip(np.sum((points - pa) * d, axis=1) / np.maximum(np.sum(d * d, axis=1), 1e-12), 0.0, 1.0)
        t = np.where(joined, t, 0.0)
        foot = pa + t[:, None] * d
        off = points - foot
        dist = np.hypot(off[:, 0], off[:, 1])
        better = dist < best
        best = np.where(better, dist, best)
        vec = np.where(better[:, None], off, vec)
    return best, vec


def distances(points: NDArray[np.float64], lines: tuple[NDArray[np.float64], ...]) -> NDArray[np.float64]:
    """(n, L): distance of each point to each true line's image."""
    return np.stack([distance_to_polyline(points, line)[0] for line in lines], axis=1)


@pytest.fixture(scope="module", params=["fisheye190", "hyperbolic"])
def scene(request: pytest.FixtureRequest) -> tuple[LineScene, list[EdgeArc], NDArray[np.float64]]:
    """A rendered room, its arcs, and the distance (n, L) of every arc point (all arcs concatenated) to
    every true line."""
    camera = line_camera(request.param, SCALE, tilt_deg=2.5, toward_deg=40.0)
    rendered = render_line_scene(camera, seed=3, supersample=2)
    arcs = find_arcs(rendered.image, circles_of(camera))
    points = np.concatenate([a.pixels for a in arcs])
    return rendered, arcs, distances(points, rendered.line_pixels)


Scene = tuple[LineScene, list[EdgeArc], NDArray[np.float64]]


@pytest.mark.slow
def test_arcs_lie_on_the_true_lines_and_curves_without_bias(scene: Scene) -> None:
    # Measured (fisheye, mirror): 0.1% / 0.1% of points on neither; on-line p50 0.055 / 0.063 px, p90
    # 0.55 / 0.34 px (thin shelves and the skirting beside the floor edge pull the tail); mean error
    # vector under 0.004 px.
    sc, arcs, d = scene
    points = np.concatenate([a.pixels for a in arcs])
    near_line = d.min(axis=1)
    near_curve = distances(points, sc.curve_pixels).min(axis=1)
    assert len(arcs) >= 40
    assert np.mean((near_line >= 1.0) & (near_curve >= 1.0)) < 0.01
    on = near_line < 1.0
    assert on.mean() > 0.85
    assert np.median(near_line[on]) < 0.12
    assert np.percentile(near_line[on], 90) < 0.8
    nearest = np.argmin(d, axis=1)
    offsets = np.concatenate(
        [
            distance_to_polyline(points[on & (nearest == i)], line)[1]
            for i, line in enumerate(sc.line_pixels)
            if len(line)
        ]
    )
    assert np.hypot(*offsets.mean(axis=0)) < 0.02  # a 0.05 px shift of every point fails this


@pytest.mark.slow  # the rendered rooms: 4-6 s of set-up on two cores
def test_arcs_stay_inside_the_usable_annulus(scene: Scene) -> None:
    sc, arcs, _ = scene
    camera = sc.camera
    points = np.concatenate([a.pixels for a in arcs])
    r = np.hypot(points[:, 0] - camera.centre[0], points[:, 1] - camera.centre[1])
    w, h = camera.image_size
    assert r.min() > camera.cutoff_radius + 2.0
    assert r.max() < camera.outer_radius - 2.0
    assert points.min() > 2.0 and points[:, 0].max() < w - 3.0 and points[:, 1].max() < h - 3.0
    assert all(len(a.pixels) >= 8 and a.contrast > 0 for a in arcs)


@pytest.mark.slow  # the rendered rooms: 4-6 s of set-up on two cores
def test_arcs_cover_the_lines_in_few_pieces_split_at_corners(scene: Scene) -> None:
    # Measured: coverage of the long lines' visible images median 0.74 / 0.63 (the checker's tile lines
    # break at every crossing; the pieces near the image circle are short), median 1 piece per line; one
    # arc of 65 / 71 runs onto a second line (at a checker crossing in the mirror).
    sc, arcs, d = scene
    points = np.concatenate([a.pixels for a in arcs])
    bounds = np.cumsum([0] + [len(a.pixels) for a in arcs])
    main = np.array([np.bincount(np.argmin(d[a:b], axis=1)).argmax() for a, b in itertools.pairwise(bounds)])
    cover, pieces = [], []
    for i, line in enumerate(sc.line_pixels):
        if len(line) < 120:  # under 60 px of visible image
            continue
        cover.append(np.mean(distance_to_polyline(line, points)[0] < 1.0))
        pieces.append(int(np.sum(main == i)))
    assert len(cover) >= 30
    assert np.median(cover) > 0.5
    assert np.median(pieces) <= 2
    mixed = 0
    for a, b in itertools.pairwise(bounds):
        ranked = np.sort(d[a:b], axis=1)
        alone = (ranked[:, 0] < 0.7) & (ranked[:, 1] > 2.0)  # on one line, far from any other
        counts = np.bincount(np.argmin(d[a:b], axis=1)[alone], minlength=d.shape[1])
        mixed += int(np.sum(counts >= 8) > 1)
    assert mixed <= 0.03 * len(arcs)


@pytest.mark.slow  # the rendered rooms: 4-6 s of set-up on two cores
def test_curved_things_come_out_as_arcs_on_no_line(scene: Scene) -> None:
    # Measured: the rug, the ring and the painted disc each give arcs in both cameras; at most 25% of
    # such an arc's points lie within 1 px of a true line (where the rug covers tile lines).
    sc, arcs, _ = scene
    for name in ("rug", "ring outer", "disc"):
        curve = sc.curve_pixels[[c.name for c in sc.curves].index(name)]
        on_curve = [a for a in arcs if np.mean(distance_to_polyline(a.pixels, curve)[0] < 1.0) > 0.8]
        assert on_curve, name
        for a in on_curve:
            assert np.mean(distances(a.pixels, sc.line_pixels).min(axis=1) < 1.0) < 0.35, name


def test_a_dark_featureless_room_gives_almost_no_arcs() -> None:
    camera = line_camera("fisheye190", SCALE)
    dark = render_line_scene(camera, "dark", seed=2, supersample=1, noise=3.0)
    arcs = find_arcs(dark.image, circles_of(camera))
    assert sum(a.length_px for a in arcs) < 200.0


def exact_step(angle_deg: float, offset: float, size: int = 160) -> tuple[NDArray[np.uint8], NDArray[np.float64]]:
    """A straight step edge, 60 to 180 grey levels, each pixel's level its exact share (16 x 16 samples)
    of the bright half-plane ``(p - c) . n > offset``, c the image middle; and n."""
    n = np.array([math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))])
    sub = (np.arange(16) + 0.5) / 16 - 0.5
    v, u = np.mgrid[0:size, 0:size].astype(np.float64)
    share = np.zeros((size, size))
    for a in sub:
        for b in sub:
            share += (u + a - size / 2) * n[0] + (v + b - size / 2) * n[1] > offset
    return np.rint(60.0 + 120.0 * share / 256).astype(np.uint8), n


@pytest.mark.parametrize("angle_deg", [0.0, 10.0, 30.0, 45.0, 77.0, 200.0])
def test_a_straight_step_edge_is_found_to_a_few_hundredths_of_a_pixel(angle_deg: float) -> None:
    # Measured: worst 0.038 px (at 0 deg, offset 0.25: the parabola's pull towards pixel centres).
    size = 160
    middle = (size / 2, size / 2)
    # the image circle's centre 12 px off the edge: a lens keeps a few px about its centre out of the arcs
    off_edge = (
        middle[0] - 12.0 * math.cos(math.radians(angle_deg)),
        middle[1] - 12.0 * math.sin(math.radians(angle_deg)),
    )
    circles = ImageCircles(centre=off_edge, outer=Circle(off_edge, 70.0, 0.0, 0, 0), cutoff=None, ellipse=None)
    for offset in (0.0, 0.25, 0.5, 0.73):
        image, n = exact_step(angle_deg, offset, size)
        arcs = find_arcs(image, circles)
        assert len(arcs) == 1
        points = np.concatenate([a.pixels for a in arcs])
        error = (points - np.asarray(middle)) @ n - offset
        assert np.abs(error).max() < 0.06, (offset, np.abs(error).max())
        # the chord 12 px from the centre inside the circle less its margin (3 + 3 sigma = 6.6 px), less 2
        # points trimmed at each end: 120.5 px
        chord = 2.0 * math.sqrt((70.0 - 6.6) ** 2 - 12.0**2) - 4.0
        assert abs(arcs[0].length_px - chord) < 4.0  # the trimmed points are up to sqrt(2) px apart
        # a 120-level step smoothed by sigma = 1.2 px, its central difference at the edge: 120 erf(1/(sigma
        # sqrt 2)) / 2 = 35.7 grey levels / px (measured 34.0: the pixels' own box adds blur)
        expected = 120.0 * math.erf(1.0 / (1.2 * math.sqrt(2.0))) / 2.0
        assert abs(arcs[0].contrast / expected - 1.0) < 0.1


def small_checkerboard(square_px: float, angle_deg: float, size: int = 200) -> tuple[NDArray[np.uint8], list]:
    """A flat 8 x 6 checkerboard of ``square_px`` squares turned by ``angle_deg`` about the image middle, 40
    and 210 grey levels on 128, each pixel its exact share of 8 x 8 samples, blurred (sigma 0.8 px, a lens)
    with 2 grey levels of noise (seeded); and its inner rows and columns as segments ((2,), (2,)) px."""
    theta = math.radians(angle_deg)
    across, down = np.array([math.cos(theta), math.sin(theta)]), np.array([-math.sin(theta), math.cos(theta)])
    corner = np.array([size / 2, size / 2]) - 4 * square_px * across - 3 * square_px * down
    sub = (np.arange(8) + 0.5) / 8 - 0.5
    v, u = np.mgrid[0:size, 0:size].astype(np.float64)
    total = np.zeros((size, size))
    for a in sub:
        for b in sub:
            q = np.stack([u + a - corner[0], v + b - corner[1]], axis=-1)
            x, y = q @ across / square_px, q @ down / square_px
            inside = (x >= 0) & (x < 8) & (y >= 0) & (y < 6)
            dark = (np.floor(x) + np.floor(y)) % 2 == 0
            total += np.where(inside, np.where(dark, 40.0, 210.0), 128.0)
    import cv2

    image = cv2.GaussianBlur(total / 64.0, (0, 0), 0.8)
    image += np.random.default_rng(5).normal(0.0, 2.0, image.shape)
    segments = [
        (corner + k * square_px * across, corner + k * square_px * across + 6 * square_px * down) for k in range(1, 8)
    ]
    segments += [
        (corner + k * square_px * down, corner + k * square_px * down + 8 * square_px * across) for k in range(1, 6)
    ]
    return np.clip(np.rint(image), 0, 255).astype(np.uint8), segments


@pytest.mark.parametrize("square_px", [18.0])
def test_a_small_checkerboards_rows_and_columns_come_out_across_its_corners(square_px: float) -> None:
    # A board in a small omni-image (a 640 x 480 mirror camera) has squares of 10-20 px; an edge between
    # two crossings is its side less the crossing's pixels (removed as junctions) and the points trimmed at
    # both ends. With 3 points trimmed and 6 required, the sides of 18 px squares were nearly all dropped
    # (the arcs spanned 4% of the rows on average); with 2 and 4: 93% (91% the worst row), one or two arcs a
    # row. Squares under 15 px still come out in pieces (measured: 45% at 15 px, 7% at 13 px).
    image, segments = small_checkerboard(square_px, 17.0)
    centre = (100.0, 100.0)
    circles = ImageCircles(centre=centre, outer=Circle(centre, 150.0, 0.0, 0, 0), cutoff=None, ellipse=None)
    arcs = find_arcs(image, circles, min_length_px=24.0)
    for start, end in segments:
        length = float(np.hypot(*(end - start)))
        direction = (end - start) / length
        normal = np.array([-direction[1], direction[0]])
        # the arcs on this line: every point within 0.5 px of it
        on = [a.pixels for a in arcs if np.abs((a.pixels - start) @ normal).max() < 0.5]
        assert 1 <= len(on) <= 2, (square_px, len(on))  # whole, across the crossings: not one per square
        along = np.concatenate([np.clip((p - start) @ direction, 0.0, length) for p in on])
        # the arcs span the line but for the trimmed ends at the board's rim
        assert float(along.max() - along.min()) > length - 2.0 * square_px / 3.0, (square_px, along.min(), along.max())
