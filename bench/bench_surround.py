"""A real car's four fisheyes placed from the floor's own landmarks, and how far its floor map lies from the truth.

Run: ``.venv/bin/python bench/bench_surround.py [--data DIR] [--floor-map OUT.png] [--keep DIR]``

The shared set ``rigs/neozhaoliang_surround_view`` (MIT; not copied into the project): four 960 x 640 fisheyes
(OpenCV ``cv::fisheye`` calibrations) on a car over a 6 m x 10 m ground pattern of 40 cm squares, and the
authors' own ground homographies (``project_matrix`` in each YAML, 1 px = 1 cm on their 1200 x 1600 canvas,
the pattern's corners on the lattice x = 300 + 40 i, y = 300 + 40 j).

The user's process, hand-free:

1. Each lens: ``panomap import`` of its YAML (its intrinsics as published), the rig of the four.
2. Floor landmarks: the lattice's points predicted in each picture from a rough placement (here the source's
   own homographies; a tape measure's rough poses would do), each refined to the checker corner within a
   quarter square of it (``cv2.cornerSubPix``) and kept only where the picture shows an X-corner there (the
   grey levels about it change sign four times, point-symmetric, with contrast): the corner's pixel, its
   lattice point's X, Y. Then again from the rig placed on them (more of the floor reaches the lattice), and
   landmarks missing the placed camera by over a quarter square dropped (a wrong lattice point).
3. ``place_on_floor`` (``panomap rig place``) of the four.

Measured, per camera: every detected corner's floor point through the placed rig (its pixel unprojected onto
Z = 0) against its lattice point (cm): median, p90, max; held out (placed on the corners of even lattice
columns, measured on the odd, and the other way round); at the seams (corners two cameras see: each camera's
distance, and the two cameras' floor points apart); beside the same corners through the source's own
homographies. World: X = (x - 600) cm, Y = (800 - y) cm of the source's canvas (+Y the car's front), metres.
"""

from __future__ import annotations

import argparse
import itertools
import math
import os
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from panomap.interop.api import import_calibration
from panomap.interop.orient import turn_table
from panomap.rig import CameraRig, save_rig
from panomap.rig.place import PlacedRig, place_on_floor

DATA = Path(os.environ.get("PANOMAP_SHARED_DATA", "/work/shared/data"))
NAMES = ("front", "left", "back", "right")
SQUARE_CM = 40.0
LATTICE_X_CM = 300.0 + SQUARE_CM * np.arange(16)  # 6 m
LATTICE_Y_CM = 300.0 + SQUARE_CM * np.arange(26)  # 10 m
MIN_SQUARE_PX = 8.0  # corners whose squares look smaller than this in the picture are not used
RING_SAMPLES = 48


@dataclass(frozen=True)
class SourceGround:
    """A camera's published ground mapping: fisheye pixel -> undistorted (new K) -> H -> its strip -> canvas."""

    name: str
    k: np.ndarray
    d: np.ndarray
    new_k: np.ndarray
    h: np.ndarray

    @classmethod
    def read(cls, path: Path, name: str) -> SourceGround:
        store = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
        k, d = store.getNode("camera_matrix").mat(), store.getNode("dist_coeffs").mat().reshape(4)
        h = store.getNode("project_matrix").mat()
        scale, shift = store.getNode("scale_xy").mat().ravel(), store.getNode("shift_xy").mat().ravel()
        new_k = k.copy()
        new_k[0, 0] *= scale[0]
        new_k[1, 1] *= scale[1]
        new_k[0, 2] += shift[0]
        new_k[1, 2] += shift[1]
        return cls(name, k, d, new_k, h)

    def to_canvas(self, pixels: np.ndarray) -> np.ndarray:
        """Canvas points (n, 2), cm, of fisheye pixels (n, 2)."""
        flat = cv2.fisheye.undistortPoints(pixels.reshape(-1, 1, 2), self.k, self.d, P=self.new_k).reshape(-1, 2)
        strip = cv2.perspectiveTransform(flat.reshape(-1, 1, 2), self.h).reshape(-1, 2)
        return strip_to_canvas(self.name, strip)

    def to_pixels(self, canvas: np.ndarray) -> np.ndarray:
        """Fisheye pixels (n, 2) of canvas points (n, 2); NaN where the homography puts them behind the camera."""
        strip = canvas_to_strip(self.name, canvas)
        q = np.column_stack([strip, np.ones(len(strip))]) @ np.linalg.inv(self.h).T
        flat = q[:, :2] / q[:, 2:]
        normal = np.column_stack([flat, np.ones(len(flat))]) @ np.linalg.inv(self.new_k).T
        pixels = cv2.fisheye.distortPoints(normal[:, None, :2].copy(), self.k, self.d).reshape(-1, 2)
        # The ground's side of the horizon: the same sign of w as a point well inside the strip.
        return np.where((q[:, 2:] * np.sign(np.linalg.inv(self.h)[2] @ [600.0, 300.0, 1.0])) > 0, pixels, np.nan)


