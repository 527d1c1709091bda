"""Checkerboards: held-out accuracy and speed beside OpenCV's omnidir and fisheye (BabelCalib's protocol).

Run: ``.venv/bin/python bench/bench_board_heldout.py [--data ../shared/data/real] [--only NAME] [--no-detect]
[--floor]``

For each real set (``--data``; each folder's SOURCE.md and corners.csv) the corners the established
calibration was made from are the detections (so detection is out of the comparison); the images with
corners, in name order, are split alternately: the even ones calibrate, the odd ones measure. Each
camera calibrated on the first half is held fixed and every held-out board's pose is fitted to its
corners (least squares from a planar PnP on the corners' rays); the measure is the RMS (px) of the
held-out corners' distances. Beside panomap (:func:`fit_boards`, every choice its own):

- **omnidir**: ``cv2.omnidir.calibrate`` (Mei's unified model, k1 k2 p1 p2, skew fixed), from
  opencv-contrib (the same version as the installed OpenCV; ``--contrib`` names a folder holding it,
  ``pip install --target /tmp/contrib opencv-contrib-python-headless==<version>``); absent: not run;
- **fisheye**: ``cv2.fisheye.calibrate`` (Kannala-Brandt, k1-k4), which cannot see beyond 90 deg.

Times: each calibration on the first half; with detection (not ``--no-detect``), panomap's
``find_boards`` on every image of the set (the board's size unknown) beside OpenCV's
``findChessboardCorners`` + ``cornerSubPix`` told the board's size (what omnidir's users run), and the
ratio of detection + fit, panomap's over omnidir's. Ratios below 1 are panomap's gain. With ``--floor``,
panomap and omnidir fitted to every image and measured on the odd ones' corners (seen in the fit): the
floor a camera fitted to the even images alone cannot be expected to beat, beside the goal of issue 54
(0.95 times the best peer's held-out RMS). SciPy and the fit's modules are imported before anything is timed.
"""

from __future__ import annotations

import argparse
import collections
import csv
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

FloatArray = NDArray[np.float64]
# A model's pixels (n, 2) of points (n, 3) in its camera's axes.
Project = Callable[[FloatArray], FloatArray]
# A model's unit rays (n, 3) of pixels (n, 2).
Lift = Callable[[FloatArray], FloatArray]


def load_cv2(contrib: Path | None):  # type: ignore[no-untyped-def]
    """OpenCV with its contrib modules where ``contrib`` holds them (the same version), else the installed one."""
    if contrib is not None and (contrib / "cv2").is_dir():
        sys.path.insert(0, str(contrib))
    import cv2

    return cv2


