"""Learning the camera from straight lines: the issue's goals, measured as its outside check does.

Run: ``.venv/bin/python bench/bench_lines.py [--data ../shared/data/real] [--quick] [--only sim|real|speed]``

**The measure** (:func:`ray_agreement`): a grid of reference pixels (every ``GRID_PX`` px) in the
evaluation region; each pixel's ray from the reference camera; the best rotation of the frame
(Kabsch over those rays, a reflection allowed: the azimuth origin and the mirroring are what lines
cannot know) taking the reference rays to the learned camera's rays of the same pixels; each rotated
reference ray through the learned camera to a pixel; the distance from the reference pixel, px:
p90 and max. The goal: p90 <= 1.0 and max <= 2.0 px. Validated first: the true model against
itself gives 0; the true model with its centre moved by 0.5 px is reported beside it.

1. **Rendered rooms** (:mod:`panomap.simulate.line_scenes`): a 190 deg equidistant fisheye on a
   16:9 sensor (1920 x 1080, the image circle cut by the frame) and a hyperbolic mirror on 4:3
   (1600 x 1200), the axis tilted 1-3 deg, vignetting, sensor noise, JPEG; several seeds. The
   image circle is found in the image (``find_image_circles``), the arcs by ``find_arcs``, the
   camera by ``fit_lines``; compared with the true camera over the whole annulus (inside the frame).
   Beside it, whether the command would accept the camera (:meth:`LineFit.refusal`: the picture pins it,
   its 95% band within 1 px at 90% of the rings and 2 px at all), and the **oracle of an ideal line fit**
   (the floor): ``fit_lines`` given the true pixels of every visible true line (noise-free, complete,
   correctly grouped) and the true circles.
2. **Real cameras** (``--data``; each folder's SOURCE.md): all the images of a set pooled, then one
   image (the first with corners); compared with the established calibration (OCamCalib's
   ``ocam_model.json``, the Mei set's ``omnidir_calibration.json``) over the radii where it has
   corners (``corners.csv``). Beside it, the time per image and the landmark fit's time
   (``calibrate_camera`` from 10 corners with their 3-D points and the image, as ``bench_real``).
   Beside it, the **floor of the objective** (:func:`objective_floor`): the fit given the grouping the
   calibration knows (the arcs straight under it inside its corners' radii, its families, its right
   angles) and started at the calibration's own law: how far the objective's minimum on these edge
   points lies from the calibration.
3. **Speed**: one 1920 x 1920 render (the mirror): arcs and fit, seconds, beside the landmark fit.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from panomap.calibrate.boards.detect import find_boards
from panomap.calibrate.circles import Circle, ImageCircles, find_image_circles
from panomap.calibrate.lines.arcs import EdgeArc, find_arcs
from panomap.calibrate.lines.frame_circles import line_circles
from panomap.camera.model import CameraModel
from panomap.errors import PanomapError
from panomap.io.images import read_image
from panomap.simulate.cameras import RadialCamera, SimulatedCamera
from panomap.simulate.line_scenes import line_camera, render_line_scene

GRID_PX = 6.0
GOAL_P90_PX = 1.0
GOAL_MAX_PX = 2.0
#: The error (px) counted for a reference pixel whose ray the learned camera cannot reach.
UNREACHED_PX = 1e6

FloatArray = NDArray[np.float64]
Rays = Callable[[FloatArray], FloatArray]


# -- the measure -----------------------------------------------------------------------------------


def camera_frame_rays(model: CameraModel, pixels: FloatArray) -> FloatArray:
    """Unit rays (n, 3) in the learned camera's own axes of pixels (n, 2) (NaN beyond its radial range).

    The rotation of a tilted model is left out: the best rotation of the frame absorbs it. Image terms beyond
    the radial law (aspect, skew, decentering) are undone first.
    """
    u0, v0 = model.centre
    pixels = model.radial_pixels(pixels)
    du, dv = pixels[:, 0] - u0, pixels[:, 1] - v0
    r = np.hypot(du, dv)
    phi = np.arctan2(dv, du)
    theta = model.s * (phi - model.phi0)
    rho_grid = np.linspace(-math.pi / 2, math.pi / 2, 20001)
    with np.errstate(invalid="ignore", over="ignore"):
        r_grid = np.asarray(model.radial(rho_grid), dtype=np.float64)
    ok = np.isfinite(r_grid)
    rho_grid, r_grid = rho_grid[ok], r_grid[ok]
    if r_grid[-1] < r_grid[0]:
        rho_grid, r_grid = rho_grid[::-1], r_grid[::-1]
    increasing = np.concatenate([[True], np.diff(r_grid) > 0])
    # the longest increasing run from the image centre
    stop = int(np.argmin(increasing[1:])) + 1 if not increasing[1:].all() else len(r_grid)
    rho_grid, r_grid = rho_grid[:stop], r_grid[:stop]
    rho = np.interp(r, r_grid, rho_grid, left=np.nan, right=np.nan)
    return np.stack([np.cos(rho) * np.cos(theta), np.cos(rho) * np.sin(theta), np.sin(rho)], axis=1)


def camera_frame_pixels(model: CameraModel, rays: FloatArray) -> FloatArray:
    """Pixels (n, 2) of rays (n, 3) in the learned camera's own axes."""
    theta = np.arctan2(rays[:, 1], rays[:, 0])
    rho = np.arctan2(rays[:, 2], np.hypot(rays[:, 0], rays[:, 1]))
    r = np.asarray(model.radial(rho), dtype=np.float64)
    phi = model.s * theta + model.phi0
    return model.with_terms(np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1))


