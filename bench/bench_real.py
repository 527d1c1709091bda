"""The radial fit on real cameras: 10 corners in, the reprojection error on all the others out.

Run: ``.venv/bin/python bench/bench_real.py [--data ../shared/data/real] [--trials 20]``

For each folder of the real data (OCamCalib calibrations of three mirror
cameras and a fisheye; OpenCV omnidir's of a paracatadioptric camera, the Mei
folder; each with its checkerboard corners; see each folder's ``SOURCE.md``):

- **Landmarks.** ``corners.csv`` gives each corner's 3-D point in the
  OCamCalib camera frame (mm) and its detected pixel (0-based row, col). Our
  pixel is ``(u, v) = (col, row)``. Our world frame *is* the OCam frame
  ``(X, Y, Z) = (x_ocam, y_ocam, z_ocam)`` (right-handed), with the camera at
  the origin: the image centre sees ``(0, 0, -1)``, so in our convention the
  camera looks **down** (elevation -90 deg at the centre; the radius grows
  with elevation, as SOURCE.md states). No flip is needed: the OCam azimuth
  ``atan2(y, x)`` runs from the row axis towards the column axis, i.e. our
  image angle is ``phi = pi/2 - theta`` (``s = -1``, ``phi0 = 90 deg``), which
  the fit estimates. (For the mirror cameras the OCam frame is the mirror
  image of the physical one; that changes no ray-pixel pair.) The Mei
  folder's corners are in OpenCV's camera frame (X along the columns, Y along
  the rows, Z forward); ``(X, Y, Z) = (Y_cv, X_cv, -Z_cv)``, a rotation, makes
  it the OCam frame. Only its corners with a pose are used (288).
- **Centre.** From the images with :func:`panomap.calibrate.circles.find_image_circles`:
  the median over the images where it finds the rim (at least half of them:
  every image but in miniomni, 11 of 15); the median image circle then gives
  the annulus, as ``panomap fit --image`` would. Where the rim is found in
  fewer than half, the calibration's centre is used, and the output says so.
- **fit --image**: :func:`panomap.calibrate.landmarks.pipeline.calibrate_camera` with
  the 10 corners and each of the folder's images in turn, no other option
  (what ``panomap fit --image`` does): the RMS on all other corners; where
  the fit puts the calibration's optical axis (our world's -Z: its centre
  for a level fit), from the calibration's centre; and how many images were
  given a tilt (a tilt about the rim's centre can stand for the rim's offset
  from the axis), with the fitted centre's own distance.
- **Choice of the 10 corners** (deterministic): the elevations of all the
  folder's corners span ``[lo, hi]``; for each of 10 elevations evenly spaced
  from ``lo`` to ``hi`` the corner nearest in elevation (each corner once).
- **Fits**: ``fit_camera`` with default settings (centre as found), the same
  with ``refine_centre=True``, and ``model="paper"`` (centre as found; the
  paper takes the centre as given).
- **Error**: the distance (px) between each other corner's detected pixel and
  where the fitted model puts its 3-D point: RMS, 95th percentile and max,
  beside the established tool's own RMS on the same corners (from
  ``reproj_err_px``) and over all its corners (``SOURCE.md``).
- **Spread of the choice**: ``--trials`` seeded draws of one random corner
  per tenth of the elevation range; median and worst RMS (refined centre).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panomap.calibrate.circles import find_image_circles
from panomap.calibrate.landmarks.fit import fit_camera
from panomap.calibrate.landmarks.pairs import Landmarks
from panomap.calibrate.landmarks.pipeline import calibrate_camera
from panomap.errors import PanomapError
from panomap.geometry import azimuth_elevation
from panomap.io.images import read_image

DEFAULT_DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
LANDMARK_COUNT = 10
FITS = {
    "default": {},
    "refined centre": {"refine_centre": True},
    "paper": {"model": "paper"},
}


@dataclass(frozen=True)
class Corners:
    """One folder's corners: pixels (n, 2) as (u, v) = (col, row), points (n, 3) in the OCam frame (mm)."""

    pixels: NDArray[np.float64]
    world: NDArray[np.float64]
    images: tuple[str, ...]
    tool_error_px: NDArray[np.float64]  # the calibration's own reprojection error of each corner

    @property
    def elevation(self) -> NDArray[np.float64]:
        return azimuth_elevation(self.world)[1]


