"""Speed of finding the image circles, and the centres found in the real images.

Run: ``.venv/bin/python bench/bench_centre.py``

1. Times ``find_image_circles`` on 1920 x 1920 omni-images (noise and JPEG as in
   the tests) against decoding each JPEG, in the same run: the bundled textured
   room through a mirror camera, the same in a bright blurred housing (a rim of either
   polarity, no dark border), that housing as bright as the mirror on half the rim
   (``housed_mirror(faint=0.5)``), a checkerboard filling the view, and a fisheye
   whose circle a 16:9 frame (1920 x 1080) cuts at top and bottom; and a full-frame
   fisheye (its circle holds the whole 1920 x 1920 frame: no rim), the slowest case,
   where every stage runs and none passes.
2. Where the real data sets (not bundled) are present, prints a Markdown table of
   the centre found in every real image against the centre of the established
   calibration shipped beside it (OCamCalib's; for the Mei folder, OpenCV's
   omnidir). Those calibrations estimate the optical axis, which can sit a few
   pixels off the rim's centre on a real mirror.
"""

from __future__ import annotations

import json
import math
import statistics
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from panomap.calibrate.circles import ImageCircles, NoImageCircle, find_image_circles
from panomap.io.images import read_image
from panomap.simulate import housed_mirror, load_room, render, standard_cameras

REAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real"


def median_seconds(function: Callable[[], object], repeats: int = 7) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def scenes() -> dict[str, tuple[np.ndarray, object]]:
    """Name: (8-bit BGR image, the simulated camera it was made with)."""
    room = load_room()
    mirror = standard_cameras((1920, 1920), centre=(975.3, 941.8))["hyperbolic"]
    # A checkerboard of 48 px squares filling the annulus: edges everywhere, as in a calibration image.
    v, u = np.mgrid[0:1920, 0:1920]
    r = np.hypot(u - mirror.centre[0], v - mirror.centre[1])
    board = np.where((u // 48 + v // 48) % 2 == 0, 235, 25).astype(np.uint8)
    checker = np.where((r < mirror.outer_radius) & (r > mirror.cutoff_radius), board, 0).astype(np.uint8)
    checker = cv2.cvtColor(cv2.GaussianBlur(checker, (0, 0), 0.7), cv2.COLOR_GRAY2BGR)
    fisheye = standard_cameras((1920, 1080), centre=(961.7, 538.4), outer_radius=600.0)["equidistant"]
    full_frame = standard_cameras((1920, 1920), centre=(963.3, 957.9), outer_radius=1400.0)["equidistant"]
    housed = housed_mirror(
        render(room, mirror, supersample=1),
        mirror.centre,
        mirror.outer_radius,
        mirror.cutoff_radius,
        np.random.default_rng(1),
    )
    faint = housed_mirror(
        render(room, mirror, supersample=1),
        mirror.centre,
        mirror.outer_radius,
        mirror.cutoff_radius,
        np.random.default_rng(2),
        faint=0.5,
    )
    return {
        "textured room, hyperbolic mirror, 1920 x 1920": (render(room, mirror, supersample=1), mirror),
        "the same mirror in a bright blurred housing (rim of either polarity), 1920 x 1920": (housed, mirror),
        "the same, the rim without contrast on half of it, 1920 x 1920": (faint, mirror),
        "checkerboard filling the view, 1920 x 1920": (checker, mirror),
        "fisheye cut at top and bottom, 1920 x 1080": (render(room, fisheye, supersample=1), fisheye),
        "full-frame fisheye (no rim in the frame), 1920 x 1920": (render(room, full_frame, supersample=1), None),
    }


def _find_or_none(image: np.ndarray) -> ImageCircles | None:
    try:
        return find_image_circles(image)
    except NoImageCircle:
        return None


def speed() -> None:
    rng = np.random.default_rng(0)
    for name, (image, camera) in scenes().items():
        noisy = np.clip(image + rng.normal(0, 5, image.shape), 0, 255).astype(np.uint8)
        ok, encoded = cv2.imencode(".jpg", noisy, [cv2.IMWRITE_JPEG_QUALITY, 75])
        assert ok
        decoded = cv2.imdecode(encoded, cv2.IMREAD_UNCHANGED)
        decode = median_seconds(lambda: cv2.imdecode(encoded, cv2.IMREAD_UNCHANGED))  # noqa: B023
        detect = median_seconds(lambda: _find_or_none(decoded))  # noqa: B023
        found = _find_or_none(decoded)
        print(f"{name}, noise 5, JPEG 75:")
        print(f"  decode the JPEG (baseline): {decode * 1e3:7.1f} ms")
        print(f"  find_image_circles:         {detect * 1e3:7.1f} ms  ({detect / decode:.2f}x the decode)")
        if found is None or camera is None:
            verdict = "right" if (found is None) == (camera is None) else "WRONG"
            print(f"  {'no image circle found (NoImageCircle)' if found is None else 'a circle reported'}: {verdict}")
            continue
        print(
            f"  centre error {math.dist(found.centre, camera.centre):.3f} px, outer radius error "  # type: ignore[attr-defined]
            f"{found.outer_radius - camera.outer_radius:+.3f} px, cut-off radius error "  # type: ignore[attr-defined]
            f"{(found.cutoff_radius or 0) - camera.cutoff_radius:+.3f} px, "  # type: ignore[attr-defined]
            f"cropped by {', '.join(found.cropped_by) or 'nothing'}, rim seen on {found.rim_seen:.0%} of the rays"
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
        "| folder | found / all | cut-off disc in | centre found (u, v), median | calibration centre | "
        "distance (px), median / worst | outer radius (px) | cropped by | rim seen | time per image (ms) |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for folder in sorted(p for p in REAL.iterdir() if p.is_dir()):
        reference = reference_centre(folder)
        found, reasons, times = [], [], []
        for path in sorted((folder / "images").iterdir()):
            image = read_image(path)
            start = time.perf_counter()
            try:
                found.append(find_image_circles(image))
            except NoImageCircle as exc:
                reasons.append(exc.detail)
            times.append(time.perf_counter() - start)
        total = len(found) + len(reasons)
        ref = f"({reference[0]:.2f}, {reference[1]:.2f})" if reference else "-"
        if not found:
            per_image = statistics.median(times) * 1e3
            print(f"| {folder.name} | 0 / {total} | - | - | {ref} | - | - | - | - | {per_image:.0f} |")
            continue
        u = statistics.median(c.centre[0] for c in found)
        v = statistics.median(c.centre[1] for c in found)
        outer = statistics.median(c.outer_radius for c in found)
        cutoffs = sum(c.cutoff is not None for c in found)
        distances = [math.dist(c.centre, reference) for c in found] if reference else []
        distance = f"{statistics.median(distances):.2f} / {max(distances):.2f}" if distances else "-"
        cropped = ", ".join(sorted({edge for c in found for edge in c.cropped_by})) or "-"
        seen = statistics.median(c.rim_seen for c in found)
        print(
            f"| {folder.name} | {len(found)} / {total} | {cutoffs} | ({u:.2f}, {v:.2f}) | {ref} | {distance} "
            f"| {outer:.1f} | {cropped} | {seen:.0%} | {statistics.median(times) * 1e3:.0f} |"
        )


if __name__ == "__main__":
    speed()
    real_table()
