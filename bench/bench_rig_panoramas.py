"""A dual fisheye imported from a camchain, rendered from real 360 photographs: each layer and the blend
against the true panorama (issue 52's first goal).

Run: ``PYTHONPATH=src .venv/bin/python bench/bench_rig_panoramas.py [--quick]``

The truth is the photograph itself. Two Kannala-Brandt lenses (Kalibr's ``pinhole`` + ``equidistant``, 200 deg
across, 960 x 960 each, distorted), back to back but for a small turn, see a real equirectangular photograph
(``../shared/data/panoramas``, not bundled: the bench says so and stops where it is absent) at infinity; the frame
holds them side by side (camera 0 on the left), rendered here in closed form from Kalibr's equations (3 x 3
samples a pixel), not by panomap. Then, as a user would: ``panomap import dual.yaml -o rig.npz --side-by-side
--image frame.png`` and ``panomap equirect rig.npz frame.png -o pano.png --size WxH --each lens_{camera}.png``.

Measured against the photograph resampled to the same equirect (the conventions' equirect and the photograph's
convention: column 0 at longitude -180 deg, growing right, so the view's azimuth is minus the longitude):

- **geometry**: the output cut into 32 x 32 tiles; each textured tile's shift from the truth by phase
  correlation (px), p50 / p90 / max, for each camera's layer where it alone covers the tile and for the blend;
- **coverage**: the share of the sphere's area (cos-weighted rows) the blend fills;
- **seams**: where the two lenses meet (azimuth +-90 deg, columns W/4 and 3W/4), the mean absolute change
  between neighbouring columns within 8 px of each seam, minus the truth's there (grey levels).

Two conditions: clean, and dressed as a real camera (each lens vignetted 30-40% at its rim, lens 1 15% brighter,
noise sigma 3, JPEG 85). The goals: layers and blend within p90 0.4 px clean, 0.6 px dressed; coverage >= 99.5%;
the seam's step at most 2 grey levels above the truth's.
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "panoramas"
PANORAMAS = ("eso_alma_correlator_room.jpg", "sun360_hotelroom_hohonet.png", "polyhaven_lebombo_room.hdr")
SIDE = 960
FOV_DEG = 200.0
# Kalibr's equidistant model: theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8), r = f theta_d.
K = (0.02, -0.004, 0.0005, 0.0)
TILE = 32


@dataclass(frozen=True)
class Lens:
    """One Kannala-Brandt lens: focal (px), principal point (px, within its own half), coefficients."""

    f: float
    cx: float
    cy: float
    k: tuple[float, float, float, float]

    def theta_d(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        t2 = theta * theta
        k1, k2, k3, k4 = self.k
        return theta * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))

    def rays(self, u: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
        """(..., 3) unit rays in the lens's OpenCV frame (z along the axis) of pixels (u, v); NaN beyond the
        field of view."""
        x, y = (u - self.cx) / self.f, (v - self.cy) / self.f
        r = np.hypot(x, y)
        theta = r.copy()
        for _ in range(30):  # Newton on theta_d(theta) = r
            t2 = theta * theta
            k1, k2, k3, k4 = self.k
            slope = 1 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)))
            theta = theta - (self.theta_d(theta) - r) / slope
        scale = np.where(r > 0, np.sin(theta) / np.maximum(r, 1e-300), 1.0)
        out = np.stack([x * scale, y * scale, np.cos(theta)], axis=-1)
        out[theta > math.radians(FOV_DEG / 2)] = np.nan
        return out


def camchain(lenses: tuple[Lens, Lens], turn: NDArray[np.float64]) -> str:
    """A Kalibr camchain of the two lenses, cam1's ``T_cn_cnm1`` the rotation ``turn`` (3, 3) and 2 cm back."""
    text = ""
    for n, lens in enumerate(lenses):
        text += (
            f"cam{n}:\n  camera_model: pinhole\n  intrinsics: [{lens.f}, {lens.f}, {lens.cx}, {lens.cy}]\n"
            f"  distortion_model: equidistant\n  distortion_coeffs: {list(lens.k)}\n  resolution: [{SIDE}, {SIDE}]\n"
        )
    rows = [[*turn[i], [0.0, 0.0, -0.02][i]] for i in range(3)] + [[0, 0, 0, 1]]
    return text + f"  T_cn_cnm1: {[[float(x) for x in row] for row in rows]}\n"