def best_orthogonal(a: FloatArray, b: FloatArray) -> FloatArray:
    """The orthogonal matrix Q (3, 3) (rotation or reflection) minimising sum |Q a_i - b_i|^2 (Kabsch)."""
    u, _, vt = np.linalg.svd(b.T @ a)
    return np.asarray(u @ vt)


@dataclass(frozen=True)
class Agreement:
    p50_px: float
    p90_px: float
    max_px: float
    points: int
    reflected: bool

    def line(self) -> str:
        ok = "meets" if self.p90_px <= GOAL_P90_PX and self.max_px <= GOAL_MAX_PX else "misses"
        return (
            f"p50 {self.p50_px:6.3f}  p90 {self.p90_px:6.3f}  max {self.max_px:6.3f} px  "
            f"({self.points} pixels{', mirrored' if self.reflected else ''}; {ok} the goal)"
        )


def ray_agreement(reference: Rays, pixels: FloatArray, model: CameraModel) -> Agreement:
    """The measure: reference pixels -> reference rays -> best orthogonal map -> the model's pixels."""
    ref = reference(pixels)
    mine = camera_frame_rays(model, pixels)
    ok = np.all(np.isfinite(ref), axis=1) & np.all(np.isfinite(mine), axis=1)
    if ok.sum() < 10:
        raise PanomapError("the learned camera covers too little of the evaluation region")
    q = best_orthogonal(ref[ok], mine[ok])
    back = camera_frame_pixels(model, ref @ q.T)
    error = np.hypot(*(back - pixels).T)
    error = np.where(np.isfinite(error), error, UNREACHED_PX)  # a reference pixel the model cannot reach
    return Agreement(
        float(np.percentile(error, 50)),
        float(np.percentile(error, 90)),
        float(np.max(error)),
        len(pixels),
        bool(np.linalg.det(q) < 0),
    )


def ring_grid(centre: tuple[float, float], r_min: float, r_max: float, size: tuple[int, int]) -> FloatArray:
    """Pixels (n, 2) every GRID_PX px with ``r_min <= r <= r_max`` from ``centre``, inside the frame."""
    w, h = size
    u, v = np.meshgrid(np.arange(0.0, w, GRID_PX), np.arange(0.0, h, GRID_PX))
    p = np.stack([u.ravel(), v.ravel()], axis=1)
    r = np.hypot(p[:, 0] - centre[0], p[:, 1] - centre[1])
    return p[(r >= r_min) & (r <= r_max)]


# -- references ------------------------------------------------------------------------------------


def simulated_rays(camera: SimulatedCamera) -> Rays:
    def rays(pixels: FloatArray) -> FloatArray:
        return np.asarray(camera.trace(pixels)[1], dtype=np.float64)

    return rays


