"""The projection uncertainty of a checkerboard fit (issue 54, item 2), against the real sets' calibrations.

Run: ``PYTHONPATH=src python bench/bench_board_uncertainty.py [--data ../shared/data/real] [--only SET]``
and ``... --simulated`` for the coverage on simulated boards (``tests/test_board_uncertainty.py``'s cameras and
truth: each condition's share of the rings inside the boards' field whose true error lies within their band).

For each real set (each folder's SOURCE.md): the boards of every image pooled, and each image alone, fitted
(``fit_boards``); each fit's 95% band (:mod:`panomap.calibrate.boards.uncertainty`) ring by ring inside the
boards' field beside the true error there (the calibration's rays of the ring's pixels, turned by the best
rotation over the field's rings, projected by the fit: the ring's largest distance), and whether the fit is
refused (``LineFit.refusal``); and each image as ``panomap fit -o T --image IMG`` learns it (its boards and its
lines, ``learn_camera``): refused, or which camera it kept and how far (p90 px over the field) it lies. The true
error holds more than the corners' noise (the radial law, the
detector's bias, the calibration's own error: the floor of ``bench_boards.py``), so the band is a lower
bound of it here; on simulated corners it covers the error 95% of the time (tests/test_board_uncertainty.py).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from bench_boards import reference_of
from panomap.calibrate.boards.choice import learn_camera
from panomap.calibrate.boards.detect import find_boards
from panomap.calibrate.boards.fit import fit_boards, project
from panomap.calibrate.lines.arcs import find_arcs
from panomap.calibrate.lines.fit import LineFit, LineFitOptions
from panomap.calibrate.lines.frame_circles import line_circles
from panomap.errors import PanomapError
from panomap.io.images import read_image


def ring_errors(fit: LineFit, reference) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per ring inside the boards' field: its angle (deg), the band (px) and the true error (px, its largest)."""
    band = fit.report.projection
    assert band is not None
    model = fit.model
    params = np.array([*model.centre, *model.radial.coefficients])
    alpha, phi = np.radians(band.alpha_deg), np.radians(band.azimuth_deg)
    sine = np.sin(alpha)[:, None]
    rays = np.stack(np.broadcast_arrays(sine * np.cos(phi), sine * np.sin(phi), np.cos(alpha)[:, None]), -1)
    rays = rays.reshape(-1, 3)
    pixels = project(model.radial.kind, model.axis, params, rays)
    truth = reference(pixels)
    inside = band.inside()
    ok = np.repeat(inside, phi.size) & np.all(np.isfinite(truth), axis=1)
    u, _, vt = np.linalg.svd(rays[ok].T @ truth[ok])
    back = project(model.radial.kind, model.axis, params, truth @ (u @ vt).T)
    error = np.hypot(*(back - pixels).T).reshape(alpha.size, phi.size)
    error = np.where(np.isfinite(error), error, np.inf).max(axis=1)
    return np.asarray(band.alpha_deg)[inside], np.asarray(band.ring_band_px)[inside], error[inside]


def line(fit: LineFit, reference) -> str:
    alpha, band, error = ring_errors(fit, reference)
    worst = int(np.argmax(band))
    refused = fit.refusal()
    covered = float(np.mean(error <= band))
    return (
        f"band worst {band[worst]:.2f} px at {alpha[worst]:.0f} deg (median {np.median(band):.2f}); true error worst "
        f"{error.max():.2f} px (median {np.median(error):.2f}); rings within the band {covered:.0%}; "
        + ("REFUSED" if refused else "accepted")
    )


# Simulated conditions: camera, law (given), boards, noise px per coordinate, sets.
SIMULATED = [
    ("equidistant", "odd1", 3, 0.3, 200),
    ("hyperbolic", "unified", 5, 0.3, 100),
    ("equidistant", "odd1", 6, 0.5, 100),
    ("parabolic", "unified", 8, 0.2, 100),
]


def simulated() -> None:
    """Coverage per condition (the sets seeded 0, 1, ...; a set's rings share its fit's error)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from test_board_fit import boards_of, level
    from test_board_uncertainty import ring_errors as true_ring_errors

    from helpers import true_circles

    for name, law, count, noise_px, sets in SIMULATED:
        camera = level(name)
        covered: list[bool] = []
        start = time.perf_counter()
        for seed in range(sets):
            boards = boards_of(camera, count, seed=seed, noise_px=noise_px)
            fit = fit_boards(boards, true_circles(camera), LineFitOptions(model=law))
            error, band = true_ring_errors(fit, camera)
            covered += list(error <= band)
        seconds = time.perf_counter() - start
        print(f"{name}, {count} boards, {noise_px} px, {sets} sets: {np.mean(covered):.1%} ({seconds:.0f} s)")
        sys.stdout.flush()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[1].parent / "shared/data/real")
    parser.add_argument("--only", help="one set (its folder's name)")
    parser.add_argument("--simulated", action="store_true", help="the coverage on simulated boards instead")
    args = parser.parse_args()
    if args.simulated:
        simulated()
        return
    if not args.data.is_dir():
        print(f"no real data at {args.data}: nothing to measure")
        return
    for folder in sorted(p for p in args.data.iterdir() if p.is_dir()):
        if args.only and folder.name != args.only:
            continue
        _, reference = reference_of(folder)
        paths = sorted((folder / "images").iterdir())
        images = [read_image(p) for p in paths]
        circles = line_circles(images[0])
        found = [find_boards(image, k) for k, image in enumerate(images)]
        print(f"{folder.name}: {sum(map(len, found))} boards in {len(images)} images")
        start = time.perf_counter()
        try:
            fit = fit_boards([b for boards in found for b in boards], circles)
            print(f"  all images ({time.perf_counter() - start:.1f} s, {fit.report.model}): {line(fit, reference)}")
        except PanomapError as exc:
            print(f"  all images: no fit ({exc.summary})")
        refused = written = 0
        for k, boards in enumerate(found):
            try:
                one = fit_boards(boards, circles)
            except PanomapError as exc:
                print(f"    {paths[k].name}: no fit ({exc.summary})")
                continue
            refused += one.refusal() is not None
            print(f"    {paths[k].name} ({one.report.model}, {one.report.boards} board(s)): {line(one, reference)}")
            try:  # as `panomap fit --image IMG` learns it: the board refused, the lines may still give a camera
                learned = learn_camera(
                    find_boards(images[k], 0), find_arcs(images[k], circles, image_index=0), circles, LineFitOptions()
                )
            except PanomapError as exc:
                print(f"      fit --image: refused: {exc.summary}")
                continue
            written += 1
            print(f"      fit --image: WRITTEN from the {learned.source}")
        print(f"  one image: {refused} of {len(found)} boards' cameras refused; fit --image wrote {written}")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