def set_boards(folder: Path) -> tuple[list[str], dict[str, tuple[FloatArray, NDArray[np.intp]]]]:
    """The images with corners (name order) and each one's corners (n, 2) px and grid places (n, 2) squares."""
    with (folder / "corners.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    by_image: dict[str, list[dict[str, str]]] = collections.defaultdict(list)
    for row in rows:
        by_image[row["image"]].append(row)
    boards = {}
    for name, these in by_image.items():
        u_key, v_key = ("u_col_px", "v_row_px") if "u_col_px" in these[0] else ("col_px", "row_px")
        pixels = np.array([[float(r[u_key]), float(r[v_key])] for r in these])
        board = np.array([[float(r["board_x_mm"]), float(r["board_y_mm"])] for r in these])
        steps = np.diff(np.unique(board[:, 0]))
        square = float(steps[steps > 1e-6].min())
        grid = np.round((board - board.min(axis=0)) / square).astype(np.intp)
        boards[name] = (pixels, grid)
    names = sorted(boards, key=lambda n: (len(n), n))  # imgBack2 before imgBack10
    return names, boards


def pose_from_rays(rays: FloatArray, grid: NDArray[np.intp], cv2) -> FloatArray:  # type: ignore[no-untyped-def]
    """A board's pose (6,) from its corners' unit rays: a planar PnP on the rays turned to face the board."""
    mean = rays.mean(axis=0)
    mean /= np.linalg.norm(mean)
    axis = np.cross(mean, [0.0, 0.0, 1.0])
    sine, cosine = float(np.linalg.norm(axis)), float(mean[2])
    facing = (
        Rotation.from_rotvec(axis / sine * math.atan2(sine, cosine)).as_matrix()
        if sine > 1e-12
        else (np.eye(3) if cosine > 0 else np.diag([1.0, -1.0, -1.0]))
    )
    turned = rays @ facing.T
    turned[:, 2] = np.maximum(turned[:, 2], 1e-3)
    plane = np.column_stack([grid.astype(np.float64), np.zeros(len(grid))])
    _, rvec, tvec = cv2.solvePnP(plane, turned[:, :2] / turned[:, 2:3], np.eye(3), None, flags=cv2.SOLVEPNP_IPPE)
    rotation = facing.T @ cv2.Rodrigues(rvec)[0]
    return np.concatenate([Rotation.from_matrix(rotation).as_rotvec(), facing.T @ np.ravel(tvec)])


def held_out_rms(project: Project, lift: Lift, tests: list[tuple[FloatArray, NDArray[np.intp]]], cv2) -> float:  # type: ignore[no-untyped-def]
    """RMS (px) of the held-out corners under a fixed camera, each board's pose fitted to its corners."""
    squares: list[FloatArray] = []
    for pixels, grid in tests:
        plane = np.column_stack([grid.astype(np.float64), np.zeros(len(grid))])

        def residuals(pose: FloatArray, plane: FloatArray = plane, pixels: FloatArray = pixels) -> FloatArray:
            points = Rotation.from_rotvec(pose[:3]).apply(plane) + pose[3:]
            out = (project(points) - pixels).ravel()
            return np.where(np.isfinite(out), out, 1e3)

        start = pose_from_rays(lift(pixels), grid, cv2)
        best = least_squares(residuals, start, x_scale="jac", method="lm", max_nfev=400)
        flipped = least_squares(residuals, _flipped(start), x_scale="jac", method="lm", max_nfev=400)
        best = min(best, flipped, key=lambda s: float(s.cost))
        squares.append(best.fun.reshape(-1, 2) ** 2)
    return float(np.sqrt(np.mean(np.concatenate(squares).sum(axis=1))))


def _flipped(pose: FloatArray) -> FloatArray:
    """The PnP's other planar solution, roughly: the board turned half a turn about its own normal's axis."""
    return np.concatenate([pose[:3] * -1.0, pose[3:]])


# -- panomap ------------------------------------------------------------------------------------------


def panomap_camera(fit) -> tuple[Project, Lift]:  # type: ignore[no-untyped-def]
    from panomap.calibrate.boards.fit import camera_lift, camera_project

    return camera_project(fit), camera_lift(fit)


# -- OpenCV ---------------------------------------------------------------------------------------------


def omnidir_camera(cv2, k: FloatArray, xi: float, d: FloatArray) -> tuple[Project, Lift]:  # type: ignore[no-untyped-def]
    """Mei's unified model: project through ``cv2.omnidir.projectPoints``, lift by undistorting then the sphere."""

    def project(points: FloatArray) -> FloatArray:
        out, _ = cv2.omnidir.projectPoints(
            points.reshape(1, -1, 3).astype(np.float64), np.zeros(3), np.zeros(3), k, xi, d
        )
        return np.asarray(out, dtype=np.float64).reshape(-1, 2)

    def lift(pixels: FloatArray) -> FloatArray:
        m = cv2.undistortPoints(pixels.reshape(-1, 1, 2), k, d.ravel()[:4]).reshape(-1, 2)
        r2 = np.sum(m**2, axis=1)
        factor = (xi + np.sqrt(np.maximum(1.0 + (1.0 - xi * xi) * r2, 0.0))) / (1.0 + r2)
        rays = np.column_stack([factor * m[:, 0], factor * m[:, 1], factor - xi])
        return rays / np.linalg.norm(rays, axis=1, keepdims=True)

    return project, lift


def omnidir_fit(cv2, trains, size):  # type: ignore[no-untyped-def]
    objects = [np.column_stack([g, np.zeros(len(g))]).reshape(1, -1, 3).astype(np.float64) for _, g in trains]
    images = [p.reshape(1, -1, 2).astype(np.float64) for p, _ in trains]
    criteria = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 500, 1e-12)
    flags = cv2.omnidir.CALIB_FIX_SKEW
    _, k, xi, d, _, _, used = cv2.omnidir.calibrate(objects, images, size, None, None, None, flags, criteria)
    return omnidir_camera(cv2, k, float(np.ravel(xi)[0]), d), np.ravel(used).size if used is not None else 0