def ocam_rays(model: dict[str, object]) -> Rays:
    """OCamCalib cam2world (SOURCE.md): pixel (u = column, v = row) -> unit ray in the OCam frame."""
    ss = np.asarray(model["ss_ascending"], dtype=np.float64)
    xc, yc = float(model["xc_row_0based"]), float(model["yc_col_0based"])  # type: ignore[arg-type]
    c, d, e = (float(model[k]) for k in ("c", "d", "e"))  # type: ignore[arg-type]
    inverse = np.linalg.inv(np.array([[c, d], [e, 1.0]]))

    def rays(pixels: FloatArray) -> FloatArray:
        rc = np.stack([pixels[:, 1] - xc, pixels[:, 0] - yc], axis=0)
        up, vp = inverse @ rc
        rho = np.hypot(up, vp)
        z = np.polynomial.polynomial.polyval(rho, ss)
        ray = np.stack([up, vp, z], axis=1)
        return np.asarray(ray / np.linalg.norm(ray, axis=1, keepdims=True))

    return rays


def mei_rays(model: dict[str, object]) -> Rays:
    """OpenCV omnidir (Mei unified, no distortion) unprojection: pixel -> unit ray in its camera frame."""
    primary = model["models"][model["primary"]]  # type: ignore[index]
    k = np.asarray(primary["K"], dtype=np.float64)
    xi = float(primary["xi"])
    if any(abs(float(x)) > 0 for x in primary["D_k1_k2_p1_p2"]):
        raise PanomapError("the Mei reference with distortion is not supported here")

    def rays(pixels: FloatArray) -> FloatArray:
        y = (pixels[:, 1] - k[1, 2]) / k[1, 1]
        x = (pixels[:, 0] - k[0, 2] - k[0, 1] * y) / k[0, 0]
        r2 = x * x + y * y
        lam = (xi + np.sqrt(1.0 + (1.0 - xi * xi) * r2)) / (1.0 + r2)
        ray = np.stack([lam * x, lam * y, lam - xi], axis=1)
        return np.asarray(ray / np.linalg.norm(ray, axis=1, keepdims=True))

    return rays


# -- the line fit ----------------------------------------------------------------------------------


def line_fit(arcs: list[EdgeArc], circles: ImageCircles) -> CameraModel:
    """Half B's fit: the camera learned from the arcs."""
    from panomap.calibrate.lines.fit import fit_lines

    return fit_lines(arcs, circles).model


def true_circles(camera: SimulatedCamera) -> ImageCircles:
    outer = Circle(centre=camera.centre, radius=float(camera.outer_radius), rms_px=0.0, inliers=0, rays=0)
    cut = float(camera.cutoff_radius)
    cutoff = Circle(centre=camera.centre, radius=cut, rms_px=0.0, inliers=0, rays=0) if cut > 0 else None
    return ImageCircles(centre=camera.centre, outer=outer, cutoff=cutoff, ellipse=None)


def true_model_of(camera: SimulatedCamera, shift: tuple[float, float] = (0.0, 0.0)) -> CameraModel:
    """The true (inner, level) camera as a CameraModel with its exact law, centre moved by ``shift``."""
    from panomap.camera.radial import RadialFunction

    inner = getattr(camera, "camera", camera)
    if not isinstance(inner, RadialCamera):
        raise PanomapError(f"no exact model for {inner.name}")
    if inner.law == "equidistant":
        radial = RadialFunction("odd1", (float(inner.scale),), "down")
    elif inner.law == "unified":
        radial = RadialFunction("unified", (float(inner.scale), float(inner.xi)), "down")
    else:
        raise PanomapError(f"no exact model for the {inner.law} law")
    return CameraModel(
        (inner.centre[0] + shift[0], inner.centre[1] + shift[1]), radial, int(inner.s), float(inner.phi0)
    )


# -- 1. rendered rooms -----------------------------------------------------------------------------