def read_corners(folder: Path) -> Corners:
    """``corners.csv`` as landmark pairs in our frame (see the module's docstring).

    OCamCalib folders: 0-based (row, col) pixels become (u, v) = (col, row); OCam (x, y, z) is our (X, Y, Z).
    The Mei folder (OpenCV's omnidir frame: X along the columns, Y along the rows, Z forward): only the
    corners with a pose; 0-based (u, v) as they are, and (X, Y, Z) = (Y_cv, X_cv, -Z_cv), a rotation that
    makes it the OCam frame (rows, columns, the image centre seeing -Z).
    """
    with (folder / "corners.csv").open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    if is_mei(folder):
        rows = [r for r in rows if r["pose_available"] == "1"]
        pixels = np.array([[float(r["u_col_px"]), float(r["v_row_px"])] for r in rows])
        world = np.array([[float(r["cam_Y_mm"]), float(r["cam_X_mm"]), -float(r["cam_Z_mm"])] for r in rows])
    else:
        pixels = np.array([[float(r["col_px"]), float(r["row_px"])] for r in rows])
        world = np.array([[float(r["cam_x_mm"]), float(r["cam_y_mm"]), float(r["cam_z_mm"])] for r in rows])
    error = np.array([float(r["reproj_err_px"]) for r in rows])
    return Corners(pixels, world, tuple(r["image"] for r in rows), error)


def is_mei(folder: Path) -> bool:
    """The folder holds OpenCV omnidir's calibration (the Mei camera), not OCamCalib's."""
    return (folder / "omnidir_calibration.json").is_file()


def calibration(folder: Path) -> dict[str, Any]:
    result: dict[str, Any] = json.loads((folder / "ocam_model.json").read_text())
    return result


def calibration_centre(folder: Path) -> tuple[float, float]:
    """The established calibration's centre (u, v): OCamCalib's, or OpenCV omnidir's primary model's."""
    if is_mei(folder):
        model = json.loads((folder / "omnidir_calibration.json").read_text())
        k = model["models"][model["primary"]]["K"]
        return (float(k[0][2]), float(k[1][2]))
    ocam = calibration(folder)
    return (float(ocam["yc_col_0based"]), float(ocam["xc_row_0based"]))


def calibration_rms(folder: Path) -> float:
    """The established calibration's own RMS over all its corners (px)."""
    if is_mei(folder):
        model = json.loads((folder / "omnidir_calibration.json").read_text())
        return float(model["models"][model["primary"]]["reproj_rms_px"])
    return float(calibration(folder)["reproj_rms_px_rootsolve"])


@dataclass(frozen=True)
class CentreChoice:
    centre: tuple[float, float]
    annulus: tuple[float, float] | None
    source: str


def find_centre(folder: Path) -> CentreChoice:
    """The median of the centres found in the folder's images (where the rim is found in at least half of
    them), with the median image circle as the annulus; else the calibration's centre, and the source says so."""
    reference = calibration_centre(folder)
    paths = sorted((folder / "images").iterdir())
    found = []
    reasons = []
    for path in paths:
        try:
            found.append(find_image_circles(read_image(path)))
        except PanomapError as exc:
            reasons.append(exc.detail)
    if 2 * len(found) < len(paths):
        reason = reasons[0].split(";")[0]
        return CentreChoice(
            reference, None, f"calibration's (no rim found in {len(reasons)} of {len(paths)} images: {reason})"
        )
    centres = np.array([c.centre for c in found])
    centre = (float(np.median(centres[:, 0])), float(np.median(centres[:, 1])))
    outer = float(np.median([c.outer_radius for c in found]))
    cutoffs = [c.cutoff_radius for c in found if c.cutoff_radius is not None]
    cutoff = float(np.median(cutoffs)) if 2 * len(cutoffs) > len(found) else 0.0
    offset = math.dist(centre, reference)
    return CentreChoice(
        centre,
        (cutoff, outer),
        f"detected (median of the {len(found)} of {len(paths)} images where the rim is found, {offset:.1f} px "
        "from the calibration's)",
    )