def half_turn(yaw_deg: float, pitch_deg: float, roll_deg: float) -> NDArray[np.float64]:
    """cam1 from cam0 (x_1 = R x_0): half a turn about the OpenCV frame's down axis, then a small turn."""
    small = cv2.Rodrigues(np.radians([pitch_deg, yaw_deg, roll_deg]))[0]
    return small @ np.diag([-1.0, 1.0, -1.0])


# Camera 0 looks along +X, level (yaw, pitch, roll 0): columns (R, Dn, F) of the conventions.
CAM0_TO_WORLD = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def read_panorama(path: Path) -> NDArray[np.uint8]:
    """The photograph as 8-bit BGR (an HDR tone-mapped: its 99th percentile to white, gamma 2.2)."""
    if path.suffix == ".hdr":
        linear = cv2.imread(str(path), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR).astype(np.float64)
        white = float(np.percentile(linear, 99)) or 1.0
        return np.asarray(np.clip((linear / white) ** (1 / 2.2), 0, 1) * 255 + 0.5, dtype=np.uint8)
    return np.asarray(cv2.imread(str(path), cv2.IMREAD_COLOR), dtype=np.uint8)


def sample_sphere(panorama: NDArray[np.uint8], world: NDArray[np.float64]) -> NDArray[np.float64]:
    """The photograph at world rays (..., 3) (bilinear, wrapping), black where a ray is NaN."""
    h, w = panorama.shape[:2]
    azimuth = np.arctan2(world[..., 1], world[..., 0])
    elevation = np.arcsin(np.clip(world[..., 2], -1, 1))
    col = ((math.pi - azimuth) / (2 * math.pi) * w - 0.5) % w
    row = (math.pi / 2 - elevation) / math.pi * h - 0.5
    seen = np.isfinite(col) & np.isfinite(row)
    out = cv2.remap(
        panorama,
        np.where(seen, col, -10).astype(np.float32),
        np.where(seen, row, -10).astype(np.float32),
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_WRAP,
    ).astype(np.float64)
    return np.where(seen[..., None], out, 0.0)


def render_frame(panorama: NDArray[np.uint8], lenses: tuple[Lens, Lens], turn: NDArray[np.float64]) -> NDArray:
    """(SIDE, 2 SIDE, 3) float64 frame: lens 0 on the left, lens 1 on the right, 3 x 3 samples a pixel."""
    frame = np.zeros((SIDE, 2 * SIDE, 3))
    offsets = (np.arange(3) + 0.5) / 3 - 0.5
    v, u = np.mgrid[0:SIDE, 0:SIDE].astype(np.float64)
    to_world = (CAM0_TO_WORLD, CAM0_TO_WORLD @ turn.T)
    for n, lens in enumerate(lenses):
        acc = np.zeros((SIDE, SIDE, 3))
        for dv in offsets:
            for du in offsets:
                rays = lens.rays(u + du, v + dv)
                acc += sample_sphere(panorama, rays @ to_world[n].T)
        frame[:, n * SIDE : (n + 1) * SIDE] = acc / 9
    return frame


def dress(frame: NDArray[np.float64], lenses: tuple[Lens, Lens], rng: np.random.Generator) -> NDArray[np.float64]:
    """Vignetting (30-40% at the rim), lens 1 15% brighter, noise sigma 3."""
    out = frame.copy()
    v, u = np.mgrid[0:SIDE, 0:SIDE].astype(np.float64)
    for n, lens in enumerate(lenses):
        r = np.hypot(u - lens.cx, v - lens.cy) / (SIDE / 2)
        fall = 1 - rng.uniform(0.3, 0.4) * np.clip(r, 0, 1) ** 2
        out[:, n * SIDE : (n + 1) * SIDE] *= fall[..., None] * (1.15 if n == 1 else 1.0)
    return out + rng.normal(0, 3, out.shape)


