"""Checkerboards: detection + fit time beside OpenCV omnidir's pipeline on the same pictures (issue 54).

Run: ``PYTHONPATH=src python bench/bench_board_speed.py [--data ../shared/data/real] [--contrib /tmp/contrib]
[--only SET] [--no-tiled] [--tiled-only] [--src OTHER/src]`` (``--src``: another tree's panomap, to time and
measure it, before and after a change, in the same run of the machine as this one)

For each real set (``--data``: each folder's ``images/`` and ``corners.csv``), every picture:

- **panomap**: the image circles of the first picture (``line_circles``, as ``panomap fit --image`` starts),
  ``find_boards`` on every picture (the board's size unknown; ``find_boards_each``, as ``panomap fit``: the board
  learned from the first two pictures, the later ones searched for one board of its size, the pictures in threads,
  one per CPU), then ``fit_boards`` on every board found;
- **OpenCV**: ``findChessboardCorners`` told the board's size (read off ``corners.csv``) + ``cornerSubPix``
  (5 x 5) on every picture, then ``cv2.omnidir.calibrate`` (Mei's model, skew fixed) on the boards it found:
  what omnidir's users run. opencv-contrib of the installed OpenCV's version, found through ``--contrib``
  (``pip install --target /tmp/contrib opencv-contrib-python-headless==<version>``); absent: not run.

Printed per set: the times (s), the ratio (panomap detection + fit) / (OpenCV detection + omnidir) (the goal:
3 or under), and panomap's corners against the set's own (``corners.csv``, the established tools'
detections): boards and corners found, the median and p90 distance (px) of each found corner to the nearest
of the set's on its picture; the fit's corner RMS; and the held-out RMS (bench_board_heldout's split: the
camera fitted to panomap's boards of the even pictures, held fixed, each board's pose fitted to the set's own
corners of the odd pictures).

Then a board tiled over a 1600 x 1600 picture (``--no-tiled`` leaves it out): an equidistant fisheye (image
circle through the frame's corners) looking down at a 60 x 60 board of 5 cm squares 0.4 m below it, rendered
(:func:`panomap.simulate.board_scenes.render_board_scene`); ``find_boards``' time (goal: under 5 s) and its
corners against the true ones (``camera.project`` of each corner's 3-D point), and the boards' fit's time.

The machine's load changes absolute times by a factor of several (two shared cores): compare the ratios. Each
time is given as wall (s) and CPU (s, every thread of the process: OpenCV's detectors run threads of their own);
the ratio is the wall times', the CPU times' beside it. OpenBLAS runs one thread, as in ``panomap``'s command line
(``panomap/__main__.py``; its idle threads spin and take the fit's CPU: 1.4-2 times its time on two cores).
SciPy and the fit's modules are imported before anything is timed (with ``--only``, the one set measured paid
SciPy's import inside its fit's time).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before NumPy loads, as panomap's command line

import argparse
import collections
import csv
import math
import sys
import time
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


class Clock:
    """Wall and CPU seconds (every thread of the process) since it was made."""

    def __init__(self) -> None:
        self.wall, self.cpu = time.perf_counter(), time.process_time()

    def lap(self) -> tuple[float, float]:
        """(wall s, CPU s) since made or since the last lap."""
        wall, cpu = time.perf_counter(), time.process_time()
        out = (wall - self.wall, cpu - self.cpu)
        self.wall, self.cpu = wall, cpu
        return out


def load_cv2(contrib: Path | None):  # type: ignore[no-untyped-def]
    """OpenCV with its contrib modules where ``contrib`` holds them (the same version), else the installed one."""
    if contrib is not None and (contrib / "cv2").is_dir():
        sys.path.insert(0, str(contrib))
    import cv2

    return cv2


def set_corners(folder: Path) -> tuple[dict[str, FloatArray], tuple[int, int]]:
    """Each picture's corners (n, 2) px from ``corners.csv`` and the board's (columns, rows) of inner corners."""
    with (folder / "corners.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    by_image: dict[str, list[dict[str, str]]] = collections.defaultdict(list)
    for row in rows:
        by_image[row["image"]].append(row)
    corners, size = {}, (0, 0)
    for name, these in by_image.items():
        u_key, v_key = ("u_col_px", "v_row_px") if "u_col_px" in these[0] else ("col_px", "row_px")
        corners[name] = np.array([[float(r[u_key]), float(r[v_key])] for r in these])
        board = np.array([[float(r["board_x_mm"]), float(r["board_y_mm"])] for r in these])
        size = (len(np.unique(board[:, 0].round(3))), len(np.unique(board[:, 1].round(3))))
    return corners, size


def opencv_pipeline(cv2, images: list[NDArray[np.uint8]], shape: tuple[int, int]):  # type: ignore[no-untyped-def]
    """OpenCV's detector told the board's size + cornerSubPix on every picture, then omnidir on the boards found:
    (detection (wall s, CPU s), omnidir (wall s, CPU s) (nan where absent or failed), boards found)."""
    clock = Clock()
    found = []
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.01)
    for image in images:
        grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
        ok, corners = cv2.findChessboardCorners(grey, shape)
        if ok:
            found.append(cv2.cornerSubPix(grey, corners, (5, 5), (-1, -1), criteria))
    detect_s = clock.lap()
    failed = (math.nan, math.nan)
    if not hasattr(cv2, "omnidir") or len(found) < 3:
        return detect_s, failed, len(found)
    column, row = np.meshgrid(np.arange(shape[0]), np.arange(shape[1]))
    plane = np.column_stack([column.ravel(), row.ravel(), np.zeros(column.size)]).astype(np.float64)
    objects = [plane.reshape(1, -1, 3) for _ in found]
    points = [np.asarray(c, dtype=np.float64).reshape(1, -1, 2) for c in found]
    size = (images[0].shape[1], images[0].shape[0])
    criteria = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 500, 1e-12)
    clock.lap()
    try:
        cv2.omnidir.calibrate(objects, points, size, None, None, None, cv2.omnidir.CALIB_FIX_SKEW, criteria)
    except cv2.error:
        return detect_s, failed, len(found)
    return detect_s, clock.lap(), len(found)


def panomap_pipeline(images: list[NDArray[np.uint8]]):  # type: ignore[no-untyped-def]
    """panomap's circles, detection and fit: (circles, detection, fit (each (wall s, CPU s)), boards per picture,
    the fit or the error)."""
    try:
        from panomap.calibrate.boards.detect import find_boards_each
    except ImportError:  # another tree's panomap (--src), from before it: one picture after another

        def find_boards_each(images):  # type: ignore[no-untyped-def]
            from panomap.calibrate.boards.detect import find_boards

            return [find_boards(image, k) for k, image in enumerate(images)]

    from panomap.calibrate.boards.fit import fit_boards
    from panomap.calibrate.lines.frame_circles import line_circles
    from panomap.errors import PanomapError

    clock = Clock()
    circles = line_circles(images[0])
    circles_s = clock.lap()
    boards = list(find_boards_each(images))  # in threads, as panomap fit: the CPU time counts them all
    detect_s = clock.lap()
    try:
        fit: object = fit_boards([b for these in boards for b in these], circles)
    except PanomapError as exc:
        fit = exc
    return circles_s, detect_s, clock.lap(), boards, fit


def distances(found: list[FloatArray], truth: FloatArray) -> FloatArray:
    """Each found corner's distance (px) to the nearest true one."""
    if not found:
        return np.zeros(0)
    pixels = np.concatenate(found)
    truth = truth[np.all(np.isfinite(truth), axis=1)]  # corners the camera does not see
    return np.min(np.linalg.norm(pixels[:, None, :] - truth[None, :, :], axis=2), axis=1)


