"""What OpenCV's checkerboard detector finds in the rendered checkerboard scenes, against their truth.

Run: ``.venv/bin/python bench/bench_board_detect.py [--scenes 10] [--pairs 3] [--blur SIGMA_PX] [--full] [--big]``

Scenes (:mod:`panomap.simulate.board_scenes`): the issue's two rendered cameras at two thirds of their
size (a 190 deg equidistant fisheye on 1280 x 720, the image circle cut by the frame; a hyperbolic mirror
on 1024 x 768), tilted 2 deg, boards placed by ``board_poses`` in the line scenes' room, vignetting,
noise 2.5 grey levels, JPEG 85. The detector: ``cv2.findChessboardCornersSBWithMeta`` with
``CALIB_CB_EXHAUSTIVE | CALIB_CB_LARGER | CALIB_CB_ACCURACY``, started at (3, 3), (4, 4), (5, 5) and
(3, 5), the largest grid kept (the size of a board is not known to a fit from checkerboards). Each
detected corner is matched to the nearest true inner corner of any board (``camera.project`` of its
3-D point); a corner more than ``MATCH_PX`` from every true corner is a false corner. A board counts as
found when every one of its inner corners is matched by exactly one detected corner and nothing else
was detected. Printed: per scene the grid found, its corners' errors, and their errors once moved by
``cv2.cornerSubPix`` (half-window a third of the smallest corner spacing, 2-5 px); then per camera the
success rate and the errors of all matched corners (median, p90, max, px); then scenes with two boards:
which board the detector returns, and what it finds once that board is painted over (the hull of its
corners, grown by two squares, filled with the median grey).
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from panomap.simulate.board_scenes import BoardScene, board_poses, render_board_scene
from panomap.simulate.line_scenes import line_camera

STARTS = ((3, 3), (4, 4), (5, 5), (3, 5))
FLAGS = cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_LARGER | cv2.CALIB_CB_ACCURACY
MATCH_PX = 3.0
CAMERAS = (("fisheye190", 2.0 / 3.0), ("hyperbolic", 0.64))


def refined(gray: NDArray[np.uint8], corners: NDArray[np.float64]) -> NDArray[np.float64]:
    """Corners (n, 2) moved by ``cv2.cornerSubPix``, its half-window a third of the smallest spacing (2-5 px)."""
    if len(corners) < 2:
        return corners
    spacing = np.linalg.norm(corners[:, None, :] - corners[None, :, :], axis=2)
    np.fill_diagonal(spacing, np.inf)
    half = int(np.clip(np.min(spacing) / 3.0, 2, 5))
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-4)
    start = corners.astype(np.float32).reshape(-1, 1, 2)
    return np.asarray(cv2.cornerSubPix(gray, start, (half, half), (-1, -1), criteria), dtype=np.float64).reshape(-1, 2)


def masked(gray: NDArray[np.uint8], corners: NDArray[np.float64]) -> NDArray[np.uint8]:
    """The image with a found board painted over: the hull of its corners grown by two squares, filled
    with the image's median grey."""
    hull = cv2.convexHull(corners.astype(np.float32)).reshape(-1, 2)
    middle = hull.mean(axis=0)
    spacing = float(np.median(np.hypot(*np.diff(corners, axis=0).T)))
    grown = middle + (hull - middle) * (1.0 + 2.0 * spacing / np.hypot(*(hull - middle).T))[:, None]
    out = gray.copy()
    cv2.fillConvexPoly(out, np.rint(grown).astype(np.int32), int(np.median(gray)))
    return out


def largest_grid(gray: NDArray[np.uint8]) -> tuple[NDArray[np.float64], tuple[int, int]]:
    """Corners (n, 2) and grid size (cols, rows) of the largest checkerboard found from any start; (0, 2) if none."""
    best = np.zeros((0, 2)), (0, 0)
    for start in STARTS:
        ok, corners, meta = cv2.findChessboardCornersSBWithMeta(gray, start, flags=FLAGS)
        if ok and len(corners) > len(best[0]):
            best = np.asarray(corners, dtype=np.float64).reshape(-1, 2), (meta.shape[1], meta.shape[0])
    return best


@dataclass(frozen=True)
class Outcome:
    grid: tuple[int, int]
    board: int  # index of the board most detected corners belong to, -1 if none
    errors: NDArray[np.float64]  # px, per matched corner
    false: int  # detected corners matching no true corner
    duplicates: int  # detected corners matching a true corner another already matched
    found: bool  # one board, every inner corner, nothing else


