"""How far apart two cameras lie, and whether the lines rule one out (panomap.calibrate.lines.agreement).

Ground truth: equidistant cameras, whose radius at an angle alpha from the axis is ``f alpha`` (px), written
here; two of them differ on a ring by the difference of their radii, which no rotation of the rays can undo
(a ring about the axis stays one). Cheap: no image.
"""

from __future__ import annotations

import math

import numpy as np

from panomap.calibrate.lines.agreement import Camera, displacement_px, pinned_band, ring_alphas, ruled_out


def equidistant(f_px: float, centre: tuple[float, float] = (400.0, 300.0)) -> Camera:
    return Camera("odd1", np.array([*centre, f_px]), f"f {f_px}")


def test_a_camera_lies_nowhere_from_itself_and_a_scale_error_shows_as_its_radius_error() -> None:
    alpha = ring_alphas(math.radians(85.0))
    np.testing.assert_allclose(np.degrees(alpha[[0, -1]]), [15.0, 85.0])
    same = displacement_px(equidistant(200.0), equidistant(200.0), "down", alpha)
    assert np.all(same < 1e-6)
    stretched = displacement_px(equidistant(200.0), equidistant(201.0), "down", alpha)
    np.testing.assert_allclose(stretched, 1.0 * alpha, rtol=0.02)  # f alpha, 1 px per unit of f per radian


def test_a_shifted_centre_is_partly_a_rotation() -> None:
    """A centre 1 px off moves each pixel by 1 px; the best rotation of the rays takes back part of it near
    the axis, none of it where the ring's radius no longer grows like the angle (it cannot): at most 1 px."""
    alpha = ring_alphas(math.radians(90.0))
    moved = displacement_px(equidistant(200.0), equidistant(200.0, (401.0, 300.0)), "down", alpha)
    assert np.all(moved <= 1.0 + 1e-6) and moved.max() > 0.05


def test_the_band_adds_the_farthest_alternative_to_the_jackknife() -> None:
    alpha = ring_alphas(math.radians(90.0))
    chosen = equidistant(200.0)
    folds = [np.array([400.0, 300.0, 200.0 + d]) for d in (-0.1, 0.1, -0.1, 0.1, 0.0)]
    band = pinned_band(chosen, [equidistant(202.0), equidistant(199.0)], folds, "down", alpha)
    np.testing.assert_allclose(band.alternative_px, 2.0 * alpha, rtol=0.02)
    assert band.farthest == "f 202.0"
    jackknife = np.sqrt(4 / 5 * 4 * (0.1 * alpha) ** 2)
    np.testing.assert_allclose(band.jackknife_se_px, jackknife, rtol=0.05)
    se = band.se_px(np.zeros(alpha.size))
    np.testing.assert_allclose(se, jackknife + 2.0 * alpha / 1.96, rtol=0.05)
    refusal = band.refusal(np.zeros(alpha.size), lines=40)  # 2 px at 1 rad: too wide
    assert refusal is not None and refusal.startswith("the picture does not pin the camera")
    pooled = band.refusal(np.zeros(alpha.size), lines=40, pictures=2)
    assert pooled is not None and pooled.startswith("the 2 pictures do not pin the camera")
    tight = pinned_band(chosen, [], folds[:4], "down", alpha)
    assert tight.refusal(np.zeros(alpha.size), lines=40) is None


def test_a_camera_is_ruled_out_only_by_most_units_not_by_one() -> None:
    rng = np.random.default_rng(1)
    mine = rng.uniform(1.0, 2.0, 40)
    assert ruled_out(mine + rng.uniform(0.05, 0.2, 40), mine)  # worse on every line
    assert not ruled_out(mine + rng.normal(0.0, 0.1, 40), mine)  # as good
    one_bad = mine.copy()
    one_bad[3] += 50.0  # one pair of families not quite square
    assert not ruled_out(one_bad + rng.normal(0.0, 0.1, 40), mine)
    assert ruled_out(np.append(mine, np.inf), np.append(mine, 1.0))  # it cannot explain a unit at all
