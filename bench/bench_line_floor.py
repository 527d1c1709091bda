"""What one picture's lines can say about the camera: the stretch along the axis, and the floor it leaves.

Run: ``.venv/bin/python bench/bench_line_floor.py [--data ../shared/data] [--quick]``

A camera's lines and their right angles are what a picture without a pattern shows. Take the true camera and
stretch its rays along its own axis: the camera ``C_s`` that sees, at each pixel, the true ray ``d`` turned into
``S d / |S d|`` with ``S = diag(1, 1, s)`` (its elevations ``tan(alpha') = tan(alpha) / s``; its azimuths
untouched). ``S`` is linear, so it maps every plane through the viewpoint onto a plane through the viewpoint:
**each edge pixel lies exactly as far (in px) from its line's image under ``C_s`` as under the truth**, for
every ``s``. It maps a direction ``D`` to ``S D``: two directions at right angles stay at right angles when
each lies along the axis or across it, and the angle between directions oblique to the axis changes. So the
picture can tell ``C_s`` from the truth only by the right angles of directions that are oblique to the axis,
and only by as much as the scene is square.

Per picture (the real scenes against their calibrations; the photographs re-projected through known cameras,
as ``bench_scenes.py`` makes them):

- the arcs ``find_arcs`` finds that are straight under the truth (RMS < 0.5 px), and the three largest
  families of parallel lines among them (``find_families``, under the truth: the best grouping there is);
- **how far ``C_s`` lies** from the truth, measured as the outside checks measure a learned camera (rings 15-85
  deg off the axis, the best orthogonal matrix, p90 px);
- **the laws follow it**: the odd quintic and the unified law (with the centre and the azimuth origin)
  fitted to ``C_s``'s own rays on the rings, p90 px: a law that follows ``C_s`` as closely as it follows the
  truth cannot tell them apart either;
- each family's angle from the axis, and each pair's angle from square under the truth;
- how square the scene must be for its right angles to place the camera within 1 px (p90 on the rings): the
  largest turn of a pair's angle per px that ``C_s`` moves the rings, near ``s = 1``;
- **the floor**: ``s`` chosen so that the pairs within 12 deg of square are most nearly square (the truth's
  own law, centre, tilt and grouping given: every unknown but ``s``), and how far that camera lies from the
  truth (p90 / max px); and again told which pairs are the scene's right angles (those within 2 deg of square
  under the truth). A fit that must also find the law, the centre and the grouping does no better.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares, minimize_scalar
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_scenes as scenes
from panomap.calibrate.lines.arcs import find_arcs
from panomap.calibrate.lines.families import ORTHOGONAL_WITHIN_RAD, find_families
from panomap.calibrate.lines.frame_circles import line_circles
from panomap.calibrate.lines.stretch import axial_stretch, obliqueness_deg
from panomap.camera.radial import fit_radial, radial_kind
from panomap.io.images import read_image

FloatArray = NDArray[np.float64]
STRAIGHT_PX = 0.5
STRETCHES = (0.95, 1.05)
# The floor told which pairs of families are the scene's right angles: those this near square under the truth.
TOLD_SQUARE_DEG = 2.0
# The stretches the floor looks among; one that runs to a bound is not pinned by the right angles.
S_BOUNDS = (0.6, 1.6)
LAWS = ("odd5", "unified")


def unit_rays(alpha: FloatArray, azimuth: FloatArray) -> FloatArray:
    """Unit rays (n, 3) at ``alpha`` rad off +z and ``azimuth`` rad."""
    return np.stack([np.sin(alpha) * np.cos(azimuth), np.sin(alpha) * np.sin(azimuth), np.cos(alpha)], axis=1)


def inverse(project: scenes.Project, alpha_max: float = math.radians(110.0)):
    """Pixels (n, 2) -> unit rays (n, 3) of the truth: a table's nearest ray, then Newton on (alpha cos, alpha sin)."""
    a, p = np.meshgrid(np.linspace(0, alpha_max, 400), np.linspace(-math.pi, math.pi, 720, endpoint=False))
    a, p = a.ravel(), p.ravel()
    with np.errstate(invalid="ignore", divide="ignore"):
        seen = project(unit_rays(a, p))
    ok = np.isfinite(seen).all(axis=1)
    tree = cKDTree(seen[ok])
    start = np.stack([a * np.cos(p), a * np.sin(p)], axis=1)[ok]

    def rays(q: FloatArray) -> FloatArray:
        return unit_rays(np.hypot(q[:, 0], q[:, 1]), np.arctan2(q[:, 1], q[:, 0]))

    def invert(pixels: FloatArray) -> FloatArray:
        q = start[tree.query(pixels)[1]]
        for _ in range(8):
            h = 1e-6
            f = project(rays(q))
            jac = np.stack(
                [(project(rays(q + np.array([h, 0.0]))) - f) / h, (project(rays(q + np.array([0.0, h]))) - f) / h],
                axis=2,
            )
            step = np.linalg.solve(jac, (f - pixels)[..., None])[..., 0]
            q = q - step
        return rays(q)

    return invert


