"""Mirrors without a single viewpoint: ``panomap project`` at 1, 2 and 4 m, beside the floor.

Each trial draws a camera (its centre and phi0 moved by the trial's seed), 12 landmarks at horizontal
distances of 2-6 m (``--near`` 1-4 m) and elevations -70..+5 deg seen from O_m, their pixels traced exactly
through the camera with 1 px of noise a coordinate and their world points with 1 cm (the landmark file's
errors), and fits the camera as ``panomap fit`` does (centre and annulus given). Then points at 1, 2 and
4 m horizontal distance, at elevations -70..-5 deg and 36 azimuths, are projected through the table and
through the true camera; each trial's worst error at each distance is kept. Printed, per camera, the p90
and the largest over the trials of:

- ``default``: the fit as ``panomap fit`` makes it (the ray origins where cross-validation chooses them);
- ``caustic``: the caustic fitted whatever cross-validation says (``--viewpoint caustic``);
- ``central``: the fit held to a single viewpoint (``--viewpoint single``), the figures before it;
- ``radius``: the sphere's radius given (``--sphere-radius``): its law and the ray origins the radius gives;
- ``floor``: a fit told the true mirror: the true ray origins, and the spherical mirror's law (its f and c)
  fitted to the same landmarks along them (what the landmarks' noise leaves, with the mirror known).

Cameras: ``sphere-big`` (a spherical mirror of radius 0.3 m, lens 0.3 m below it, 1600 px: its ray origins
spread over 53 mm), ``sphere-wide`` (radius 0.15 m, lens 0.3 m below, seen to 15 deg off its axis, 1200 px:
its rim near the grazing ray, where no law of a single-viewpoint camera follows it), ``sphere`` (the
simulator's standard one, 5 cm, 1200 px: 14 mm) and two single-viewpoint cameras (``hyperbolic``,
``equidistant``), whose figures the default must leave as they are.

    python bench/bench_noncentral.py [--trials 20] [--near]
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace
from typing import Any

import numpy as np

from panomap import calibrate_camera
from panomap.calibrate.landmarks.pairs import Landmarks
from panomap.calibrate.landmarks.viewpoint import SphericalMirror
from panomap.camera.radial import RadialFunction, fit_radial
from panomap.camera.viewpoint import Viewpoint, caustic_shape
from panomap.simulate import SphericalMirrorCamera, standard_cameras

CAMERA = np.array([0.0, 0.0, 2.0])
DISTANCES_M = (1.0, 2.0, 4.0)
CAMERAS = ("sphere-big", "sphere-wide", "sphere", "hyperbolic", "equidistant")


def make_camera(name: str, seed: int) -> Any:
    """The camera ``name`` of the trial ``seed`` (see the module's docstring)."""
    if name == "sphere-big":
        base = standard_cameras(size=(1600, 1600), seed=seed)["spherical"]
        return base.with_mirror(0.3, 0.3, math.radians(25.0))
    if name == "sphere-wide":
        base = standard_cameras(size=(1200, 1200), seed=seed)["spherical"]
        return base.with_mirror(0.15, 0.3, math.radians(15.0))
    cameras = standard_cameras(size=(1200, 1200), seed=seed)
    return cameras["spherical" if name == "sphere" else name]


def true_viewpoint(camera: Any) -> Viewpoint | None:
    """The camera's true ray origins on its axis, relative to O_m (None for a single viewpoint)."""
    if not isinstance(camera, SphericalMirrorCamera):
        return None
    beta = np.linspace(camera.beta_min * 0.5, min(camera.beta_max * 1.05, 1.2), 400)
    x, z, dx, dz = camera._reflect(beta)
    rho = np.arctan2(dz, dx)
    return Viewpoint(tuple(rho.tolist()), tuple((z - x * dz / dx - camera.viewpoint_offset).tolist()))


def landmarks(camera: Any, rng: np.random.Generator, distances: tuple[float, float], count: int = 12) -> Landmarks:
    """``count`` visible landmarks with 1 px and 1 cm of noise a coordinate."""
    pixels, world = [], []
    while len(pixels) < count:
        distance = rng.uniform(*distances)
        rho = math.radians(rng.uniform(-70.0, 5.0))
        theta = rng.uniform(0, 2 * math.pi)
        d = np.array([distance * math.cos(theta), distance * math.sin(theta), distance * math.tan(rho)])
        uv = camera.project(d)
        if not np.all(np.isfinite(uv)):
            continue
        pixels.append(uv + rng.normal(0, 1.0, 2))
        world.append(CAMERA + d + rng.normal(0, 0.01, 3))
    return Landmarks(np.array(pixels), np.array(world), tuple(f"L{k}" for k in range(count)))


def test_points(distance: float) -> np.ndarray:
    """(k, 3) points relative to O_m at ``distance`` (horizontal), elevations -70..-5 deg, 36 azimuths."""
    rho = np.radians(np.arange(-70.0, -4.9, 2.5))
    theta = np.radians(np.arange(0.0, 360.0, 10.0))
    t, r = np.meshgrid(theta, rho)
    return np.stack([distance * np.cos(t), distance * np.sin(t), distance * np.tan(r)], axis=-1).reshape(-1, 3)


def worst(project: Any, camera: Any) -> list[float]:
    """Each distance's largest error (px) of ``project`` (points relative to O_m -> pixels) against the truth."""
    out = []
    for distance in DISTANCES_M:
        points = test_points(distance)
        truth = camera.project(points)
        error = np.linalg.norm(np.asarray(project(points), dtype=np.float64) - truth, axis=1)
        seen = np.isfinite(truth[:, 0])
        out.append(float(np.max(np.where(np.isfinite(error), error, np.inf)[seen])))
    return out


def floor_projection(calibration: Any, camera: Any, marks: Landmarks) -> Any:
    """Points -> pixels of a fit told the true ray origins (see the module's docstring)."""
    model = calibration.table.model
    truth = true_viewpoint(camera)
    assert truth is not None
    d = marks.world - CAMERA
    rho = truth.elevation_of_point(np.hypot(d[:, 0], d[:, 1]), d[:, 2])
    r = np.hypot(*(marks.pixels - np.asarray(model.centre)).T)
    radial = fit_radial("sphere", rho, r, model.axis)
    known = replace(model, radial=radial, viewpoint=truth, rotation=None)

    def project(points: np.ndarray) -> np.ndarray:
        return known.pixels(*known.point_angles(points))

    return project


def size_bound(camera: Any, marks: Landmarks) -> float:
    """The Cramer-Rao bound of the sphere's radius from these landmarks, as a fraction of it: the standard
    deviation of R that no unbiased fit of the true law (f, c and R free, the ray origins exact, 1 px and 1 cm
    of noise a coordinate) can beat."""
    r = np.linspace(camera.cutoff_radius, camera.outer_radius, 200)
    _, direction = camera.trace(np.stack([camera.centre[0] + r, np.full_like(r, camera.centre[1])], axis=1))
    rho = np.arctan2(direction[:, 2], np.hypot(direction[:, 0], direction[:, 1]))
    seen = np.isfinite(rho)
    law = fit_radial("sphere", rho[seen], r[seen], "down")
    truth = true_viewpoint(camera)
    assert truth is not None
    nodes = np.linspace(-1.5, 0.3, 181)
    d = marks.world - CAMERA
    horizontal, height = np.hypot(d[:, 0], d[:, 1]), d[:, 2]
    sigma = np.hypot(1.0, law.slope(np.arctan2(height, horizontal)) * 0.01 / np.hypot(horizontal, height))
    mean = float(np.mean(truth.offset(nodes)))

    def whitened(p: np.ndarray) -> np.ndarray:
        radial = RadialFunction("sphere", (float(p[0]), float(p[1])), "down")
        h = caustic_shape(radial, nodes)
        origins = Viewpoint(tuple(nodes.tolist()), tuple((p[2] * (h - np.mean(h)) + mean).tolist()))
        return np.asarray(radial(origins.elevation_of_point(horizontal, height)) / sigma)

    p0 = np.array([*law.coefficients, camera.mirror_radius])
    steps = np.array([1e-3 * p0[0], 1e-5, 1e-4])
    jacobian = np.stack(
        [(whitened(p0 + e) - whitened(p0 - e)) / (2 * e[k]) for k, e in enumerate(np.diag(steps))], axis=1
    )
    return float(math.sqrt(np.linalg.inv(jacobian.T @ jacobian)[2, 2]) / camera.mirror_radius)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=20)
    parser.add_argument("--near", action="store_true", help="landmarks at 1-4 m (default 2-6 m)")
    parser.add_argument("--cameras", nargs="+", default=list(CAMERAS), choices=CAMERAS)
    args = parser.parse_args()
    distances = (1.0, 4.0) if args.near else (2.0, 6.0)
    print(
        f"12 landmarks at {distances[0]:g}-{distances[1]:g} m, 1 px / 1 cm a coordinate, {args.trials} trials a "
        "camera; each trial's worst error (px) of project at 1, 2 and 4 m; p90 / max over the trials"
    )
    print(f"{'camera':12s} {'fit':8s} {'chosen':>7s}  " + "  ".join(f"{d:g} m p90 / max" for d in DISTANCES_M))
    for name in args.cameras:
        rows: dict[str, list[list[float]]] = {"default": [], "caustic": [], "central": [], "radius": [], "floor": []}
        chosen, start, bounds = 0, time.perf_counter(), []
        for seed in range(args.trials):
            camera = make_camera(name, seed)
            marks = landmarks(camera, np.random.default_rng(1000 + seed), distances)
            given = dict(
                centre=camera.centre, cutoff_radius=camera.cutoff_radius, outer_radius=camera.outer_radius,
                image_size=camera.image_size,
            )  # fmt: skip
            fitted = calibrate_camera(marks, tuple(CAMERA), **given)
            central = calibrate_camera(marks, tuple(CAMERA), **given, viewpoint="single")
            forced = calibrate_camera(marks, tuple(CAMERA), **given, viewpoint="caustic")
            chosen += not fitted.table.model.single_viewpoint
            rows["default"].append(worst(lambda p, t=fitted.table: t.project(p + CAMERA), camera))
            rows["central"].append(worst(lambda p, t=central.table: t.project(p + CAMERA), camera))
            rows["caustic"].append(worst(lambda p, t=forced.table: t.project(p + CAMERA), camera))
            if true_viewpoint(camera) is not None:
                known = calibrate_camera(marks, tuple(CAMERA), **given, viewpoint=SphericalMirror(camera.mirror_radius))
                rows["radius"].append(worst(lambda p, t=known.table: t.project(p + CAMERA), camera))
                rows["floor"].append(worst(floor_projection(central, camera, marks), camera))
                bounds.append(size_bound(camera, marks))
        seconds = (time.perf_counter() - start) / args.trials
        for fit, values in rows.items():
            if not values:
                continue
            errors = np.array(values)
            cells = "  ".join(
                f"{np.percentile(errors[:, k], 90):5.2f} / {errors[:, k].max():5.2f}" for k in range(len(DISTANCES_M))
            )
            count = f"{chosen}/{args.trials}" if fit == "default" else ""
            print(f"{name:12s} {fit:8s} {count:>7s}  {cells}")
        print(f"{name:12s} ({seconds:.1f} s a trial for the three fits)")
        if bounds:
            print(
                f"{name:12s} the sphere's radius from these landmarks: Cramer-Rao bound {np.median(bounds):.0%} of it "
                f"(median; {min(bounds):.0%}-{max(bounds):.0%})"
            )


if __name__ == "__main__":
    main()