def exact_layer(
    frame: NDArray[np.uint8], lens: Lens, to_world: NDArray[np.float64], world: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Grey layer of camera 0 (the frame's left half) at world rays (H, W, 3) through the true model, and where
    it sees (the floor of the measure: the same frame, no fit, no table)."""
    local = world @ to_world  # world to the lens's frame (rows: d_c = R^T d_w)
    theta = np.arccos(np.clip(local[..., 2], -1, 1))
    r = lens.f * lens.theta_d(theta)
    norm = np.maximum(np.hypot(local[..., 0], local[..., 1]), 1e-300)
    u = (lens.cx + r * local[..., 0] / norm).astype(np.float32)
    v = (lens.cy + r * local[..., 1] / norm).astype(np.float32)
    seen = theta < math.radians(FOV_DEG / 2) - 0.02
    grey = cv2.cvtColor(frame[:, :SIDE], cv2.COLOR_BGR2GRAY)
    return cv2.remap(grey, u, v, cv2.INTER_LINEAR).astype(np.float64), seen


def tile_shifts(view: NDArray[np.float64], truth: NDArray[np.float64], mask: NDArray[np.bool_]) -> NDArray:
    """Each textured tile's shift (px) from the truth by phase correlation, over tiles the mask holds whole."""
    h, w = truth.shape
    window = cv2.createHanningWindow((TILE, TILE), cv2.CV_64F)
    shifts = []
    for y in range(0, h - TILE + 1, TILE):
        for x in range(0, w - TILE + 1, TILE):
            if not mask[y : y + TILE, x : x + TILE].all():
                continue
            a, b = truth[y : y + TILE, x : x + TILE], view[y : y + TILE, x : x + TILE]
            if a.std() < 8:
                continue
            (dx, dy), _ = cv2.phaseCorrelate(a, b, window)
            shifts.append(math.hypot(dx, dy))
    return np.asarray(shifts)


def seam_step(view: NDArray[np.float64], truth: NDArray[np.float64], filled: NDArray[np.bool_]) -> float:
    """The mean |change between neighbouring columns| within 8 px of the seams (columns W/4, 3W/4; rows within
    60 deg of the horizon), the view's minus the truth's (grey levels)."""
    h, w = truth.shape
    rows = slice(h // 6, h - h // 6)
    out = []
    for seam in (w // 4, 3 * w // 4):
        cols = slice(seam - 8, seam + 8)
        a = np.abs(np.diff(view[rows, cols], axis=1))
        b = np.abs(np.diff(truth[rows, cols], axis=1))
        ok = filled[rows, cols][:, 1:] & filled[rows, cols][:, :-1]
        out.append(float(a[ok].mean() - b[ok].mean()))
    return max(out)


def panomap(*args: str) -> None:
    command = [sys.executable, "-m", "panomap", *args, "-q"]
    result = subprocess.run(command, capture_output=True, text=True, check=False)
    if result.returncode != 0:
        raise SystemExit(f"{' '.join(command)}: {result.stderr.strip()}")


def measure(panorama_path: Path, dressed: bool, folder: Path, say: bool = True) -> dict[str, float]:
    rng = np.random.default_rng(7)
    lenses = (Lens(262.0, 479.5, 479.5, K), Lens(264.5, 481.2, 478.1, K))
    turn = half_turn(0.8, -0.5, 0.3)
    panorama = read_panorama(panorama_path)
    frame = render_frame(panorama, lenses, turn)
    if dressed:
        frame = dress(frame, lenses, rng)
    frame_path = folder / "frame.png" if not dressed else folder / "frame.jpg"
    image = np.clip(frame + 0.5, 0, 255).astype(np.uint8)
    cv2.imwrite(str(frame_path), image, [cv2.IMWRITE_JPEG_QUALITY, 85] if dressed else [])
    (folder / "dual.yaml").write_text(camchain(lenses, turn))
    panomap("import", str(folder / "dual.yaml"), "-o", str(folder / "rig.npz"), "--side-by-side",
            "--image", str(frame_path))  # fmt: skip
    width, height = 1728, 864  # 4.8 px a degree, the lenses' own
    panomap("equirect", str(folder / "rig.npz"), str(frame_path), "-o", str(folder / "pano.png"),
            "--size", f"{width}x{height}", "--each", str(folder / "lens_{camera}.png"))  # fmt: skip
    # The truth: the photograph at the view's rays (azimuth pi - 2 pi (k + 0.5)/W).
    k, l_ = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    azimuth = math.pi - 2 * math.pi * k / width
    elevation = math.pi / 2 - math.pi * l_ / height
    world = np.stack([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)], -1)
    blur = max(1.0, panorama.shape[1] / width) * 0.5
    smooth = cv2.GaussianBlur(panorama, (0, 0), blur) if blur > 0.6 else panorama
    truth = cv2.cvtColor(sample_sphere(smooth, world).astype(np.float32), cv2.COLOR_BGR2GRAY).astype(np.float64)

    def grey(path: Path) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        picture = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        filled = picture[..., 3] > 0 if picture.shape[-1] == 4 else picture.max(axis=-1) > 0
        g = cv2.cvtColor(picture[..., :3], cv2.COLOR_BGR2GRAY).astype(np.float64)
        return g, filled

    blend, filled = grey(folder / "pano.png")
    layers = [grey(path) for path in sorted(folder.glob("lens_*.png"))]
    weight = np.cos(elevation)
    figures: dict[str, float] = {"coverage %": 100 * float((weight * filled).sum() / weight.sum())}
    for name, (view, mask) in [("blend", (blend, filled)), ("lens 0", layers[0]), ("lens 1", layers[1])]:
        shifts = tile_shifts(view, truth, mask)
        figures[f"{name} tiles"] = len(shifts)
        figures[f"{name} p50"], figures[f"{name} p90"] = np.percentile(shifts, [50, 90])
        figures[f"{name} max"] = float(shifts.max())
    figures["seam step"] = seam_step(blend, truth, filled)
    # The floor: lens 0's layer made from the same frame through the true model (what the measure leaves).
    exact, seen = exact_layer(image, lenses[0], CAM0_TO_WORLD, world)
    shifts = tile_shifts(exact, truth, seen)
    figures["floor p50"], figures["floor p90"] = np.percentile(shifts, [50, 90])
    figures["floor max"] = float(shifts.max())
    if say:
        shown = ", ".join(f"{key} {value:.3g}" for key, value in figures.items())
        print(f"  {panorama_path.name} ({'dressed' if dressed else 'clean'}): {shown}", flush=True)
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DATA)
    parser.add_argument("--quick", action="store_true", help="one photograph")
    args = parser.parse_args()
    names = [p for p in PANORAMAS if (args.data / p).exists()]
    if not names:
        raise SystemExit(f"no photographs under {args.data} (the shared panoramas)")
    rows = []
    with tempfile.TemporaryDirectory() as temporary:
        for name in names[:1] if args.quick else names:
            for dressed in (False, True):
                rows.append((name, dressed, measure(args.data / name, dressed, Path(temporary))))
    print(
        "\n| photograph | condition | coverage | blend p50 / p90 / max (px) | lens 0 p90 | lens 1 p90 "
        "| floor p90 / max | seam step |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for name, dressed, f in rows:
        print(
            f"| {name} | {'dressed' if dressed else 'clean'} | {f['coverage %']:.2f}% | {f['blend p50']:.2f} / "
            f"{f['blend p90']:.2f} / {f['blend max']:.2f} | {f['lens 0 p90']:.2f} | {f['lens 1 p90']:.2f} | "
            f"{f['floor p90']:.2f} / {f['floor max']:.2f} | {f['seam step']:+.2f} |"
        )


if __name__ == "__main__":
    main()
