"""The image circle where the rim fades over 20-30 px (a fisheye's field stop far out of focus, an OCam fisheye's:
imgBack1 in ../shared), the circle cut at top and bottom, dark things of the scene at the rim, over-exposed after
the stop and a halo of scattered light on one side: renders with known truth (bench/bench_circles_unkind.py's
``faded``; panomap.simulate's ``halo`` and ``over_exposed``).

32 such renders: all found within 3 px, 29 within 1 px, the median 0.11 px, the worst 1.44 px (seed 16). Where a
dark thing lies at the rim, a ray's half level is the thing's edge: such rays are left out of the re-measure by the
width of their fall.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from panomap.calibrate.circles import find_image_circles
from panomap.calibrate.circles.evidence import _rim_points
from panomap.calibrate.circles.find import exposed
from panomap.calibrate.circles.sampling import to_grey
from panomap.calibrate.circles.thresholds import NARROW_REACH
from panomap.simulate import halo, over_exposed

from helpers import bench_module


def _inside(low: float, high: float, at: float, sigma: float) -> float:
    """The share of a Gaussian of ``sigma`` about ``at`` that lies between ``low`` and ``high``."""
    return 0.5 * (math.erf((high - at) / sigma / math.sqrt(2)) - math.erf((low - at) / sigma / math.sqrt(2)))


def test_the_halo_and_the_over_exposure_are_drawn_as_asked() -> None:
    """On a 101 x 101 picture, a square of 200 levels (pixels 40-60) on black: the halo adds ``fraction`` of the
    picture blurred, towards its angle (0: along +u), nothing on the far side; over-exposure by 1.5 clips 200 to
    255 and takes 100 to 150."""
    picture = np.zeros((101, 101), np.uint8)
    picture[40:61, 40:61] = 200
    lit = halo(picture, (50.0, 50.0), 0.2, 5.0, angle=0.0, spread=1.0)
    across = _inside(39.5, 60.5, 50.0, 5.0)  # the blur across the square's middle row, by erf
    assert lit[50, 62] == round(0.2 * 200 * _inside(39.5, 60.5, 62.0, 5.0) * across)  # 1.5 px past its edge: 15
    assert lit[50, 50] == round(200 + 0.2 * 200 * across**2)  # its middle: 237
    assert lit[50, 38] == 0 and lit[50, 45] == 200  # the far side (angle pi): no halo
    assert over_exposed(np.array([[200, 100]], np.uint8), 1.5).tolist() == [[255, 150]]


@pytest.mark.parametrize(("seed", "bound_px"), [(0, 0.3), (3, 0.8), (16, 2.0)])
def test_a_rim_fading_over_twenty_px(seed: int, bound_px: float) -> None:
    """Measured: 0.02, 0.39 and 1.44 px from the truth (seed 16, the worst of 32: a dark thing at the rim, its fall
    scattered outward by 2-9 px on most arcs; its half levels lie on the truth but fit no better, and are not
    taken), the radius within 1 px."""
    image, centre, radius = bench_module("bench_circles_unkind").faded(seed)
    found = find_image_circles(image)
    assert math.dist(found.centre, centre) < bound_px, (found.centre, centre)
    assert found.outer_radius == pytest.approx(radius, abs=1.0)


@pytest.mark.parametrize("seed", [8, 16])
def test_a_things_edge_at_a_fading_rim_is_no_half_level(seed: int) -> None:
    """Each ray's half-level crossing about the true circle (the re-measure a bright disc's rim gets once found):
    where a dark thing of the scene lies at the rim, the crossing was the thing's edge, 5-10 px inside the rim, on
    105 and 133 of the rays (of 364 and 430); that fall is 3-6 px wide against the rim's 14-18 px, and such rays
    are now left out. Measured: 1 and 2 rays more than 3 px inside, the 95th percentile 2.8 and 2.9 px (before:
    10.9 and 9.0 px)."""
    image, centre, radius = bench_module("bench_circles_unkind").faded(seed)
    grey = exposed(to_grey(image))
    points = _rim_points(grey, centre, radius, 1, NARROW_REACH, halfway=True)
    residual = np.hypot(points[:, 0] - centre[0], points[:, 1] - centre[1]) - radius
    assert len(points) >= 250
    assert np.sum(residual < -3.0) <= 0.02 * len(points)
    assert np.percentile(np.abs(residual), 95) < 4.0
