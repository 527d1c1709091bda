"""The weighted, robust radial fit on the issue's scenarios (a few trials; bench/bench_fit.py runs 50)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from panomap.calibrate.landmarks.fit import fit_camera
from panomap.calibrate.landmarks.pairs import Landmarks
from panomap.calibrate.landmarks.table import create_table
from panomap.simulate.cameras import RadialCamera
from panomap.simulate.scenarios import (
    CAMERA_POSITION,
    IMAGE_SIZE,
    make_landmarks,
    scenario_cameras,
)
from panomap.simulate.scenarios import (
    test_points as probe_points,
)
from panomap.table.table import PanoMappingTable

from helpers import learn_table, spread_landmarks, worst_error

CAMERAS = scenario_cameras()


@pytest.mark.parametrize("name", list(CAMERAS))
def test_exact_landmarks_give_a_tenth_of_a_pixel(name: str) -> None:
    camera = CAMERAS[name]
    trial = make_landmarks(camera, 10, np.random.default_rng(1), pixel_sigma=0.0, world_sigma=0.0)
    # Measured 0.0007-0.0022 px (float32 table entries and bilinear sampling): the bar is about 3x the worst.
    assert worst_error(camera, trial, probe_points(camera)) <= 0.007


@pytest.mark.parametrize("name", ["equisolid", "hyperbolic-0.9"])
@pytest.mark.parametrize("seed", [7, 1007])
def test_a_landmark_50_px_off_is_flagged_and_the_fit_holds(name: str, seed: int) -> None:
    camera = CAMERAS[name]
    trial = make_landmarks(camera, 12, np.random.default_rng(seed), outlier_px=50.0)
    assert trial.outlier is not None
    fit = fit_camera(
        Landmarks(*trial.landmarks),
        CAMERA_POSITION,
        camera.centre,
        image_size=IMAGE_SIZE,
        annulus=(camera.cutoff_radius, camera.outer_radius),
    )
    assert fit.outliers == [trial.landmarks.names[trial.outlier]]
    assert fit.report().landmarks[trial.outlier].outlier is True
    # The noise floor is about 3 px (1 cm at 2 m); measured worst errors here are 2-3.3 px.
    assert worst_error(camera, trial, probe_points(camera)) < 4.0


def test_the_paper_model_keeps_every_landmark_and_is_unweighted() -> None:
    camera = CAMERAS["equidistant"]
    trial = make_landmarks(camera, 12, np.random.default_rng(3), outlier_px=50.0)
    fit = fit_camera(Landmarks(*trial.landmarks), CAMERA_POSITION, camera.centre, model="paper")
    assert fit.outliers == []
    # The paper's least squares written out, from the landmarks themselves (not the fit's elevations):
    # the 4th-degree polynomial through (rho, r) and the centre (-pi/2, 0).
    offsets = trial.landmarks.world - np.array(CAMERA_POSITION)
    rho = np.concatenate([[-np.pi / 2], np.arctan2(offsets[:, 2], np.hypot(offsets[:, 0], offsets[:, 1]))])
    r = np.concatenate([[0.0], np.hypot(*(trial.landmarks.pixels - camera.centre).T)])
    expected, *_ = np.linalg.lstsq(np.vander(rho, 5, increasing=True), r, rcond=None)
    np.testing.assert_allclose(fit.model.radial.coefficients, expected, rtol=1e-9, atol=1e-9)


def test_uncertainty_grows_beyond_the_landmarks_and_extrapolation_is_warned() -> None:
    camera = CAMERAS["parabolic"]
    low, high = camera.elevation_range
    trial = make_landmarks(camera, 10, np.random.default_rng(5))
    # Keep only landmarks below -30 deg: the table must extrapolate upwards.
    keep = (
        np.degrees(
            np.arctan2(*(lambda d: (d[:, 2], np.hypot(d[:, 0], d[:, 1])))(trial.landmarks.world - CAMERA_POSITION))
        )
        < -30
    )
    lower = Landmarks(
        trial.landmarks.pixels[keep],
        trial.landmarks.world[keep],
        tuple(n for n, k in zip(trial.landmarks.names, keep, strict=True) if k),
    )
    fit = fit_camera(lower, CAMERA_POSITION, camera.centre, image_size=IMAGE_SIZE)
    table = create_table(
        fit, image_size=IMAGE_SIZE, cutoff_radius=camera.cutoff_radius, outer_radius=camera.outer_radius
    )
    uncertainty = table.info["fit"]["uncertainty"]
    assert uncertainty["max_se_px"] > 2 * uncertainty["max_se_in_landmark_range_px"]
    assert any("above the highest landmark" in w for w in table.info["warnings"])
    assert high > low


def test_a_model_within_one_standard_error_with_fewer_parameters_is_chosen() -> None:
    """Random landmarks on the equidistant camera (the bench's trial 7): odd5 wins the leave-one-out
    score by chance; the one-standard-error rule keeps odd1, the camera's own law."""
    camera = CAMERAS["equidistant"]
    trial = make_landmarks(camera, 10, np.random.default_rng(7007), spread=False)
    fit = fit_camera(
        Landmarks(*trial.landmarks),
        CAMERA_POSITION,
        camera.centre,
        image_size=IMAGE_SIZE,
        annulus=(camera.cutoff_radius, camera.outer_radius),
    )
    assert min(fit.selection, key=lambda kind: fit.selection[kind]) == "odd5"
    assert fit.model.radial.kind == "odd1"
    points = probe_points(camera)
    # Measured: 0.62 px with odd1, 7.07 px with odd5 forced (the old 2% tolerance chose it: 7.07 px).
    assert worst_error(camera, trial, points) < 1.0
    assert worst_error(camera, trial, points, "odd5") > 5.0


def test_a_model_that_extrapolates_badly_does_not_drop_good_landmarks() -> None:
    """Level equisolid fisheye, 10 good landmarks (seed 21007). The robust choice scored models by the median
    held-out error and chose `unified`, whose error at the top landmark is 6.9 sigma (`fisheye`: 1.5); the top
    two landmarks were then dropped as outliers: 4.20 px. Scored by the trimmed RMS, all ten are kept."""
    camera = CAMERAS["equisolid"]
    trial = make_landmarks(camera, 10, np.random.default_rng(21007), spread=True)
    fit = fit_camera(
        Landmarks(*trial.landmarks),
        CAMERA_POSITION,
        camera.centre,
        image_size=IMAGE_SIZE,
        annulus=(camera.cutoff_radius, camera.outer_radius),
    )
    assert fit.outliers == []
    assert fit.model.radial.kind == "fisheye"
    # Measured: 1.29 px (4.20 px before, with two good landmarks dropped).
    assert worst_error(camera, trial, probe_points(camera)) < 2.0


def test_the_mirror_law_is_kept_against_a_curve_that_wins_by_less_than_two_standard_errors() -> None:
    """Level parabolic mirror, 10 landmarks (seed 3007): odd5's held-out score beats `unified`'s by more than
    one standard error, by chance (its pixel RMS is 7.46 against 4.73); the mirror law is kept within two."""
    camera = CAMERAS["parabolic"]
    trial = make_landmarks(camera, 10, np.random.default_rng(3007), spread=True)
    fit = fit_camera(
        Landmarks(*trial.landmarks),
        CAMERA_POSITION,
        camera.centre,
        image_size=IMAGE_SIZE,
        annulus=(camera.cutoff_radius, camera.outer_radius),
    )
    assert fit.model.radial.kind == "unified"
    points = probe_points(camera)
    # Measured: 2.79 px with unified; odd5, chosen before, 3.76 px.
    assert worst_error(camera, trial, points) < 3.1
    assert worst_error(camera, trial, points, "odd5") > 3.5


def probe_error(table: PanoMappingTable, camera: RadialCamera) -> float:
    """Worst pixel error (px) of ``table`` over the scenario's test points (inf for a missed one)."""
    world, truth = probe_points(camera)
    error = np.linalg.norm(table.project(world) - truth, axis=1)
    return float(np.max(np.where(np.isnan(error), np.inf, error)))


def learn(camera: RadialCamera, pixels: np.ndarray, world: np.ndarray, names: tuple[str, ...]) -> tuple:
    annulus = (camera.cutoff_radius, camera.outer_radius)
    return learn_table(camera, CAMERA_POSITION, Landmarks(pixels, world, names), IMAGE_SIZE, annulus=annulus)


@pytest.mark.parametrize("name", ["equisolid", "hyperbolic-0.9"])
@pytest.mark.parametrize("seed", [7, 11])
def test_two_landmarks_50_px_off_are_both_flagged_and_the_fit_holds(name: str, seed: int) -> None:
    camera = CAMERAS[name]
    pairs = make_landmarks(camera, 14, np.random.default_rng(seed)).landmarks  # 1 px and 1 cm of noise
    rng = np.random.default_rng(seed + 1)
    moved = rng.choice(14, 2, replace=False)
    pixels = pairs.pixels.copy()
    for k in moved:
        angle = rng.uniform(0, 2 * np.pi)
        pixels[k] += 50.0 * np.array([np.cos(angle), np.sin(angle)])
    table, fit = learn(camera, pixels, pairs.world, pairs.names)
    assert sorted(fit.outliers) == sorted(pairs.names[k] for k in moved)
    # As with one outlier: the noise floor is about 3 px; measured 0.71-1.53 px here.
    assert probe_error(table, camera) < 4.0


@pytest.mark.parametrize(
    ("name", "seed"),
    [
        ("equisolid", 7),
        ("equisolid", 21),
        ("hyperbolic-0.9", 7),
        # Found by this test: the world point of the highest landmark (L14, 2 deg below the top of
        # the range) 0.3 m too high goes unflagged and the table is 47.8 px off.
        pytest.param(
            "hyperbolic-0.9", 11, marks=pytest.mark.xfail(strict=True, reason="an end landmark's wrong world point")
        ),
    ],
)
def test_a_world_point_30_cm_off_is_flagged_and_the_fit_holds(name: str, seed: int) -> None:
    """A landmark whose world point was mis-measured (Z 0.3 m too high): flagged like a pixel outlier."""
    camera = CAMERAS[name]
    pairs = make_landmarks(camera, 14, np.random.default_rng(seed)).landmarks
    wrong = int(np.random.default_rng(seed + 1).choice(14, 3, replace=False)[2])
    world = pairs.world.copy()
    world[wrong, 2] += 0.3
    table, fit = learn(camera, pairs.pixels, world, pairs.names)
    assert fit.outliers == [pairs.names[wrong]]
    assert probe_error(table, camera) < 4.0  # measured 0.81-1.24 px


def test_an_up_looking_camera_is_detected_and_learned_exactly() -> None:
    """A fisheye looking up (alpha = pi/2 - rho), mirrored and rotated, from 12 exact landmarks: the
    fit finds the axis, s and phi0, and the table projects as the camera does."""
    camera = RadialCamera(
        name="up", law="equidistant", scale=200.0, image_size=(800, 800), centre=(401.3, 398.7),
        s=-1, phi0=0.7, axis="up", alpha_min=math.radians(5), alpha_max=math.radians(100),
    )  # fmt: skip
    landmarks = spread_landmarks(camera, CAMERA_POSITION, 12, np.random.default_rng(2))
    table, fit = learn_table(camera, CAMERA_POSITION, landmarks, camera.image_size)
    assert (table.model.radial.axis, table.model.s) == ("up", -1)
    assert table.model.phi0 == pytest.approx(0.7, abs=1e-6)
    rng = np.random.default_rng(0)
    low, high = fit.landmark_range
    theta, rho = rng.uniform(0, 2 * np.pi, 2000), rng.uniform(low, high, 2000)
    rays = 2.0 * np.stack([np.cos(rho) * np.cos(theta), np.cos(rho) * np.sin(theta), np.sin(rho)], axis=-1)
    error = np.linalg.norm(table.project(np.asarray(CAMERA_POSITION) + rays) - camera.project(rays), axis=1)
    # Measured 0.00037 px (float32 entries, bilinear sampling); the bar is about 5x.
    assert np.all(np.isfinite(error)) and error.max() < 0.002


@pytest.mark.parametrize("tilt", ["none", "fit"])
def test_a_landmark_pushed_50_px_beyond_the_rim_is_flagged_not_fatal(tilt: str) -> None:
    """The rim landmark of a level fisheye moved 50 px outward, beyond the image circle: under it no model
    covers the annulus, which used to stop the fit ("no radial model fits"). Found as an outlier without the
    annulus, it is dropped and the model chosen with the annulus on the rest; the camera stays level."""
    from panomap.simulate.scenarios import CAMERA_POSITION, IMAGE_SIZE, make_landmarks, scenario_cameras

    camera = scenario_cameras()["equisolid"]
    trial = make_landmarks(camera, 12, np.random.default_rng(3))
    pixels = trial.landmarks.pixels.copy()
    radius = np.hypot(pixels[:, 0] - camera.centre[0], pixels[:, 1] - camera.centre[1])
    rim = int(np.argmax(radius))
    pixels[rim] += 50 * (pixels[rim] - np.asarray(camera.centre)) / radius[rim]
    landmarks = Landmarks(pixels, trial.landmarks.world, trial.landmarks.names)
    fit = fit_camera(
        landmarks,
        CAMERA_POSITION,
        camera.centre,
        image_size=IMAGE_SIZE,
        annulus=(camera.cutoff_radius, camera.outer_radius),
        tilt_deg=tilt,
    )
    assert fit.outliers == [trial.landmarks.names[rim]]
    assert fit.model.rotation is None


@pytest.mark.parametrize("name", ["equisolid", "hyperbolic-0.6"])
def test_a_wrong_landmark_next_to_the_top_one_is_dropped_not_the_top_one(name: str) -> None:
    """The wrong landmark (50 px off) is the second highest: it drags the held-out prediction of the top one,
    whose error is then the larger. Dropping the top one left the wrong one in (hyperbolic-0.6: 20.4 px), or
    dropped both (equisolid: a wrong model, 11.4 px)."""
    camera = CAMERAS[name]
    trial = make_landmarks(camera, 12, np.random.default_rng(30007), spread=True, outlier_px=50.0)
    assert trial.outlier is not None
    world = np.asarray(trial.landmarks.world) - np.asarray(CAMERA_POSITION)
    elevations = np.arcsin(world[:, 2] / np.linalg.norm(world, axis=1))
    assert int(np.argsort(elevations)[-2]) == trial.outlier  # the set-up: second highest
    fit = fit_camera(
        Landmarks(*trial.landmarks),
        CAMERA_POSITION,
        camera.centre,
        image_size=IMAGE_SIZE,
        annulus=(camera.cutoff_radius, camera.outer_radius),
    )
    assert fit.outliers == [trial.landmarks.names[trial.outlier]]
    # Measured 2.30 px (equisolid) and 3.79 px (hyperbolic-0.6): the true model fitted without the wrong
    # landmark gets the same.
    assert worst_error(camera, trial, probe_points(camera)) < 4.5