def measure(folder: Path, cv2) -> None:  # type: ignore[no-untyped-def]
    from panomap.io.images import read_image

    corners, shape = set_corners(folder)
    paths = sorted(p for p in (folder / "images").iterdir() if p.is_file())
    images = [read_image(p) for p in paths]
    cv_detect_s, omnidir_s, cv_boards = opencv_pipeline(cv2, images, shape)
    circles_s, detect_s, fit_s, boards, fit = panomap_pipeline(images)
    near = np.concatenate(
        [
            distances([b.pixels for b in these], corners[p.name])
            for p, these in zip(paths, boards, strict=True)
            if p.name in corners
        ]
    )
    near = near[near < 3.0]  # a corner of another grid (a misread board) is no match
    found = sum(len(these) for these in boards)
    held_out = held_out_rms(folder, paths, boards, cv2)
    fitted = (
        type(fit).__name__
        if isinstance(fit, Exception)
        else f"{fit.report.model}, corner RMS {fit.report.corner_rms_px:.3f} px"  # type: ignore[attr-defined]
    )
    ours = np.add(np.add(circles_s, detect_s), fit_s)
    theirs = np.add(cv_detect_s, omnidir_s if math.isfinite(omnidir_s[0]) else (0.0, 0.0))
    print(
        f"  {folder.name} ({len(images)} pictures), wall / CPU s: panomap circles {_pair(circles_s)} + detection "
        f"{_pair(detect_s)} + fit {_pair(fit_s)} ({fitted}) = {_pair(ours)}; OpenCV detection (size told) "
        f"{_pair(cv_detect_s)} + omnidir {_pair(omnidir_s)} = {_pair(theirs)} ({cv_boards} boards); ratio "
        f"{_pair(np.divide(ours, theirs), 1)} (detection alone {_pair(np.divide(detect_s, cv_detect_s), 1)})"
    )
    print(
        f"      panomap's corners: {found} boards, {sum(len(b.pixels) for t in boards for b in t)} corners; "
        f"against the set's own: median {np.median(near):.3f} p90 {np.percentile(near, 90):.3f} px "
        f"({len(near)} matched); held out: {held_out:.4f} px RMS"
    )
    sys.stdout.flush()


