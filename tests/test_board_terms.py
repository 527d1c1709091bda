"""Image terms beyond the radial law (aspect, skew, decentering): kept where images left out say they help.

Ground truth: a simulated camera (:mod:`panomap.simulate.cameras`) whose pixels are moved by a known
aspect, skew and decentering written out here in closed form (OpenCV's p1, p2 on the offset scaled by R,
then ``u = aspect xt + skew yt``), independently of :mod:`panomap.camera.image_terms`; each board's
corners are that camera's projections of a grid with 0.3 px of noise per coordinate.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from panomap.calibrate.boards.detect import Board
from panomap.calibrate.boards.fit import camera_lift, camera_project, fit_boards
from panomap.calibrate.boards.terms import image_folds
from panomap.calibrate.lines.fit import LineFitOptions
from panomap.camera.image_terms import TERM_KINDS, ImageTerms
from panomap.errors import PanomapError
from test_board_fit import board_corners, level

from helpers import true_circles


class MovedCamera:
    """A simulated camera whose pixels are moved by aspect, skew and decentering (module docstring)."""

    def __init__(self, camera, aspect: float, skew: float, p1: float, p2: float) -> None:
        self.camera = camera
        self.elevation_range = camera.elevation_range
        self.terms = (aspect, skew, p1, p2)
        self.radius = camera.outer_radius

    def move(self, pixels: np.ndarray) -> np.ndarray:
        aspect, skew, p1, p2 = self.terms
        u0, v0 = self.camera.centre
        x, y = (pixels[:, 0] - u0) / self.radius, (pixels[:, 1] - v0) / self.radius
        r2 = x * x + y * y
        xt = x + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        yt = y + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        return np.stack([u0 + self.radius * (aspect * xt + skew * yt), v0 + self.radius * yt], axis=1)

    def project(self, points: np.ndarray) -> np.ndarray:
        return self.move(self.camera.project(points))


def moved_boards(camera: MovedCamera, count: int, seed: int, noise_px: float = 0.3) -> list[Board]:
    rng = np.random.default_rng(seed)
    boards = []
    for k in range(count):
        pixels, grid = board_corners(camera, rng, k)
        boards.append(Board(k, pixels + rng.normal(0.0, noise_px, pixels.shape), grid))
    return boards


def looking_down_rays(elevation_range: tuple[float, float], rings: int, azimuths: int) -> np.ndarray:
    """Unit rays (rings * azimuths, 3) in the world of a camera looking down: ``rings`` elevations 0.05 rad inside
    ``elevation_range`` (rad), ``azimuths`` round each."""
    low, high = elevation_range
    alpha = np.linspace(math.pi / 2 + low + 0.05, math.pi / 2 + high - 0.05, rings)
    phi = np.linspace(0.0, 2 * math.pi, azimuths, endpoint=False)
    a, p = (x.ravel() for x in np.meshgrid(alpha, phi))
    return np.stack([np.sin(a) * np.cos(p), np.sin(a) * np.sin(p), -np.cos(a)], axis=1)


def ray_errors_px(fit, camera: MovedCamera) -> np.ndarray:
    """Distances (px) between the true pixels of rays across the image and where the learned camera puts them
    (after the rotation or reflection of the rays that best aligns the two: what boards cannot know)."""
    rays = looking_down_rays(camera.elevation_range, 15, 48)
    truth = camera.project(rays)
    learned = camera_lift(fit)(truth)
    left, _, right = np.linalg.svd(learned.T @ rays)
    return np.asarray(np.hypot(*(camera_project(fit)(rays @ (left @ right).T) - truth).T))


def test_the_terms_map_offsets_as_written_and_undo_them() -> None:
    """apply() against the closed form above, undo() its inverse to 1e-9 px across a 900 px image."""
    camera = MovedCamera(level("equidistant"), 1.01, 0.006, 0.002, -0.0015)
    terms = ImageTerms(("aspect", "skew", "decentering"), (1.01, 0.006, 0.002, -0.0015), camera.radius)
    rng = np.random.default_rng(1)
    pixels = rng.uniform(0.0, 960.0, (500, 2))
    centre = np.asarray(camera.camera.centre)
    np.testing.assert_allclose(terms.apply(pixels - centre) + centre, camera.move(pixels), atol=1e-9)
    np.testing.assert_allclose(terms.undo(terms.apply(pixels - centre)), pixels - centre, atol=1e-9)
    # the field (thin prism): x moved by R (s1 rn^2 + s2 rn^4), y by R (s3 rn^2 + s4 rn^4)
    field = ImageTerms(("field",), (0.004, -0.003, 0.002, 0.001), camera.radius)
    offsets = pixels - centre
    rn2 = np.sum(offsets**2, axis=1) / camera.radius**2
    expected = offsets + camera.radius * np.stack([0.004 * rn2 - 0.003 * rn2**2, 0.002 * rn2 + 0.001 * rn2**2], axis=1)
    np.testing.assert_allclose(field.apply(offsets), expected, atol=1e-9)
    np.testing.assert_allclose(field.undo(field.apply(offsets)), offsets, atol=1e-9)
    assert ImageTerms.from_dict(terms.to_dict()) == terms
    with pytest.raises(PanomapError, match="beyond"):
        ImageTerms.from_dict({"kept": ["aspect"], "values": [1.5], "radius_px": 400.0})


def test_aspect_and_skew_are_kept_and_recovered() -> None:
    """Pixels 1% wider than tall and skewed 0.006 (a fisheye, 8 images): both kept, each within 0.0015 of the
    truth; the rays 3 times closer (p90) than the rotationally symmetric fit's.

    Measured (seed 3): aspect 1.0096, skew 0.0055; held-out RMS 0.531 px without terms, 0.413 with them
    (the corners' noise: 0.42); ray error p90 0.31 px with them, 1.55 px without.
    """
    camera = MovedCamera(level("equidistant"), 1.01, 0.006, 0.0, 0.0)
    boards = moved_boards(camera, 8, seed=3)
    fit = fit_boards(boards, true_circles(camera.camera))
    choice = fit.report.terms
    assert choice is not None and choice.kept == ("aspect", "skew")
    assert fit.model.terms is not None
    values = fit.model.terms.named()
    assert values["aspect"] == pytest.approx(1.01, abs=0.0015)
    assert values["skew"] == pytest.approx(0.006, abs=0.0015)
    plain = fit_boards(boards, true_circles(camera.camera), LineFitOptions(terms="none"))
    assert plain.model.terms is None and plain.report.terms is not None and plain.report.terms.kept == ()
    with_terms, without = np.percentile(ray_errors_px(fit, camera), 90), np.percentile(ray_errors_px(plain, camera), 90)
    assert with_terms < 0.6 and with_terms < without / 3
    sentence = next(s for s in fit.report.sentences() if s.startswith("image terms beyond the radial law"))
    assert sentence.startswith("image terms beyond the radial law: aspect 1.01") and ", skew 0.00" in sentence


def test_decentering_is_kept_and_recovered() -> None:
    """A lens off the sensor's axis (p1 0.004, p2 -0.003: up to 4 px at the image circle): decentering kept
    alone, p1 and p2 within 0.0015 of the truth.

    Measured (seed 5): p1 0.0049, p2 -0.0031; held-out RMS 0.468 px without, 0.407 with it.
    """
    camera = MovedCamera(level("equidistant"), 1.0, 0.0, 0.004, -0.003)
    fit = fit_boards(moved_boards(camera, 8, seed=5), true_circles(camera.camera))
    assert fit.report.terms is not None and fit.report.terms.kept == ("decentering",)
    assert fit.model.terms is not None
    values = fit.model.terms.named()
    assert values["p1"] == pytest.approx(0.004, abs=0.0015)
    assert values["p2"] == pytest.approx(-0.003, abs=0.0015)


@pytest.mark.parametrize(("name", "count", "seed"), [("equidistant", 8, 1), ("hyperbolic", 10, 4)])
def test_a_rotationally_symmetric_camera_keeps_no_term(name: str, count: int, seed: int) -> None:
    """No term where there is none: each lowers the corners fitted and predicts the images left out no better.

    Measured: held-out RMS 0.416 px without terms, 0.425, 0.417, 0.421 with aspect, skew, decentering
    (equidistant, seed 1); 0.4246, 0.4251, 0.4247, 0.4253 (hyperbolic, seed 4).
    """
    camera = MovedCamera(level(name), 1.0, 0.0, 0.0, 0.0)
    fit = fit_boards(moved_boards(camera, count, seed=seed), true_circles(camera.camera))
    assert fit.model.terms is None
    choice = fit.report.terms
    assert choice is not None and choice.kept == () and choice.folds == 5
    assert [names for names, _ in choice.tried][:4] == [(), ("aspect",), ("skew",), ("decentering",)]
    assert "better by more than its standard error" in choice.reason


def test_two_images_are_too_few_to_leave_one_out() -> None:
    camera = MovedCamera(level("equidistant"), 1.01, 0.006, 0.0, 0.0)
    boards = moved_boards(camera, 4, seed=3)
    boards = [Board(k // 2, b.pixels, b.grid) for k, b in enumerate(boards)]  # two boards per image
    assert image_folds(boards) == [[0, 1], [2, 3]]
    fit = fit_boards(boards, true_circles(camera.camera))
    assert fit.model.terms is None
    assert fit.report.terms is not None and "at least 3 are needed" in fit.report.terms.reason


def test_the_fits_jacobian_with_terms_is_the_derivative_of_its_residuals() -> None:
    """As test_board_fit's, with aspect, skew, decentering and the field freed: the terms' columns and the chain through
    them (equal to 1e-6 of the largest derivative: both are differences of smooth functions, steps 1e-6)."""
    from scipy.optimize._numdiff import approx_derivative

    from panomap.calibrate.boards.fit import _jacobian_blocks, _residuals
    from panomap.calibrate.boards.terms import TermLayout

    grid = np.stack(np.meshgrid(np.arange(5), np.arange(4)), axis=-1).reshape(-1, 2)
    boards = [Board(k, np.zeros((len(grid), 2)), grid) for k in range(3)]
    observed = np.random.default_rng(54).uniform(100.0, 900.0, (3 * len(grid), 2))
    layout = TermLayout(("aspect", "skew", "decentering", "field"), 450.0)
    poses = np.concatenate([[0.3, 0.2, 0.1, -3.0 + k, 2.0, 5.0 + k] for k in range(3)])
    x = np.concatenate([[512.0, 384.0, 300.0, 0.8], [1.02, 0.01, 0.003, -0.002, 0.004, -0.003, 0.002, 0.001], poses])
    closed = _jacobian_blocks(x, "unified", "down", boards, observed, layout).dense()
    numeric = approx_derivative(_residuals, x, method="3-point", args=("unified", "down", boards, observed, layout))
    assert np.abs(closed - numeric).max() < 1e-6 * np.abs(numeric).max()


@pytest.mark.parametrize("kept", [("decentering",), ("field",), ("smooth",), ("aspect", "decentering")])
def test_the_jacobian_at_the_terms_identity_is_the_derivative_of_its_residuals(kept: tuple[str, ...]) -> None:
    """Each kind of term freed at its identity (zeros: where every fold's fit starts), where the map and its
    derivatives leave out the groups whose values are all zero: the columns of the terms and the chain through them
    are the residuals' differences (to 1e-6 of the largest derivative), and the residuals those of no terms."""
    from scipy.optimize._numdiff import approx_derivative

    from panomap.calibrate.boards.fit import _jacobian_blocks, _residuals
    from panomap.calibrate.boards.terms import TermLayout

    grid = np.stack(np.meshgrid(np.arange(5), np.arange(4)), axis=-1).reshape(-1, 2)
    boards = [Board(k, np.zeros((len(grid), 2)), grid) for k in range(3)]
    observed = np.random.default_rng(55).uniform(100.0, 900.0, (3 * len(grid), 2))
    layout = TermLayout(kept, 450.0)
    identity = [v for name in kept for v in TERM_KINDS[name].identity]
    poses = np.concatenate([[0.3, 0.2, 0.1, -3.0 + k, 2.0, 5.0 + k] for k in range(3)])
    camera = np.array([512.0, 384.0, 300.0, 0.8])
    x = np.concatenate([camera, identity, poses])
    closed = _jacobian_blocks(x, "unified", "down", boards, observed, layout).dense()
    numeric = approx_derivative(_residuals, x, method="3-point", args=("unified", "down", boards, observed, layout))
    assert np.abs(closed - numeric).max() < 1e-6 * np.abs(numeric).max()
    plain = _residuals(np.concatenate([camera, poses]), "unified", "down", boards, observed)
    np.testing.assert_array_equal(_residuals(x, "unified", "down", boards, observed, layout), plain)


@pytest.mark.slow
def test_a_table_of_a_camera_with_terms_holds_them_and_unprojects_through_them(tmp_path) -> None:
    """The table's entries are the camera's pixels through its terms (float32: 1e-3 px); saved as format
    version 5 and loaded, the terms and their choice come back (``info``); unproject then sample gives each
    pixel back within 1e-3 px (the table's chords in azimuth and float32, as without terms); a table without
    terms stays version 3."""
    from panomap.calibrate.lines.table import create_line_table
    from panomap.table.file import load_table, save_table

    camera = MovedCamera(level("equidistant"), 1.01, 0.006, 0.0, 0.0)
    fit = fit_boards(moved_boards(camera, 8, seed=3), true_circles(camera.camera))
    table = create_line_table(
        fit, cutoff_radius=0.0, outer_radius=camera.camera.outer_radius - 5.0, image_size=camera.camera.image_size
    )
    theta, rho = np.meshgrid(table.azimuths(), table.elevations(), indexing="ij")
    np.testing.assert_allclose(table.entries, fit.model.pixels(theta, rho), atol=1e-3)
    assert table.metadata()["version"] == 5
    save_table(table, tmp_path / "t.npz")
    loaded = load_table(tmp_path / "t.npz")
    assert loaded.model.terms == fit.model.terms
    assert loaded.info["fit"]["lines"]["terms"]["kept"] == ["aspect", "skew"]
    rng = np.random.default_rng(2)
    angle, radius = rng.uniform(0, 2 * math.pi, 400), rng.uniform(20.0, camera.camera.outer_radius - 40.0, 400)
    pixels = np.asarray(camera.camera.centre) + np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)
    back = loaded.sample(*loaded.unproject(pixels))
    assert np.max(np.hypot(*(back - pixels).T)) < 1e-3
    plain = fit_boards(moved_boards(camera, 3, seed=3), true_circles(camera.camera), LineFitOptions(terms="none"))
    outer = camera.camera.outer_radius - 5.0
    assert create_line_table(plain, cutoff_radius=0.0, outer_radius=outer, image_size=None).metadata()["version"] == 3


def test_the_command_line_checks_terms_before_any_work(tmp_path) -> None:
    """``--terms``: unknown names and a landmark fit are usage errors (exit 2), in one line, before any fit."""
    from helpers import assert_one_line_error, run

    picture = tmp_path / "omni.png"
    picture.write_bytes(b"not read")
    result = run("fit", "-o", tmp_path / "t.npz", "--image", picture, "--terms", "aspect,tilt")
    assert_one_line_error(result, "unknown image term 'tilt'", "aspect, skew, decentering, field", exit_code=2)
    landmarks = tmp_path / "lm.csv"
    landmarks.write_text("u,v,X,Y,Z\n1,2,3,4,5\n")
    result = run("fit", landmarks, "-o", tmp_path / "t.npz", "--camera", 0, 0, 1, "--centre", 5, 5, "--terms", "none")
    assert_one_line_error(result, "--terms is for learning from lines (no LANDMARKS)", exit_code=2)
