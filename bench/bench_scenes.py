"""One picture, no pattern: ``panomap fit -o cam.npz --image IMG`` on real scenes, measured as the outside checks do.

Run: ``.venv/bin/python bench/bench_scenes.py [--data ../shared/data] [--only real|pano|speed|circles] [--quick]
[--keep DIR]``

Per picture, the whole command is run as a user runs it (a fresh process, its defaults), then:

- **accepted or refused** (its exit status; a refusal's one line);
- **p90 / max px from the truth** (:func:`ring_agreement`, the way ``scenes/README.md`` says outside checks
  measure it): pixels on rings about the true centre from 15 to 85 deg off the optical axis (every 2.5 deg,
  about every 6 px along a ring, inside the frame 3 px from its edges); each pixel's ray under the learned
  camera (its own axes: the tilt is a rotation the best orthogonal matrix absorbs) and under the truth; the
  learned rays turned into the truth's frame by the one best orthogonal matrix (Kabsch, a mirror allowed);
  each turned ray projected by the truth, its distance to the pixel;
- **the reported uncertainty**: the largest standard error of the radius the table reports, and how often the
  true error lies inside the reported 95% band (1.96 standard errors): over the rings, the ring's median
  error against the band at the ring's elevation under the learned camera (the goal: at 95% of them);
- **time**: the command's wall time (under ``nice``; the machine may be shared).

Pictures:

1. **Real scenes** (``scenes/``): each folder's pictures against its established calibration (a Ricoh Theta
   lens, Mei unified with radial-tangential distortion, BoofCV; a small fisheye, double sphere, Basalt).
2. **Real 360-degree photographs re-projected** (``panoramas/``; exact truth): through fisheyes of 190-200 deg
   (equidistant, equisolid, a Kannala-Brandt polynomial lens), cut by the frame or not, and a hyperbolic
   mirror that sees its own camera (a dark disc), each looking down, tilted 1-3 deg, vignetted, with noise
   and JPEG, at no more than the photograph's resolution (about 2.8 px per degree for the 1024-wide files).

3. **Speed** (``--only speed``): the server room through a 195 deg fisheye on a 2048 x 2048 frame, the command's
   time, then each stage's in one process (read, circles, arcs, checkerboard search, fit).

4. **Image circles** (``--only circles``): the rim found on re-projected photographs whose rims are sharp, soft
   and vignetted (a field stop out of focus), cut by a square frame, or dark: its distance from the truth.

The goal of issue 43: every accepted picture within p90 1.0 px and max 2.0 px; at least 80% accepted.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from panomap.camera.model import CameraModel
from panomap.simulate import mount_rotation, noisy_jpeg, vignette
from panomap.simulate.cameras import RadialCamera, TiltedCamera
from panomap.table.file import load_table

FloatArray = NDArray[np.float64]
#: Rays (n, 3) in the truth's camera frame -> pixels (n, 2) (NaN where it does not see them).
Project = Callable[[FloatArray], FloatArray]

DEFAULT_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
RING_ALPHA_DEG = np.arange(15.0, 85.0 + 1e-9, 2.5)
RING_STEP_PX = 6.0
FRAME_MARGIN_PX = 3.0
GOAL_P90_PX = 1.0
GOAL_MAX_PX = 2.0
UNREACHED_PX = 1e6
BAND_SIGMAS = 1.96


# -- the truths: forward projections of rays in the camera's frame (+z the optical axis) ----------


def mei_radtan(
    fx: float, fy: float, cx: float, cy: float, xi: float, k: tuple[float, float], t: tuple[float, float]
) -> Project:
    """BoofCV's "omnidirectional_universal" (Mei, radial-tangential; scenes/theta_back/SOURCE.md)."""

    def project(rays: FloatArray) -> FloatArray:
        d = rays / np.linalg.norm(rays, axis=1, keepdims=True)
        z = d[:, 2] + xi
        x, y = d[:, 0] / z, d[:, 1] / z
        r2 = x * x + y * y
        radial = 1 + k[0] * r2 + k[1] * r2 * r2
        xd = x * radial + 2 * t[0] * x * y + t[1] * (r2 + 2 * x * x)
        yd = y * radial + t[0] * (r2 + 2 * y * y) + 2 * t[1] * x * y
        return np.stack([fx * xd + cx, fy * yd + cy], axis=1)

    return project