def judge(scene: BoardScene, corners: NDArray[np.float64]) -> Outcome:
    truth = np.concatenate([t.pixels for t in scene.truth])
    owner = np.concatenate([np.full(len(t.pixels), k) for k, t in enumerate(scene.truth)])
    if len(corners) == 0:
        return Outcome((0, 0), -1, np.zeros(0), 0, 0, False)
    distance = np.hypot(*(corners[:, None, :] - truth[None, :, :]).transpose(2, 0, 1))
    nearest = np.argmin(distance, axis=1)
    error = distance[np.arange(len(corners)), nearest]
    matched = error <= MATCH_PX
    duplicates = int(matched.sum() - len(np.unique(nearest[matched])))
    board = int(np.bincount(owner[nearest[matched]]).argmax()) if matched.any() else -1
    complete = board >= 0 and len(np.unique(nearest[matched & (owner[nearest] == board)])) == len(
        scene.truth[board].pixels
    )
    found = complete and bool(matched.all()) and duplicates == 0 and len(corners) == len(scene.truth[board].pixels)
    return Outcome((0, 0), board, error[matched], int((~matched).sum()), duplicates, found)


def stats(errors: NDArray[np.float64]) -> str:
    if len(errors) == 0:
        return "no corners"
    p50, p90 = np.percentile(errors, [50, 90])
    return f"median {p50:.3f}  p90 {p90:.3f}  max {errors.max():.3f} px ({len(errors)} corners)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=10, help="scenes with one board per camera (default 10)")
    parser.add_argument("--pairs", type=int, default=3, help="scenes with two boards per camera (default 3)")
    parser.add_argument("--blur", type=float, default=0.0, help="lens blur, Gaussian sigma in px (default 0)")
    parser.add_argument("--full", action="store_true", help="the issue's full-size sensors (1920 x 1080, 1600 x 1200)")
    parser.add_argument("--big", action="store_true", help="boards as big as on the real sets (span 1.0-1.6)")
    args = parser.parse_args()
    span = (1.0, 1.6) if args.big else (0.4, 1.6)
    print(f"blur {args.blur} px, span {span}")
    for kind, scale in CAMERAS:
        camera = line_camera(kind, 1.0 if args.full else scale)
        print(f"\n{kind} {camera.image_size[0]} x {camera.image_size[1]}, one board per image")
        found, errors, errors_refined, seconds = 0, [], [], []
        for seed in range(args.scenes):
            boards = board_poses(camera, 1, seed, span=span)
            scene = render_board_scene(camera, boards, seed, blur_px=args.blur)
            start = time.perf_counter()
            corners, grid = largest_grid(scene.image)
            seconds.append(time.perf_counter() - start)
            outcome = judge(scene, corners)
            found += outcome.found
            errors.append(outcome.errors)
            again = judge(scene, refined(scene.image, corners))
            errors_refined.append(again.errors)
            b = boards[0]
            spacing = np.hypot(*np.diff(scene.truth[0].pixels.reshape(b.rows, b.cols, 2), axis=1).reshape(-1, 2).T)
            print(
                f"  seed {seed}: board {b.cols} x {b.rows} (squares {spacing.min():.0f}-{spacing.max():.0f} px), "
                f"found {grid[0]} x {grid[1]}{'' if outcome.found else ' (not the whole board)'}; "
                f"false {outcome.false}, duplicates {outcome.duplicates}; {stats(outcome.errors)}; "
                f"then cornerSubPix: {stats(again.errors)}"
            )
        all_errors = np.concatenate([np.zeros(0), *errors])
        print(
            f"  {kind}: {found} of {args.scenes} boards found whole; matched corners: {stats(all_errors)}; "
            f"detector {np.mean(seconds):.2f} s per image (4 starts)"
        )
        moved = np.concatenate([np.zeros(0), *errors_refined])
        print(f"  {kind}: the same corners moved by cornerSubPix: {stats(moved)}")
        print(f"{kind}, two boards per image")
        for seed in range(100, 100 + args.pairs):
            boards = board_poses(camera, 2, seed, span=span)
            scene = render_board_scene(camera, boards, seed, blur_px=args.blur)
            corners, grid = largest_grid(scene.image)
            outcome = judge(scene, corners)
            second = judge(scene, largest_grid(masked(scene.image, corners))[0]) if len(corners) else outcome
            sizes = ", ".join(
                f"{b.cols} x {b.rows} ({math.hypot(*np.ptp(t.pixels, axis=0)):.0f} px across)"
                for b, t in zip(boards, scene.truth, strict=True)
            )
            print(
                f"  seed {seed}: boards {sizes}; found {grid[0]} x {grid[1]} on board {outcome.board}"
                f"{' whole' if outcome.found else ''}; false {outcome.false}; {stats(outcome.errors)}; "
                f"that board masked: board {second.board}{' whole' if second.found else ''}, {stats(second.errors)}"
            )


if __name__ == "__main__":
    main()
