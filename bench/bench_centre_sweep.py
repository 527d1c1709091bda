"""Circle finding over random unkind renders: how often it fails, and its worst error.

Run: ``.venv/bin/python bench/bench_centre_sweep.py [--trials 120] [--workers 2] [--crop 0 0.15] [--first-seed 0]``

Each seeded trial draws a frame size (640 x 480 to 1920 x 1920, 4:3, 16:9 and
square), a camera (equidistant and equisolid fisheyes; parabolic, hyperbolic and
spherical mirrors), a crop of the image circle by the frame of 0-15% of its radius
(``--crop LOW HIGH``; on a square frame, on all four sides; the share of the rim the frame
shows is printed with each trial that failed), a centre up to 2% of the frame's short side
off its middle, and an image angle; renders the bundled room through it, then either
puts a mirror in a bright, blurred housing (half the mirror trials:
``panomap.simulate.housed_mirror``, a rim whose contrast changes sign) or vignettes
the image (up to 50% at the rim, up to 30% more on one side); then noise 5 and JPEG 75.
Prints, per kind of image, how many trials found the circle, and the median, 90th
percentile and worst centre, outer radius and cut-off radius errors (px) against the
simulated camera; then every trial that failed or missed the issue's bar (centre 0.5 px,
radius 1 px, the cut-off disc found within 1 px).
"""

from __future__ import annotations

import argparse
import math
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from panomap.calibrate.circles import NoImageCircle, find_image_circles
from panomap.simulate import housed_mirror, load_room, noisy_jpeg, render, standard_cameras, vignette

ROOM = load_room()
SIZES = ((1920, 1440), (1920, 1080), (1280, 960), (640, 480), (1920, 1920), (1024, 768))
NAMES = ("equidistant", "equisolid", "parabolic", "hyperbolic", "spherical")
MIRRORS = ("parabolic", "hyperbolic", "spherical")


def rim_in_frame(centre: tuple[float, float], radius: float, size: tuple[int, int]) -> float:
    """The share of the circle's circumference inside the frame (W, H)."""
    angles = np.linspace(0.0, 2 * math.pi, 3600, endpoint=False)
    u, v = centre[0] + radius * np.cos(angles), centre[1] + radius * np.sin(angles)
    return float(np.mean((u >= -0.5) & (u <= size[0] - 0.5) & (v >= -0.5) & (v <= size[1] - 0.5)))


def trial(job: tuple[int, float, float]) -> tuple[str, str, tuple[float, float, float | None] | None]:
    """One trial (seed, least and largest crop): (kind of image, description, (centre, radius, cut-off errors) or
    None where none was found)."""
    seed, low, high = job
    rng = np.random.default_rng(seed)
    size = SIZES[rng.integers(len(SIZES))]
    name = NAMES[rng.integers(len(NAMES))]
    short = min(size)
    crop = rng.uniform(low, high)
    radius = (short / 2) / (1 - crop) if crop > 0.01 else 0.47 * short
    middle = ((size[0] - 1) / 2, (size[1] - 1) / 2)
    off = 0.02 * short
    centre = (middle[0] + rng.uniform(-off, off), middle[1] + rng.uniform(-off, off))
    camera = standard_cameras(size, centre=centre, phi0=rng.uniform(0, 2 * math.pi), outer_radius=radius)[name]
    image = render(ROOM, camera, supersample=1)
    housed = name in MIRRORS and rng.uniform() < 0.5
    if housed:
        image = housed_mirror(image, camera.centre, camera.outer_radius, camera.cutoff_radius, rng)
        kind = "mirror in a housing"
    else:
        image = vignette(
            image,
            camera.centre,
            camera.outer_radius,
            falloff=rng.uniform(0, 0.5),
            dim=rng.uniform(0, 0.3),
            dim_angle=rng.uniform(0, 2 * math.pi),
        )
        kind = "mirror, vignetted" if name in MIRRORS else "fisheye, vignetted"
    image = noisy_jpeg(image, rng)
    shown = rim_in_frame(camera.centre, camera.outer_radius, size)
    described = (
        f"seed {seed}: {name}, {size[0]} x {size[1]}, cut by {crop:.0%} of the radius "
        f"({shown:.0%} of the rim in the frame)"
    )
    try:
        found = find_image_circles(image)
    except NoImageCircle:
        return kind, described, None
    cutoff = None
    if camera.cutoff_radius > 0:
        cutoff = math.inf if found.cutoff is None else abs(found.cutoff.radius - camera.cutoff_radius)
    errors = (math.dist(found.centre, camera.centre), abs(found.outer_radius - camera.outer_radius), cutoff)
    return kind, described, errors


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=120)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument(
        "--crop",
        type=float,
        nargs=2,
        default=(0.0, 0.15),
        metavar=("LOW", "HIGH"),
        help="share of the circle's radius the frame cuts off, drawn in [LOW, HIGH] (default 0 0.15)",
    )
    parser.add_argument("--first-seed", type=int, default=0, help="seed of the first trial (default 0)")
    args = parser.parse_args()
    rows: dict[str, list[tuple[str, tuple[float, float, float | None] | None]]] = {}
    with ProcessPoolExecutor(args.workers) as pool:
        jobs = [(seed, *args.crop) for seed in range(args.first_seed, args.first_seed + args.trials)]
        for kind, described, errors in pool.map(trial, jobs):
            rows.setdefault(kind, []).append((described, errors))
    print(
        f"{args.trials} trials, circles cut by {args.crop[0]:.0%}-{args.crop[1]:.0%} of the radius; "
        "errors in px: median / 90th percentile / worst"
    )
    print("| image | found / trials | centre | outer radius | cut-off radius |")
    print("| --- | --- | --- | --- | --- |")
    missed = []
    for kind in sorted(rows):
        found = [e for _, e in rows[kind] if e is not None]

        def show(values: list[float]) -> str:
            if not values:
                return "-"
            return " / ".join(f"{v:.2f}" for v in (np.median(values), np.percentile(values, 90), max(values)))

        cutoffs = [e[2] for e in found if e[2] is not None]
        print(
            f"| {kind} | {len(found)} / {len(rows[kind])} | {show([e[0] for e in found])} | "
            f"{show([e[1] for e in found])} | {show(cutoffs)} |"
        )
        for described, e in rows[kind]:
            if e is None:
                missed.append(f"{described}: no circle found")
            elif e[0] > 0.5 or e[1] > 1.0 or (e[2] is not None and e[2] > 1.0):
                cut = "" if e[2] is None else f", cut-off {e[2]:.2f}"
                missed.append(f"{described}: centre {e[0]:.2f}, radius {e[1]:.2f}{cut}")
    print(f"\nmissed the bar (centre 0.5 px, radius 1 px, cut-off disc within 1 px): {len(missed)} of {args.trials}")
    for line in missed:
        print(f"  {line}")


if __name__ == "__main__":
    main()
