"""The quick map paths against the exact one: the perspective and floor views read a direction lookup,
the panoramas sample one row and one column of angles (``build_map`` against ``build_map(exact=True)``).

The exact path (per-pixel azimuth and elevation, sampled from the table) is tested against the simulated
cameras' closed-form projections in test_views_more.py and test_ground_truth.py; here the quick maps must
agree with it on every camera kind: within 0.01 px wherever both have a source, with the same pixels valid
apart from those within 0.01 px of the edge of the table's range or of the image.
"""

from __future__ import annotations

import dataclasses
import functools
import gc
import math

import cv2
import numpy as np
import pytest

from panomap.geometry import azimuth_elevation
from panomap.simulate import standard_cameras
from panomap.table.table import PanoMappingTable
from panomap.views import Band, CylinderPanorama, FloorView, GenericPanorama, PerspectiveView, View, build_map
from panomap.views.lookup import (
    _LOOKUPS,
    LOOKUP_ERROR_PX,
    direction_lookup,
    lookup_coordinates,
    lookup_error,
    make_lookup,
    read_lookup,
    row_sine_bounds,
    runs_across,
)

from helpers import learn_table, spread_landmarks

SIZE = (800, 760)
CAMERA_POSITION = (3.1, 2.4, 2.45)
# Off-middle, rotated and mirrored, as in test_views_more.py.
CAMERAS = standard_cameras(SIZE, centre=(412.3, 371.6), s=-1, phi0=0.9)
DEG = math.pi / 180
# Measured worst case 0.0021 px (the hyperbolic mirror, up to the range's top; 0.001 px on the
# bench's 1920 px mirror image): float32 rounding of the lookup's texels and of both paths' read
# positions, plus the lookup's interpolation. The bound is 0.01 px.
TOLERANCE_PX = 0.006
# Pixels whose validity may differ sit this close to an edge (px).
EDGE_PX = 0.01


@functools.cache
def learn(name: str) -> PanoMappingTable:
    """The table learned from 20 exact landmarks (fisheyes reach straight down, mirrors have a cut-off)."""
    camera = CAMERAS[name]
    options = {"distance_range": (1.5, 3.0)} if name == "spherical" else {}
    landmarks = spread_landmarks(camera, CAMERA_POSITION, 20, np.random.default_rng(0), **options)
    table, _ = learn_table(camera, CAMERA_POSITION, landmarks, SIZE)
    direction_lookup(table)  # made now: the first map of a table would otherwise take the exact way
    return table


def looking_up(table: PanoMappingTable) -> PanoMappingTable:
    """The same entries read as a camera looking up: elevations mirrored about the horizon."""
    rho_s, rho_e = table.elevation_range
    return dataclasses.replace(table, entries=table.entries[:, ::-1], elevation_range=(-rho_e, -rho_s))


def tables() -> dict[str, PanoMappingTable]:
    out = {name: learn(name) for name in CAMERAS}
    out["parabolic looking up"] = looking_up(learn("parabolic"))
    # A smaller image than the table's entries reach: the quick path must clip to it as the exact one does.
    parabolic = learn("parabolic")
    out["parabolic, entries off the image"] = dataclasses.replace(parabolic, image_size=(700, 640))
    for table in out.values():
        direction_lookup(table)  # made now: the first map of a table would otherwise take the exact way
    return out


PERSPECTIVES = {
    "pitch -35": PerspectiveView(30 * DEG, -35 * DEG, 0.0, 90 * DEG, (320, 180)),
    "across the azimuth seam": PerspectiveView(0.0, -10 * DEG, 0.0, 60 * DEG, (320, 180)),
    "straight down, fov 150, roll": PerspectiveView(20 * DEG, -90 * DEG, 10 * DEG, 150 * DEG, (320, 180)),
    "straight down, odd size": PerspectiveView(0.0, -90 * DEG, 0.0, 100 * DEG, (161, 91)),
    "up to the range's top": PerspectiveView(200 * DEG, 5 * DEG, -20 * DEG, 120 * DEG, (320, 180)),
    "fov 170": PerspectiveView(359.5 * DEG, -60 * DEG, 30 * DEG, 170 * DEG, (320, 180)),
    "straight up": PerspectiveView(0.0, 90 * DEG, 0.0, 90 * DEG, (81, 61)),
}


