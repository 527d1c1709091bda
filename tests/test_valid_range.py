"""The table's elevation range grows from the landmarks' to the whole annulus, whatever the ends' values."""

from __future__ import annotations

import math

import pytest

from panomap.camera.radial import RadialFunction
from panomap.camera.valid_range import valid_elevation_range


@pytest.mark.parametrize(
    "high", [0.15707963267948963, math.radians(9.0), math.radians(8.99999999999), math.radians(7.3)]
)
def test_the_range_reaches_the_image_circle_when_a_landmark_end_sits_on_the_grid(high: float) -> None:
    """A unified (xi = 0.8) camera whose image circle is at alpha = 100 deg (rho = 10 deg).

    9 deg is a point of the internal 20001-step grid; a landmark 3e-17 rad below it once stopped
    the growth (two points 1e-17 rad apart, no rise between them), so the table ended at the
    landmark, 8.5 px short of the image circle.
    """
    gamma, xi = 227.18431110340686, 0.8
    radial = RadialFunction("unified", (gamma, xi), "down")
    outer = float(radial(math.radians(10.0)))
    low = -1.3439035240356336
    rho_s, rho_e = valid_elevation_range(radial, (low, high), 26.56, outer)
    assert float(radial(rho_e)) == pytest.approx(outer, abs=1e-6)
    assert rho_e == pytest.approx(math.radians(10.0), abs=1e-9)
    assert float(radial(rho_s)) == pytest.approx(26.56, abs=1e-6)