def double_sphere(fx: float, fy: float, cx: float, cy: float, xi: float, alpha: float) -> Project:
    """Usenko's double sphere (scenes/ds_building/SOURCE.md)."""

    def project(rays: FloatArray) -> FloatArray:
        x, y, z = rays.T
        d1 = np.sqrt(x * x + y * y + z * z)
        zx = xi * d1 + z
        d2 = np.sqrt(x * x + y * y + zx * zx)
        den = alpha * d2 + (1 - alpha) * zx
        return np.stack([fx * x / den + cx, fy * y / den + cy], axis=1)

    return project


def simulated(camera: RadialCamera) -> Project:
    """A level simulated camera: +z of the truth's frame is its axis (world -Z looking down, +Z looking up)."""
    turn = np.array([1.0, -1.0, -1.0]) if camera.axis == "down" else np.ones(3)  # down: a rotation about x

    def project(rays: FloatArray) -> FloatArray:
        world = rays * turn
        return np.asarray(camera.project(world), dtype=np.float64)

    return project


# -- the measure -------------------------------------------------------------------------------------


def ring_pairs(project: Project, size: tuple[int, int]) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Pixels (n, 2), their true rays (n, 3) and off-axis angles (n,) deg on the rings, inside the frame."""
    pixels, rays, alphas = [], [], []
    width, height = size
    for alpha_deg in RING_ALPHA_DEG:
        a = math.radians(alpha_deg)
        edge = project(np.array([[math.sin(a), 0.0, math.cos(a)], [0.0, 0.0, 1.0]]))
        radius = float(np.nan_to_num(np.hypot(*(edge[0] - edge[1])), nan=100.0))
        count = max(int(2 * math.pi * radius / RING_STEP_PX), 12)
        azimuth = np.linspace(0, 2 * math.pi, count, endpoint=False)
        d = np.stack(
            [math.sin(a) * np.cos(azimuth), math.sin(a) * np.sin(azimuth), np.full(count, math.cos(a))], axis=1
        )
        p = project(d)
        with np.errstate(invalid="ignore"):
            inside = (
                np.isfinite(p).all(axis=1)
                & (p[:, 0] >= FRAME_MARGIN_PX)
                & (p[:, 0] <= width - 1 - FRAME_MARGIN_PX)
                & (p[:, 1] >= FRAME_MARGIN_PX)
                & (p[:, 1] <= height - 1 - FRAME_MARGIN_PX)
            )
        pixels.append(p[inside])
        rays.append(d[inside])
        alphas.append(np.full(int(inside.sum()), alpha_deg))
    return np.concatenate(pixels), np.concatenate(rays), np.concatenate(alphas)


def learned_rays(model: CameraModel, pixels: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Unit rays (n, 3) in the learned camera's own axes (NaN beyond its radial range) and their elevations (rad)."""
    u0, v0 = model.centre
    du, dv = pixels[:, 0] - u0, pixels[:, 1] - v0
    r = np.hypot(du, dv)
    theta = model.s * (np.arctan2(dv, du) - model.phi0)
    grid = np.linspace(-math.pi / 2, math.pi / 2, 20001)
    with np.errstate(invalid="ignore", over="ignore"):
        radius = np.abs(np.asarray(model.radial(grid), dtype=np.float64))
    ok = np.isfinite(radius)
    grid, radius = grid[ok], radius[ok]
    if radius[-1] < radius[0]:
        grid, radius = grid[::-1], radius[::-1]
    rising = np.diff(radius) > 0
    stop = len(radius) if rising.all() else int(np.argmin(rising)) + 1
    rho = np.interp(r, radius[:stop], grid[:stop], left=np.nan, right=np.nan)
    rays = np.stack([np.cos(rho) * np.cos(theta), np.cos(rho) * np.sin(theta), np.sin(rho)], axis=1)
    return rays, rho


