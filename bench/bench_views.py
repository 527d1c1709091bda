"""Building view maps, and applying them with float or fixed-point maps.

Run: ``.venv/bin/python bench/bench_views.py [--quick]``

From a simulated 1920 x 1920 parabolic-mirror omni-image and its default table, the
script times building the map of each view (the issue's budget: a 1280 x 720
perspective view in under 15 ms), and remapping one frame with float maps and with
OpenCV's fixed-point maps (``Remapper(fixed_point=True)``). Times are medians;
absolute figures drift by +-30% on shared machines, so each is also given as a ratio
to a baseline taken in the same run: ``cv2.remap`` of one 1280 x 720 frame (bilinear,
3 x 8 bits) with the perspective view's map.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time
from collections.abc import Callable

import cv2
import numpy as np

from panomap.calibrate.fit import fit_camera
from panomap.calibrate.landmarks import Landmarks
from panomap.calibrate.make_table import create_table
from panomap.remap import Remapper
from panomap.simulate import standard_cameras
from panomap.simulate.sampling import spread_landmarks
from panomap.views import Band, CylinderPanorama, FloorView, GenericPanorama, PerspectiveView, View, build_map

IMAGE_SIZE = (1920, 1920)
BUDGET_MS = 15.0


def median_time(function: Callable[[], object], repeats: int) -> float:
    function()  # warm up (caches, the table's sampling images)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats")
    args = parser.parse_args()
    repeats = 5 if args.quick else 31

    camera = standard_cameras(IMAGE_SIZE)["parabolic"]
    position = (0.0, 0.0, 2.5)
    landmarks = Landmarks(*spread_landmarks(camera, position, 20, np.random.default_rng(0)))
    fit = fit_camera(landmarks, position, camera.centre, image_size=IMAGE_SIZE)
    table = create_table(
        fit, image_size=IMAGE_SIZE, cutoff_radius=camera.cutoff_radius, outer_radius=camera.outer_radius
    )
    frame = np.random.default_rng(1).integers(0, 256, (*IMAGE_SIZE[::-1], 3), dtype=np.uint8)

    perspective = PerspectiveView(math.radians(30), math.radians(-35), 0.0, math.radians(90), (1280, 720))
    views: dict[str, View] = {
        "perspective 1280 x 720, fov 90, pitch -35": perspective,
        "perspective 1280 x 720, fov 150, straight down": PerspectiveView(
            0.0, -math.pi / 2, 0.0, math.radians(150), (1280, 720)
        ),
        "floor 1280 x 720": FloorView(0.0, (-4.0, 4.0), (-2.25, 2.25), (1280, 720)),
        "cylinder 2048 x 512": CylinderPanorama(2.0, Band(-2.4, 0.3), (2048, 512)),
        "generic panorama 2048 x 512": GenericPanorama((2048, 512)),
    }
    map_uv = build_map(table, perspective)
    map_u = np.ascontiguousarray(np.nan_to_num(map_uv[..., 0]))
    map_v = np.ascontiguousarray(np.nan_to_num(map_uv[..., 1]))
    baseline = median_time(lambda: cv2.remap(frame, map_u, map_v, cv2.INTER_LINEAR), repeats)

    print(f"table {table.size[0]} x {table.size[1]} for a {IMAGE_SIZE[0]} x {IMAGE_SIZE[1]} omni-image")
    print(f"baseline: cv2.remap of one 1280 x 720 frame (bilinear): {baseline * 1e3:.2f} ms")
    print(f"{'build the map of':<48} {'time':>9} {'ns/px':>7} {'x baseline':>11}")
    perspective_ms = 0.0
    for label, view in views.items():
        seconds = median_time(lambda view=view: build_map(table, view), repeats)
        width, height = view.output_size(table)
        print(f"{label:<48} {seconds * 1e3:7.2f}ms {seconds / (width * height) * 1e9:7.1f} {seconds / baseline:10.2f}x")
        if view is perspective:
            perspective_ms = seconds * 1e3
    verdict = "within" if perspective_ms < BUDGET_MS else "OVER"
    print(f"perspective 1280 x 720 map: {perspective_ms:.2f} ms, {verdict} the {BUDGET_MS:.0f} ms budget")

    print(f"{'remap one frame to 1280 x 720':<48} {'float':>9} {'fixed':>9} {'fixed/float':>11} {'map bytes':>15}")
    for interpolation in ("linear", "nearest"):
        remappers = [Remapper(map_uv, IMAGE_SIZE, interpolation, fixed_point=fixed) for fixed in (False, True)]
        float_s, fixed_s = (median_time(lambda r=r: r(frame), repeats) for r in remappers)
        sizes = [r._map1.nbytes + (0 if r._map2 is None else r._map2.nbytes) for r in remappers]
        outputs = [r(frame) for r in remappers]
        differ = float(np.mean(np.any(outputs[0] != outputs[1], axis=-1)))
        print(
            f"{'Remapper, ' + interpolation:<48} {float_s * 1e3:7.2f}ms {fixed_s * 1e3:7.2f}ms "
            f"{fixed_s / float_s:10.2f}x {sizes[0]:>7} {sizes[1]:>7}  ({differ:.1%} of pixels differ)"
        )


if __name__ == "__main__":
    main()