def _pair(times: tuple[float, float] | NDArray[np.float64], digits: int = 2) -> str:
    """A (wall, CPU) pair written ``wall / CPU``."""
    return f"{float(times[0]):.{digits}f} / {float(times[1]):.{digits}f}"


def held_out_rms(folder: Path, paths: list[Path], boards, cv2) -> float:  # type: ignore[no-untyped-def]
    """The RMS (px) of the set's own corners of the odd pictures under the camera fitted to panomap's boards of
    the even ones (bench_board_heldout's split and measure)."""
    import bench_board_heldout as heldout
    from panomap.calibrate.boards.detect import Board
    from panomap.calibrate.boards.fit import fit_boards
    from panomap.calibrate.lines.frame_circles import line_circles
    from panomap.errors import PanomapError
    from panomap.io.images import read_image

    names, corners = heldout.set_boards(folder)
    found = {p.name: these for p, these in zip(paths, boards, strict=True)}
    trains = [Board(k, b.pixels, b.grid) for k, name in enumerate(names[0::2]) for b in found[name]]
    try:
        fit = fit_boards(trains, line_circles(read_image(folder / "images" / names[0])))
    except PanomapError:
        return math.nan
    return float(heldout.held_out_rms(*heldout.panomap_camera(fit), [corners[n] for n in names[1::2]], cv2))


def tiled_scene():  # type: ignore[no-untyped-def]
    """The 1600 x 1600 fisheye picture of a board tiled over the frame, and its true corners (n, 2) px."""
    from panomap.simulate.board_scenes import Board, render_board_scene
    from panomap.simulate.cameras import standard_cameras

    camera = standard_cameras((1600, 1600), outer_radius=1131.0)["equidistant"]
    columns, square, below = 60, 0.05, 0.4
    # flat under the camera, which looks down: the board's x along the image's u, its y along v, z down
    turn = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
    corner = np.array([-(columns - 1) / 2 * square, (columns - 1) / 2 * square, -below])
    scene = render_board_scene(camera, (Board(columns, columns, square, turn, corner),), seed=3, supersample=2)
    return scene.image, scene.truth[0].pixels


def measure_tiled() -> None:
    from panomap.calibrate.boards.detect import find_boards
    from panomap.calibrate.boards.fit import fit_boards
    from panomap.calibrate.lines.frame_circles import line_circles
    from panomap.errors import PanomapError

    image, truth = tiled_scene()
    clock = Clock()
    boards = find_boards(image)
    detect_s = clock.lap()
    near = distances([b.pixels for b in boards], truth)
    try:
        fit_boards(boards, line_circles(image))
        outcome = "fitted"
    except PanomapError as exc:
        outcome = f"refused: {exc.summary[:60]}"
    fit_s = clock.lap()
    print(
        f"  tiled 1600 x 1600 (wall / CPU s): find_boards {_pair(detect_s)}, {len(boards)} boards "
        f"({', '.join(f'{c} x {r}' for c, r in (b.shape for b in boards))}), corners against the truth median "
        f"{np.median(near):.3f} p90 {np.percentile(near, 90):.3f} max {near.max():.3f} px; circles + fit "
        f"{_pair(fit_s)} ({outcome})"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[1].parent / "shared/data/real")
    parser.add_argument("--contrib", type=Path, default=Path("/tmp/contrib"))
    parser.add_argument("--only", help="one set (its folder's name)")
    parser.add_argument("--no-tiled", action="store_true", help="leave the tiled picture out")
    parser.add_argument("--tiled-only", action="store_true", help="the tiled picture alone")
    parser.add_argument("--src", type=Path, help="another tree's src folder, whose panomap is measured")
    args = parser.parse_args()
    cv2 = load_cv2(args.contrib)
    if args.src is not None:
        sys.path.insert(0, str(args.src.resolve()))
    from bench_board_heldout import import_before_timing

    import_before_timing()
    print(f"OpenCV {cv2.__version__}, omnidir {'present' if hasattr(cv2, 'omnidir') else 'absent (not run)'}")
    if not args.tiled_only:
        if not args.data.is_dir():
            print(f"  no real sets at {args.data} (--data)")
        else:
            for folder in sorted(p for p in args.data.iterdir() if (p / "corners.csv").is_file()):
                if args.only is None or args.only == folder.name:
                    measure(folder, cv2)
    if not args.no_tiled:
        measure_tiled()


if __name__ == "__main__":
    main()