@dataclass(frozen=True)
class Agreement:
    p90_px: float
    max_px: float
    covered: float  # share of the rings where the true error lies within the reported 95% band (NaN: none reported)


def ring_agreement(
    project: Project, size: tuple[int, int], model: CameraModel, band: Callable[[FloatArray], FloatArray] | None
) -> Agreement:
    """The outside checks' measure (module doc), and the reported band's coverage."""
    pixels, truth, alpha_deg = ring_pairs(project, size)
    mine, rho = learned_rays(model, pixels)
    ok = np.isfinite(mine).all(axis=1)
    if ok.sum() < 10:
        return Agreement(UNREACHED_PX, UNREACHED_PX, float("nan"))
    u, _, vt = np.linalg.svd(truth[ok].T @ mine[ok])
    q = u @ vt  # mine -> truth
    with np.errstate(invalid="ignore"):
        back = project(mine @ q.T)
    error = np.hypot(*(back - pixels).T)
    error = np.where(np.isfinite(error), error, UNREACHED_PX)
    covered = float("nan")
    if band is not None:
        inside = []
        for a in np.unique(alpha_deg):
            ring = (alpha_deg == a) & ok
            if ring.sum() < 3:
                continue
            inside.append(float(np.median(error[ring])) <= BAND_SIGMAS * float(band(np.degrees(np.median(rho[ring])))))
        covered = float(np.mean(inside)) if inside else float("nan")
    return Agreement(float(np.percentile(error, 90)), float(np.max(error)), covered)


# -- the pictures ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Picture:
    name: str
    image: Path | None  # a file to fit as it is
    pixels: NDArray[np.uint8] | None  # or an image to write first
    project: Project
    size: tuple[int, int]


def real_pictures(data: Path) -> list[Picture]:
    out: list[Picture] = []
    theta = data / "scenes" / "theta_back"
    if theta.is_dir():
        truth = mei_radtan(
            620.298809979,
            620.399434447,
            478.483148536,
            480.318274837,
            1.19807286909,
            (-0.257089970771, 0.0128307442205),
            (-9.1179697419e-4, 3.91862130427e-4),
        )
        for path in sorted((theta / "images").glob("*.jpg")):
            out.append(Picture(f"theta {path.stem}", path, None, truth, (960, 1080)))
    building = data / "scenes" / "ds_building"
    if building.is_dir():
        calib = json.loads((building / "calibration.json").read_text())["value0"]["intrinsics"][0]["intrinsics"]
        truth = double_sphere(calib["fx"], calib["fy"], calib["cx"], calib["cy"], calib["xi"], calib["alpha"])
        for path in sorted((building / "images").glob("*.jpg")):
            out.append(Picture(f"ds {path.stem}", path, None, truth, (640, 480)))
    return out


def read_panorama(path: Path) -> NDArray[np.uint8]:
    """The photograph as 8-bit BGR (an HDR tone-mapped: its 99th percentile to white, gamma 2.2)."""
    if path.suffix == ".hdr":
        linear = cv2.imread(str(path), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR).astype(np.float64)
        white = float(np.percentile(linear, 99)) or 1.0
        return np.asarray(np.clip((linear / white) ** (1 / 2.2), 0, 1) * 255 + 0.5, dtype=np.uint8)
    return np.asarray(cv2.imread(str(path), cv2.IMREAD_COLOR), dtype=np.uint8)


