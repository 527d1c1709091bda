"""Learning the camera from the checkerboards in its images: the issue's real-camera goal, measured.

Run: ``.venv/bin/python bench/bench_boards.py [--data ../shared/data/real] [--quick]``

The measure is :func:`bench_lines.ray_agreement` (the established calibration's rays against the
learned camera's after the best rotation of the frame, over the radii where the calibration has
corners; goal p90 <= 1.0 and max <= 2.0 px). For each real set (``--data``; each folder's SOURCE.md):

- **all images**: every board found (``find_boards``) pooled in one ``fit_boards``; beside it the
  same images through the edge-arc line fit (``fit_lines``, what ``--no-boards`` gives), the baseline;
- **one image**: each image as ``panomap fit -o T --image IMG`` learns it (its boards and its lines,
  ``learn_camera``); median, best and worst p90 over the images;
- **the floor**: the fit given the corners the calibration itself was made from (``corners.csv``, with
  their places on the board), where the file has the board coordinates: how far the best any board fit
  can do on this set's own corners lies from the calibration (the calibration's own law and the
  corners' noise).
- times: boards' detection per image, fit, and the line fit beside them.

And **rendered sets** (``--only sim``; :mod:`panomap.simulate.board_scenes`): the issue's two cameras (a
190 deg fisheye on 16:9, a hyperbolic mirror on 4:3, tilted 2 deg, vignetting, noise, JPEG), boards held
around them, two per image, in several images and in one; the camera learned by ``find_boards`` and
``fit_boards`` against the true one over the whole annulus; beside it the floor, the same fit from the
true corners (no detection) with the true law forced.
"""

from __future__ import annotations

import argparse
import collections
import csv
import json
import sys
import time
from pathlib import Path

import numpy as np

from bench_lines import (
    corner_radii,
    line_fit,
    mei_rays,
    ocam_rays,
    ray_agreement,
    ring_grid,
    simulated_rays,
    true_circles,
    true_model_of,
)
from panomap.calibrate.boards.choice import learn_camera
from panomap.calibrate.boards.detect import Board, find_boards
from panomap.calibrate.boards.fit import fit_boards
from panomap.calibrate.lines.arcs import find_arcs
from panomap.calibrate.lines.fit import LineFitOptions
from panomap.calibrate.lines.frame_circles import line_circles
from panomap.errors import PanomapError
from panomap.io.images import read_image
from panomap.simulate.board_scenes import board_poses, render_board_scene
from panomap.simulate.line_scenes import line_camera


def reference_of(folder: Path):
    if (folder / "omnidir_calibration.json").is_file():
        model = json.loads((folder / "omnidir_calibration.json").read_text())
        k = model["models"][model["primary"]]["K"]
        return (float(k[0][2]), float(k[1][2])), mei_rays(model)
    model = json.loads((folder / "ocam_model.json").read_text())
    return (float(model["yc_col_0based"]), float(model["xc_row_0based"])), ocam_rays(model)


