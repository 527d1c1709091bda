"""The camera learned from straight lines (panomap.calibrate.lines.fit), against simulated cameras.

Ground truth: 3-D segments of a box room (its edges, floor tiles, door and shelf edges) projected
through the simulated cameras of :mod:`panomap.simulate.cameras`, with noise, a tilted mount, lines
cut in pieces and curved things (circles in the room) that must be set aside. The learned camera is
compared with the true one after the best orthogonal map of the rays (the azimuth origin and the
mirroring are not knowable from lines), written here with its own projection equations.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from panomap.calibrate.circles import Circle, ImageCircles
from panomap.calibrate.core.line_report import LineFitReport
from panomap.calibrate.lines.arcs import EdgeArc
from panomap.calibrate.lines.fit import LineFitOptions, fit_lines
from panomap.errors import PanomapError
from panomap.simulate.cameras import TiltedCamera, mount_rotation, standard_cameras

from helpers import pixel_errors, true_circles

ROOM = ((-2.6, 3.1), (-2.2, 2.4), (-1.3, 1.5))
TILT_DEG = 2.0


def room_segments() -> list[tuple[tuple[float, ...], tuple[float, ...]]]:
    (x0, x1), (y0, y1), (z0, z1) = ROOM
    segments: list[tuple[tuple[float, ...], tuple[float, ...]]] = [
        ((x, y, z0), (x, y, z1)) for x in (x0, x1) for y in (y0, y1)
    ]
    for z in (z0, z1):
        segments += [((x, y0, z), (x, y1, z)) for x in (x0, x1)] + [((x0, y, z), (x1, y, z)) for y in (y0, y1)]
    segments += [((t, y0, z0), (t, y1, z0)) for t in np.arange(-2.0, 2.5, 0.5)]
    segments += [((x0, t, z0), (x1, t, z0)) for t in np.arange(-2.0, 2.0, 0.5)]
    segments += [((x1, y, z0), (x1, y, 0.8)) for y in (-1.0, 0.5, 1.5)]
    for z in (-0.5, 0.0, 0.7):
        segments += [((x0, -1.5, z), (x0, 1.0, z)), ((-2.0, y1, z), (2.0, y1, z))]
    return segments


def _resampled(pixels: np.ndarray) -> np.ndarray:
    """Points 1 px apart along a projected curve."""
    along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pixels, axis=0).T))])
    steps = np.arange(0.0, along[-1], 1.0)
    return np.stack([np.interp(steps, along, pixels[:, 0]), np.interp(steps, along, pixels[:, 1])], axis=-1)


def line_arcs(camera, rng: np.random.Generator, noise_px: float) -> list[EdgeArc]:
    """Each visible stretch of each room segment as an arc; a third of the long ones in two pieces."""
    arcs = []
    for start, end in room_segments():
        t = np.linspace(0.0, 1.0, 4000)[:, None]
        pixels = camera.project(np.array(start) * (1 - t) + np.array(end) * t)
        seen = np.flatnonzero(np.all(np.isfinite(pixels), axis=1))
        for run in np.split(seen, np.flatnonzero(np.diff(seen) > 1) + 1):
            if run.size < 50:
                continue
            points = _resampled(pixels[run])
            if len(points) < 30:
                continue
            pieces = [points]
            if len(points) > 200 and rng.random() < 0.35:
                half = len(points) // 2
                pieces = [points[: half - 10], points[half + 10 :]]
            arcs += [EdgeArc(p + rng.normal(0.0, noise_px, p.shape), 0, 50.0) for p in pieces]
    return arcs


def curve_arcs(camera, rng: np.random.Generator, noise_px: float) -> list[EdgeArc]:
    """Half of each of three circles in the room (a rug, a table top, a plate): no lines."""
    arcs = []
    for (cx, cy), radius, z in (((0.8, 0.5), 0.6, -1.3), ((-1.0, -0.8), 0.4, -0.6), ((1.5, -1.0), 0.3, -1.3)):
        t = np.linspace(0.0, 2.0 * math.pi, 3000)
        world = np.stack([cx + radius * np.cos(t), cy + radius * np.sin(t), np.full_like(t, z)], axis=-1)
        pixels = camera.project(world)
        points = _resampled(pixels[np.all(np.isfinite(pixels), axis=1)])
        half = points[: len(points) // 2]
        arcs.append(EdgeArc(half + rng.normal(0.0, noise_px, half.shape), 0, 50.0))
    return arcs


def _scene(name: str, noise_px: float, seed: int, centre=None):
    camera = standard_cameras((960, 960), centre=centre)[name]
    tilted = TiltedCamera(camera, mount_rotation(math.radians(TILT_DEG), 0.5))
    rng = np.random.default_rng(seed)
    lines = line_arcs(tilted, rng, noise_px)
    curves = curve_arcs(tilted, rng, noise_px)
    return tilted, lines, curves


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "p90_px", "max_px"),
    [("equidistant", 0.25, 0.4), ("hyperbolic", 0.6, 0.8)],
)
def test_learned_camera_matches_the_true_one(name: str, p90_px: float, max_px: float) -> None:
    """A tilted fisheye and a mirror camera, 0.3 px edge noise, lines in pieces, three curved things.

    Measured (seed 3): fisheye p90 0.10 / max 0.14 px, mirror p90 0.26 / max 0.30 px; tilt within 0.03 deg.
    """
    camera, lines, curves = _scene(name, 0.3, seed=3)
    fit = fit_lines(lines + curves, true_circles(camera))
    errors = pixel_errors(fit.model, camera)
    assert np.percentile(errors, 90) < p90_px
    assert errors.max() < max_px
    rejected = {arc.arc for arc in fit.report.rejected}
    assert set(range(len(lines), len(lines) + len(curves))) <= rejected, "a curved thing was taken for a line"
    used = sum(len(line.arcs) for line in fit.report.lines)
    assert used >= 0.8 * len(lines)
    assert any(len(line.arcs) > 1 for line in fit.report.lines), "no line's pieces were merged"
    assert math.degrees(fit.model.tilt[0]) == pytest.approx(TILT_DEG, abs=0.15)


def test_noise_free_arcs_give_the_centre_exactly() -> None:
    """Without noise the centre is found to 0.01 px (a 0.05 px bias fails) and the rays to 0.005 px.

    Measured: centre 1e-6 px off, p90 3e-5 px, from a start 1.8 px away.
    """
    centre = (481.3, 477.6)
    camera, lines, _ = _scene("equisolid", 0.0, seed=5, centre=centre)
    start = ImageCircles((centre[0] + 1.5, centre[1] - 1.0), Circle(centre, camera.outer_radius, 0.1, 9, 9), None, None)
    fit = fit_lines(lines, start)
    assert math.dist(fit.model.centre, centre) < 0.01
    assert np.percentile(pixel_errors(fit.model, camera), 90) < 0.005


def test_too_few_lines_is_one_clear_error() -> None:
    camera, lines, _ = _scene("equidistant", 0.3, seed=1)
    with pytest.raises(PanomapError, match=r"only 5 edge arcs found \(at least 8 are needed\).*straight edges"):
        fit_lines(lines[:5], true_circles(camera))


@pytest.mark.slow
def test_azimuth_zero_and_handedness_are_the_callers() -> None:
    """The pixel given as azimuth 0 sees world azimuth 0; the handedness given is kept; the report round-trips."""
    camera, lines, _ = _scene("equidistant", 0.3, seed=2)
    pixel = (700.0, 400.0)
    fit = fit_lines(lines, true_circles(camera), LineFitOptions(s=1, azimuth_zero=pixel))
    assert fit.model.s == 1
    rho = np.radians(np.linspace(-89.0, 5.0, 4000))
    curve = fit.model.pixels(np.zeros_like(rho), rho)
    assert np.nanmin(np.hypot(curve[:, 0] - pixel[0], curve[:, 1] - pixel[1])) < 0.1
    assert LineFitReport.from_dict(fit.report.to_dict()) == fit.report


@pytest.fixture(scope="module")
def rendered_fisheye(tmp_path_factory: pytest.TempPathFactory):
    """A rendered room through a tilted 190 deg fisheye on a 16:9 sensor (noise, vignetting, JPEG), 0.8 scale
    (1536 x 864: at 0.4 scale the picture does not pin the camera, see
    ``test_a_picture_that_cannot_pin_the_camera_is_refused``)."""
    import cv2

    from panomap.simulate.line_scenes import line_camera, render_line_scene

    camera = line_camera("fisheye190", 0.8)
    scene = render_line_scene(camera, seed=2, supersample=2)
    path = tmp_path_factory.mktemp("lines") / "room.png"
    cv2.imwrite(str(path), scene.image)
    return camera, path


@pytest.mark.slow
def test_cli_refuses_a_level_rendered_room_that_cannot_pin_the_stretch(rendered_fisheye, tmp_path) -> None:
    """``panomap fit -o T --image IMG`` on a room under a fisheye tilted 2 deg: the fit lands on the true camera
    (p90 0.03 px), but the lines run along and across the axis, so the camera stretched along it keeps them
    straight and their right angles square (:mod:`panomap.calibrate.lines.stretch`): the picture cannot tell
    them apart and the command refuses in one line, the overlay of the lines found still written, no table.
    (Until issue 55 it was accepted, right by the law's assumption, not by what the picture shows.)

    Measured: the right angles do not reject s = 0.77-1.44; the band p90 55.6 / max 56.3 px.
    """
    from click.testing import CliRunner

    from panomap.cli.app import main

    _, image = rendered_fisheye
    table_path = tmp_path / "cam.npz"
    overlay = tmp_path / "seen.png"
    result = CliRunner().invoke(
        main,
        ["fit", "-o", str(table_path), "--image", str(image), "--camera-height", "1.3", "--overlay", str(overlay)],
    )
    assert result.exit_code == 1, result.output
    errors = [line for line in result.output.splitlines() if line.startswith("panomap: error")]
    assert len(errors) == 1 and "lines all along or across its axis" in errors[0], result.output
    assert not table_path.exists()
    import cv2

    drawn = cv2.imread(str(overlay))
    assert drawn is not None, "no overlay written"
    yellow = (drawn[..., 1] > 200) & (drawn[..., 2] > 200) & (drawn[..., 0] < 90)  # BGR
    assert yellow.sum() > 2000, "the edges found are not drawn"


def _rendered_room_arcs(scale: float, seed: int = 2):
    from panomap.calibrate.lines.arcs import find_arcs
    from panomap.calibrate.lines.frame_circles import line_circles
    from panomap.simulate.line_scenes import line_camera, render_line_scene

    camera = line_camera("fisheye190", scale)
    image = render_line_scene(camera, seed=seed, supersample=2).image
    circles = line_circles(image)
    return camera, image, find_arcs(image, circles), circles


@pytest.mark.slow
def test_a_picture_that_cannot_pin_the_camera_is_refused(tmp_path) -> None:
    """A wrong camera is not accepted: on a small render (768 x 432, 42 lines) a flexible law explains the lines
    and their right angles as well as the true law does, and lies 2-3 px from the true camera; the command
    refuses in one line rather than bet on the stiff law.

    Measured: odd5 max 2.6 px from the truth; the refusal's band up to 2.6-3.0 px.
    """
    import cv2
    from click.testing import CliRunner

    from panomap.cli.app import main

    camera, image, arcs, circles = _rendered_room_arcs(0.4)
    flexible = fit_lines(arcs, circles, LineFitOptions(model="odd5"))
    assert pixel_errors(flexible.model, camera, step=4).max() > 2.0  # what the picture cannot rule out
    path = tmp_path / "room.png"
    cv2.imwrite(str(path), image)
    table_path = tmp_path / "cam.npz"
    result = CliRunner().invoke(main, ["fit", "-o", str(table_path), "--image", str(path)])
    assert result.exit_code == 1, result.output
    errors = [line for line in result.output.splitlines() if line.startswith("panomap: error")]
    assert len(errors) == 1 and "does not pin the camera" in errors[0], result.output
    assert not table_path.exists()


@pytest.mark.slow
def test_a_scene_with_no_straight_lines_is_refused(tmp_path) -> None:
    """Trees, rocks, clouds: curved edges only (ellipses of every size and slant in a fisheye's circle). The
    command refuses in one line and writes no table."""
    import cv2
    from click.testing import CliRunner

    from panomap.cli.app import main

    rng = np.random.default_rng(5)
    image = np.full((480, 640, 3), 90, np.uint8)
    for _ in range(120):
        centre = (int(rng.integers(120, 520)), int(rng.integers(40, 440)))
        axes = (int(rng.integers(8, 90)), int(rng.integers(8, 90)))
        shade = tuple(int(x) for x in rng.integers(20, 235, 3))
        cv2.ellipse(image, centre, axes, float(rng.uniform(0, 180)), 0, 360, shade, -1, cv2.LINE_AA)
    v, u = np.mgrid[0:480, 0:640]
    image[np.hypot(u - 320, v - 240) > 225] = 0
    path = tmp_path / "trees.png"
    cv2.imwrite(str(path), image)
    table_path = tmp_path / "cam.npz"
    result = CliRunner().invoke(main, ["fit", "-o", str(table_path), "--image", str(path)])
    assert result.exit_code == 1, result.output
    assert "Traceback" not in result.output
    errors = [line for line in result.output.splitlines() if line.startswith("panomap: error")]
    assert len(errors) == 1, result.output
    assert not table_path.exists()


@pytest.mark.slow
def test_cli_dark_room_is_one_clear_line_and_no_table(tmp_path) -> None:
    import cv2
    from click.testing import CliRunner

    from panomap.cli.app import main
    from panomap.simulate.line_scenes import line_camera, render_line_scene

    scene = render_line_scene(line_camera("fisheye190", 0.3), "dark", seed=1, supersample=1)
    image = tmp_path / "dark.png"
    cv2.imwrite(str(image), scene.image)
    table_path = tmp_path / "cam.npz"
    result = CliRunner().invoke(main, ["fit", "-o", str(table_path), "--image", str(image)])
    assert result.exit_code == 1
    assert "Traceback" not in result.output
    errors = [line for line in result.output.splitlines() if line.startswith("panomap: error")]
    assert len(errors) == 1 and "found (at least 8 are needed)" in errors[0], result.output
    assert not table_path.exists()


@pytest.mark.parametrize("fan_deg", [150.0, 6.0])
def test_a_familys_direction_uncertainty_matches_its_scatter(fan_deg: float) -> None:
    """The direction of a family of 8 planes through the viewpoint (normals perpendicular to it, fanned over
    ``fan_deg``, each tipped by 0.1 deg of noise), and its covariance, against 3000 seeded draws: the
    predicted standard deviation of the direction towards each axis perpendicular to it within 15% of the
    drawn one. Planes that nearly coincide (a 6 deg fan) fix the direction 20x worse across them: the
    weight of a right angle between two families must follow that (objective.orthogonality_residuals).
    """
    from panomap.calibrate.lines.objective import direction_spread

    rng = np.random.default_rng(11)
    direction = np.array([0.3, -0.5, 0.81])
    direction /= np.linalg.norm(direction)
    e1 = np.cross(direction, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(direction, e1)
    fan = np.radians(np.linspace(-fan_deg / 2, fan_deg / 2, 8))
    clean = np.cos(fan)[:, None] * e1 + np.sin(fan)[:, None] * e2
    noise_rad = math.radians(0.1)
    drawn, predicted = [], []
    for _ in range(3000):
        normals = clean + rng.normal(0.0, noise_rad, clean.shape)
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        found, covariance = direction_spread(normals)
        found = found if found @ direction > 0 else -found
        drawn.append([found @ e1, found @ e2])
        predicted.append([e1 @ covariance @ e1, e2 @ covariance @ e2])
    spread = np.std(np.array(drawn), axis=0)
    expected = np.sqrt(np.mean(np.array(predicted), axis=0))
    assert np.allclose(expected, spread, rtol=0.15), (expected, spread)


@pytest.mark.slow
@pytest.mark.parametrize(("name", "p90_px", "max_px"), [("equidistant", 0.25, 0.4), ("hyperbolic", 0.6, 0.8)])
def test_with_no_rim_the_fit_starts_from_the_frame_or_the_cutoff_disc(name: str, p90_px: float, max_px: float) -> None:
    """An image that shows no rim (a mirror image overfilling the frame, a full-frame fisheye): the fit starts
    from the stand-in circles of frame_circles, the frame's middle 9 px from the true centre (the fisheye) or
    a cut-off disc found 1.8 px off it (the mirror), and the lines find the centre and the rays as with a rim.

    Measured (seed 3): fisheye p90 0.10 / max 0.14 px, mirror p90 0.26 / max 0.31 px; centres within 0.2 px.
    """
    from panomap.calibrate.lines.frame_circles import frame_circles

    true_centre = (486.0, 471.0)
    camera = standard_cameras((960, 960), centre=true_centre)[name]
    tilted = TiltedCamera(camera, mount_rotation(math.radians(TILT_DEG), 0.5))
    lines = line_arcs(tilted, np.random.default_rng(3), 0.3)
    cutoff = None if camera.cutoff_radius <= 0 else Circle((487.5, 470.0), float(camera.cutoff_radius), 0.3, 100, 100)
    circles = frame_circles((960, 960), (479.5, 479.5), cutoff)
    fit = fit_lines(lines, circles)
    errors = pixel_errors(fit.model, tilted)
    assert np.percentile(errors, 90) < p90_px
    assert errors.max() < max_px
    assert math.dist(fit.model.centre, true_centre) < 0.4


def test_an_image_with_no_rim_gets_stand_in_circles_through_the_frames_corner() -> None:
    from panomap.calibrate.lines.frame_circles import line_circles

    image = np.random.default_rng(2).integers(90, 160, (300, 400), dtype=np.uint8)  # texture, no rim
    circles = line_circles(image)
    assert circles.centre == pytest.approx((199.5, 149.5))
    assert circles.outer_radius == pytest.approx(math.hypot(200.0, 150.0))  # to the pixels' outer corner
    assert circles.cutoff is None
    assert circles.rim_in_frame == 0.0