def spread_choice(elevation: NDArray[np.float64], count: int = LANDMARK_COUNT) -> NDArray[np.intp]:
    """Indices of the corners nearest to ``count`` elevations evenly spaced over their range (each once)."""
    chosen: list[int] = []
    for target in np.linspace(elevation.min(), elevation.max(), count):
        order = np.argsort(np.abs(elevation - target), kind="stable")
        chosen.append(next(int(k) for k in order if int(k) not in chosen))
    return np.array(chosen, dtype=np.intp)


def random_spread_choice(
    elevation: NDArray[np.float64], rng: np.random.Generator, count: int = LANDMARK_COUNT
) -> NDArray[np.intp]:
    """One random corner from each of ``count`` equal slices of the elevation range (skipping empty slices)."""
    edges = np.linspace(elevation.min(), elevation.max(), count + 1)
    slot = np.clip(np.searchsorted(edges, elevation, side="right") - 1, 0, count - 1)
    return np.array([rng.choice(np.flatnonzero(slot == k)) for k in range(count) if np.any(slot == k)], dtype=np.intp)


def reprojection_errors(
    corners: Corners, chosen: NDArray[np.intp], centre: CentreChoice, **options: Any
) -> tuple[NDArray[np.float64], Any]:
    """Fit to the chosen corners; the pixel error (px) of every other corner, and the fit."""
    landmarks = Landmarks(corners.pixels[chosen], corners.world[chosen], tuple(f"corner{k}" for k in chosen))
    fit = fit_camera(landmarks, (0.0, 0.0, 0.0), centre.centre, annulus=centre.annulus, **options)
    others = np.setdiff1d(np.arange(len(corners.pixels)), chosen)
    # From the fit's camera position: the corners' frame puts the camera at the origin, which the fit may refine.
    theta, rho = azimuth_elevation(corners.world[others] - np.asarray(fit.camera_position))
    error = np.linalg.norm(fit.model.pixels(theta, rho) - corners.pixels[others], axis=1)
    return error, fit


