"""Landmarks with and without the lines of an image of the same camera, against the oracle: tilted rendered rooms.

Run: ``.venv/bin/python bench/bench_joint.py [--trials 4] [--counts 5 8 12] [--cameras fisheye190 hyperbolic]``

Each trial renders the room of ``panomap.simulate.line_scenes`` through a camera of
:func:`panomap.simulate.line_scenes.line_camera` (a 190 deg equidistant fisheye on a 1920 x 1080
sensor, the circle cut by the frame; a hyperbolic mirror on 1600 x 1200), its axis tilted by a uniform
1-3 deg toward a random azimuth, with vignetting, sensor noise and JPEG. Landmarks on the room's walls,
floor and ceiling, spread in elevation (5, 8 and 12 of them), with 1 px noise on each pixel coordinate
and 1 cm on each world coordinate; the camera position given exactly (the fit may refine it with its
default prior). Fits:

- **landmarks**: ``calibrate_camera`` with the image, no lines (the centre and radii found in the image,
  the centre refined): ``panomap fit LANDMARKS --image IMG --no-lines``;
- **landmarks + lines**: the same with the image's lines joined (``panomap fit LANDMARKS --image IMG``,
  the default);
- **oracle**: ``fit_camera`` knowing the true radial family (``odd1``, ``unified``), the true centre
  and annulus, from the same landmarks (the floor of a landmark fit, as in ``bench/bench_mount.py``);
- **oracle + lines**: the oracle with the lines joined (the true family forced on the joint fit).

Per trial, the worst pixel error over test points on the room's surfaces at every elevation the camera
sees, at least 5 px inside the annulus and inside the frame (inf where the fit fails). Printed per camera
and landmark count: median / p90 / worst trial, the lines joined (median) and their RMS (px, median).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from panomap.calibrate.circles import find_image_circles
from panomap.calibrate.landmarks.fit import CameraFit, fit_camera
from panomap.calibrate.landmarks.joint import ImageLines
from panomap.calibrate.landmarks.pairs import Landmarks
from panomap.calibrate.landmarks.pipeline import calibrate_camera
from panomap.calibrate.lines.arcs import find_arcs
from panomap.errors import PanomapError
from panomap.geometry import FloatArray, azimuth_elevation
from panomap.simulate.cameras import TiltedCamera
from panomap.simulate.line_scenes import ROOM_X, ROOM_Y, ROOM_Z, line_camera, render_line_scene

FITS = ("landmarks", "landmarks + lines", "oracle", "oracle + lines")
TRUE_FAMILY = {"fisheye190": "odd1", "hyperbolic": "unified"}
EDGE_PX = 5.0
PIXEL_SIGMA = 1.0
WORLD_SIGMA = 0.01
# The bench renders at this fraction of the sensor's size by default (1.0: full size).
SCALE = 1.0


def hit_room(directions: FloatArray) -> FloatArray:
    """Where rays (n, 3) from the camera (at the origin) meet the room's walls, floor or ceiling (n, 3), m."""
    t = np.full(len(directions), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for axis, bounds in enumerate((ROOM_X, ROOM_Y, ROOM_Z)):
            for value in bounds:
                hit = value / directions[:, axis]
                t = np.where((hit > 0) & (hit < t), hit, t)
    return np.asarray(directions * t[:, None])


def usable(camera: TiltedCamera, pixels: FloatArray) -> FloatArray:
    """Which pixels (n, 2) are inside the frame and at least EDGE_PX inside the annulus."""
    width, height = camera.image_size
    radius = np.hypot(pixels[:, 0] - camera.centre[0], pixels[:, 1] - camera.centre[1])
    inside = (radius >= camera.cutoff_radius + EDGE_PX) & (radius <= camera.outer_radius - EDGE_PX)
    inside &= (pixels[:, 0] >= EDGE_PX) & (pixels[:, 0] <= width - 1 - EDGE_PX)
    inside &= (pixels[:, 1] >= EDGE_PX) & (pixels[:, 1] <= height - 1 - EDGE_PX)
    return np.asarray(inside & np.all(np.isfinite(pixels), axis=1))


def directions_at(camera: TiltedCamera, theta: FloatArray, rho: FloatArray) -> FloatArray:
    """World directions of rays at camera-frame azimuths ``theta`` and elevations ``rho`` (rad)."""
    d = np.stack([np.cos(rho) * np.cos(theta), np.cos(rho) * np.sin(theta), np.sin(rho)], axis=-1)
    return np.asarray(d @ camera.rotation.T)


def landmarks_of(camera: TiltedCamera, count: int, rng: np.random.Generator) -> Landmarks:
    """``count`` landmarks spread in elevation (camera axes), inside the frame, with 1 px / 1 cm noise."""
    low, high = camera.elevation_range
    pixels, world = [], []
    for rho in np.linspace(low + math.radians(2), high - math.radians(2), count):
        for _ in range(200):
            point = hit_room(directions_at(camera, rng.uniform(0, 2 * math.pi, 1), np.array([rho])))
            pixel = camera.project(point)
            if usable(camera, pixel)[0]:
                break
        pixels.append(pixel[0] + rng.normal(0, PIXEL_SIGMA, 2))
        world.append(point[0] + rng.normal(0, WORLD_SIGMA, 3))
    return Landmarks(np.array(pixels), np.array(world), tuple(f"L{k + 1}" for k in range(count)), (0.0, 0.0, 0.0))


def test_points(camera: TiltedCamera) -> tuple[FloatArray, FloatArray]:
    """World points (n, 3) over the camera's view and their true pixels (n, 2)."""
    low, high = camera.elevation_range
    theta, rho = np.meshgrid(np.linspace(0, 2 * math.pi, 120, endpoint=False), np.linspace(low, high, 60))
    world = hit_room(directions_at(camera, theta.ravel(), rho.ravel()))
    truth = camera.project(world)
    keep = usable(camera, truth)
    return world[keep], truth[keep]


def worst_error(fit: CameraFit, world: FloatArray, truth: FloatArray) -> float:
    theta, rho = azimuth_elevation(world - np.asarray(fit.camera_position))
    error = np.linalg.norm(fit.model.pixels(theta, rho) - truth, axis=1)
    return float(np.max(np.where(np.isfinite(error), error, np.inf)))


def run(job: tuple[str, int, tuple[int, ...]]) -> tuple[str, dict[int, dict[str, tuple[float, int, float]]]]:
    """One rendered camera: per landmark count, each fit's worst error, its lines joined and their RMS (px)."""
    kind, seed, counts = job
    rng = np.random.default_rng(seed)
    camera = line_camera(kind, SCALE, tilt_deg=rng.uniform(1.0, 3.0), toward_deg=rng.uniform(0, 360))
    image = render_line_scene(camera, seed=seed, supersample=2).image
    world, truth = test_points(camera)
    circles = find_image_circles(image)
    arcs = find_arcs(image, circles)
    true_annulus = (float(camera.cutoff_radius), float(camera.outer_radius))
    out: dict[int, dict[str, tuple[float, int, float]]] = {}
    for count in counts:
        landmarks = landmarks_of(camera, count, np.random.default_rng(seed * 100 + count))
        row: dict[str, tuple[float, int, float]] = {}
        for label in FITS:
            try:
                if label.startswith("landmarks"):
                    fit = calibrate_camera(
                        landmarks, omni=image, pixel_sigma=PIXEL_SIGMA, world_sigma=WORLD_SIGMA,
                        lines=label.endswith("lines"),
                    ).fit  # fmt: skip
                else:
                    fit = fit_camera(
                        landmarks, (0.0, 0.0, 0.0), camera.centre, model=TRUE_FAMILY[kind],
                        image_size=camera.image_size, annulus=true_annulus, pixel_sigma=PIXEL_SIGMA,
                        world_sigma=WORLD_SIGMA, lines=ImageLines(arcs, circles) if label.endswith("lines") else None,
                    )  # fmt: skip
            except PanomapError:
                row[label] = (math.inf, 0, math.nan)
                continue
            joined = fit.lines
            row[label] = (
                worst_error(fit, world, truth),
                0 if joined is None else len(joined.lines),
                math.nan if joined is None else joined.rms_px,
            )
        out[count] = row
    return kind, out


def summary(values: FloatArray) -> str:
    failed = int(np.count_nonzero(~np.isfinite(values)))
    median, p90 = (float(np.percentile(values, q, method="higher")) for q in (50, 90))
    worst = f"fails ({failed})" if failed else f"{float(np.max(values)):.2f}"
    return f"{median:.2f} / {p90:.2f} / {worst}" if math.isfinite(p90) else f"{median:.2f} / fails / {worst}"


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--trials", type=int, default=4)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--counts", nargs="*", type=int, default=[5, 8, 12])
    parser.add_argument("--cameras", nargs="*", default=list(TRUE_FAMILY), choices=list(TRUE_FAMILY))
    args = parser.parse_args()
    jobs = [(kind, 7 * t + 3, tuple(args.counts)) for kind in args.cameras for t in range(args.trials)]
    results: dict[tuple[str, int], list[dict[str, tuple[float, int, float]]]] = {}
    start = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as pool:
        for kind, rows in pool.map(run, jobs):
            for count, row in rows.items():
                results.setdefault((kind, count), []).append(row)
    print(
        f"{args.trials} trials per camera, {time.perf_counter() - start:.0f} s; worst error (px) over the test "
        "points: median / p90 / worst trial ('fails (k)': k trials with no fit)"
    )
    print("| camera | n landmarks | " + " | ".join(FITS) + " | lines joined | line RMS px |")
    print("| --- | --- | " + " | ".join("---" for _ in FITS) + " | --- | --- |")
    for kind in args.cameras:
        for count in args.counts:
            rows = results[(kind, count)]
            cells = [summary(np.array([row[label][0] for row in rows])) for label in FITS]
            joined = np.array([row["landmarks + lines"][1] for row in rows])
            rms = np.array([row["landmarks + lines"][2] for row in rows])
            rms_text = f"{np.nanmedian(rms):.2f}" if np.isfinite(rms).any() else "-"
            print(f"| {kind} | {count} | " + " | ".join(cells) + f" | {int(np.median(joined))} | {rms_text} |")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