def reproject(panorama: NDArray[np.uint8], camera: TiltedCamera, supersample: int = 2) -> NDArray[np.uint8]:
    """The photograph seen through ``camera`` (rays from its trace; black outside its annulus), box-filtered
    over ``supersample`` squared samples per pixel."""
    width, height = camera.image_size
    n = supersample
    offsets = (np.arange(n) + 0.5) / n - 0.5
    acc = np.zeros((height, width, 3))
    h_p, w_p = panorama.shape[:2]
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    for dv in offsets:
        for du in offsets:
            _, d = camera.trace(np.stack([u + du, v + dv], axis=-1))
            lon = np.arctan2(d[..., 1], d[..., 0])
            lat = np.arcsin(np.clip(d[..., 2], -1, 1))
            col = ((lon + math.pi) / (2 * math.pi) * w_p - 0.5).astype(np.float32)
            row = ((math.pi / 2 - lat) / math.pi * h_p - 0.5).astype(np.float32)
            seen = np.isfinite(col) & np.isfinite(row)
            sample = cv2.remap(
                panorama,
                np.where(seen, col, -10),
                np.where(seen, row, -10),
                cv2.INTER_LINEAR,
                borderMode=cv2.BORDER_WRAP,
            )
            acc += np.where(seen[..., None], sample, 0.0)
    return np.asarray(np.clip(acc / n**2 + 0.5, 0, 255), dtype=np.uint8)


#: (name, law, half field of view deg, frame (W, H), image-circle radius px, distortion, xi, cut-off deg)
CAMERAS = (
    ("equidistant 195", "equidistant", 97.5, (600, 600), 280.0, (), 0.0, 0.0),
    ("equisolid 190 cut", "equisolid", 95.0, (640, 480), 290.0, (), 0.0, 0.0),
    ("kb-poly 200 cut", "polynomial", 100.0, (720, 540), 300.0, (-0.02, 0.001), 0.0, 0.0),
    ("hyperbolic mirror", "unified", 100.0, (640, 640), 290.0, (), 0.8, 12.0),
)
PANORAMAS = (
    "sun360_hotelroom_hohonet.png",
    "polyhaven_lebombo_room.hdr",
    "eso_alma_correlator_room.jpg",
    "polyhaven_empty_warehouse.hdr",
    "sun360_bedroom_horizonnet.png",
    "polyhaven_potsdamer_platz.hdr",
)


def panorama_camera(spec: tuple, seed: int) -> TiltedCamera:
    name, law, half_deg, size, outer, distortion, xi, cut_deg = spec
    rng = np.random.default_rng(seed)
    a_max = math.radians(half_deg)
    if law == "equidistant":
        scale = outer / a_max
    elif law == "equisolid":
        scale = outer / (2 * math.sin(a_max / 2))
    elif law == "polynomial":
        scale = outer / (a_max + distortion[0] * a_max**3 + distortion[1] * a_max**5)
    else:
        scale = outer * (xi + math.cos(a_max)) / math.sin(a_max)
    centre = ((size[0] - 1) / 2 + rng.uniform(-6, 6), (size[1] - 1) / 2 + rng.uniform(-6, 6))
    inner = RadialCamera(
        name=name,
        law=law,
        scale=scale,
        xi=xi,
        distortion=distortion,
        image_size=size,
        centre=centre,
        s=int(rng.choice([-1, 1])),
        phi0=float(rng.uniform(0, 2 * math.pi)),
        alpha_min=math.radians(cut_deg),
        alpha_max=a_max,
    )
    tilt = math.radians(rng.uniform(1.0, 3.0))
    return TiltedCamera(inner, mount_rotation(tilt, float(rng.uniform(0, 2 * math.pi))))


#: Mirror cameras cropped by a 16:9 frame (issue 55, item 1: a real catadioptric camera's 1920 x 1080 frame, its
#: mirror's circle cut at the top and bottom): (name, xi, cut-off deg, image circle deg, axis, frame (W, H), circle
#: radius px). 960 x 540 for the 1024-wide photographs (about their resolution), 1920 x 1080 for the 4000-wide one.
MIRRORS = (
    ("hyperbolic down 16:9", 0.8, 12.0, 100.0, "down", 300.0),
    ("parabolic down 16:9", 1.0, 15.0, 105.0, "down", 320.0),
    ("hyperbolic up 16:9", 0.8, 12.0, 100.0, "up", 340.0),
    ("parabolic up 16:9", 1.0, 15.0, 105.0, "up", 300.0),
)