def simulated(quick: bool) -> None:
    print("== rendered rooms: learned vs true camera over the whole annulus (after the best rotation)")
    cases = [("fisheye190", 1, 1.0), ("fisheye190", 2, 2.0), ("fisheye190", 3, 3.0)]
    cases += [("hyperbolic", 1, 1.0), ("hyperbolic", 2, 2.0), ("hyperbolic", 3, 3.0)]
    if quick:
        cases = [("fisheye190", 1, 2.0), ("hyperbolic", 1, 2.0)]
    scale = 0.5 if quick else 1.0
    validated = False
    for kind, seed, tilt in cases:
        camera = line_camera(kind, scale, tilt_deg=tilt, toward_deg=40.0 * seed)
        scene = render_line_scene(camera, seed=seed, supersample=2)
        truth = true_circles(camera)
        grid = ring_grid(camera.centre, camera.cutoff_radius + 1.0, camera.outer_radius - 1.0, camera.image_size)
        reference = simulated_rays(camera)
        if not validated:
            exact = ray_agreement(reference, grid, true_model_of(camera))
            shifted = ray_agreement(reference, grid, true_model_of(camera, (0.5, 0.0)))
            print(f"  measure check, {kind}: true model vs itself {exact.line()}")
            print(f"  measure check, {kind}: centre moved 0.5 px   {shifted.line()}")
            validated = True
        label = f"{kind:10s} tilt {tilt:.0f} deg seed {seed}"
        start = time.perf_counter()
        circles = find_image_circles(scene.image)
        t_circles = time.perf_counter() - start
        start = time.perf_counter()
        arcs = find_arcs(scene.image, circles)
        t_arcs = time.perf_counter() - start
        start = time.perf_counter()
        try:
            from panomap.calibrate.lines.fit import fit_lines

            fitted = fit_lines(arcs, circles)
            learned = ray_agreement(reference, grid, fitted.model)
            refusal = fitted.refusal()
            verdict = learned.line() + (
                "; the command accepts it"
                if refusal is None
                else "; the command refuses it (" + refusal.split("differ by ")[-1].split(" (")[0] + ")"
            )
        except PanomapError as exc:
            verdict = f"no fit: {exc.detail if hasattr(exc, 'detail') else exc}"
        t_fit = time.perf_counter() - start
        ideal = [
            EdgeArc(pixels=p[:: max(1, len(p) // 400)], image_index=0, contrast=100.0)
            for p in scene.line_pixels
            if len(p) >= 40
        ]
        try:
            floor = ray_agreement(reference, grid, line_fit(ideal, truth)).line()
        except PanomapError as exc:
            floor = f"no fit: {exc}"
        print(f"  {label}: {len(arcs)} arcs; circles {t_circles:.2f} s, arcs {t_arcs:.2f} s, fit {t_fit:.2f} s")
        print(f"      learned: {verdict}")
        print(f"      oracle (ideal line fit, true lines' pixels): {floor}")


# -- 2. real cameras -------------------------------------------------------------------------------


def reference_as_model(
    reference: Rays, centre: tuple[float, float], r_min: float, r_max: float, kind: str
) -> CameraModel:
    """The reference's own radial law (along +u from its centre) fitted by the radial ``kind``, as a
    rotationally symmetric CameraModel: the check of the measure on a real set, and the floor of that kind
    (what remains is the kind's misfit and the reference's affine part)."""
    from panomap.camera.radial import fit_radial

    r = np.linspace(r_min, r_max, 300)  # over the evaluation region only
    rays = reference(np.stack([centre[0] + r, np.full_like(r, centre[1])], axis=1))
    axis_ray = reference(np.array([[centre[0], centre[1]]]))[0]
    rho = np.arccos(np.clip(rays @ axis_ray, -1.0, 1.0)) - math.pi / 2
    return CameraModel(centre, fit_radial(kind, rho, r, "down"), 1, 0.0)


#: An arc is a line under the calibration when its RMS distance (px) from its best plane's image is under this.
FLOOR_STRAIGHT_PX = 0.5
#: Two families are a true right angle under the calibration when within this angle (deg) of perpendicular.
FLOOR_SQUARE_DEG = 1.0


def reference_line_rms(reference: Rays, pixels: FloatArray) -> tuple[float, FloatArray]:
    """RMS distance (px, first order) of an arc's pixels from its best plane's image under the reference, and
    that plane's unit normal (the reference's rays' scatter; their turn per px by central differences)."""
    d = reference(pixels)
    step_u, step_v = np.array([0.5, 0.0]), np.array([0.0, 0.5])
    du = reference(pixels + step_u) - reference(pixels - step_u)
    dv = reference(pixels + step_v) - reference(pixels - step_v)
    normal = np.linalg.eigh(d.T @ d)[1][:, 0]
    distance = (d @ normal) / np.maximum(np.hypot(du @ normal, dv @ normal), 1e-12)
    return float(np.sqrt(np.mean(distance**2))), normal


def objective_floor(
    reference: Rays, centre: tuple[float, float], arcs: list[EdgeArc], band: tuple[float, float], kind: str
) -> tuple[CameraModel, CameraModel, int, int]:
    """The floor of the line fit's objective on these edge points: the grouping known (the arcs straight under
    the calibration inside the radii ``band`` (px from its centre) where it has corners, 10% beyond: outside
    it the calibration extrapolates; its families and their true right angles), the fit started at the
    calibration's own law (fitted by ``kind`` over the band); the camera it ends at, straightness and right
    angles, and straightness alone.
    What separates that camera from the calibration is not the grouping nor the start: it is the edge points
    and what straightness and right angles can tell."""
    from scipy import optimize

    from panomap.calibrate.lines.families import find_families, orthogonal_pairs
    from panomap.calibrate.lines.fit import _orthogonality_scale, _thin
    from panomap.calibrate.lines.objective import LineData, residuals
    from panomap.camera.radial import RadialFunction

    kept, normals = [], []
    for arc in arcs:
        r = np.hypot(arc.pixels[:, 0] - centre[0], arc.pixels[:, 1] - centre[1])
        if r.min() < 0.9 * band[0] or r.max() > 1.1 * band[1]:
            continue
        rms, normal = reference_line_rms(reference, arc.pixels)
        if rms < FLOOR_STRAIGHT_PX:
            kept.append(arc)
            normals.append(normal)
    images = np.array([a.image_index for a in kept], dtype=np.intp)
    families = find_families(np.array(normals), images)
    pairs = orthogonal_pairs(families, math.radians(FLOOR_SQUARE_DEG))
    pixels = [_thin(a.pixels, 100) for a in kept]
    if len(pixels) < 8:
        raise PanomapError(f"only {len(pixels)} arcs straight under the calibration inside its corners' radii")
    data = LineData.of(pixels, 1.1 * band[1] + 2.0)
    start_model = reference_as_model(reference, centre, band[0], band[1], kind)
    start = np.array([*start_model.centre, *start_model.radial.coefficients])
    scale = _orthogonality_scale(kind, "down", start, data)
    out = []
    for these in (pairs, []):
        x = optimize.least_squares(
            lambda x, these=these: residuals(kind, "down", x, data, families, these, scale),
            start,
            method="lm",
            x_scale="jac",
            max_nfev=400,
        ).x
        out.append(CameraModel((float(x[0]), float(x[1])), RadialFunction(kind, tuple(x[2:]), "down"), 1, 0.0))
    return out[0], out[1], len(kept), len(pairs)


def corner_radii(folder: Path, centre: tuple[float, float]) -> tuple[float, float, list[str]]:
    """The radii (px, from the calibration's centre) the calibration's corners span; the images with corners."""
    with (folder / "corners.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    if "u_col_px" in rows[0]:
        u = np.array([float(r["u_col_px"]) for r in rows])
        v = np.array([float(r["v_row_px"]) for r in rows])
    else:
        u = np.array([float(r["col_px"]) for r in rows])
        v = np.array([float(r["row_px"]) for r in rows])
    r = np.hypot(u - centre[0], v - centre[1])
    images = sorted({row["image"] for row in rows})
    return float(r.min()), float(r.max()), images


def stand_in(circles: ImageCircles) -> str:
    if circles.cutoff is not None:
        return f"cut-off disc's centre ({circles.centre[0]:.1f}, {circles.centre[1]:.1f})"
    return f"frame's middle ({circles.centre[0]:.1f}, {circles.centre[1]:.1f})"


def real(data: Path) -> None:
    print("== real cameras: learned vs the established calibration over the corners' radii")
    for folder in sorted(p for p in data.iterdir() if p.is_dir()):
        if (folder / "omnidir_calibration.json").is_file():
            model = json.loads((folder / "omnidir_calibration.json").read_text())
            k = model["models"][model["primary"]]["K"]
            centre = (float(k[0][2]), float(k[1][2]))
            reference = mei_rays(model)
        else:
            model = json.loads((folder / "ocam_model.json").read_text())
            centre = (float(model["yc_col_0based"]), float(model["xc_row_0based"]))
            reference = ocam_rays(model)
        r_min, r_max, with_corners = corner_radii(folder, centre)
        paths = sorted((folder / "images").iterdir())
        images = [read_image(p) for p in paths]
        h, w = images[0].shape[:2]
        grid = ring_grid(centre, r_min, r_max, (w, h))
        print(f"  {folder.name}: {len(images)} images {w} x {h}, corners at r {r_min:.0f}-{r_max:.0f} px")
        own_law: dict[str, float] = {}
        for kind in ("poly3", "odd5", "unified"):
            check = ray_agreement(reference, grid, reference_as_model(reference, centre, r_min, r_max, kind))
            own_law[kind] = check.p90_px
            print(f"      floor: the calibration's own law fitted by {kind:7s} {check.line()}")
        # the kind with fewest parameters that follows the calibration within 0.1 px of the best
        floor_kind = next(k for k in ("unified", "poly3", "odd5") if own_law[k] <= min(own_law.values()) + 0.1)
        arcs: list[EdgeArc] = []
        first_circles: ImageCircles | None = None
        t_arcs = 0.0
        one_arcs: list[EdgeArc] = []
        one_name = ""
        one_circles: ImageCircles | None = None
        for index, (path, image) in enumerate(zip(paths, images, strict=True)):
            start = time.perf_counter()
            try:
                circles = line_circles(image)
            except PanomapError as exc:
                print(f"      {path.name}: no image circle ({exc})")
                continue
            if circles.rim_in_frame == 0:
                print(f"      {path.name}: no rim in the frame; the fit starts from the {stand_in(circles)}")
            found = find_arcs(image, circles, image_index=index)
            t_arcs += time.perf_counter() - start
            first_circles = first_circles or circles
            arcs += found
            if path.name in with_corners and one_circles is None:
                one_arcs = [EdgeArc(a.pixels, 0, a.contrast) for a in found]
                one_circles, one_name = circles, path.name
        if first_circles is None:
            continue
        print(f"      circles + arcs: {t_arcs / len(images):.2f} s per image, {len(arcs)} arcs in all")
        runs = [("all images", arcs, first_circles)]
        if one_circles is not None:
            runs.append((f"one image ({one_name})", one_arcs, one_circles))
        for label, these, circ in runs:
            start = time.perf_counter()
            try:
                verdict = ray_agreement(reference, grid, line_fit(these, circ)).line()
            except PanomapError as exc:
                verdict = f"no fit: {exc}"
            print(f"      {label}: fit {time.perf_counter() - start:.2f} s: {verdict}")
            kind = floor_kind  # the kind that follows the calibration best
            try:
                both, straight, lines, pairs = objective_floor(reference, centre, these, (r_min, r_max), kind)
                print(
                    f"        floor ({kind}, the grouping known: {lines} arcs inside the corners' radii, {pairs} right "
                    f"angles; started at the calibration): {ray_agreement(reference, grid, both).line()}"
                )
                print(f"        the same, straightness alone: {ray_agreement(reference, grid, straight).line()}")
            except (PanomapError, ValueError, np.linalg.LinAlgError) as exc:
                print(f"        floor: none ({exc})")


# -- 3. speed --------------------------------------------------------------------------------------


def speed() -> None:
    print("== speed: one 1920 x 1920 image")
    camera = line_camera("hyperbolic", 1.6, tilt_deg=2.0)
    scene = render_line_scene(camera, seed=5, supersample=1)
    image = scene.image[:, 320:2240]  # 1920 x 1920 about the circle (radius 902 px)
    start = time.perf_counter()
    circles = find_image_circles(image)
    t_circles = time.perf_counter() - start
    start = time.perf_counter()
    arcs = find_arcs(image, circles)
    t_arcs = time.perf_counter() - start
    start = time.perf_counter()
    try:
        line_fit(arcs, circles)
        fitted = "fitted"
    except PanomapError as exc:
        fitted = f"no fit ({exc})"
    t_fit = time.perf_counter() - start
    start = time.perf_counter()
    boards = find_boards(image)  # fit --image looks for checkerboards first (none here: the search's cost)
    t_boards = time.perf_counter() - start
    total = t_circles + t_arcs + t_fit + t_boards
    print(
        f"  circles {t_circles:.2f} s, arcs {t_arcs:.2f} s ({len(arcs)}), fit {t_fit:.2f} s ({fitted}), "
        f"checkerboards {t_boards:.2f} s ({len(boards)} found): {total:.2f} s in all; goal 10 s "
        f"(ratio {total / 10.0:.2f})"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--data", type=Path, default=Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
    )
    parser.add_argument("--quick", action="store_true", help="half-size renders, two cases")
    parser.add_argument("--only", choices=("sim", "real", "speed"), default=None)
    args = parser.parse_args()
    if args.only in (None, "sim"):
        simulated(args.quick)
    if args.only in (None, "real"):
        if args.data.is_dir():
            real(args.data)
        else:
            print(f"== real cameras: skipped, no data at {args.data}", file=sys.stderr)
    if args.only in (None, "speed"):
        speed()


if __name__ == "__main__":
    main()
