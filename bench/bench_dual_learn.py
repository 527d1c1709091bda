"""A dual fisheye learned from its own frames, no calibration (``panomap rig learn --side-by-side``): rendered in
closed form, checked against the truth.

Run: ``PYTHONPATH=src .venv/bin/python bench/bench_dual_learn.py [--quick]``

Two equidistant lenses (190 deg, 960 x 960 each, the Insta360 Air's size: f 283.6 px/rad), back to back but for a
small turn, see either the line scene's room (:mod:`panomap.simulate.line_scenes`: straight edges of its three
directions) or a real 360 photograph (``../shared/data/panoramas``, skipped where absent), at the lens centre. The
frame holds them side by side (lens 0 on the left), rendered here from the lenses' own equations (3 x 3 samples a
pixel), not by panomap. A lens may be *stretched* along its axis: each pixel sees ``S d / |S d|``, ``S = diag(1, 1,
s)``, of the equidistant lens's ray ``d`` (:mod:`panomap.calibrate.lines.stretch`): its lines are exactly as straight
for every ``s``, and two lenses stretched alike share one linear map of the world, so their overlap agrees too.

Cases: the room with the lenses' axes along its walls (every line along or across the axes: the stretch is free),
the same lenses stretched 6% (the case that must be refused), the room with the axes 30 deg off its walls (its right
angles pin the stretch), the real photograph. Each case's outcome: refused (its line) or accepted, and then each
lens's rays against the truth in px (p90 / max over rings 15-85 deg and over the overlap ring 85-95 deg, the learned
rotation applied), against the band the command stated.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from panomap.errors import PanomapError
from panomap.simulate.line_scenes import room_grey

FloatArray = NDArray[np.float64]
DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "panoramas"
PHOTOGRAPH = DATA / "eso_alma_correlator_room.jpg"
SIDE = 960
F_PX = 0.928 * 960 / math.pi  # the Insta360 Air's (its SOURCE.md): 283.6 px/rad
FOV_DEG = 190.0


@dataclass(frozen=True)
class Lens:
    """An equidistant lens (``r = f alpha``) stretched by ``stretch`` along its axis; centre (px, in its half)."""

    f: float = F_PX
    cx: float = 479.5
    cy: float = 479.5
    stretch: float = 1.0

    def rays(self, u: FloatArray, v: FloatArray) -> FloatArray:
        """(..., 3) unit rays in the lens's OpenCV frame (z ahead) of pixels (u, v); NaN beyond its field."""
        x, y = u - self.cx, v - self.cy
        r = np.hypot(x, y)
        alpha = r / self.f
        phi = np.arctan2(y, x)
        out = np.stack([np.sin(alpha) * np.cos(phi), np.sin(alpha) * np.sin(phi), self.stretch * np.cos(alpha)], -1)
        out /= np.linalg.norm(out, axis=-1, keepdims=True)
        out[alpha > math.radians(FOV_DEG / 2)] = np.nan
        return np.asarray(out)

    def project(self, rays: FloatArray) -> FloatArray:
        """Pixels (n, 2) of unit rays (n, 3) in the lens's OpenCV frame (the stretch undone)."""
        d = rays / np.array([1.0, 1.0, self.stretch])
        alpha = np.arccos(np.clip(d[:, 2] / np.linalg.norm(d, axis=1), -1, 1))
        phi = np.arctan2(d[:, 1], d[:, 0])
        return np.stack([self.cx + self.f * alpha * np.cos(phi), self.cy + self.f * alpha * np.sin(phi)], axis=1)


def lens_axes(yaw_deg: float, pitch_deg: float = 0.0) -> FloatArray:
    """A lens looking along world azimuth ``yaw_deg``, ``pitch_deg`` up, no roll: columns (right, down, ahead) in
    world axes (the conventions' perspective view's)."""
    psi, tau = math.radians(yaw_deg), math.radians(pitch_deg)
    ahead = np.array([math.cos(tau) * math.cos(psi), math.cos(tau) * math.sin(psi), math.sin(tau)])
    right = np.array([math.sin(psi), -math.cos(psi), 0.0])
    return np.stack([right, np.cross(ahead, right), ahead], axis=1)


def small_turn(yaw_deg: float, pitch_deg: float, roll_deg: float) -> FloatArray:
    """A small rotation (3, 3) of lens 1 in its own frame."""
    return np.asarray(cv2.Rodrigues(np.radians([pitch_deg, yaw_deg, roll_deg]))[0], dtype=np.float64)


