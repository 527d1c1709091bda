"""Real omni-images from ../shared/data/real (skipped where that folder is absent)."""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from panomap.calibrate.circles import find_image_circles
from panomap.errors import PanomapError
from panomap.io.images import read_image

from helpers import bench_module

REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
pytestmark = [
    pytest.mark.real_data,
    pytest.mark.skipif(not REAL.is_dir(), reason=f"real data not found at {REAL} (../shared is not beside the repo)"),
]
OCAM_FOLDERS = [
    "ocam_kaidan_catadioptric",
    "ocam_vmr_catadioptric",
    "ocam_miniomni_catadioptric",
    "ocam_fisheye_imgback",
]
FOLDERS = [*OCAM_FOLDERS, "mei_paracatadioptric"]


def ocam_centre(folder: str) -> tuple[float, float]:
    model = json.loads((REAL / folder / "ocam_model.json").read_text())
    return model["yc_col_0based"], model["xc_row_0based"]


@pytest.mark.slow
@pytest.mark.parametrize("folder", OCAM_FOLDERS)
def test_a_centre_found_is_near_the_calibrations_or_it_is_an_error(folder: str) -> None:
    """Never a guess: every image gives a centre within a few px of the calibration's, or an error.

    The calibration estimates the optical axis, which can sit a few pixels off the rim's
    centre on a real mirror (measured worst: 0.9 px for kaidan, 2.7 px for vmr); the
    imgback fisheye's rim is soft and cut by the frame (7.0 px), miniomni's is a mirror's
    edge in a bright housing (10.3 px; docs/centre.md).
    """
    bound = {"ocam_fisheye_imgback": 14.0, "ocam_miniomni_catadioptric": 21.0}.get(folder, 4.0)
    reference = ocam_centre(folder)
    found = 0
    for path in sorted((REAL / folder / "images").iterdir()):
        try:
            circles = find_image_circles(read_image(path))
        except PanomapError as exc:
            assert "no image circle found" in str(exc)
            continue
        found += 1
        assert math.dist(circles.centre, reference) < bound, path.name
    if folder in ("ocam_kaidan_catadioptric", "ocam_vmr_catadioptric", "ocam_fisheye_imgback"):
        assert found == len(list((REAL / folder / "images").iterdir()))


def _bench_real() -> ModuleType:
    return bench_module("bench_real")


@functools.cache
def _evaluated(folder: str) -> dict[str, Any]:
    result: dict[str, Any] = _bench_real().evaluate(REAL / folder, trials=0)
    return result


@pytest.mark.slow
@pytest.mark.parametrize("folder", FOLDERS)
def test_ten_corners_reproject_all_others_within_a_pixel(folder: str) -> None:
    """bench/bench_real.py: 10 corners spread in elevation in, RMS on all other corners out (goal <= 1 px).

    Measured RMS with the centre refined: 0.39-0.66 px (the tools' own: 0.32-0.59 px);
    0.8 px leaves room for small platform differences in the centre detection and the
    optimiser while staying inside the goal.
    """
    result = _evaluated(folder)
    refined = result["fits"]["refined centre"]
    assert refined["rms_px"] <= 0.8, refined
    # Our world is the OCam frame (Z its optical axis, the camera looking down): the image angle
    # is phi = pi/2 - theta, i.e. s = -1, phi0 = 90 deg. imgback's affine terms d = -0.042,
    # e = 0.045 add a rotation of (d - e)/2 = -2.5 deg (measured phi0 87.6 deg). Where a small tilt about
    # the rim's centre stands for the rim's offset from the axis (kaidan: 0.26 deg), phi0 moves with it
    # (measured 89.68 deg; 89.89 level): a wrong convention would be degrees off.
    assert refined["s"] == -1
    expected_phi0 = 87.5 if folder == "ocam_fisheye_imgback" else 90.0
    assert abs(refined["phi0_deg"] - expected_phi0) < 0.5, refined["phi0_deg"]
    if folder == "ocam_kaidan_catadioptric":
        # Measured 0.64 px with the centre held where the rim puts it (0.7 px from the axis); the other
        # rims' centres are 1.3-3.0 px off the axis, which the centre held cannot undo (0.52-1.83 px).
        assert result["fits"]["default"]["rms_px"] <= 0.8, result["fits"]["default"]
    # The rim is found in at least half of each folder's images (miniomni: 11 of 15), never the calibration's.
    assert result["centre"].source.startswith("detected"), result["centre"].source