def floor_views(table: PanoMappingTable) -> dict[str, FloorView]:
    """Two floors below the camera; none for the table read as looking up (its model still looks down)."""
    x0, y0, z0 = table.camera_position
    if table.elevation_range[0] + table.elevation_range[1] > 0:
        return {}
    z = z0 - 2.45
    return {
        "floor around the camera": FloorView(z, (x0 - 6, x0 + 6), (y0 - 5, y0 + 4), (300, 200)),
        "floor off to one side": FloorView(z, (x0 + 0.5, x0 + 9), (y0 - 1, y0 + 1), (240, 60)),
    }


def edge_distance_px(table: PanoMappingTable, view: View, uv: np.ndarray) -> np.ndarray:
    """How far (px, an upper bound) pixels are from the edge of the table's range or of the image."""
    rays = view.rays() if isinstance(view, PerspectiveView) else view.points(table)
    _, rho = azimuth_elevation(rays)
    rho_s, rho_e = table.elevation_range
    # The table's steepest step per rad of elevation turns an angle from the range's ends into px.
    n = table.size[1]
    steps = np.linalg.norm(np.diff(table.entries.astype(np.float64), axis=1), axis=-1)
    px_per_rad = float(steps.max()) * n / (rho_e - rho_s)
    from_range = np.minimum(np.abs(rho - rho_s), np.abs(rho - rho_e)) * px_per_rad
    if table.image_size is None:
        return from_range
    width, height = table.image_size
    u, v = uv[..., 0], uv[..., 1]
    from_image = np.min(np.abs([u + 0.5, u - (width - 0.5), v + 0.5, v - (height - 0.5)]), axis=0)
    return np.minimum(from_range, np.nan_to_num(from_image, nan=np.inf))


def compare(table: PanoMappingTable, view: View) -> tuple[float, int]:
    """Largest difference (px) of the quick map from the exact one, and how many pixels' validity differs.

    Fails unless every pixel whose validity differs is within EDGE_PX of an edge.
    """
    quick, exact = build_map(table, view), build_map(table, view, exact=True)
    assert quick.shape == exact.shape and quick.dtype == np.float32
    has_quick, has_exact = np.isfinite(quick).all(axis=-1), np.isfinite(exact).all(axis=-1)
    assert np.array_equal(has_quick, np.isfinite(quick).any(axis=-1))  # u and v NaN together
    both = has_quick & has_exact
    difference = float(np.max(np.abs(quick - exact)[both])) if both.any() else 0.0
    differs = has_quick != has_exact
    if differs.any():
        uv = np.where(has_quick[..., None], quick, exact)
        assert np.all(edge_distance_px(table, view, uv)[differs] < EDGE_PX)
    return difference, int(np.count_nonzero(differs))


@pytest.mark.parametrize("name", [*list(CAMERAS), "parabolic looking up", "parabolic, entries off the image"])
def test_quick_maps_match_the_exact_ones(name: str) -> None:
    table = tables()[name]
    assert direction_lookup(table) is not None
    views: dict[str, View] = {**PERSPECTIVES, **floor_views(table)}
    valid_pixels = 0
    for label, view in views.items():
        difference, differs = compare(table, view)
        assert difference < TOLERANCE_PX, f"{label}: {difference:.5f} px"
        # Measured: none. At most a handful of pixels sit that close to an edge.
        assert differs <= 20, f"{label}: {differs} pixels"
        valid_pixels += int(np.isfinite(build_map(table, view)[..., 0]).sum())
    # The views see something: the comparisons are not of empty maps.
    assert valid_pixels > 100_000


