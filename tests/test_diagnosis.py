"""The fit report's diagnosis in words, on simulated cameras whose error is known (a centre off, a wrong model)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from panomap.calibrate.core.report import CENTRE_AS_FOUND
from panomap.calibrate.landmarks.diagnosis import diagnose, noise_ratio
from panomap.calibrate.landmarks.fit import fit_camera
from panomap.calibrate.landmarks.pairs import Landmarks
from panomap.calibrate.landmarks.pipeline import calibrate_camera
from panomap.cli.demo import pick_landmarks
from panomap.simulate import load_room, render, standard_cameras
from panomap.simulate.example import make_example

from helpers import spread_landmarks

SIZE = (960, 960)
POSITION = (3.0, 2.0, 2.5)
CAMERAS = standard_cameras(SIZE, centre=(481.2, 478.9), s=1, phi0=0.3)
NOISE = np.random.default_rng(11)


def noisy(camera_name: str, count: int = 16, sigma: float = 0.3) -> Landmarks:
    landmarks = spread_landmarks(CAMERAS[camera_name], POSITION, count, np.random.default_rng(4))
    return Landmarks(
        landmarks.pixels + NOISE.normal(0, sigma, landmarks.pixels.shape), landmarks.world, landmarks.names
    )


def test_a_clean_fit_has_nothing_to_say() -> None:
    camera = CAMERAS["hyperbolic"]
    assert diagnose(fit_camera(noisy("hyperbolic"), POSITION, camera.centre)) == []


def test_a_centre_6_px_off_shows_as_a_swing_in_azimuth_towards_the_offset() -> None:
    camera = CAMERAS["equidistant"]
    offset = np.array([6.0 * math.cos(0.8), 6.0 * math.sin(0.8)])  # image direction 0.8 rad
    # Level and at the given position: by default a small tilt or a shift of the camera, which move the image
    # much as a centre error does, take up part of the offset, and the pattern left is weaker.
    fit = fit_camera(
        noisy("equidistant"), POSITION, tuple(np.asarray(camera.centre) + offset), tilt_deg="none", camera_sigma=0
    )
    notes = diagnose(fit)
    assert len(notes) == 1 and "swing with azimuth" in notes[0] and "refine the centre" in notes[0]
    amplitude = float(notes[0].split("amplitude ")[1].split(" px")[0])
    towards = math.radians(float(notes[0].split("towards ")[1].split(" deg")[0]))
    # The radius measured about the wrong centre is short by offset . u: the residual swings with
    # the offset's size (part of it absorbed by phi0 and the model: measured 5.8 px) towards its
    # image direction, azimuth (0.8 - phi0)/s.
    assert 4.0 < amplitude < 7.0
    assert abs(math.remainder(towards - (0.8 - 0.3), 2 * math.pi)) < math.radians(10)
    # Refining the centre removes it.
    assert (
        diagnose(
            fit_camera(fit.landmarks, POSITION, fit.model.centre, refine_centre=True, tilt_deg="none", camera_sigma=0)
        )
        == []
    )


def test_a_model_that_cannot_follow_the_camera_shows_as_a_trend_in_elevation() -> None:
    camera = CAMERAS["hyperbolic"]
    fit = fit_camera(noisy("hyperbolic"), POSITION, camera.centre, model="odd1")
    notes = diagnose(fit)
    assert any("trend with elevation" in note and "(odd1)" in note for note in notes)


def test_a_landmark_measured_wrong_is_named() -> None:
    camera = CAMERAS["parabolic"]
    landmarks = noisy("parabolic")
    pixels = landmarks.pixels.copy()
    pixels[5] += (30.0, -40.0)
    fit = fit_camera(Landmarks(pixels, landmarks.world, landmarks.names), POSITION, camera.centre)
    notes = diagnose(fit)
    assert notes == [
        f"dropped as outliers: {landmarks.names[5]}: their world point or pixel is probably wrong; measure them again"
    ]


def test_landmarks_that_no_camera_explains_are_said_to_be_wrong_together() -> None:
    """Every other landmark's height 0.5 m off (measured from a table top, not the floor): the fit cannot put
    them where they are seen (RMS 18.4 px), and no pattern or single landmark is the cause: before, the
    diagnosis said nothing. The residuals' RMS against what the noise model expects of them: 0.78 median,
    1.67 at most over 288 noisy fits (bench_fit's cameras); here 7, over the bar of 4."""
    camera = CAMERAS["equidistant"]
    landmarks = noisy("equidistant")
    world = landmarks.world.copy()
    world[::2, 2] += 0.5
    fit = fit_camera(Landmarks(landmarks.pixels, world, landmarks.names), POSITION, camera.centre)
    notes = diagnose(fit)
    assert any("times what the landmarks' noise explains" in note and "units and axes" in note for note in notes)
    assert not any("noise explains" in note for note in diagnose(fit_camera(landmarks, POSITION, camera.centre)))


@pytest.mark.slow
def test_a_tilt_within_its_uncertainty_about_the_rim_is_not_said_to_be_one() -> None:
    """The learn page's screenshot session (docs/make_screenshots.py): a level mirror camera, 10 landmarks
    clicked 0.4 px off, one height 0.5 m off. The fit keeps the rim's centre with a tilt of 0.05 +- 0.16 deg
    (the level camera, the centre where the rim puts it): no note that it was "given a tilt"."""
    example = make_example((800, 800), count=10, supersample=2)
    clicked = example.pixels + np.random.default_rng(7).normal(0.0, 0.4, example.pixels.shape)
    world = example.world.copy()
    world[6, 2] += 0.5
    landmarks = Landmarks(clicked, world, tuple(example.names))
    result = calibrate_camera(landmarks, tuple(example.camera_position), omni=example.image)
    mount = result.fit.mount
    assert mount is not None and mount.chosen.endswith(CENTRE_AS_FOUND) and mount.tilt_se_deg is not None
    assert mount.tilt_deg < mount.tilt_se_deg  # measured: 0.05 +- 0.16 deg
    notes = diagnose(result.fit)
    assert not any("given a tilt" in note for note in notes), notes
    sentence = result.fit.report().centre_sentence()
    assert sentence is not None and sentence.endswith("the landmarks do not ask to move it"), sentence
    assert any(note.startswith("dropped as outliers: E_window_bottom_right") for note in notes), notes


@pytest.mark.slow
def test_landmarks_given_as_row_and_column_are_said_to_be_so() -> None:
    """The example camera on an 800 x 760 frame (its centre (397.7, 381.7), 23 px from its transpose) with
    every landmark's u and v swapped (all still inside the frame): a transposed camera fits them as well,
    the refinement takes the centre to the rim's centre transposed, and the diagnosis says what happened."""
    example = make_example((800, 760), count=12, supersample=1)
    swapped = Landmarks(example.pixels[:, ::-1].copy(), example.world, tuple(example.names))
    result = calibrate_camera(swapped, tuple(example.camera_position), omni=example.image)
    notes = diagnose(result.fit)
    assert any("look like (row, column)" in note for note in notes), notes
    plain = calibrate_camera(
        Landmarks(example.pixels, example.world, tuple(example.names)),
        tuple(example.camera_position),
        omni=example.image,
    )
    assert not any("row, column" in note for note in diagnose(plain.fit))


def test_landmarks_in_millimetres_with_the_camera_in_metres_are_said_to_be_wrong() -> None:
    """The demo's camera and landmarks, the world points typed in mm and the camera position in m: a table
    is made (RMS about 200 px), and the diagnosis must say that no camera explains them. One landmark, the
    room's corner at the world's origin, lies 4.6 "mm" from the camera, where 1.9 cm of world noise is a
    huge angle: averaged over the landmarks, its expected error (hundreds of px) hid every other's misfit."""
    room = load_room()
    camera = standard_cameras((1024, 1024), centre=(517.3, 503.8), s=-1, phi0=0.6)["hyperbolic"]
    position = np.asarray(room.camera)
    names, points = room.landmarks()
    landmarks = pick_landmarks(names, points, camera.project(points - position), position, 12)
    assert "corner_SW_floor" in landmarks.names
    in_mm = Landmarks(landmarks.pixels, landmarks.world * 1000, landmarks.names)
    result = calibrate_camera(in_mm, room.camera, omni=render(room, camera, supersample=1))
    assert result.fit.rms_px > 50
    assert noise_ratio(result.fit) > 20  # measured: 56
    assert any("times what the landmarks' noise explains" in note and "units" in note for note in diagnose(result.fit))


@pytest.mark.slow
def test_landmarks_of_a_cropped_copy_of_the_image_are_said_to_be_so() -> None:
    """The example's landmarks measured on a copy of the image cropped by 30 px at the left and 20 at the top:
    the refinement takes the centre 36 px from the rim's, which no real rim is off its axis (0.7-2.3 px)."""
    example = make_example((800, 760), count=12, supersample=1)
    cropped = Landmarks(example.pixels - (30.0, 20.0), example.world, tuple(example.names))
    result = calibrate_camera(cropped, tuple(example.camera_position), omni=example.image)
    assert result.fit.centre_shift_px > 30
    notes = diagnose(result.fit)
    assert any("further than a rim lies off its camera's axis" in note for note in notes), notes
    plain = calibrate_camera(
        Landmarks(example.pixels, example.world, tuple(example.names)),
        tuple(example.camera_position),
        omni=example.image,
    )
    assert not any("further than a rim" in note for note in diagnose(plain.fit))