def sample_photograph(panorama: NDArray[np.uint8], world: FloatArray) -> FloatArray:
    """The equirect photograph's grey level at unit world rays (n, 3) (column 0 at longitude -180 deg)."""
    h, w = panorama.shape[:2]
    azimuth = np.arctan2(world[:, 1], world[:, 0])
    elevation = np.arcsin(np.clip(world[:, 2], -1, 1))
    col = ((math.pi - azimuth) / (2 * math.pi) * w - 0.5) % w
    row = (math.pi / 2 - elevation) / math.pi * h - 0.5
    grey = cv2.cvtColor(panorama, cv2.COLOR_BGR2GRAY)
    side = 1024  # remap's maps at most 32767 across: the rays as a square
    count = len(col)
    pad = (-count) % side
    maps = [np.concatenate([m, np.zeros(pad)]).astype(np.float32).reshape(-1, side) for m in (col, row)]
    out = cv2.remap(grey, maps[0], maps[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
    return np.asarray(out.ravel()[:count], dtype=np.float64)


def render_frame(
    lenses: tuple[Lens, Lens], to_world: tuple[FloatArray, FloatArray], scene: str, supersample: int = 3
) -> NDArray[np.uint8]:
    """(SIDE, 2 SIDE) uint8 grey frame: lens 0 on the left; ``scene`` "room" or a photograph's path."""
    panorama = None if scene == "room" else np.asarray(cv2.imread(scene, cv2.IMREAD_COLOR), dtype=np.uint8)
    frame = np.zeros((SIDE, 2 * SIDE))
    sub = (np.arange(supersample) + 0.5) / supersample - 0.5
    v, u = np.mgrid[0:SIDE, 0:SIDE].astype(np.float64)
    for n, (lens, axes) in enumerate(zip(lenses, to_world, strict=True)):
        acc = np.zeros((SIDE, SIDE))
        for dv in sub:
            for du in sub:
                rays = lens.rays(u + du, v + dv).reshape(-1, 3)
                seen = np.isfinite(rays).all(axis=1)
                world = rays[seen] @ axes.T
                grey = np.zeros(len(rays))
                grey[seen] = room_grey(world) if panorama is None else sample_photograph(panorama, world)
                acc += grey.reshape(SIDE, SIDE)
        frame[:, n * SIDE : (n + 1) * SIDE] = acc / supersample**2
    return np.asarray(np.clip(np.rint(frame), 0, 255), dtype=np.uint8)


@dataclass(frozen=True)
class Case:
    name: str
    scene: str
    poses_deg: tuple[tuple[float, float], ...]  # one frame at each (yaw, pitch) of lens 0's axis in the world
    stretch: float


def case_truth(case: Case, pose_deg: tuple[float, float]) -> tuple[tuple[Lens, Lens], tuple[FloatArray, FloatArray]]:
    """The two lenses and their axes (columns right, down, ahead in world axes) in the frame at ``pose_deg``."""
    lenses = (Lens(stretch=case.stretch), Lens(cx=481.2, cy=478.1, stretch=case.stretch))
    axes0 = lens_axes(*pose_deg)
    axes1 = axes0 @ np.diag([-1.0, 1.0, -1.0]) @ small_turn(0.8, -0.5, 0.3)  # back to back, then a small turn
    return lenses, (axes0, axes1)


def ray_errors_px(learned_rig: object, lenses: tuple[Lens, Lens], to_world: tuple[FloatArray, FloatArray]) -> dict:
    """Each lens's learned table against the truth: pixels on rings about the true centre at 15-85 deg and 85-95
    deg, each pixel's true world ray (in the learned world: the best rotation between the truth's and the rig's
    world, from lens 0) through the learned table, back to pixels; p90 and max of the distance (px) over 15-85 deg
    (where the band is stated), and the largest over 85-92.5 deg (the overlap; inf where the table stops short)."""
    from panomap.geometry import azimuth_elevation

    rig = learned_rig  # CameraRig
    out: dict[str, float] = {}
    # The learned world and the truth's differ by one rotation: lens 0's (camera 0 places the world).
    pixels, rings = [], []
    for alpha_deg in np.arange(15.0, 92.51, 2.5):
        phi = np.linspace(0, 2 * math.pi, 72, endpoint=False)
        pixels.append(np.stack([np.cos(phi), np.sin(phi)], axis=1) * F_PX * math.radians(alpha_deg))
        rings.append(np.full(72, alpha_deg))
    offsets = np.concatenate(pixels)
    alpha = np.concatenate(rings)
    world_truth = []
    for lens, axes in zip(lenses, to_world, strict=True):
        px = offsets + np.array([lens.cx, lens.cy])
        world_truth.append(lens.rays(px[:, 0], px[:, 1]) @ axes.T)
    # Align: lens 0's rays in the learned world versus the truth's world.
    table0 = rig.tables[0]  # type: ignore[attr-defined]
    px0 = offsets + np.array([lenses[0].cx, lenses[0].cy])
    learned0 = _table_rays(table0, px0)
    ok = np.isfinite(learned0).all(axis=1) & (alpha <= 85)
    u, _, vt = np.linalg.svd(learned0[ok].T @ world_truth[0][ok])
    align = u @ np.diag([1, 1, np.sign(np.linalg.det(u @ vt))]) @ vt  # truth world -> learned world
    for k, lens in enumerate(lenses):
        table = rig.tables[k]  # type: ignore[attr-defined]
        px = offsets + np.array([lens.cx, lens.cy])
        rays = world_truth[k] @ align.T
        back = table.sample(*azimuth_elevation(rays)).astype(np.float64)
        d = np.hypot(*(back - px).T)
        d = np.where(np.isfinite(d), d, np.inf)
        inner, rim = alpha <= 85, alpha > 85
        out[f"lens {k} p90"] = float(np.percentile(d[inner], 90))
        out[f"lens {k} max"] = float(np.max(d[inner]))
        out[f"lens {k} rim max"] = float(np.max(d[rim]))
    return out


def _table_rays(table: object, pixels: FloatArray) -> FloatArray:
    """World rays (n, 3) of pixels (n, 2) through a table (NaN where it sees none)."""
    from panomap.geometry import ray_from_angles

    theta, rho = table.unproject(pixels)  # type: ignore[attr-defined]
    return np.asarray(ray_from_angles(theta, rho), dtype=np.float64)


LEVEL = ((0.0, 0.0),)
OBLIQUE = ((40.0, 25.0),)
THREE = ((20.0, 25.0), (65.0, -20.0), (110.0, 35.0))
SIX = (*THREE, (155.0, 10.0), (200.0, -30.0), (250.0, 20.0))
CASES = (
    Case("room, level, axes along its walls", "room", LEVEL, 1.0),
    Case("room, level, axes along its walls, both lenses stretched 6%", "room", LEVEL, 1.06),
    Case("room, level, axes 30 deg off its walls", "room", ((30.0, 0.0),), 1.0),
    Case("room, axes 40 deg off its walls, pitched 25 deg", "room", OBLIQUE, 1.0),
    Case("room, axes 40 deg off its walls, pitched 25 deg, both lenses stretched 6%", "room", OBLIQUE, 1.06),
    Case("room, three frames turned and pitched", "room", THREE, 1.0),
    Case("room, three frames turned and pitched, both lenses stretched 6%", "room", THREE, 1.06),
    Case("room, six frames turned and pitched", "room", SIX, 1.0),
    Case("room, six frames turned and pitched, both lenses stretched 6%", "room", SIX, 1.06),
    Case("photograph (ESO ALMA correlator room), level", str(PHOTOGRAPH), LEVEL, 1.0),
    Case("photograph (ESO ALMA correlator room), level, both lenses stretched 6%", str(PHOTOGRAPH), LEVEL, 1.06),
    Case("photograph (ESO ALMA correlator room), three frames turned and pitched", str(PHOTOGRAPH), THREE, 1.0),
)


def main() -> None:
    from panomap.calibrate.dual_fisheye import learn_dual_fisheye

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="the first two cases only")
    parser.add_argument("--case", type=int, action="append", help="only these cases (0-based)")
    parser.add_argument("--save", type=Path, help="write each case's frame here (case<k>.png)")
    args = parser.parse_args()
    picked = args.case if args.case else (range(2) if args.quick else range(len(CASES)))
    for k in picked:
        case = CASES[k]
        if case.scene != "room" and not Path(case.scene).exists():
            print(f"{case.name}: skipped ({case.scene} absent)")
            continue
        start = time.perf_counter()
        frames = [render_frame(*case_truth(case, pose), case.scene) for pose in case.poses_deg]
        lenses, to_world = case_truth(case, case.poses_deg[0])
        rendered = time.perf_counter() - start
        if args.save is not None:
            for n, frame in enumerate(frames):
                cv2.imwrite(str(args.save / f"case{k}_{n}.png"), frame)
        try:
            learned = learn_dual_fisheye(frames)
        except PanomapError as exc:
            print(f"{case.name}: refused ({time.perf_counter() - start - rendered:.0f} s): {exc.summary}")
            for line in exc.figures.splitlines():
                print(f"    {line}")
            continue
        errors = ray_errors_px(learned.rig, lenses, to_world)
        print(f"{case.name}: accepted ({time.perf_counter() - start - rendered:.0f} s)")
        for line in learned.describe():
            print(f"    {line}")
        print("    truth: " + ", ".join(f"{key} {value:.2f} px" for key, value in errors.items()))


if __name__ == "__main__":
    main()
