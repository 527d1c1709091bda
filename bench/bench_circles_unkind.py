"""The image circle on unkind renders: what real rims do that the kind renders do not (issue 53, item 2).

Run: ``PYTHONPATH=src .venv/bin/python bench/bench_circles_unkind.py [--count 32]``

Every picture is the bundled room through a fisheye (equidistant or equisolid) on a 748 x 480, 1280 x 800,
960 x 1080 or 1024 x 768 frame, its circle inside the frame or cut at top and bottom (a third of them), its field
stop out of focus (blurred by 1-6 px), vignetted by 20-65%, up to two dark things of the scene at the rim (5-25%
of the level, 10-40 deg wide, reaching 15-80 px in), dimmed to 40-100%, noise of 2-5 grey levels and JPEG at
quality 60-89. Then, on every other picture, a lens barrel's edge lit past the rim on one arc (a ring 20-60 grey
levels, 1-2 px wide, 3-10 px out: a Ricoh Theta's bluish ring, an OCam's), and on the others a glow past the rim on
one side (10-40 levels fading over 5-20 px: flare). Then robots' fisheyes (``--robots``, 16 more): the circle in a
dark square (10-30 grey levels, its pedestal under the picture too) inside a black 1280 x 800 frame, cut at top and
bottom or not, the stop blurred by 1.5-5 px, vignetted by 40-80%, dimmed to 40-100%, a lit ring on one arc (20-50
levels, 4-9 px out), noise of 3 levels, JPEG at 80. Then fading rims (``--faded``, 16 more: an OCam fisheye's, imgBack1
in ../shared): a 748 x 480 or 1024 x 768 frame cutting the circle at top and bottom, the stop blurred by 4-8 px (the
rim fading over 20-30 px), one or two dark things of the scene at the rim, vignetted by 10-40%, over-exposed by
1-2.2x after the stop (a bright scene clips on the stop's fall), a halo of its own light (10-30%, blurred by 6-15 px)
on one side, noise of 2-4 levels, JPEG at 70-89. Prints each picture whose centre is found more than 0.5 px from
the truth, then, per set, the count found, within 1 and 3 px, the median and the worst.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

import cv2
import numpy as np

from panomap.calibrate.circles import NoImageCircle, find_image_circles
from panomap.simulate import (
    dark_square,
    field_stop,
    halo,
    lit_ring,
    load_room,
    noisy_jpeg,
    over_exposed,
    render,
    side_glow,
    standard_cameras,
    vignette,
)

ROOM = load_room()
SIZES = ((748, 480), (1280, 800), (960, 1080), (1024, 768))


def dark_things(
    image: np.ndarray, centre: tuple[float, float], radius: float, rng: np.random.Generator, count: int
) -> np.ndarray:
    """``count`` dark things of the scene touching the rim: sectors 10-40 deg wide from 15-80 px inside it outward,
    at 5-25% of the level, their edges blurred by 1.5 px."""
    height, width = image.shape[:2]
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    r = np.hypot(u - centre[0], v - centre[1])
    phi = np.arctan2(v - centre[1], u - centre[0])
    gain = np.ones((height, width))
    for _ in range(count):
        angle, half, depth = rng.uniform(0, 2 * math.pi), math.radians(rng.uniform(5, 20)), rng.uniform(15, 80)
        off = np.abs((phi - angle + math.pi) % (2 * math.pi) - math.pi)
        gain[(off < half) & (r > radius - depth)] = rng.uniform(0.05, 0.25)
    gain = cv2.GaussianBlur(gain, (0, 0), 1.5)
    return np.clip(image * (gain[..., None] if image.ndim == 3 else gain), 0, 255).astype(np.uint8)


def unkind(seed: int) -> tuple[np.ndarray, tuple[float, float], float]:
    """Picture ``seed``: the image, the circle's centre (u, v) and radius, px."""
    rng = np.random.default_rng(500 + seed)
    width, height = SIZES[seed % 4]
    name = ("equidistant", "equisolid")[seed // 4 % 2]
    radius = rng.uniform(0.52, 0.6) * height if seed % 3 == 0 else rng.uniform(0.40, 0.48) * min(width, height)
    centre = (width / 2 + rng.uniform(-15, 15), height / 2 + rng.uniform(-15, 15))
    soft = rng.uniform(1.0, 6.0)
    camera = standard_cameras(
        (width, height), centre=centre, phi0=rng.uniform(0, 6.3), outer_radius=radius + 3 * soft + 10
    )
    image = dark_things(render(ROOM, camera[name], supersample=1), centre, radius, rng, int(rng.integers(0, 3)))
    image = field_stop(image, centre, radius, softness_px=soft)
    image = vignette(image, centre, radius, falloff=rng.uniform(0.2, 0.65), power=rng.uniform(2, 4))
    angle = rng.uniform(0, 2 * math.pi)
    if seed % 2 == 0:
        level, at_px, width_px = rng.uniform(20, 60), rng.uniform(3, 10), rng.uniform(1, 2)
        image = lit_ring(image, centre, radius, level, at_px, width_px, angle=angle, spread=rng.uniform(0.5, 2.0))
    else:
        level, fade_px = rng.uniform(10, 40), rng.uniform(5, 20)
        image = side_glow(image, centre, radius, level, fade_px, angle=angle, spread=rng.uniform(0.5, 2.0))
    image = np.asarray(image * rng.uniform(0.4, 1.0), np.uint8)
    return noisy_jpeg(image, rng, noise=rng.uniform(2, 5), quality=int(rng.integers(60, 90))), centre, radius


def robot(seed: int) -> tuple[np.ndarray, tuple[float, float], float]:
    """Robot's fisheye ``seed``: the image, the circle's centre (u, v) and radius, px."""
    rng = np.random.default_rng(seed)
    square = (640 + rng.uniform(-150, 150), 399.5)
    radius = rng.uniform(0.40, 0.56) * 800
    centre = (square[0] + rng.uniform(-8, 8), square[1] + rng.uniform(-8, 8))
    soft = rng.uniform(1.5, 5)
    camera = standard_cameras((1280, 800), centre=centre, phi0=rng.uniform(0, 6.3), outer_radius=radius + 3 * soft + 12)
    image = field_stop(render(ROOM, camera["equidistant"], supersample=1), centre, radius, softness_px=soft)
    image = vignette(image, centre, radius, falloff=rng.uniform(0.4, 0.8), power=rng.uniform(2, 4))
    image = np.asarray(image * rng.uniform(0.4, 1.0), np.uint8)
    image = dark_square(image, centre, radius, 399.5, rng.uniform(10, 30), square_centre=square, under_disc=True)
    level, at_px, width_px = rng.uniform(20, 50), rng.uniform(4, 9), rng.uniform(1, 2)
    image = lit_ring(
        image, centre, radius, level, at_px, width_px, angle=rng.uniform(0, 6.3), spread=rng.uniform(0.5, 2)
    )
    return noisy_jpeg(image, rng, noise=3.0, quality=80), centre, radius


def faded(seed: int) -> tuple[np.ndarray, tuple[float, float], float]:
    """Fading rim ``seed``: the image, the circle's centre (u, v) and radius, px."""
    rng = np.random.default_rng(900 + seed)
    width, height = ((748, 480), (1024, 768))[seed % 2]
    radius = rng.uniform(0.55, 0.62) * height
    centre = (width / 2 + rng.uniform(-10, 10), height / 2 + rng.uniform(-10, 10))
    soft = rng.uniform(4.0, 8.0)
    outer = radius + 3 * soft + 10
    camera = standard_cameras((width, height), centre=centre, phi0=rng.uniform(0, 6.3), outer_radius=outer)
    scene = render(ROOM, camera["equidistant"], supersample=1)
    image = dark_things(scene, centre, radius, rng, int(rng.integers(1, 3)))
    image = field_stop(image, centre, radius, softness_px=soft)
    image = vignette(image, centre, radius, falloff=rng.uniform(0.1, 0.4), power=rng.uniform(2, 4))
    image = over_exposed(image, rng.uniform(1.0, 2.2))
    fraction, blur_px = rng.uniform(0.1, 0.3), rng.uniform(6, 15)
    image = halo(image, centre, fraction, blur_px, angle=rng.uniform(0, 2 * math.pi), spread=rng.uniform(0.5, 2.0))
    return noisy_jpeg(image, rng, noise=rng.uniform(2, 4), quality=int(rng.integers(70, 90))), centre, radius


def measure(name: str, make: Callable[[int], tuple[np.ndarray, tuple[float, float], float]], count: int) -> None:
    """Prints the pictures ``make`` draws for seeds 0 .. count - 1 whose centre is off by over 0.5 px, then a line."""
    if count <= 0:
        return
    errors = []
    for seed in range(count):
        image, centre, radius = make(seed)
        try:
            found = find_image_circles(image)
        except NoImageCircle as exc:
            errors.append(math.inf)
            print(f"{name} {seed:3d} {image.shape[1]} x {image.shape[0]}: not found ({str(exc)[:80]})")
            continue
        errors.append(math.dist(found.centre, centre))
        if errors[-1] > 0.5:
            print(
                f"{name} {seed:3d} {image.shape[1]} x {image.shape[0]}: centre {errors[-1]:.2f} px off, radius "
                f"{found.outer_radius - radius:+.2f} px, fit RMS {found.outer.rms_px:.2f} px"
            )
    error = np.array(errors)
    found_errors = error[np.isfinite(error)]
    print(
        f"{name}: found {found_errors.size} of {count}; within 1 px {int(np.sum(error <= 1))}, within 3 px "
        f"{int(np.sum(error <= 3))}; median {np.median(error):.2f} px, worst found {found_errors.max():.2f} px"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=32)
    parser.add_argument("--robots", type=int, default=16)
    parser.add_argument("--faded", type=int, default=16)
    args = parser.parse_args()
    measure("fisheyes", unkind, args.count)
    measure("robots", robot, args.robots)
    measure("faded", faded, args.faded)


if __name__ == "__main__":
    main()