def strip_to_canvas(name: str, strip: np.ndarray) -> np.ndarray:
    """The source's flips (``birdview.py``): its strip's pixels (n, 2) to the 1200 x 1600 canvas (cm)."""
    x, y = strip[:, 0], strip[:, 1]
    if name == "front":
        return np.column_stack([x, y])
    if name == "back":
        return np.column_stack([1199 - x, 1050 + 549 - y])
    if name == "left":
        return np.column_stack([y, 1599 - x])
    return np.column_stack([1199 - y, x])  # right


def canvas_to_strip(name: str, canvas: np.ndarray) -> np.ndarray:
    x, y = canvas[:, 0], canvas[:, 1]
    if name == "front":
        return np.column_stack([x, y])
    if name == "back":
        return np.column_stack([1199 - x, 1599 - y])
    if name == "left":
        return np.column_stack([1599 - y, x])
    return np.column_stack([y, 1199 - x])  # right


def canvas_to_world(canvas: np.ndarray) -> np.ndarray:
    """World X, Y (m) of canvas points (cm): X right, Y toward the car's front."""
    return np.column_stack([(canvas[:, 0] - 600.0) / 100.0, (800.0 - canvas[:, 1]) / 100.0])


def lattice_canvas() -> np.ndarray:
    """The pattern's lattice points (n, 2) on the canvas, cm: the 6 m x 10 m frame about the car, not the car's
    rectangle (x 500..700, y 550..1050 in the source's ``param_settings.py``), where its body shows the pattern
    mirrored."""
    x, y = np.meshgrid(LATTICE_X_CM, LATTICE_Y_CM)
    points = np.column_stack([x.ravel(), y.ravel()])
    under_car = (points[:, 0] > 500) & (points[:, 0] < 700) & (points[:, 1] > 550) & (points[:, 1] < 1050)
    return points[~under_car]