@pytest.mark.slow
@pytest.mark.parametrize("folder", FOLDERS)
def test_fit_image_finds_the_calibrations_centre_from_ten_corners(folder: str) -> None:
    """``panomap fit --image`` with no other option, once with each of the folder's images: the calibration's
    optical axis (our world's -Z) put within 1 px of the established calibration's centre (the issue's goal),
    the RMS on all other corners within 0.7 px (goal).

    Measured: 0.07-0.61 px (worst over each folder's images: mei 0.07, imgback 0.17, kaidan 0.61, miniomni
    0.20, vmr 0.13; on 9 of imgback's 11 images and 13 of kaidan's 17 a tilt about the rim's centre explains
    the landmarks better than moving the centre, and stands for the rim's offset); RMS 0.39-0.67 px.
    """
    result = _evaluated(folder)
    assert max(result["fit_image_centre_offset_px"]) < 1.0, result["fit_image_centre_offset_px"]
    assert max(result["fit_image_rms_px"]) <= 0.7, result["fit_image_rms_px"]


@pytest.mark.slow
def test_the_refined_centre_moves_from_the_rim_to_the_axis_on_vmr() -> None:
    """vmr's rim centre is 2.2 px from the calibrated axis: held there, the fit is off by 2.4 px RMS.

    Refining the centre brings it to 0.14 px of the calibration's (measured) and the RMS to 0.45 px.
    """
    result = _evaluated("ocam_vmr_catadioptric")
    assert result["fits"]["default"]["rms_px"] > 1.5
    assert result["fits"]["paper"]["rms_px"] > 1.5  # the paper's model takes the centre as given
    assert math.dist(result["fits"]["refined centre"]["centre"], ocam_centre("ocam_vmr_catadioptric")) < 0.5


@pytest.mark.slow
def test_miniomni_tables_keep_the_cameras_reflection_out_where_the_rim_is_found_off_the_axis() -> None:
    """On three MiniOmni images the rim is found 7-11 px off the calibrated axis, and the cut-off disc, looked
    for about it, was missed (none) or found off the axis: their tables cut off at 0, 13.9 and 16.1 px, where
    the other images' cut off at 26.6-28.6 px, letting a ring of the camera into the view. Looked for again
    about the fitted centre: 24.4-28.6 px on every image with a rim (measured)."""
    from panomap.calibrate.landmarks.pairs import Landmarks
    from panomap.calibrate.landmarks.pipeline import calibrate_camera

    bench = _bench_real()
    folder = REAL / "ocam_miniomni_catadioptric"
    corners = bench.read_corners(folder)
    chosen = bench.spread_choice(corners.elevation)
    landmarks = Landmarks(corners.pixels[chosen], corners.world[chosen], tuple(f"corner{k}" for k in chosen))
    cutoffs = {}
    for path in sorted((folder / "images").iterdir()):
        result = calibrate_camera(landmarks, (0.0, 0.0, 0.0), omni=read_image(path))
        if result.circles is not None:  # (a rim found: on 12 of the 15 images)
            cutoffs[path.name] = round(result.table.cutoff_radius, 1)
    assert len(cutoffs) >= 11, cutoffs
    assert min(cutoffs.values()) >= 23.0, cutoffs


def test_a_fit_whose_radius_does_not_reach_the_image_circle_is_one_clear_error() -> None:
    """Five MiniOmni corners spread in elevation on its first image: the fisheye law fitted to them gives no radius
    at the image circle's elevation (NaN); that was a ValueError from the table's size, now one line saying so."""
    from panomap.calibrate.landmarks.pairs import Landmarks
    from panomap.calibrate.landmarks.pipeline import calibrate_camera
    from panomap.errors import PanomapError

    bench = _bench_real()
    folder = REAL / "ocam_miniomni_catadioptric"
    corners = bench.read_corners(folder)
    chosen = bench.spread_choice(corners.elevation, 5)
    landmarks = Landmarks(corners.pixels[chosen], corners.world[chosen], tuple(f"corner{k}" for k in chosen))
    with pytest.raises(PanomapError, match="gives no radius over the elevations"):
        calibrate_camera(landmarks, (0.0, 0.0, 0.0), omni=read_image(folder / "images" / "MiniOmni1.jpg"))


@pytest.mark.slow
def test_the_line_fit_of_an_image_with_no_rim_starts_from_stand_in_circles(tmp_path: Path) -> None:
    """MiniOmni13 overfills the frame (no rim to find): `panomap fit --image` without landmarks used to stop at
    "no image circle"; it now starts from the cut-off disc's centre and fits its one board, whose projection
    uncertainty (2.1 px at 95% at 92 deg, over the 2 px limit: one board cannot vouch for the camera; issue 54)
    refuses the table in one line naming what to add; the overlay of what was found is written all the same."""
    from helpers import assert_one_line_error, run

    image = REAL / "ocam_miniomni_catadioptric" / "images" / "MiniOmni13.jpg"
    result = run("fit", "-o", tmp_path / "cam.npz", "--image", image, "--overlay", tmp_path / "seen.png")
    assert_one_line_error(result, "the checkerboard does not pin the camera")
    assert "image circle" not in result.stderr and "add pictures with the board" in result.stderr
    assert not (tmp_path / "cam.npz").exists() and (tmp_path / "seen.png").stat().st_size > 10_000