def mirror_camera(spec: tuple, size: tuple[int, int], seed: int) -> TiltedCamera:
    """A mirror camera of ``spec`` (:data:`MIRRORS`) on a 16:9 frame of ``size``, its circle (radius scaled with the
    frame from 960 px wide) cut at the top and bottom, tilted 1-3 deg."""
    name, xi, cut_deg, half_deg, axis, radius = spec
    rng = np.random.default_rng(seed)
    outer = radius * size[0] / 960
    a_max = math.radians(half_deg)
    inner = RadialCamera(
        name=name,
        law="unified",
        scale=outer * (xi + math.cos(a_max)) / math.sin(a_max),
        xi=xi,
        image_size=size,
        centre=((size[0] - 1) / 2 + rng.uniform(-8, 8), (size[1] - 1) / 2 + rng.uniform(-6, 6)),
        s=int(rng.choice([-1, 1])),
        phi0=float(rng.uniform(0, 2 * math.pi)),
        axis=axis,
        alpha_min=math.radians(cut_deg),
        alpha_max=a_max,
    )
    tilt = math.radians(rng.uniform(1.0, 3.0))
    return TiltedCamera(inner, mount_rotation(tilt, float(rng.uniform(0, 2 * math.pi)), looking_down=axis == "down"))


def mirror_pictures(data: Path, quick: bool) -> list[Picture]:
    """The photographs through :data:`MIRRORS`, each as seen on a 16:9 frame: the mirror's own camera a dark disc
    in the middle, vignetted, noise and JPEG (as :func:`panorama_pictures`)."""
    folder = data / "panoramas"
    if not folder.is_dir():
        return []
    out: list[Picture] = []
    for k, file in enumerate(PANORAMAS[:3] if quick else PANORAMAS):
        panorama = read_panorama(folder / file)
        size = (1920, 1080) if panorama.shape[1] >= 4000 else (960, 540)
        for j, spec in enumerate(MIRRORS if not quick else MIRRORS[k % 2 :: 2]):
            seed = 5000 + 100 * k + j
            camera = mirror_camera(spec, size, seed)
            image = reproject(panorama, camera)
            out.append(
                Picture(
                    f"{file.split('.')[0][:22]} / {spec[0]}",
                    None,
                    dressed(image, camera, seed),
                    simulated(camera.camera),
                    size,
                )
            )
    return out


def dressed(
    image: NDArray[np.uint8], camera: TiltedCamera, seed: int, body_px: float | None = None
) -> NDArray[np.uint8]:
    """``image`` with the mirror's own camera (a dark disc with a lens in it, ``body_px`` across its radius: the
    camera's cut-off radius where None), vignetting, noise and JPEG."""
    rng = np.random.default_rng(seed + 7)
    body = camera.cutoff_radius if body_px is None else body_px
    if body > 0:
        v, u = np.mgrid[0 : image.shape[0], 0 : image.shape[1]]
        r = np.hypot(u - camera.centre[0], v - camera.centre[1])
        image[r < body] = (25, 25, 30)
        image[r < 0.4 * body] = (5, 5, 5)
    image = vignette(
        image,
        camera.centre,
        camera.outer_radius,
        falloff=float(rng.uniform(0.2, 0.5)),
        dim=float(rng.uniform(0.0, 0.2)),
        dim_angle=float(rng.uniform(0, 2 * math.pi)),
    )
    return noisy_jpeg(image, rng, noise=4.0, quality=80)


def panorama_pictures(data: Path, quick: bool) -> list[Picture]:
    folder = data / "panoramas"
    if not folder.is_dir():
        return []
    out: list[Picture] = []
    names = PANORAMAS[:3] if quick else PANORAMAS
    for k, file in enumerate(names):
        panorama = read_panorama(folder / file)
        for j, spec in enumerate(CAMERAS if not quick else CAMERAS[k % 2 :: 2]):
            seed = 100 * k + j
            camera = panorama_camera(spec, seed)
            rng = np.random.default_rng(seed + 7)
            image = reproject(panorama, camera)
            if camera.cutoff_radius > 0:  # the mirror sees its own camera: a dark disc with a lens in it
                v, u = np.mgrid[0 : image.shape[0], 0 : image.shape[1]]
                r = np.hypot(u - camera.centre[0], v - camera.centre[1])
                image[r < camera.cutoff_radius] = (25, 25, 30)
                image[r < 0.4 * camera.cutoff_radius] = (5, 5, 5)
            image = vignette(
                image,
                camera.centre,
                camera.outer_radius,
                falloff=float(rng.uniform(0.2, 0.5)),
                dim=float(rng.uniform(0.0, 0.2)),
                dim_angle=float(rng.uniform(0, 2 * math.pi)),
            )
            image = noisy_jpeg(image, rng, noise=4.0, quality=80)
            out.append(
                Picture(
                    f"{file.split('.')[0][:22]} / {spec[0]}", None, image, simulated(camera.camera), camera.image_size
                )
            )
    return out