def x_corner(grey: np.ndarray, point: np.ndarray, radius: float) -> bool:
    """Whether ``grey`` (blurred, float32) shows a checker's X-corner at ``point``: on a ring of ``radius`` px,
    the samples clearly bright or dark (a quarter of the contrast beyond the mid-grey; the rest, the edges'
    blur, left out) change between the two four times, point-symmetric (the opposite quadrants alike), with a
    contrast of at least 40 grey levels between the bright and dark arcs."""
    angle = np.linspace(0, 2 * math.pi, RING_SAMPLES, endpoint=False)
    ring_x = (point[0] + radius * np.cos(angle)).astype(np.float32)[None]
    ring_y = (point[1] + radius * np.sin(angle)).astype(np.float32)[None]
    ring = cv2.remap(grey, ring_x, ring_y, cv2.INTER_LINEAR, borderValue=np.nan).ravel()
    if not np.all(np.isfinite(ring)):
        return False
    bright, dark = np.percentile(ring, 85), np.percentile(ring, 15)
    centred = ring - (bright + dark) / 2
    clear = np.sign(centred)[np.abs(centred) > 0.25 * (bright - dark)]
    changes = int(np.sum(clear != np.roll(clear, 1)))
    symmetric = float(np.corrcoef(centred, np.roll(centred, RING_SAMPLES // 2))[0, 1]) > 0.5
    return changes == 4 and symmetric and bright - dark > 40.0


def detect(grey: np.ndarray, predicted: np.ndarray, square_px: np.ndarray) -> np.ndarray:
    """Each predicted lattice point (n, 2) refined to the checker corner within a quarter square of it (its
    square ``square_px`` (n,) wide in the picture); NaN where there is none."""
    out = np.full_like(predicted, np.nan)
    blurred = cv2.GaussianBlur(grey, (0, 0), 1.0)
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 0.005)
    height, width = grey.shape
    for k, (point, side) in enumerate(zip(predicted, square_px, strict=True)):
        if not (np.all(np.isfinite(point)) and side >= MIN_SQUARE_PX):
            continue
        half = max(2, round(float(0.3 * side)))
        if not (half + 1 <= point[0] < width - half - 1 and half + 1 <= point[1] < height - half - 1):
            continue
        found = cv2.cornerSubPix(grey, point.reshape(1, 1, 2).astype(np.float32), (half, half), (-1, -1), criteria)
        found = found.reshape(2).astype(np.float64)
        if np.hypot(*(found - point)) <= 0.25 * side and x_corner(blurred, found, max(2.0, 0.3 * side)):
            out[k] = found
    return out


def square_sizes(pixels_of: object, canvas: np.ndarray) -> np.ndarray:
    """How wide (px) each lattice point's square looks: the nearest of its four neighbours' pixels."""
    here = pixels_of(canvas)  # type: ignore[operator]
    sizes = np.full(len(canvas), np.inf)
    for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        there = pixels_of(np.add(canvas, (dx * SQUARE_CM, dy * SQUARE_CM)))  # type: ignore[operator]
        sizes = np.fmin(sizes, np.hypot(*(there - here).T))
    return np.where(np.isfinite(sizes), sizes, np.nan)


@dataclass(frozen=True)
class Corners:
    """A camera's detected corners: pixels (n, 2) and their lattice points on the canvas (n, 2), cm."""

    pixels: np.ndarray
    canvas: np.ndarray


def find_corners(grey: np.ndarray, pixels_of: object) -> Corners:
    canvas = lattice_canvas()
    predicted = pixels_of(canvas)  # type: ignore[operator]
    found = detect(grey, predicted, square_sizes(pixels_of, canvas))
    keep = np.all(np.isfinite(found), axis=1)
    return Corners(found[keep], canvas[keep])


def placed_pixels(table: object) -> object:
    """A placed table's pixels of canvas points (its projection of their floor points)."""

    def pixels_of(canvas: np.ndarray) -> np.ndarray:
        world = canvas_to_world(canvas)
        return np.asarray(table.project(np.column_stack([world, np.zeros(len(world))])), dtype=np.float64)  # type: ignore[attr-defined]

    return pixels_of


def floor_points(table: object, pixels: np.ndarray) -> np.ndarray:
    """World floor points (n, 2), m, of pixels through a placed table."""
    theta, rho = table.unproject(pixels)  # type: ignore[attr-defined]
    ray = np.stack([np.cos(rho) * np.cos(theta), np.cos(rho) * np.sin(theta), np.sin(rho)], axis=-1)
    origin = np.asarray(table.camera_position)  # type: ignore[attr-defined]
    return origin[:2] + (-origin[2] / ray[:, 2])[:, None] * ray[:, :2]


def place(rig: CameraRig, corners: list[Corners]) -> PlacedRig:
    landmarks = [(c.pixels, canvas_to_world(c.canvas)) for c in corners]
    return place_on_floor(rig, landmarks, turn=lambda t, r: turn_table(t, r, "placed from floor landmarks"))


def drop_misses(placed: PlacedRig, corners: list[Corners]) -> list[Corners]:
    """Each camera's corners whose lattice point the placed camera sees within a quarter square of them."""
    out = []
    for table, c in zip(placed.rig.tables, corners, strict=True):
        pixels_of = placed_pixels(table)
        miss = np.hypot(*(pixels_of(c.canvas) - c.pixels).T)  # type: ignore[operator]
        keep = miss <= 0.25 * square_sizes(pixels_of, c.canvas)
        out.append(Corners(c.pixels[keep], c.canvas[keep]))
    return out


def stats(values_cm: np.ndarray) -> str:
    if values_cm.size == 0:
        return "none"
    median, p90, most = np.median(values_cm), np.percentile(values_cm, 90), np.max(values_cm)
    return f"median {median:.2f}, p90 {p90:.2f}, max {most:.2f} cm ({values_cm.size})"


@dataclass(frozen=True)
class CameraFigures:
    """A camera's detected corners' floor points from their lattice points (cm, one per corner): through the
    placed rig, through the rig placed on the other half of the corners (held out), through the source's own
    homography."""

    name: str
    placed_cm: np.ndarray
    held_out_cm: np.ndarray
    source_cm: np.ndarray


@dataclass(frozen=True)
class SeamFigures:
    """The corners two cameras see: each camera's floor point from the lattice point (cm, two per corner), the
    two cameras' floor points apart (cm, one per corner), and apart through the source's homographies."""

    pair: tuple[str, str]
    lattice_cm: np.ndarray
    apart_cm: np.ndarray
    source_apart_cm: np.ndarray


@dataclass(frozen=True)
class SurroundResult:
    placed: PlacedRig
    corners: list[Corners]
    cameras: tuple[CameraFigures, ...]
    seams: tuple[SeamFigures, ...]


def seams(placed: PlacedRig, corners: list[Corners], sources: list[SourceGround]) -> tuple[SeamFigures, ...]:
    floors = [floor_points(table, c.pixels) for table, c in zip(placed.rig.tables, corners, strict=True)]
    out = []
    for i, j in itertools.combinations(range(len(NAMES)), 2):
        a, b = corners[i].canvas, corners[j].canvas
        shared = [(p, q) for p in range(len(a)) for q in range(len(b)) if np.array_equal(a[p], b[q])]
        if not shared:
            continue
        p, q = (np.array(k) for k in zip(*shared, strict=True))
        truth = canvas_to_world(a[p])
        each = 100 * np.concatenate([np.hypot(*(floors[i][p] - truth).T), np.hypot(*(floors[j][q] - truth).T)])
        apart = 100 * np.hypot(*(floors[i][p] - floors[j][q]).T)
        source_apart = np.hypot(*(sources[i].to_canvas(corners[i].pixels[p]) -
                                  sources[j].to_canvas(corners[j].pixels[q])).T)  # fmt: skip
        out.append(SeamFigures((NAMES[i], NAMES[j]), each, apart, source_apart))
    return tuple(out)


def held_out(rig: CameraRig, corners: list[Corners]) -> list[np.ndarray]:
    """Each camera's corners' distance (cm) from their lattice points, placed on the other half (even lattice
    columns against odd)."""
    out: list[list[np.ndarray]] = [[] for _ in corners]
    for parity in (0, 1):
        column = [np.round((c.canvas[:, 0] - LATTICE_X_CM[0]) / SQUARE_CM).astype(int) % 2 for c in corners]
        train = [Corners(c.pixels[col == parity], c.canvas[col == parity]) for c, col in
                 zip(corners, column, strict=True)]  # fmt: skip
        placed = place(rig, train)
        for k, (table, c, col) in enumerate(zip(placed.rig.tables, corners, column, strict=True)):
            test = col != parity
            floor = floor_points(table, c.pixels[test])
            out[k].append(100 * np.hypot(*(floor - canvas_to_world(c.canvas[test])).T))
    return [np.concatenate(parts) for parts in out]


def render_pattern(table: object, samples: int = 3) -> np.ndarray:
    """A grey picture (H, W) float32 of an ideal, flat pattern of 40 cm squares (dark 40, bright 215) on grey
    ground (128), the lattice's frame about the car, through a placed table: each pixel the mean of
    ``samples`` x ``samples`` rays unprojected onto Z = 0."""
    width, height = table.image_size  # type: ignore[attr-defined]
    offsets = (np.arange(samples) + 0.5) / samples - 0.5
    total = np.zeros((height, width))
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    for du, dv in itertools.product(offsets, offsets):
        pixels = np.stack([u + du, v + dv], axis=-1).reshape(-1, 2)
        value = np.full(len(pixels), 128.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            floor = floor_points(table, pixels)
        canvas = np.column_stack([600 + 100 * floor[:, 0], 800 - 100 * floor[:, 1]])
        i = np.floor((canvas[:, 0] - LATTICE_X_CM[0]) / SQUARE_CM)
        j = np.floor((canvas[:, 1] - LATTICE_Y_CM[0]) / SQUARE_CM)
        inside = (i >= 0) & (i < len(LATTICE_X_CM) - 1) & (j >= 0) & (j < len(LATTICE_Y_CM) - 1)
        inside &= ~((canvas[:, 0] > 500) & (canvas[:, 0] < 700) & (canvas[:, 1] > 550) & (canvas[:, 1] < 1050))
        value[inside] = np.where((i[inside] + j[inside]) % 2 == 0, 215.0, 40.0)
        total += value.reshape(height, width)
    return (total / samples**2).astype(np.float32)


def evaluate(data: Path, say: object = print, greys: list[np.ndarray] | None = None) -> SurroundResult:
    """The set in ``data`` placed from its floor's corners (two passes), and the figures; ``greys``: other
    pictures of its four cameras (renders) instead of its own."""
    if greys is None:
        images = [data / "images" / f"{name}.png" for name in NAMES]
        greys = [cv2.cvtColor(cv2.imread(str(p)), cv2.COLOR_BGR2GRAY).astype(np.float32) for p in images]
    sources = [SourceGround.read(data / "yaml" / f"{name}.yaml", name) for name in NAMES]
    tables = tuple(import_calibration(data / "yaml" / f"{name}.yaml", image_size=(960, 640)) for name in NAMES)
    rig = CameraRig(tables, NAMES, None, {"made of": [f"{n}.yaml" for n in NAMES]})
    corners = [find_corners(g, s.to_pixels) for g, s in zip(greys, sources, strict=True)]
    counts = ", ".join(f"{n} {len(c.pixels)}" for n, c in zip(NAMES, corners, strict=True))
    say(f"pass 1 (predicted by the source's homographies): {counts}")  # type: ignore[operator]
    placed = place(rig, corners)
    again = [find_corners(g, placed_pixels(t)) for g, t in zip(greys, placed.rig.tables, strict=True)]
    corners = drop_misses(placed, again)
    counts = ", ".join(f"{n} {len(c.pixels)}" for n, c in zip(NAMES, corners, strict=True))
    say(f"pass 2 (predicted by the rig placed on pass 1): {counts}")  # type: ignore[operator]
    placed = place(rig, corners)
    cameras = []
    for name, table, c, source, out in zip(NAMES, placed.rig.tables, corners, sources, held_out(rig, corners),
                                           strict=True):  # fmt: skip
        ours = 100 * np.hypot(*(floor_points(table, c.pixels) - canvas_to_world(c.canvas)).T)
        theirs = np.hypot(*(source.to_canvas(c.pixels) - c.canvas).T)
        cameras.append(CameraFigures(name, ours, out, theirs))
    return SurroundResult(placed, corners, tuple(cameras), seams(placed, corners, sources))


def report(result: SurroundResult) -> None:
    for line in result.placed.describe("m"):
        print(" ", line)
    print("\nper camera: detected corners' floor points from their lattice points (cm)")
    for camera in result.cameras:
        print(f"  {camera.name:5s} placed: {stats(camera.placed_cm)}")
        print(f"  {'':5s} held out: {stats(camera.held_out_cm)}")
        print(f"  {'':5s} source's homography: {stats(camera.source_cm)}")
    print("\nat the seams: corners two cameras see (cm)")
    for seam in result.seams:
        print(f"  {'-'.join(seam.pair)}: {seam.apart_cm.size} corners; from the lattice {stats(seam.lattice_cm)}")
        print(f"  {'':11s} the two cameras apart: {stats(seam.apart_cm)}; the source's: {stats(seam.source_apart_cm)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DATA / "rigs" / "neozhaoliang_surround_view")
    parser.add_argument("--floor-map", type=Path, help="write the placed rig's floor map here (panomap floor)")
    parser.add_argument("--render", action="store_true", help="also run it on renders of an ideal, flat pattern")
    parser.add_argument("--keep", type=Path, help="keep the rig file and the landmark CSVs in this folder")
    args = parser.parse_args()
    if not (args.data / "yaml" / "front.yaml").exists():
        sys.exit(f"no surround set at {args.data}: see bench_surround.py's docstring")
    folder = args.keep or Path(tempfile.mkdtemp())
    folder.mkdir(parents=True, exist_ok=True)
    result = evaluate(args.data)
    report(result)
    if args.render:
        print("\nthe same on renders of an ideal, flat pattern through the placed rig (what detection leaves):")
        renders = [render_pattern(table) for table in result.placed.rig.tables]
        report(evaluate(args.data, greys=renders))
    rig_path = folder / "placed.npz"
    save_rig(result.placed.rig, rig_path)
    for name, c in zip(NAMES, result.corners, strict=True):
        world = canvas_to_world(c.canvas)
        rows = [f"{u:.3f},{v:.3f},{x:.2f},{y:.2f},0" for (u, v), (x, y) in zip(c.pixels, world, strict=True)]
        (folder / f"{name}.csv").write_text("u,v,X,Y,Z\n" + "\n".join(rows) + "\n")
    print(f"\nthe placed rig and each camera's landmarks (panomap rig place's CSVs): {folder}")
    if args.floor_map is not None:
        images = [str(args.data / "images" / f"{name}.png") for name in NAMES]
        command = [sys.executable, "-m", "panomap", "floor", str(rig_path), *images, "-o", str(args.floor_map),
                   "--z", "0", "--x", "-4", "4", "--y", "-6", "6", "--resolution", "0.02"]  # fmt: skip
        subprocess.run(command, check=True)


if __name__ == "__main__":
    main()