def evaluate(folder: Path, trials: int = 0) -> dict[str, Any]:
    """Everything the table reports for one folder."""
    corners = read_corners(folder)
    centre = find_centre(folder)
    chosen = spread_choice(corners.elevation)
    others = np.setdiff1d(np.arange(len(corners.pixels)), chosen)
    result: dict[str, Any] = {
        "folder": folder.name,
        "corners": len(corners.pixels),
        "centre": centre,
        "chosen_elevation_deg": np.degrees(corners.elevation[chosen]).tolist(),
        "chosen_images": sorted(set(corners.images[k] for k in chosen)),
        "tool_rms_px": float(np.sqrt(np.mean(corners.tool_error_px[others] ** 2))),
        "tool_rms_all_px": calibration_rms(folder),
        "fits": {},
    }
    for name, options in FITS.items():
        try:
            error, fit = reprojection_errors(corners, chosen, centre, **options)
        except PanomapError as exc:
            result["fits"][name] = {"error": exc.detail}
            continue
        result["fits"][name] = {
            "rms_px": float(np.sqrt(np.mean(error**2))),
            "p95_px": float(np.percentile(error, 95)),
            "max_px": float(np.max(error)),
            "kind": fit.model.radial.kind,
            "s": fit.model.s,
            "phi0_deg": math.degrees(fit.model.phi0),
            "centre": fit.model.centre,
            "centre_offset_px": math.dist(fit.model.centre, calibration_centre(folder)),
            "outliers": fit.outliers,
        }
    # What `panomap fit --image IMAGE` does with no other option, with each of the folder's images.
    landmarks = Landmarks(corners.pixels[chosen], corners.world[chosen], tuple(f"corner{k}" for k in chosen))
    per_image = []
    offsets = []
    centres = []
    tilted = 0
    for path in sorted((folder / "images").iterdir()):
        try:
            fit = calibrate_camera(landmarks, (0.0, 0.0, 0.0), omni=read_image(path)).fit
        except PanomapError:
            per_image.append(math.inf)
            offsets.append(math.inf)
            centres.append(math.inf)
            continue
        theta, rho = azimuth_elevation(corners.world[others] - np.asarray(fit.camera_position))
        error = np.linalg.norm(fit.model.pixels(theta, rho) - corners.pixels[others], axis=1)
        per_image.append(float(np.sqrt(np.mean(error**2))))
        # The calibration's centre is where its optical axis lands: our world's -Z (the world frame is the
        # calibration's camera frame). A level fit puts it at its centre; a tilted one elsewhere.
        axis = fit.model.pixels(np.array(0.0), np.array(-math.pi / 2))
        offsets.append(math.dist((float(axis[0]), float(axis[1])), calibration_centre(folder)))
        centres.append(math.dist(fit.model.centre, calibration_centre(folder)))
        tilted += fit.mount is not None and fit.mount.tilt_deg > 0
    result["fit_image_rms_px"] = per_image
    result["fit_image_centre_offset_px"] = offsets
    result["fit_image_centre_parameter_offset_px"] = centres
    result["fit_image_tilted"] = tilted
    draws = []
    rng = np.random.default_rng(2007)
    for _ in range(trials):
        pick = random_spread_choice(corners.elevation, rng)
        try:
            error, _ = reprojection_errors(corners, pick, centre, refine_centre=True)
            draws.append(float(np.sqrt(np.mean(error**2))))
        except PanomapError:
            draws.append(math.inf)
    result["draws_rms_px"] = draws
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--trials", type=int, default=20, help="random spread choices per folder (0: none)")
    args = parser.parse_args()
    folders = sorted(path.parent for path in args.data.glob("*/corners.csv"))
    if not folders:
        raise SystemExit(f"no real data sets (folders with a corners.csv) in {args.data}")
    results = [evaluate(folder, args.trials) for folder in folders]
    for r in results:
        print(f"{r['folder']}: {r['corners']} corners; centre {r['centre'].source}")
        low, high = r["chosen_elevation_deg"][0], r["chosen_elevation_deg"][-1]
        print(f"  10 corners at {low:.1f}..{high:.1f} deg from {len(r['chosen_images'])} images")
        for name, fit in r["fits"].items():
            if "error" in fit:
                print(f"  {name}: refused ({fit['error']})")
                continue
            print(
                f"  {name}: {fit['kind']}, s {fit['s']:+d}, phi0 {fit['phi0_deg']:.2f} deg, centre "
                f"({fit['centre'][0]:.2f}, {fit['centre'][1]:.2f}; {fit['centre_offset_px']:.2f} px from the "
                f"calibration's), outliers {fit['outliers'] or 'none'}"
            )
    print()
    print(
        "RMS / p95 / max reprojection error (px) on all other corners, from 10 corners spread in elevation; "
        "the tool's RMS on the same corners (and on all of them, SOURCE.md)"
    )
    print(
        "| folder | centre | other corners | fit --image, RMS over its images: median / worst | fit --image, where "
        "it puts the calibration's axis, from the calibration's centre (px): median / worst | fit --image: images "
        "given a tilt, its centre from the calibration's (px): median / worst | default | refined centre | paper | "
        "tool | random spread choices |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in results:

        def cell(fit: dict[str, Any]) -> str:
            if "error" in fit:
                return "refused"
            return f"{fit['rms_px']:.2f} / {fit['p95_px']:.2f} / {fit['max_px']:.2f}"

        draws = np.array(r["draws_rms_px"])
        spread = (
            f"{len(draws)} draws: median {np.median(draws):.2f}, worst {np.max(draws):.2f}" if draws.size else "not run"
        )
        where = "detected" if r["centre"].source.startswith("detected") else "calibration's"
        print(
            f"| {r['folder'].removeprefix('ocam_')} | {where} | {r['corners'] - LANDMARK_COUNT} | "
            f"{np.median(r['fit_image_rms_px']):.2f} / {np.max(r['fit_image_rms_px']):.2f} "
            f"({len(r['fit_image_rms_px'])} images) | "
            f"{np.median(r['fit_image_centre_offset_px']):.2f} / {np.max(r['fit_image_centre_offset_px']):.2f} | "
            f"{r['fit_image_tilted']}, {np.median(r['fit_image_centre_parameter_offset_px']):.2f} / "
            f"{np.max(r['fit_image_centre_parameter_offset_px']):.2f} | "
            f"{cell(r['fits']['default'])} | {cell(r['fits']['refined centre'])} | {cell(r['fits']['paper'])} | "
            f"{r['tool_rms_px']:.2f} ({r['tool_rms_all_px']:.2f}) | {spread} |"
        )


if __name__ == "__main__":
    main()