# -- the command -------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Outcome:
    name: str
    accepted: bool
    detail: str
    seconds: float
    agreement: Agreement | None
    max_se_px: float | None


def run_fit(picture: Picture, workdir: Path) -> Outcome:
    """``panomap fit -o cam.npz --image IMG`` in a fresh process; the table's camera against the truth."""
    image = picture.image
    if image is None:
        image = workdir / (re.sub(r"[^a-z0-9]+", "_", picture.name.lower()) + ".png")
        cv2.imwrite(str(image), picture.pixels)
    output = workdir / "cam.npz"
    output.unlink(missing_ok=True)
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1] / "src"))
    start = time.perf_counter()
    done = subprocess.run(
        ["nice", "-n", "5", sys.executable, "-m", "panomap", "fit", "-o", str(output), "--image", str(image)],
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    seconds = time.perf_counter() - start
    if done.returncode != 0 or not output.is_file():
        lines = [x for x in done.stderr.strip().splitlines() if x.strip()]
        detail = lines[-1] if lines else f"exit {done.returncode}"
        would_be = would_be_agreement(picture, image) if "does not pin" in detail else None
        return Outcome(picture.name, False, detail, seconds, would_be, None)
    table = load_table(output)
    report = table.info.get("fit", {}).get("uncertainty")
    band = None
    max_se = None
    if report is not None:
        elevation = np.asarray(report["elevation_deg"], dtype=np.float64)
        se = np.asarray(report["radius_se_px"], dtype=np.float64)
        order = np.argsort(elevation)
        max_se = float(report["max_se_px"])

        def band(rho_deg: FloatArray) -> FloatArray:
            return np.interp(rho_deg, elevation[order], se[order])

    agreement = ring_agreement(picture.project, picture.size, table.model, band)
    return Outcome(picture.name, True, "", seconds, agreement, max_se)


def would_be_agreement(picture: Picture, image: Path) -> Agreement | None:
    """Where the command refused because the picture does not pin the camera: how far the camera it would have
    written lies from the truth (the line fit's choice, in this process), to count refusals of right answers."""
    from panomap.calibrate.lines.arcs import find_arcs
    from panomap.calibrate.lines.fit import fit_lines
    from panomap.calibrate.lines.frame_circles import line_circles
    from panomap.errors import PanomapError
    from panomap.io.images import read_image

    pixels = read_image(image)
    circles = line_circles(pixels)
    try:
        model = fit_lines(find_arcs(pixels, circles), circles).model
    except PanomapError:
        return None
    return ring_agreement(picture.project, picture.size, model, None)


def table_row(o: Outcome) -> str:
    if not o.accepted:
        reason = re.sub(r"^panomap: error: (\S+: )?", "", o.detail)
        band = re.search(r"differ by up to ([0-9.]+ px at [0-9]+ deg)", reason)
        along = re.search(r"along and across the camera's axis \(every direction within ([0-9.]+ deg)\)", reason)
        reason = f"does not pin the camera (band {band.group(1)})" if band else reason[:110]
        if along:
            reason += f"; its lines along and across the axis (within {along.group(1)})"
        if o.agreement is not None:
            reason += f"; the camera refused lay p90 {o.agreement.p90_px:.1f} / max {o.agreement.max_px:.1f} px off"
        return f"| {o.name} | refused | | | | | {o.seconds:.1f} | {reason} |"
    a = o.agreement
    assert a is not None
    goal = "yes" if a.p90_px <= GOAL_P90_PX and a.max_px <= GOAL_MAX_PX else "**no**"
    se = "" if o.max_se_px is None else f"{o.max_se_px:.2f}"
    cover = "" if math.isnan(a.covered) else f"{a.covered:.0%}"
    return f"| {o.name} | accepted | {a.p90_px:.2f} | {a.max_px:.2f} | {goal} | {se} / {cover} | {o.seconds:.1f} | |"


def speed_picture(data: Path) -> Picture:
    """The server room re-projected through a 195 deg equidistant fisheye on a 2048 x 2048 frame (radius 1000 px:
    10 px per degree, under the 4000-wide photograph's 11), tilted, vignetted, noise, JPEG."""
    spec = ("equidistant 195 2048", "equidistant", 97.5, (2048, 2048), 1000.0, (), 0.0, 0.0)
    camera = panorama_camera(spec, 2048)
    rng = np.random.default_rng(2048)
    image = reproject(read_panorama(data / "panoramas" / "eso_alma_correlator_room.jpg"), camera, supersample=1)
    image = vignette(image, camera.centre, camera.outer_radius, falloff=0.4, dim=0.1, dim_angle=1.0)
    image = noisy_jpeg(image, rng, noise=4.0, quality=80)
    return Picture("eso 2048 x 2048 / equidistant 195", None, image, simulated(camera.camera), camera.image_size)


def stages(path: Path) -> str:
    """Seconds of each stage of the command on ``path`` (in this process: imports already paid)."""
    from panomap.calibrate.boards.choice import learn_camera
    from panomap.calibrate.boards.detect import find_boards
    from panomap.calibrate.lines.arcs import find_arcs
    from panomap.calibrate.lines.fit import LineFitOptions
    from panomap.calibrate.lines.frame_circles import line_circles
    from panomap.errors import PanomapError
    from panomap.io.images import read_image

    out = []
    start = time.perf_counter()
    image = read_image(path)
    out.append(f"read {time.perf_counter() - start:.1f}")
    start = time.perf_counter()
    circles = line_circles(image)
    out.append(f"circles {time.perf_counter() - start:.1f}")
    start = time.perf_counter()
    arcs = find_arcs(image, circles)
    out.append(f"arcs {time.perf_counter() - start:.1f} ({len(arcs)})")
    start = time.perf_counter()
    boards = find_boards(image)
    out.append(f"checkerboards {time.perf_counter() - start:.1f}")
    start = time.perf_counter()
    try:
        learn_camera(boards, arcs, circles, LineFitOptions())
        verdict = "accepted"
    except PanomapError as exc:
        verdict = "refused: " + exc.detail[:60]
    out.append(f"fit {time.perf_counter() - start:.1f} ({verdict})")
    return ", ".join(out) + " s"


#: The rims a circle finder meets on real pictures: (name, frame side over the circle's radius (None: the
#: camera's own frame), rim softness px, vignetting at the rim, brightness).
RIMS = (
    ("sharp", None, 0.0, 0.3, 1.0),
    ("soft, vignetted", None, 3.0, 0.75, 1.0),
    ("square frame cuts it, soft", 1.7, 2.0, 0.6, 1.0),
    ("dark", None, 1.0, 0.5, 0.25),
)


def circles_section(data: Path) -> None:
    """The image circle found on re-projected photographs with real cameras' rims (``RIMS``): its centre's and
    radius' distance from the truth (px), or the finder's refusal."""
    from panomap.calibrate.circles import find_image_circles
    from panomap.errors import PanomapError
    from panomap.simulate import field_stop

    print("| photograph / camera | rim | centre error px | radius error px | fit RMS px, rays agreeing | refusal |")
    print("| --- | --- | --- | --- | --- | --- |")
    found = total = 0
    errors: list[float] = []
    for k, file in enumerate(PANORAMAS[:4]):
        panorama = read_panorama(data / "panoramas" / file)
        for j, spec in enumerate(CAMERAS[:2]):
            for rim_name, side, softness, falloff, gain in RIMS:
                name, law, half_deg, size, outer, distortion, xi, cut_deg = spec
                if side is not None:
                    size = (int(side * outer), int(side * outer))
                camera = panorama_camera(
                    (name, law, half_deg + 3.0, size, outer + 8, distortion, xi, cut_deg), 10 * k + j
                )
                rng = np.random.default_rng(10 * k + j)
                image = reproject(panorama, camera, supersample=1)
                image = field_stop(image, camera.centre, outer, softness_px=softness)
                image = vignette(image, camera.centre, outer, falloff=falloff)
                image = np.asarray(np.clip(image * gain, 0, 255), dtype=np.uint8)
                image = noisy_jpeg(image, rng, noise=3.0, quality=85)
                total += 1
                label = f"| {file.split('.')[0][:22]} / {name} | {rim_name} |"
                try:
                    circles = find_image_circles(image)
                except PanomapError as exc:
                    print(f"{label} | | | {exc.detail[:100]} |")
                    continue
                found += 1
                error = math.dist(circles.centre, camera.centre)
                errors.append(error)
                print(
                    f"{label} {error:.2f} | {circles.outer_radius - outer:+.2f} | {circles.outer.rms_px:.2f}, "
                    f"{circles.outer.inliers} of {circles.outer.rays} | |"
                )
    print(
        f"\nfound {found} of {total}; centre error median {np.median(errors):.2f} px, worst {max(errors):.2f} px"
        if errors
        else f"\nfound none of {total}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--only", choices=("real", "pano", "mirrors", "speed", "circles"), default=None)
    parser.add_argument("--quick", action="store_true", help="three photographs, two cameras each")
    parser.add_argument("--keep", type=Path, default=None, help="keep the re-projected pictures here")
    args = parser.parse_args()
    pictures: list[Picture] = []
    if args.only in (None, "real"):
        pictures += real_pictures(args.data)
    if args.only in (None, "pano"):
        pictures += panorama_pictures(args.data, args.quick)
    if args.only in (None, "mirrors"):
        pictures += mirror_pictures(args.data, args.quick)
    if args.only == "circles":
        circles_section(args.data)
        return
    if args.only == "speed":
        pictures = [speed_picture(args.data)]
    if not pictures:
        raise SystemExit(f"no pictures under {args.data} (scenes/, panoramas/)")
    print("| picture | fit | p90 px | max px | within goal | reported max SE px / band covers truth | s | refusal |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    outcomes = []
    with tempfile.TemporaryDirectory() as tmp:
        workdir = args.keep or Path(tmp)
        workdir.mkdir(parents=True, exist_ok=True)
        for picture in pictures:
            outcome = run_fit(picture, workdir)
            outcomes.append(outcome)
            print(table_row(outcome), flush=True)
        if args.only == "speed":
            image = next(iter(sorted(workdir.glob("eso_2048*.png"))))
            print(f"\nstages: {stages(image)}")
    accepted = [o for o in outcomes if o.accepted]
    good = [
        o for o in accepted if o.agreement and o.agreement.p90_px <= GOAL_P90_PX and o.agreement.max_px <= GOAL_MAX_PX
    ]
    lost = [
        o
        for o in outcomes
        if not o.accepted and o.agreement and o.agreement.p90_px <= GOAL_P90_PX and o.agreement.max_px <= GOAL_MAX_PX
    ]
    print(f"\nrefused though the camera it would have written was within the goal: {len(lost)}")
    along = [o for o in outcomes if "along and across the camera's axis" in o.detail]
    print(f"refused with the lines along and across the camera's axis (the stretch, bench_line_floor.py): {len(along)}")
    print(
        f"\n{len(accepted)} of {len(outcomes)} accepted, {len(good)} of them within the goal "
        f"({len(accepted) - len(good)} accepted beyond it); time median "
        f"{np.median([o.seconds for o in outcomes]):.1f} s, worst {max(o.seconds for o in outcomes):.1f} s"
    )


if __name__ == "__main__":
    main()