def fisheye_fit(cv2, trains, size):  # type: ignore[no-untyped-def]
    objects = [np.column_stack([g, np.zeros(len(g))]).reshape(-1, 1, 3).astype(np.float64) for _, g in trains]
    images = [p.reshape(-1, 1, 2).astype(np.float64) for p, _ in trains]
    flags = cv2.fisheye.CALIB_RECOMPUTE_EXTRINSIC | cv2.fisheye.CALIB_FIX_SKEW
    criteria = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-10)
    _, k, d, _, _ = cv2.fisheye.calibrate(objects, images, size, None, None, flags=flags, criteria=criteria)

    def project(points: FloatArray) -> FloatArray:
        out, _ = cv2.fisheye.projectPoints(points.reshape(-1, 1, 3).astype(np.float64), np.zeros(3), np.zeros(3), k, d)
        out = np.asarray(out, dtype=np.float64).reshape(-1, 2)
        return np.where(points[:, 2:3] > 0, out, np.nan)  # the model sees nothing beyond 90 deg

    def lift(pixels: FloatArray) -> FloatArray:
        m = cv2.fisheye.undistortPoints(pixels.reshape(-1, 1, 2), k, d).reshape(-1, 2)
        rays = np.column_stack([m, np.ones(len(m))])
        return rays / np.linalg.norm(rays, axis=1, keepdims=True)

    return project, lift


def opencv_detect(cv2, image: NDArray[np.uint8], shape: tuple[int, int]) -> bool:  # type: ignore[no-untyped-def]
    """OpenCV's detector told the board's size (columns, rows of inner corners), refined as its tutorials do."""
    grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
    found, corners = cv2.findChessboardCorners(grey, shape)
    if found:
        criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.01)
        cv2.cornerSubPix(grey, corners, (5, 5), (-1, -1), criteria)
    return bool(found)


def _label(fit) -> str:  # type: ignore[no-untyped-def]
    """The radial kind and the image terms kept (held-out RMS of each set tried, px)."""
    choice = fit.report.terms
    if choice is None or not choice.tried:
        return fit.report.model
    tried = ", ".join(f"{'+'.join(names) or 'none'} {rms:.3f}" for names, rms in choice.tried)
    return f"{fit.report.model}, terms {'+'.join(choice.kept) or 'none'} [{tried}]"


def timed(run: Callable[[], object]) -> tuple[object, float]:
    start = time.perf_counter()
    try:
        out = run()
    except Exception as exc:  # a peer that fails is reported, not fatal
        out = exc
    return out, time.perf_counter() - start


def floor_row(trains, tests, circles, cv2, size, best_peer: float) -> str:  # type: ignore[no-untyped-def]
    """The floor: each camera fitted to every image (the odd ones too), measured on the odd ones' corners (their
    poses fitted again under it): what no camera fitted to the even images alone can be expected to beat."""
    from panomap.calibrate.boards.detect import Board
    from panomap.calibrate.boards.fit import fit_boards

    everything = trains + tests
    out = [f"floor (fit on all {len(everything)} images, measured on the odd ones' corners):"]
    fit = fit_boards([Board(k, p, g) for k, (p, g) in enumerate(everything)], circles)
    out.append(f"panomap {held_out_rms(*panomap_camera(fit), tests, cv2):.3f} px ({_label(fit)})")
    if hasattr(cv2, "omnidir"):
        out.append(f"omnidir {held_out_rms(*omnidir_fit(cv2, everything, size)[0], tests, cv2):.3f} px")
    out.append(f"the goal, 0.95 x the best peer's held-out RMS: {0.95 * best_peer:.3f} px")
    return " ".join(out[:1]) + " " + "; ".join(out[1:])