def test_a_view_with_no_source_is_all_nan() -> None:
    # The table looks down (to 15 deg or so above the horizon): straight up has no source.
    table = learn("parabolic")
    assert np.isnan(build_map(table, PERSPECTIVES["straight up"])).all()


@pytest.mark.parametrize("sampling", ["bilinear", "nearest"])
def test_panorama_quick_maps_are_the_exact_ones(sampling: str) -> None:
    table = learn("hyperbolic")
    views = [
        GenericPanorama(),
        GenericPanorama((600, 150), 1.0),
        CylinderPanorama(2.0, Band(-2.4, 0.3), (500, 120), -3.0),
        # Rows above and below the table's range have no source.
        CylinderPanorama(0.5, Band(-20.0, 5.0), (300, 200), 7.0),
    ]
    for view in views:
        quick = build_map(table, view, sampling)
        assert np.array_equal(quick, build_map(table, view, sampling, exact=True), equal_nan=True)
        assert np.isfinite(quick).any()


def test_nearest_sampling_takes_the_exact_path() -> None:
    table = learn("equisolid")
    view = PERSPECTIVES["pitch -35"]
    assert np.array_equal(build_map(table, view, "nearest"), build_map(table, view, "nearest", exact=True))


def test_a_table_reaching_far_above_the_horizon_takes_the_exact_path() -> None:
    # 80 deg above the horizon would need a lookup of 4579 texels a side at the coarsest step (at most
    # 2048): none is made.
    table = learn("parabolic")
    wide = dataclasses.replace(table, elevation_range=(table.elevation_range[0], 80 * DEG))
    assert direction_lookup(wide) is None
    view = PERSPECTIVES["up to the range's top"]
    assert np.array_equal(build_map(wide, view), build_map(wide, view, exact=True), equal_nan=True)


def test_the_lookup_is_made_once_per_table_and_dropped_with_it() -> None:
    table = dataclasses.replace(learn("equidistant"))
    lookup = direction_lookup(table)
    assert direction_lookup(table) is lookup
    key = id(table)
    assert key in _LOOKUPS
    del table
    gc.collect()
    assert key not in _LOOKUPS


def test_the_views_bound_their_elevations_row_by_row() -> None:
    # The quick path checks the elevation only on rows whose bounds reach the edge of the table's range:
    # every row's bounds must hold its pixels' sines of elevation, computed here from the rays in float64.
    table = learn("parabolic")
    cases: list[tuple[View, tuple[np.ndarray, np.ndarray], np.ndarray]] = []
    for view in PERSPECTIVES.values():
        rays = view.rays()
        forward, right, down = view.axes()
        x, y = view._offsets()
        bounds = row_sine_bounds([forward[a] + y * down[a] for a in range(3)], right, x)
        cases.append((view, bounds, rays[..., 2] / np.linalg.norm(rays, axis=-1)))
    for floor in floor_views(table).values():
        points = floor.points(table)
        rows, cols = floor._rays(table)
        bounds = row_sine_bounds(rows, np.array([1.0, 0.0, 0.0]), cols[0])
        cases.append((floor, bounds, points[..., 2] / np.linalg.norm(points, axis=-1)))
    for view, (low, high), sines in cases:
        assert np.all(low <= sines.min(axis=1) + 1e-12) and np.all(sines.max(axis=1) <= high + 1e-12), view
        # Tight: within a pixel's worth of each row's extremes (the continuous line between pixels).
        assert np.all(sines.min(axis=1) - low < 0.01) and np.all(high - sines.max(axis=1) < 0.01), view
    # A row through the nadir reaches -1 exactly; its neighbours do not.
    down = PerspectiveView(0.0, -90 * DEG, 0.0, 90 * DEG, (101, 101))
    forward, right, below = down.axes()
    x, y = down._offsets()
    low, _ = row_sine_bounds([forward[a] + y * below[a] for a in range(3)], right, x)
    assert low[50] == pytest.approx(-1.0, abs=1e-12) and low[49] > -1.0 + 1e-6


