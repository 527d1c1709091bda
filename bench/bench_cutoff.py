"""Every cut-off disc the circle finder reports, against whether the camera has one (issue: a fisheye taken for a
mirror camera).

Run: ``PYTHONPATH=src .venv/bin/python bench/bench_cutoff.py [--real] [--renders]``

Real pictures (``../shared/data``, not bundled; skipped where absent): every picture of the real mirror cameras
(Kaidan, VMR, MiniOmni, Mei paracatadioptric: each has a cut-off disc) and of the fisheyes (the OCam fisheye,
the Theta, the DS building camera, each lens of the Insta360 Air's side-by-side frames, the surround-view and
car-park fisheyes: none has one). Renders: the bundled room through the standard fisheyes with a dark or a
bright thing straight ahead (a round blob or a square, 3-25% of the outer radius, at the image centre: a lamp,
an object in front), and through the standard mirror cameras (their disc, the housing's grey) with noise and
JPEG. Prints a Markdown table: the picture, whether its camera has a disc, the disc reported (radius px,
radius / outer radius) and whether the answer is right; then the count of wrong answers per set.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from panomap.calibrate.circles import NoImageCircle, find_image_circles
from panomap.io.images import read_image
from panomap.simulate import load_room, noisy_jpeg, render, standard_cameras

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
MIRRORS = ("ocam_kaidan_catadioptric", "ocam_miniomni_catadioptric", "ocam_vmr_catadioptric", "mei_paracatadioptric")


def real_pictures() -> Iterator[tuple[str, np.ndarray, bool]]:
    """(name, image, whether the camera has a cut-off disc) for every shared real picture."""
    for folder in sorted((DATA / "real").iterdir()):
        if not (folder / "images").is_dir():
            continue
        for image in sorted((folder / "images").iterdir()):
            yield f"{folder.name}/{image.name}", read_image(image), folder.name in MIRRORS
    for folder in ("scenes/theta_back/images", "scenes/ds_building/images", "rigs/neozhaoliang_surround_view/images"):
        for image in sorted((DATA / folder).iterdir()):
            yield f"{folder.split('/')[1]}/{image.name}", read_image(image), False
    for image in sorted((DATA / "rigs" / "pjlab_ocam_parking_surround" / "imgs").iterdir()):
        yield f"car park/{image.name}", read_image(image), False
    for image in sorted((DATA / "rigs" / "theta_table_pair").glob("*.jpg")):
        yield f"theta_table_pair/{image.name}", read_image(image), False
    for image in sorted((DATA / "rigs" / "insta360_air_dualfisheye" / "images").iterdir()):
        frame = read_image(image)
        side = frame.shape[0]
        for half in (0, 1):
            yield f"insta360/{image.stem} lens {half}", frame[:, half * side : (half + 1) * side], False


def centre_thing(
    image: np.ndarray, centre: tuple[float, float], size_px: float, level: float, square: bool
) -> np.ndarray:
    """``image`` with a thing of grey ``level`` at ``centre``: a disc of radius ``size_px`` or a square of that
    half-side, its edge blurred by 1 px."""
    height, width = image.shape[:2]
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    if square:
        inside = (np.abs(u - centre[0]) <= size_px) & (np.abs(v - centre[1]) <= size_px)
    else:
        inside = np.hypot(u - centre[0], v - centre[1]) <= size_px
    alpha = cv2.GaussianBlur(inside.astype(np.float64), (0, 0), 1.0)
    if image.ndim == 3:
        alpha = alpha[..., None]
    return np.clip(image * (1 - alpha) + level * alpha, 0, 255).astype(np.uint8)


def rendered_pictures(count: int) -> Iterator[tuple[str, np.ndarray, bool]]:
    """(name, image, has a disc): fisheyes with a centred dark or bright thing, mirror cameras with their disc."""
    room = load_room()
    for seed in range(count):
        rng = np.random.default_rng(900 + seed)
        size = ((640, 480), (800, 800), (1024, 768))[seed % 3]
        name = ("equidistant", "equisolid")[seed % 2]
        camera = standard_cameras(size, seed=seed)[name]
        image = render(room, camera, supersample=1)
        fraction = rng.uniform(0.03, 0.25)
        level, square = (rng.uniform(0, 30), rng.uniform(220, 255))[seed // 2 % 2], bool(seed // 4 % 2)
        image = centre_thing(image, camera.centre, fraction * camera.outer_radius, level, square)
        image = noisy_jpeg(image, rng, 3.0, 85)
        kind = ("dark", "bright")[seed // 2 % 2] + (" square" if square else " disc")
        yield f"{name} {size[0]}x{size[1]} {kind} {fraction:.2f}R", image, False
    for seed in range(count):
        rng = np.random.default_rng(700 + seed)
        size = ((640, 480), (800, 800), (1024, 768))[seed % 3]
        name = ("parabolic", "hyperbolic", "spherical")[seed % 3]
        camera = standard_cameras(size, seed=seed)[name]
        image = noisy_jpeg(render(room, camera, supersample=1), rng, 3.0, 85)
        ratio = camera.cutoff_radius / camera.outer_radius
        yield f"{name} {size[0]}x{size[1]} (disc {ratio:.2f}R)", image, True


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--real", action="store_true")
    parser.add_argument("--renders", type=int, default=0, help="renders of each kind (fisheye, mirror)")
    parser.add_argument("--detail", action="store_true", help="the disc's edge rays, fit, offset")
    args = parser.parse_args()
    sets = []
    if args.real:
        if not DATA.is_dir():
            print(f"the shared data is not at {DATA}: no real pictures")
        else:
            sets.append(("real", real_pictures()))
    if args.renders:
        sets.append(("renders", rendered_pictures(args.renders)))
    print("| picture | has a disc | disc found: radius px (/ outer) | right |")
    print("| --- | --- | --- | --- |")
    for label, pictures in sets:
        wrong = total = 0
        for name, image, truth in pictures:
            try:
                circles = find_image_circles(image)
                cutoff, outer = circles.cutoff, circles.outer.radius
            except NoImageCircle as exc:
                cutoff, outer = exc.cutoff, None
            if cutoff is None:
                found = "none"
            else:
                ratio = f" ({cutoff.radius / outer:.3f})" if outer else ""
                found = f"{cutoff.radius:.1f}{ratio}"
                if args.detail:
                    off = math.dist(cutoff.centre, circles.centre) if outer else 0.0
                    found += f" in {cutoff.inliers}/{cutoff.rays} rms {cutoff.rms_px:.2f} off {off:.1f}"
            right = (cutoff is not None) == truth
            wrong += not right
            total += 1
            print(f"| {name} | {'yes' if truth else 'no'} | {found} | {'yes' if right else '**no**'} |", flush=True)
        print(f"\n{label}: {wrong} wrong of {total}\n")


if __name__ == "__main__":
    sys.exit(main())