def plane_normal(rays: FloatArray) -> FloatArray:
    return np.linalg.svd(rays, full_matrices=False)[2][-1]


def straightness_px(project: scenes.Project, rays: FloatArray) -> FloatArray:
    """Each edge pixel's distance (px, near enough) from its line's image under the truth (rays: (n, 3))."""
    normal = plane_normal(rays)
    foot = rays - np.outer(rays @ normal, normal)
    foot /= np.linalg.norm(foot, axis=1, keepdims=True)
    return np.hypot(*(project(foot) - project(rays)).T)


def ring_px(project: scenes.Project, size: tuple[int, int], s: float) -> FloatArray:
    """The outside checks' distance (px) of ``C_s`` from the truth at each ring pixel."""
    pixels, truth, _ = scenes.ring_pairs(project, size)
    mine = axial_stretch(truth, s)
    u, _, vt = np.linalg.svd(truth.T @ mine)
    back = project(mine @ (u @ vt).T)
    return np.asarray(np.hypot(*(back - pixels).T), dtype=np.float64)


def law_px(project: scenes.Project, size: tuple[int, int], s: float, kind: str) -> float:
    """p90 px of the law ``kind`` (its centre, azimuth origin and handedness free) fitted to ``C_s``'s rays."""
    pixels, truth, _ = scenes.ring_pairs(project, size)
    rays = axial_stretch(truth, s)
    theta = np.arctan2(rays[:, 1], rays[:, 0])
    rho = np.arcsin(np.clip(rays[:, 2], -1, 1))  # the elevation looking up (+z the axis)
    spec = radial_kind(kind)
    best = math.inf
    for hand in (1, -1):
        c0 = pixels.mean(axis=0)
        law = fit_radial(kind, rho, np.hypot(*(pixels - c0).T), "up")
        phi = np.arctan2(pixels[:, 1] - c0[1], pixels[:, 0] - c0[0])
        phi0 = float(np.angle(np.mean(np.exp(1j * (phi - hand * theta)))))

        def residual(x: FloatArray, hand: int = hand) -> FloatArray:
            r = spec.evaluate(tuple(x[3:]), rho, "up")
            angle = hand * theta + x[2]
            p = np.stack([x[0] + r * np.cos(angle), x[1] + r * np.sin(angle)], axis=1)
            return np.nan_to_num((p - pixels).ravel(), nan=1e3)

        fitted = least_squares(residual, np.array([*c0, phi0, *law.coefficients]))
        best = min(best, float(np.percentile(np.hypot(*residual(fitted.x).reshape(-1, 2).T), 90)))
    return best


def pair_angles_deg(directions: FloatArray, s: float) -> FloatArray:
    d = axial_stretch(directions, s)
    i, j = np.triu_indices(len(d), k=1)
    return np.degrees(np.arccos(np.clip(np.abs(np.sum(d[i] * d[j], axis=1)), 0, 1)))