def measure(folder: Path, cv2, detect: bool, floor: bool = False) -> None:  # type: ignore[no-untyped-def]
    from panomap.calibrate.boards.detect import Board, find_boards
    from panomap.calibrate.boards.fit import fit_boards
    from panomap.calibrate.lines.frame_circles import line_circles
    from panomap.io.images import read_image

    names, boards = set_boards(folder)
    trains = [boards[n] for n in names[0::2]]
    tests = [boards[n] for n in names[1::2]]
    first = read_image(folder / "images" / names[0])
    size = (first.shape[1], first.shape[0])
    circles = line_circles(first)
    row = [f"{folder.name} ({len(trains)}+{len(tests)} images)"]
    fit, pm_s = timed(lambda: fit_boards([Board(k, p, g) for k, (p, g) in enumerate(trains)], circles))
    pm_rms = math.nan if isinstance(fit, Exception) else held_out_rms(*panomap_camera(fit), tests, cv2)
    label = "failed" if isinstance(fit, Exception) else _label(fit)
    row.append(f"panomap {pm_rms:.3f} px ({label}, {pm_s:.2f} s)")
    peers: dict[str, tuple[float, float]] = {}
    if hasattr(cv2, "omnidir"):
        out, om_s = timed(lambda: omnidir_fit(cv2, trains, size))
        om_rms = math.nan if isinstance(out, Exception) else held_out_rms(*out[0], tests, cv2)  # type: ignore[index]
        peers["omnidir"] = (om_rms, om_s)
    out, fe_s = timed(lambda: fisheye_fit(cv2, trains, size))
    peers["fisheye"] = (math.nan if isinstance(out, Exception) else held_out_rms(*out, tests, cv2), fe_s)  # type: ignore[misc]
    for peer, (rms, seconds) in peers.items():
        row.append(f"{peer} {rms:.3f} px ({seconds:.2f} s)" if math.isfinite(rms) else f"{peer} failed")
    valid = [rms for rms, _ in peers.values() if math.isfinite(rms)]
    if valid:
        row.append(f"panomap / best peer {pm_rms / min(valid):.2f}")
    print("  " + "; ".join(row))
    if floor:
        print("    " + floor_row(trains, tests, circles, cv2, size, min(valid, default=math.nan)))
    if detect:
        images = [read_image(p) for p in sorted((folder / "images").iterdir())]
        shape = tuple(int(x) for x in boards[names[0]][1].max(axis=0) + 1)
        found, detect_s = timed(lambda: [b for k, image in enumerate(images) for b in find_boards(image, k)])
        _, all_fit_s = timed(lambda: fit_boards(found, circles))  # type: ignore[arg-type]
        _, cv_s = timed(lambda: [opencv_detect(cv2, image, shape) for image in images])  # type: ignore[arg-type]
        everything = [boards[n] for n in names]
        _, om_s = timed(lambda: omnidir_fit(cv2, everything, size)) if hasattr(cv2, "omnidir") else (None, math.nan)
        print(
            f"    speed, {len(images)} pictures: panomap detect {detect_s:.2f} s + fit {all_fit_s:.2f} s; OpenCV "
            f"detect (size told) {cv_s:.2f} s + omnidir {om_s:.2f} s; "
            f"ratio {(detect_s + all_fit_s) / (cv_s + om_s):.1f}"
        )
    sys.stdout.flush()


def import_before_timing() -> None:
    """Import what the timed steps import lazily (SciPy's optimize, stats and spatial, the fit's modules), so
    that the first set's fit is not charged with SciPy's import (about a second on this machine)."""
    import scipy.optimize
    import scipy.sparse
    import scipy.spatial
    import scipy.stats

    import panomap.calibrate.boards.fit
    import panomap.calibrate.lines.fit
    import panomap.camera.valid_range

    del scipy, panomap


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[1].parent / "shared/data/real")
    parser.add_argument("--contrib", type=Path, default=Path("/tmp/contrib"))
    parser.add_argument("--only", help="one set (its folder's name)")
    parser.add_argument("--no-detect", action="store_true", help="the held-out table only")
    parser.add_argument("--floor", action="store_true", help="also each camera fitted to every image (the floor)")
    args = parser.parse_args()
    cv2 = load_cv2(args.contrib)
    import_before_timing()
    print(f"OpenCV {cv2.__version__}, omnidir {'present' if hasattr(cv2, 'omnidir') else 'absent (not run)'}")
    print("== held-out RMS (fit on the even images, measured on the odd ones' corners)")
    for folder in sorted(p for p in args.data.iterdir() if p.is_dir()):
        if args.only is None or args.only == folder.name:
            measure(folder, cv2, not args.no_detect, args.floor)


if __name__ == "__main__":
    main()