def calibration_boards(folder: Path, names: list[str]) -> list[Board]:
    """The corners the calibration was made from, with their places on the board (squares)."""
    with (folder / "corners.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    by_image: dict[str, list[dict[str, str]]] = collections.defaultdict(list)
    for row in rows:
        by_image[row["image"]].append(row)
    boards = []
    for name, these in sorted(by_image.items()):
        u_key, v_key = ("u_col_px", "v_row_px") if "u_col_px" in these[0] else ("col_px", "row_px")
        pixels = np.array([[float(r[u_key]), float(r[v_key])] for r in these])
        board = np.array([[float(r["board_x_mm"]), float(r["board_y_mm"])] for r in these])
        steps = np.diff(np.unique(board[:, 0]))
        square = float(steps[steps > 1e-6].min())
        grid = np.round((board - board.min(axis=0)) / square).astype(np.intp)
        boards.append(Board(names.index(name), pixels, grid))
    return boards


def rendered(quick: bool) -> None:
    print("== rendered sets: learned from boards vs the true camera over the whole annulus (after the best rotation)")
    scale = 0.5 if quick else 0.75
    for kind, law in (("fisheye190", "odd1"), ("hyperbolic", "unified")):
        camera = line_camera(kind, scale, tilt_deg=2.0)
        grid = ring_grid(camera.centre, camera.cutoff_radius + 1.0, camera.outer_radius - 1.0, camera.image_size)
        reference = simulated_rays(camera)
        print(
            f"  {kind} {camera.image_size[0]} x {camera.image_size[1]}, tilt 2 deg; measure check, true model: "
            f"{ray_agreement(reference, grid, true_model_of(camera)).line()}"
        )
        for images in (1, 3) if quick else (1, 3, 6):
            found: list[Board] = []
            truth: list[Board] = []
            detect_s = 0.0
            for k in range(images):
                scene = render_board_scene(camera, board_poses(camera, 2, seed=10 * images + k), seed=k, supersample=2)
                start = time.perf_counter()
                found += find_boards(scene.image, k)
                detect_s += time.perf_counter() - start
                truth += [Board(k, t.pixels, t.grid.astype(np.intp)) for t in scene.truth]
            circles = true_circles(camera)
            start = time.perf_counter()
            try:
                fit = fit_boards(found, circles)
                verdict = ray_agreement(reference, grid, fit.model).line()
            except PanomapError as exc:
                verdict = f"no fit ({exc})"
            fit_s = time.perf_counter() - start
            try:
                floor = ray_agreement(
                    reference, grid, fit_boards(truth, circles, LineFitOptions(model=law)).model
                ).line()
            except PanomapError as exc:
                floor = f"none ({exc})"
            print(
                f"    {images} image(s), {len(found)} of {len(truth)} boards found ({detect_s / images:.1f} s per "
                f"image), fit {fit_s:.1f} s: {verdict}"
            )
            print(f"      floor (true corners, the true law {law}): {floor}")
        sys.stdout.flush()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[1].parent / "shared/data/real")
    parser.add_argument("--quick", action="store_true", help="smaller renders, and no line fit beside the boards")
    parser.add_argument("--only", choices=("sim", "real"), help="one part only")
    args = parser.parse_args()
    if args.only != "real":
        rendered(args.quick)
    if args.only == "sim":
        return
    if not args.data.is_dir():
        print(f"no real data at {args.data}: nothing to measure")
        return
    print("== real cameras: learned from checkerboards vs the established calibration over the corners' radii")
    for folder in sorted(p for p in args.data.iterdir() if p.is_dir()):
        centre, reference = reference_of(folder)
        r_min, r_max, _ = corner_radii(folder, centre)
        paths = sorted((folder / "images").iterdir())
        images = [read_image(p) for p in paths]
        h, w = images[0].shape[:2]
        grid = ring_grid(centre, r_min, r_max, (w, h))
        circles = line_circles(images[0])
        start = time.perf_counter()
        boards = [board for k, image in enumerate(images) for board in find_boards(image, k)]
        detect_s = (time.perf_counter() - start) / len(images)
        print(f"  {folder.name}: {len(boards)} boards in {len(images)} images ({w} x {h}), {detect_s:.2f} s per image")
        try:
            floor = ray_agreement(
                reference, grid, fit_boards(calibration_boards(folder, [p.name for p in paths]), circles).model
            )
            print(f"      floor (the calibration's own corners): {floor.line()}")
        except (PanomapError, KeyError, ValueError) as exc:
            print(f"      floor: none ({exc})")
        start = time.perf_counter()
        try:
            fit = fit_boards(boards, circles)
            print(
                f"      all images, boards: fit {time.perf_counter() - start:.1f} s, {fit.report.model}, corners RMS "
                f"{fit.report.corner_rms_px:.2f} px: {ray_agreement(reference, grid, fit.model).line()}"
            )
        except PanomapError as exc:
            print(f"      all images, boards: no fit ({exc})")
        if not args.quick:
            start = time.perf_counter()
            arcs = [arc for k, image in enumerate(images) for arc in find_arcs(image, circles, image_index=k)]
            try:
                verdict = ray_agreement(reference, grid, line_fit(arcs, circles)).line()
            except PanomapError as exc:
                verdict = f"no fit ({exc})"
            seconds = time.perf_counter() - start
            print(f"      all images, edge arcs (--no-boards, the baseline): {seconds:.1f} s: {verdict}")
        p90: list[float] = []
        largest: list[float] = []
        failed = 0
        worst = ""
        chose_boards = 0
        for k, image in enumerate(images):  # one image as `panomap fit -o T --image IMG` learns it
            try:
                learned = learn_camera(
                    find_boards(image, 0), find_arcs(image, circles, image_index=0), circles, LineFitOptions()
                )
                one = ray_agreement(reference, grid, learned.fit.model)
            except PanomapError:
                failed += 1
                continue
            chose_boards += learned.source == "checkerboards"
            if not p90 or one.p90_px > max(p90):
                worst = paths[k].name
            p90.append(one.p90_px)
            largest.append(one.max_px)
        if p90:
            print(
                f"      one image, as fit --image learns it ({len(p90)} images, boards kept on {chose_boards}): p90 "
                f"median {np.median(p90):.2f}, best {min(p90):.2f}, worst {max(p90):.2f} ({worst}); max px median "
                f"{np.median(largest):.2f}, worst {max(largest):.2f}; {sum(x <= 1.0 for x in p90)} meet p90 <= 1; "
                f"no fit {failed}"
            )
        sys.stdout.flush()


if __name__ == "__main__":
    main()