def measure(picture: scenes.Picture) -> str:
    image = read_image(picture.image) if picture.image is not None else picture.pixels
    circles = line_circles(image)
    invert = inverse(picture.project)
    straight = []
    for arc in find_arcs(image, circles):
        with np.errstate(invalid="ignore"):
            rays = invert(arc.pixels)
            truth_px = straightness_px(picture.project, rays)
        if not np.isfinite(truth_px).all() or math.sqrt(float(np.mean(truth_px**2))) >= STRAIGHT_PX:
            continue
        straight.append(plane_normal(rays))
    normals = np.array(straight)
    spread = [np.percentile(ring_px(picture.project, picture.size, s), 90) for s in STRETCHES]
    laws = {kind: [law_px(picture.project, picture.size, s, kind) for s in (1.0, *STRETCHES)] for kind in LAWS}
    head = f"| {picture.name} | {len(normals)} | {spread[0]:.1f} / {spread[1]:.1f} | " + " | ".join(
        f"{v[0]:.2f} / {v[1]:.2f} / {v[2]:.2f}" for v in laws.values()
    )
    families = find_families(normals, np.zeros(len(normals), dtype=np.intp)) if len(normals) >= 6 else []
    families = sorted(families, key=lambda f: -len(f.members))[:3]
    directions = np.array([f.direction for f in families])
    off_axis = [math.degrees(math.acos(min(1.0, abs(float(d[2]))))) for d in directions]
    oblique = float(obliqueness_deg(directions).max()) if len(directions) else math.nan
    if len(directions) < 2:
        return head + f" | {len(directions)} families | | | no two families | |"
    angles = pair_angles_deg(directions, 1.0)
    square = np.abs(90 - angles) < math.degrees(ORTHOGONAL_WITHIN_RAD)
    fams = ", ".join(f"{len(f.members)} at {a:.1f}" for f, a in zip(families, off_axis, strict=True))
    fams += f" (most oblique {oblique:.1f})"
    squares = ", ".join(f"{90 - a:.2f}" for a in angles[square]) or "none"
    if not square.any():
        return head + f" | {fams} | {squares} | | no pair near square | |"
    # How square the scene must be for the angles to place s within 1 px of the rings (p90).
    step = 0.01
    turn = np.abs(pair_angles_deg(directions, 1 + step) - angles)[square].max()
    needed = turn / float(np.percentile(ring_px(picture.project, picture.size, 1 + step), 90))

    floors = []
    for chosen in (square, np.abs(90 - angles) < TOLD_SQUARE_DEG):
        if not chosen.any():
            floors.append("no pair")
            continue

        def cost(s: float, chosen: NDArray[np.bool_] = chosen) -> float:
            return float(np.sum((90 - pair_angles_deg(directions, s)[chosen]) ** 2))

        grid = np.linspace(*S_BOUNDS, 401)  # the right angles' best stretch: global on a grid, then refined
        at = int(np.argmin([cost(s) for s in grid]))
        near = (grid[max(at - 1, 0)], grid[min(at + 1, grid.size - 1)])
        s_hat = float(minimize_scalar(cost, bounds=near, method="bounded").x) if near[1] > near[0] else grid[at]
        floor = ring_px(picture.project, picture.size, s_hat)
        if min(abs(s_hat - b) for b in S_BOUNDS) < 1e-3 or not np.isfinite(floor).all():
            floors.append(f"not pinned (s runs to {s_hat:.2f})")
            continue
        p90, worst = float(np.percentile(floor, 90)), float(floor.max())
        goal = " (goal)" if p90 <= scenes.GOAL_P90_PX and worst <= scenes.GOAL_MAX_PX else ""
        floors.append(f"s {s_hat:.3f}: {p90:.2f} / {worst:.2f}{goal}")
    return head + f" | {fams} | {squares} | {needed:.3f} | {floors[0]} | {floors[1]} |"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=scenes.DEFAULT_DATA)
    parser.add_argument("--quick", action="store_true", help="three photographs, two cameras each")
    args = parser.parse_args()
    pictures = scenes.real_pictures(args.data) + scenes.panorama_pictures(args.data, args.quick)
    if not pictures:
        sys.exit(f"no pictures under {args.data} (scenes/, panoramas/)")
    print(
        "| picture | straight lines | C_0.95 / C_1.05 p90 px | "
        + " | ".join(f"{k} p90 px: truth / C_0.95 / C_1.05" for k in LAWS)
        + " | families: lines at deg off axis | pairs' deg off square | square to 1 px: deg | floor: s, p90 / max px"
        + " | floor told the square pairs |"
    )
    print("| --- " * (7 + len(LAWS)) + "|")
    rows = []
    for picture in pictures:
        rows.append(measure(picture))
        print(rows[-1], flush=True)
    for k, name in ((-3, "the floor"), (-2, "the floor told the square pairs")):
        within = sum(row.split("|")[k].strip().endswith("(goal)") for row in rows)
        print(f"{name}: within p90 1 px and max 2 px on {within} of {len(rows)} pictures")


if __name__ == "__main__":
    main()