def test_a_lone_map_takes_the_exact_way_and_the_second_reads_the_lookup() -> None:
    """Making the lookup costs about two exact maps: the first map of a table is exact, the next ones quick."""
    table = dataclasses.replace(learn("hyperbolic"))  # a new table: no lookup yet
    view = PERSPECTIVES["pitch -35"]
    first = build_map(table, view)
    assert id(table) not in _LOOKUPS
    assert np.array_equal(first, build_map(table, view, exact=True), equal_nan=True)
    second = build_map(table, view)
    assert _LOOKUPS.get(id(table)) is not None
    assert not np.array_equal(second, first, equal_nan=True)  # read from the lookup: rounding differs
    assert float(np.nanmax(np.abs(second - first))) < TOLERANCE_PX


def test_each_table_gets_the_coarsest_lookup_within_its_error_bound() -> None:
    # The hyperbolic mirror's steep rim needs a finer lookup than the others: the choice is measured.
    chosen = {}
    for name, table in tables().items():
        lookup = direction_lookup(table)
        assert lookup is not None
        assert lookup_error(lookup, table) <= LOOKUP_ERROR_PX, name
        chosen[name] = lookup.scale
    coarse = make_lookup(learn("hyperbolic"))
    assert coarse is not None and lookup_error(coarse, learn("hyperbolic")) > LOOKUP_ERROR_PX
    assert chosen["hyperbolic"] > chosen["parabolic"] == coarse.scale


def test_maps_do_not_depend_on_the_number_of_threads() -> None:
    """Strips are made at once in several threads: each pixel is computed the same way whatever the cut."""
    table = learn("equisolid")
    views = [*PERSPECTIVES.values(), *floor_views(table).values(), GenericPanorama((640, 160))]
    before = cv2.getNumThreads()
    try:
        cv2.setNumThreads(1)
        alone = [build_map(table, view) for view in views]
        cv2.setNumThreads(5)
        several = [build_map(table, view) for view in views]
    finally:
        cv2.setNumThreads(before)
    for view, one, many in zip(views, alone, several, strict=True):
        assert np.array_equal(one, many, equal_nan=True), view


def test_the_transposed_lookup_reads_the_same_map() -> None:
    """Views whose rows run along the lookup's columns read it transposed: the same bilinear values."""
    table = learn("hyperbolic")
    lookup = direction_lookup(table)
    assert lookup is not None
    chosen = []
    for view in PERSPECTIVES.values():
        forward, right, down = view.axes()
        x, y = view._offsets()
        rows, cols = [forward[a] + y * down[a] for a in range(3)], [x * right[a] for a in range(3)]
        lengths = np.sqrt(1.0 + np.square(x)[None, :] + np.square(y)[:, None]).astype(np.float32)
        middle = view.size[1] // 2
        chosen.append(runs_across(lookup, [values[middle] for values in rows], cols, lengths[middle]))
        texels = lookup_coordinates(lookup, rows, cols, lengths)
        plain, transposed = (read_lookup(lookup, *texels, across=across).copy() for across in (False, True))
        assert np.array_equal(np.isnan(plain), np.isnan(transposed))
        # Measured: 6e-5 px (the two reads round the weights in another order).
        difference = np.abs(plain - transposed)[np.isfinite(plain)]
        assert difference.size == 0 or difference.max() < 1e-3
    # Both ways are exercised, and the views along the lookup's rows read it as it is.
    assert 0 < sum(chosen) < len(chosen)
    straight_down = PerspectiveView(0.0, -90 * DEG, 0.0, 90 * DEG, (320, 180))
    forward, right, down = straight_down.axes()
    x, y = straight_down._offsets()
    lengths = np.sqrt(1.0 + np.square(x) + np.square(y[90])).astype(np.float32)
    # Yaw 0 straight down: the view's right is -y, its rows run along the lookup's columns.
    assert runs_across(lookup, list(forward + y[90] * down), [x * right[a] for a in range(3)], lengths)
