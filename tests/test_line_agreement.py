"""How far apart two cameras lie, and whether the lines rule one out (panomap.calibrate.lines.agreement).

Ground truth: equidistant cameras, whose radius at an angle alpha from the axis is ``f alpha`` (px), written
here; two of them differ on a ring by the difference of their radii, which no rotation of the rays can undo
(a ring about the axis stays one). Cheap: no image.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

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
    # Issue 53: the first line says what is missing and what to do, short and without option names; the
    # figures (the band, its ring, the lines in folds) follow on the next line.
    first, figures = refusal.split("\n")
    assert len(first) <= 110 and "--" not in first and "px" not in first, first
    assert "differ by up to" in figures and "95% band" in figures and "lines in folds" in figures
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


# -- the stretch along the axis (panomap.calibrate.lines.stretch) -------------------------------------------------


def _line_rays(normal: np.ndarray, count: int = 50) -> np.ndarray:
    """Unit rays (count, 3) to points of a straight world line whose plane through the viewpoint has ``normal``."""
    normal = normal / np.linalg.norm(normal)
    a = np.cross(normal, [0.3, 0.5, 0.8])
    a /= np.linalg.norm(a)
    b = np.cross(normal, a)
    points = 2.0 * a + np.outer(np.linspace(-5.0, 5.0, count), b)  # a line 2 units away, in the plane
    return points / np.linalg.norm(points, axis=1, keepdims=True)


def test_a_camera_stretched_along_its_axis_keeps_every_line_straight() -> None:
    """Closed form: S = diag(1, 1, s) maps the plane with normal n onto the plane with normal S^-1 n."""
    from panomap.calibrate.lines.stretch import axial_stretch

    rng = np.random.default_rng(4)
    for s in (0.7, 0.95, 1.3):
        for normal in rng.normal(size=(20, 3)):
            rays = axial_stretch(_line_rays(normal), s)
            np.testing.assert_allclose(np.linalg.norm(rays, axis=1), 1.0, atol=1e-12)
            image_normal = normal / np.array([1.0, 1.0, s])
            assert np.max(np.abs(rays @ image_normal)) < 1e-12 * np.linalg.norm(image_normal)
            assert np.max(np.abs(rays - _line_rays(normal))) > 1e-3  # the rays did move


def test_a_stretch_keeps_right_angles_along_and_across_the_axis_and_turns_oblique_ones() -> None:
    from panomap.calibrate.lines.stretch import axial_stretch, obliqueness_deg

    s = 0.9
    level = axial_stretch(np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]), s)
    np.testing.assert_allclose(level @ level.T, np.eye(3), atol=1e-15)  # a level room stays square
    for a_deg in (3.0, 30.0, 45.0):
        a = math.radians(a_deg)
        pair = np.array([[math.sin(a), 0.0, math.cos(a)], [math.cos(a), 0.0, -math.sin(a)]])
        turned = axial_stretch(pair, s)
        cosine = math.sin(a) * math.cos(a) * (1 - s**2) / math.hypot(math.sin(a), s * math.cos(a))
        cosine /= math.hypot(math.cos(a), s * math.sin(a))
        assert float(turned[0] @ turned[1]) == pytest.approx(cosine, rel=1e-12)
        np.testing.assert_allclose(obliqueness_deg(pair), [a_deg, a_deg], atol=1e-9)
    along = np.array([[0.0, 0.0, -1.0], [0.0, 0.2, 1.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 1.0]])
    np.testing.assert_allclose(obliqueness_deg(along), [0.0, math.degrees(math.atan(0.2)), 0.0, 0.0, 45.0], atol=1e-9)


def test_a_picture_whose_lines_run_along_and_across_the_axis_is_told_why_it_cannot_pin_the_camera() -> None:
    """The refusal names the cause where every family is within 15 deg of the axis or of square to it, and says
    what picture would fix it; an oblique scene gets the general advice."""
    from dataclasses import replace

    alpha = ring_alphas(math.radians(90.0))
    band = pinned_band(equidistant(200.0), [equidistant(205.0)], [], "down", alpha)
    assert math.isnan(band.oblique_deg)
    aligned = replace(band, oblique_deg=2.5).refusal(np.zeros(alpha.size), lines=80)
    assert aligned is not None and "along and across the camera's axis (every direction within 2.5 deg)" in aligned
    assert "checkerboard held tilted" in aligned.split("\n")[0] and "give more pictures" not in aligned
    oblique = replace(band, oblique_deg=30.0).refusal(np.zeros(alpha.size), lines=80)
    assert oblique is not None and "give more pictures" in oblique and "along and across" not in oblique
    assert all(len(text.split("\n")[0]) <= 115 and "--" not in text for text in (aligned, oblique))
    directions = np.array([[0.02, 0.0, 1.0], [1.0, 0.03, 0.0]])
    measured = pinned_band(equidistant(200.0), [equidistant(205.0)], [], "down", alpha, directions)
    assert measured.oblique_deg == pytest.approx(math.degrees(math.atan(0.02)), rel=1e-9)  # the first


def test_an_alternative_that_sees_no_ray_at_a_ring_is_named_not_counted_in_px() -> None:
    from panomap.calibrate.lines.agreement import PinnedBand

    alpha_deg = np.array([15.0, 50.0, 85.0])
    band = PinnedBand(alpha_deg, np.zeros(3), np.array([0.5, math.inf, math.inf]), "the unified law", 30.0)
    refusal = band.refusal(np.zeros(3), lines=50)
    assert refusal is not None and "disagree at 50 deg from the axis, where one of them sees no ray" in refusal
    assert "inf" not in refusal and "nan" not in refusal
