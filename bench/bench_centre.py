"""Speed of finding the image circles, and the centres found in the real images.

Run: ``.venv/bin/python bench/bench_centre.py``

1. Times ``find_image_circles`` on a rendered 1920 x 1920 omni-image (noise and
   JPEG as in the tests) against decoding that JPEG, in the same run.
2. Where ``../shared/data/real`` is present, prints a Markdown table of the
   centre found in every real image against the centre of the established
   calibration shipped beside it (OCamCalib's; for the Mei folder, OpenCV's
   omnidir). Those calibrations estimate the optical axis, which can sit a few
   pixels off the rim's centre on a real mirror.
"""

from __future__ import annotations

import json
import math
import statistics
import time
from pathlib import Path

import cv2
import numpy as np

from panomap.calibrate.circles import find_image_circles
from panomap.errors import PanomapError
from panomap.io.images import read_image
from panomap.simulate import load_room, render, standard_cameras

REAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real"


def speed() -> None:
    rng = np.random.default_rng(0)
    camera = standard_cameras((1920, 1920), centre=(975.3, 941.8))["hyperbolic"]
    image = render(load_room(), camera, supersample=1)
    noisy = np.clip(image + rng.normal(0, 5, image.shape), 0, 255).astype(np.uint8)
    ok, encoded = cv2.imencode(".jpg", noisy, [cv2.IMWRITE_JPEG_QUALITY, 75])
    assert ok
    decoded = cv2.imdecode(encoded, cv2.IMREAD_UNCHANGED)

    def median_seconds(function: object, repeats: int = 7) -> float:
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            function()  # type: ignore[operator]
            times.append(time.perf_counter() - start)
        return statistics.median(times)

    decode = median_seconds(lambda: cv2.imdecode(encoded, cv2.IMREAD_UNCHANGED))
    detect = median_seconds(lambda: find_image_circles(decoded))
    found = find_image_circles(decoded)
    print("1920 x 1920 hyperbolic-mirror render, noise 5, JPEG 75:")
    print(f"  decode the JPEG (baseline): {decode * 1e3:7.1f} ms")
    print(f"  find_image_circles:         {detect * 1e3:7.1f} ms  ({detect / decode:.2f}x the decode)")
    print(
        f"  centre error {math.dist(found.centre, camera.centre):.3f} px, outer radius error "
        f"{found.outer_radius - camera.outer_radius:+.3f} px, cut-off radius error "
        f"{(found.cutoff_radius or 0) - camera.cutoff_radius:+.3f} px"
    )


def reference_centre(folder: Path) -> tuple[float, float] | None:
    """(u, v) centre of the calibration shipped in ``folder``, 0-based, pixel centres at integers."""
    ocam = folder / "ocam_model.json"
    if ocam.exists():
        model = json.loads(ocam.read_text())
        return float(model["yc_col_0based"]), float(model["xc_row_0based"])
    omnidir = folder / "omnidir_calibration.json"
    if omnidir.exists():
        data = json.loads(omnidir.read_text())
        k = data["models"][data["primary"]]["K"]
        return float(k[0][2]), float(k[1][2])
    return None


def real_table() -> None:
    if not REAL.is_dir():
        print(f"(no real data at {REAL}: skipped the real-image table)")
        return
    print()
    print(
        "| folder | images found / all | centre found (u, v), median | calibration centre | distance (px) | "
        "outer radius (px) | cut-off radius (px) | why not found |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for folder in sorted(p for p in REAL.iterdir() if p.is_dir()):
        reference = reference_centre(folder)
        found, reasons = [], []
        for path in sorted((folder / "images").iterdir()):
            try:
                found.append(find_image_circles(read_image(path)))
            except PanomapError as exc:
                reasons.append(exc.detail)
        total = len(found) + len(reasons)
        if found:
            u = statistics.median(c.centre[0] for c in found)
            v = statistics.median(c.centre[1] for c in found)
            outer = statistics.median(c.outer_radius for c in found)
            cutoffs = [c.cutoff_radius for c in found if c.cutoff_radius is not None]
            cutoff = f"{statistics.median(cutoffs):.1f} in {len(cutoffs)}" if cutoffs else "none"
            distance = f"{math.dist((u, v), reference):.2f}" if reference else "-"
            centre = f"({u:.2f}, {v:.2f})"
        else:
            centre = distance = outer_text = cutoff = "-"
        outer_text = f"{outer:.1f}" if found else "-"
        ref = f"({reference[0]:.2f}, {reference[1]:.2f})" if reference else "-"
        why = reasons[0] if reasons else ""
        print(
            f"| {folder.name} | {len(found)} / {total} | {centre} | {ref} | {distance} | {outer_text} | {cutoff} "
            f"| {why} |"
        )


if __name__ == "__main__":
    speed()
    real_table()
