"""The paper's per-pixel unwarping against ours (map built once, then cv2.remap).

Run: ``.venv/bin/python bench/bench_unwarp.py [--quick]``

Both make the same cylinder panorama (paper 2.3.2) with the paper's sampling
(floor table indices, nearest image pixel) from a simulated 1920 x 1920
omni-image; the script checks the outputs are equal, then prints the times
and their ratio. Times are medians; absolute figures drift by +-30% on shared
machines, so only the ratios in one run mean much.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time
from collections.abc import Callable

import numpy as np

from panomap.calibrate.landmarks.fit import fit_camera
from panomap.calibrate.landmarks.pairs import Landmarks
from panomap.calibrate.landmarks.table import create_table
from panomap.remap import Remapper
from panomap.simulate import standard_cameras
from panomap.simulate.sampling import spread_landmarks
from panomap.table.table import PanoMappingTable
from panomap.views import Band, CylinderPanorama, build_map

IMAGE_SIZE = (1920, 1920)


def paper_cylinder(table: PanoMappingTable, image: np.ndarray, view: CylinderPanorama) -> np.ndarray:
    """The paper's algorithm, pixel by pixel, in plain Python (eqs. 9-12, floor indices)."""
    m, n = table.size
    width, height = view.size
    rho_s, rho_e = table.elevation_range
    entries = table.entries
    image_height, image_width = image.shape[:2]
    out = np.zeros((height, width, *image.shape[2:]), image.dtype)
    for l in range(height):  # noqa: E741 (the paper names the row l)
        h_q = view.band.z_top - (l + 0.5) * (view.band.z_top - view.band.z_bottom) / height  # eq. 10
        rho_q = math.atan2(h_q, view.distance)  # eq. 11
        j = math.floor((rho_q - rho_s) * (n / (rho_e - rho_s)))  # eq. 12
        if not 0 <= j < n:
            continue
        for k in range(width):
            theta_q = (view.theta_start_rad - 2 * math.pi * (k + 0.5) / width) % (2 * math.pi)
            i = math.floor(theta_q * (m / (2 * math.pi))) % m  # eq. 9
            u, v = entries[i, j]
            col, row = round(float(u)), round(float(v))
            if 0 <= col < image_width and 0 <= row < image_height:
                out[l, k] = image[row, col]
    return out


def median_time(function: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller view, fewer repeats")
    args = parser.parse_args()
    view_size = (512, 128) if args.quick else (1024, 256)

    camera = standard_cameras(IMAGE_SIZE)["parabolic"]
    position = (0.0, 0.0, 2.5)
    landmarks = Landmarks(*spread_landmarks(camera, position, 20, np.random.default_rng(0)))
    fit = fit_camera(landmarks, position, camera.centre, image_size=IMAGE_SIZE)
    table = create_table(
        fit, image_size=IMAGE_SIZE, cutoff_radius=camera.cutoff_radius, outer_radius=camera.outer_radius
    )
    image = np.random.default_rng(1).integers(0, 256, (*IMAGE_SIZE[::-1], 3), dtype=np.uint8)
    view = CylinderPanorama(2.0, Band(-2.4, 0.3), view_size)

    paper_seconds = median_time(lambda: paper_cylinder(table, image, view), 1 if args.quick else 3)
    build_seconds = median_time(lambda: build_map(table, view, "nearest"), 5)
    remapper = Remapper(build_map(table, view, "nearest"), IMAGE_SIZE, "nearest")
    remap_seconds = median_time(lambda: remapper(image), 50)
    ours = remapper(image)
    reference = paper_cylinder(table, image, view)
    mismatched = int(np.count_nonzero(np.any(ours != reference, axis=-1)))

    default_map = build_map(table, view)
    default_remapper = Remapper(default_map, IMAGE_SIZE, "linear")
    default_seconds = median_time(lambda: default_remapper(image), 50)

    pixels = view_size[0] * view_size[1]
    print(
        f"cylinder panorama {view_size[0]} x {view_size[1]} from a {IMAGE_SIZE[0]} x {IMAGE_SIZE[1]} omni-image, "
        f"table {table.size[0]} x {table.size[1]}"
    )
    print(f"{'method':<48} {'time':>10} {'ns/px':>8} {'ratio':>8}")
    rows = [
        ("paper, per pixel in Python (floor, nearest)", paper_seconds),
        ("ours: build the map once (floor)", build_seconds),
        ("ours: remap one frame (floor, nearest)", remap_seconds),
        ("ours: build once + one frame", build_seconds + remap_seconds),
        ("ours default: remap one frame (bilinear, linear)", default_seconds),
    ]
    for label, seconds in rows:
        print(f"{label:<48} {seconds * 1e3:8.2f}ms {seconds / pixels * 1e9:8.1f} {paper_seconds / seconds:7.0f}x")
    print(f"outputs equal: {mismatched == 0} ({mismatched} of {pixels} pixels differ)")


if __name__ == "__main__":
    main()
