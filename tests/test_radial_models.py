"""Every registered radial model kind: its declaration, its file form, and its fit of its own family."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner
from numpy.polynomial import polynomial

from panomap.calibrate.landmarks.fit import fit_camera
from panomap.calibrate.landmarks.pairs import landmarks_to_csv
from panomap.camera.radial import RadialFunction, fit_radial
from panomap.camera.radial_models import AUTO_CANDIDATES, MIRROR_CANDIDATES, MODELS, RADIAL_KINDS
from panomap.cli.app import main
from panomap.errors import PanomapError
from panomap.simulate import standard_cameras

from helpers import spread_landmarks


def example_coefficients(kind: str, axis: str) -> tuple[float, ...]:
    """Coefficients of a plausible camera of each kind: r grows from 0 at the pole the centre sees."""
    if kind == "paper":
        # 180 a + 20 a^2 - 6 a^3 + a^4 in alpha, the angle from the pole (0 at the centre pair), as powers of rho.
        t = np.array([math.pi / 2, 1.0 if axis == "down" else -1.0])
        p = polynomial.polyadd(
            polynomial.polyadd(180 * t, 20 * polynomial.polypow(t, 2)),
            polynomial.polyadd(-6 * polynomial.polypow(t, 3), polynomial.polypow(t, 4)),
        )
        return tuple(float(c) for c in p)
    examples = {
        "odd1": (190.0,),
        "odd3": (190.0, -9.0),
        "odd5": (190.0, -9.0, 1.5),
        "poly2": (180.0, 12.0),
        "poly3": (180.0, 12.0, -4.0),
        "unified": (227.18431110340686, 0.8),
        "fisheye": (380.0, 0.5),  # equisolid: r = 2 * 190 sin(alpha / 2)
        "sphere": (900.0, 1.0),  # the lens one sphere radius below the apex: alpha reaches 80 deg at 26 deg
    }
    return examples[kind]


def test_the_registry_is_the_one_list_of_kinds() -> None:
    assert MODELS == tuple(RADIAL_KINDS) == (
        "paper", "odd1", "fisheye", "odd3", "odd5", "poly2", "poly3", "unified", "sphere",
    )  # fmt: skip
    # The spherical mirror's law is tried with its caustic (calibrate/landmarks/viewpoint), not as a single viewpoint.
    assert sorted(AUTO_CANDIDATES) == sorted(set(MODELS) - {"sphere"})
    # Automatic selection prefers fewer parameters first.
    counts = [RADIAL_KINDS[name].parameter_count for name in AUTO_CANDIDATES]
    assert counts == sorted(counts)
    # Among two-parameter kinds the designed fisheye projections first, then the polynomial and the mirrors' law
    # (an image with a cut-off disc puts the mirrors' law first: MIRROR_CANDIDATES).
    assert AUTO_CANDIDATES == ("odd1", "fisheye", "odd3", "unified", "poly2", "odd5", "poly3", "paper")
    assert MIRROR_CANDIDATES == ("odd1", "unified", "fisheye", "odd3", "poly2", "odd5", "poly3", "paper")
    for name, kind in RADIAL_KINDS.items():
        assert kind.name == name
        assert len(set(kind.parameters)) == kind.parameter_count
    paper = RADIAL_KINDS["paper"]
    assert paper.centre_given and not paper.weighted and paper.needed_elevations == 4
    assert all(k.weighted and not k.centre_given for n, k in RADIAL_KINDS.items() if n != "paper")


@pytest.mark.parametrize("axis", ["down", "up"])
@pytest.mark.parametrize("kind", MODELS)
def test_each_kind_round_trips_and_fits_exact_data_of_its_family(kind: str, axis: str) -> None:
    radial = RadialFunction(kind, example_coefficients(kind, axis), axis)
    assert RadialFunction.from_dict(radial.to_dict()) == radial
    assert radial.to_dict() == {"kind": kind, "coefficients": list(radial.coefficients), "axis": axis}
    # Elevations from 5 deg off the pole to 80 deg from it, where every example is finite and monotonic.
    alpha = np.radians(np.linspace(5.0, 80.0, 12))
    rho = alpha - math.pi / 2 if axis == "down" else math.pi / 2 - alpha
    r = radial(rho)
    assert np.all(np.isfinite(r)) and np.all(np.diff(r) > 0)
    assert float(radial(-math.pi / 2 if axis == "down" else math.pi / 2)) == pytest.approx(0.0, abs=1e-9)
    fitted = fit_radial(kind, rho, r, axis)
    assert fitted.kind == kind and fitted.axis == axis
    # Exact data: the residual is rounding (the unified model's xi is found to 1e-12 by a bounded search).
    np.testing.assert_allclose(fitted(rho), r, rtol=0, atol=1e-6)
    weighted = fit_radial(kind, rho, r, axis, np.linspace(0.5, 2.0, rho.size))
    np.testing.assert_allclose(weighted(rho), r, rtol=0, atol=1e-6)


@pytest.mark.parametrize("kind", MODELS)
def test_a_kind_refuses_too_few_elevations_and_a_wrong_coefficient_count(kind: str) -> None:
    needed = RADIAL_KINDS[kind].needed_elevations
    rho = np.radians(np.linspace(-80.0, -10.0, needed - 1)) if needed > 1 else np.array([])
    with pytest.raises(PanomapError, match=f"needs landmarks at {needed} or more distinct elevations"):
        fit_radial(kind, rho, 100 + rho, "down")
    count = RADIAL_KINDS[kind].parameter_count
    with pytest.raises(PanomapError, match=f"takes {count} coefficients, got {count + 1}"):
        RadialFunction(kind, (1.0,) * (count + 1))


def test_refining_the_centre_with_the_paper_model_is_refused_in_library_words() -> None:
    size = (640, 600)
    camera = standard_cameras(size, centre=(321.4, 298.2))["parabolic"]
    position = (3.0, 2.0, 2.5)
    landmarks = spread_landmarks(camera, position, 12, np.random.default_rng(5))
    with pytest.raises(PanomapError) as error:
        fit_camera(landmarks, position, camera.centre, model="paper", refine_centre=True)
    assert error.value.detail == (
        "the paper model takes the centre as given; refining the centre needs another model than 'paper'"
    )
    assert "--" not in error.value.detail


def test_the_command_line_names_its_flag_for_the_same_refusal(tmp_path: Path) -> None:
    camera = standard_cameras((640, 600), centre=(321.4, 298.2))["parabolic"]
    position = (3.0, 2.0, 2.5)
    (tmp_path / "lm.csv").write_text(landmarks_to_csv(spread_landmarks(camera, position, 12, np.random.default_rng(5))))
    arguments = [tmp_path / "lm.csv", "-o", tmp_path / "x.npz", "--camera", *position, "--centre", *camera.centre]
    result = CliRunner().invoke(main, ["fit", *map(str, arguments), "--model", "paper", "--refine-centre"])
    assert result.exit_code == 2 and not (tmp_path / "x.npz").exists()  # options that do not go together: usage
    assert "error: the paper model takes the centre as given; --refine-centre needs another model" in result.stderr


@pytest.mark.parametrize(
    ("k", "law"),
    [
        (1.0, lambda a: np.sin(a)),  # orthographic
        (0.5, lambda a: 2 * np.sin(a / 2)),  # equisolid
        (0.0, lambda a: a),  # equidistant
        (-0.5, lambda a: 2 * np.tan(a / 2)),  # stereographic
        (-1.0, lambda a: np.tan(a)),  # perspective
    ],
)
def test_the_fisheye_family_holds_the_designed_projections(k: float, law: Any) -> None:
    """Closed form: r = f * law(alpha) for each designed projection, and the fit finds its k from exact data."""
    alpha = np.radians(np.linspace(3.0, 85.0, 10))
    radial = RadialFunction("fisheye", (300.0, k), "down")
    np.testing.assert_allclose(radial(alpha - math.pi / 2), 300.0 * law(alpha), rtol=1e-12, atol=1e-9)
    fitted = fit_radial("fisheye", alpha - math.pi / 2, 300.0 * law(alpha), "down")
    assert fitted.coefficients == pytest.approx((300.0, k), abs=1e-6)
    # Beyond |k| alpha = 90 deg the radius would turn back (sine) or diverge (tangent): NaN.
    if k != 0:
        assert np.isnan(radial(np.radians(95.0) / abs(k) - math.pi / 2))


@pytest.mark.parametrize(("radius", "distance"), [(0.3, 0.3), (0.05, 0.15), (0.15, 0.3)])
def test_the_sphere_law_is_a_traced_spherical_mirror(radius: float, distance: float) -> None:
    """Fitted to rays traced through the simulator's pinhole over a sphere (the law of reflection off its
    surface, not the kind's formula), the sphere law recovers the lens' focal length and distance over radius
    and follows every ray to 1e-3 px; no law of a single-viewpoint camera follows it that closely."""
    base = standard_cameras((1200, 1200))["spherical"]
    grazing = math.asin(radius / (radius + distance))
    camera = base.with_mirror(radius, distance, 0.85 * grazing)
    r = np.linspace(camera.cutoff_radius, camera.outer_radius, 150)
    _, direction = camera.trace(np.stack([camera.centre[0] + r, np.full_like(r, camera.centre[1])], axis=1))
    rho = np.arctan2(direction[:, 2], np.hypot(direction[:, 0], direction[:, 1]))
    fitted = fit_radial("sphere", rho, r, "down")
    assert fitted.coefficients == pytest.approx((camera.focal_px, distance / radius), rel=1e-5)
    assert float(np.max(np.abs(fitted(rho) - r))) < 1e-3
    assert min(float(np.max(np.abs(fit_radial(kind, rho, r, "down")(rho) - r))) for kind in ("unified", "odd3")) > 0.1
