"""A rig's video (issue 52): ``panomap video RIG ...`` against ffmpeg, on synthetic clips, in one run.

Run: ``.venv/bin/python bench/bench_rig.py [--frames N] [--surround-frames M] [--repeats R] [--keep DIR]
[--dual-only] [--compile-each-run] [--before SRC]`` (``--keep``: the clips are kept there, and taken from there by
a later run given the same folder and lengths, so that runs compare on one clip; ``--dual-only``: (a) and the
start-up alone; ``--before``: (a) and its start-up also run from the package folder ``SRC``, another checkout's
``src``, interleaved with the rest: a change against the code before it, in one run)

Two figures, each end to end (start-up, maps, decoding, blending, encoding with libx264 preset veryfast, crf 20,
yuv420p):

(a) **Dual fisheye to equirect.** A 3840 x 1920 H.264 clip of two ideal equidistant lenses back to back (each
    1920 x 1920, 202.1 deg across its half's width, seeing 95 deg off its axis: 10 deg of overlap), camera 0 on
    the left, rendered in closed form from a textured world turning 1 deg a frame, with sensor noise (a real
    camera's bit rate). The rig is its Kalibr camchain (``pinhole`` + ``equidistant``, zero coefficients, the
    back lens ``T_cn_cnm1`` = a half turn about the vertical, 2 cm behind), imported ``--side-by-side
    --fov 190``. Against ffmpeg ``v360=input=dfisheye:output=e`` with ``ih_fov``/``iv_fov`` the lenses' field,
    3840 x 1920, bilinear: the ratio is ffmpeg's time over panomap's (above 1: faster than ffmpeg). ffmpeg
    does not blend: it cuts at 90 deg; panomap feathers the 10 deg band and matches the lenses' gains.
(b) **Surround view to a floor map.** Four 1280 x 960 clips (a car's four lenses, chained by quarter turns and
    1 m offsets, camera 0 pitched 40 deg down 1.2 m above the floor), a textured floor sliding under them,
    blended into one 1024 x 1024 floor map: frames per second against real time (25), and ffmpeg decoding the
    four streams alone, the floor of what any program can do.

**Start-up.** (a) again on the clip's first frame alone (panomap ``--duration`` of one frame, ffmpeg
``-frames:v 1``): imports, reading the rig, the maps, the feathered weights and the blend's buffers, against
v360's set-up.

**Bytecode.** panomap runs from compiled bytecode, as an installed package does (pip compiles it on install): the
bench lets Python cache it in a folder of its own (``PYTHONPYCACHEPREFIX``, compiled once before the timed runs)
even where the environment says ``PYTHONDONTWRITEBYTECODE`` (this machine's does; each run then compiled the ~100
modules it imports again: 0.1-0.15 s of its start-up, measured with ``python -X importtime``). ``--compile-each-run``
keeps the environment's setting.

The run prints how far the two equirect pictures' first frames differ where both have a source (v360's turned half
a turn to panomap's azimuth origin; grey levels;
ffmpeg's dfisheye and panomap's rig are the same lenses, so the difference is the seam's and the codecs'). Each
run is repeated ``repeats`` times, interleaved; the fastest counts (the machine is shared).
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import av
import cv2
import imageio_ffmpeg
import numpy as np

from bench_video import Timing, first_frame, timed_command
from panomap.interop.rig_of_camchain import rig_of_camchain
from panomap.rig import load_rig, save_rig

X264 = ["-c:v", "libx264", "-preset", "veryfast", "-crf", "20", "-pix_fmt", "yuv420p"]
LENS = 1920
LENS_FOV_DEG = 2 * 95 / 0.94  # across the half's width (v360's ih_fov)
F_PX = (LENS / 2) / math.radians(LENS_FOV_DEG / 2)
HALF_FIELD = math.radians(95.0)
BACK_TO_BACK = [[-1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1, -0.02], [0, 0, 0, 1]]
EQUIRECT = (3840, 1920)
V360 = (
    f"v360=input=dfisheye:output=e:ih_fov={LENS_FOV_DEG:.3f}:iv_fov={LENS_FOV_DEG:.3f}:"
    f"w={EQUIRECT[0]}:h={EQUIRECT[1]}:interp=linear"
)
SURROUND = (1280, 960)
SURROUND_F_PX = 300.0
QUARTER = [[0, 0, -1, 1.0], [0, 1, 0, 0], [1, 0, 0, 1.0], [0, 0, 0, 1]]
FLOOR = (1024, 1024)
RATE = 25


def camchain(path: Path, size: tuple[int, int], f_px: float, poses: list[list[list[float]]]) -> Path:
    """A Kalibr camchain of ideal equidistant lenses of ``size``, camera n after the first at ``poses[n - 1]``."""
    lines = []
    for k in range(len(poses) + 1):
        lines += [f"cam{k}:", "  camera_model: pinhole",
                  f"  intrinsics: [{f_px}, {f_px}, {(size[0] - 1) / 2}, {(size[1] - 1) / 2}]",
                  "  distortion_model: equidistant", "  distortion_coeffs: [0.0, 0.0, 0.0, 0.0]",
                  f"  resolution: [{size[0]}, {size[1]}]"]  # fmt: skip
        if k:
            lines += ["  T_cn_cnm1:", *(f"  - {row}" for row in poses[k - 1])]
    path.write_text("\n".join(lines) + "\n")
    return path


def axes_of(yaw_deg: float, pitch_deg: float) -> np.ndarray:
    """Camera 0's axes (columns right, down, forward; world X ahead, Z up), from the conventions."""
    psi, tau = math.radians(yaw_deg), math.radians(pitch_deg)
    forward = np.array([math.cos(tau) * math.cos(psi), math.cos(tau) * math.sin(psi), math.sin(tau)])
    right = np.array([math.sin(psi), -math.cos(psi), 0.0])
    return np.stack([right, np.cross(forward, right), forward], axis=1)


def chain(
    axes0: np.ndarray, centre0: np.ndarray, poses: list[list[list[float]]]
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each camera's (axes, centre): ``G_n = G_(n-1) R^T``, ``c_n = c_(n-1) - G_(n-1) R^T t``."""
    out = [(axes0, centre0)]
    for pose in poses:
        matrix = np.asarray(pose, dtype=float)
        axes, centre = out[-1]
        out.append((axes @ matrix[:3, :3].T, centre - axes @ matrix[:3, :3].T @ matrix[:3, 3]))
    return out


def lens_rays(size: tuple[int, int], f_px: float, axes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World rays (H, W, 3) of an ideal equidistant lens's pixels, and where it sees (within 95 deg)."""
    u, v = np.meshgrid(np.arange(size[0], dtype=float), np.arange(size[1], dtype=float))
    x, y = u - (size[0] - 1) / 2, v - (size[1] - 1) / 2
    r = np.maximum(np.hypot(x, y), 1e-9)
    alpha = r / f_px
    rays = np.stack([np.sin(alpha) * x / r, np.sin(alpha) * y / r, np.cos(alpha)], axis=-1) @ axes.T
    return rays, alpha <= HALF_FIELD


def textured(shape: tuple[int, int], seed: int) -> np.ndarray:
    """A colour texture of smooth blobs and sharp rectangles."""
    rng = np.random.default_rng(seed)
    height, width = shape
    base = cv2.resize(rng.uniform(0, 255, (height // 128, width // 128, 3)).astype(np.float32), (width, height),
                      interpolation=cv2.INTER_CUBIC)  # fmt: skip
    base = (base - base.mean()) * 2 + 128
    for _ in range(400):
        x, y = int(rng.integers(0, width - 200)), int(rng.integers(0, height - 200))
        base[y : y + int(rng.integers(8, 160)), x : x + int(rng.integers(8, 160))] += rng.uniform(-70, 70, 3)
    return np.clip(base, 0, 255).astype(np.uint8)


def write_clip(path: Path, size: tuple[int, int], frames: int, frame_at: Callable[[int], np.ndarray]) -> float:
    """An H.264 clip (crf 18) of ``frame_at(i)`` with sensor noise; its bit rate (Mbit/s)."""
    rng = np.random.default_rng(7)
    noise = rng.normal(0, 3, size=(3, size[1], size[0], 3)).astype(np.int16)
    with av.open(str(path), "w") as container:
        stream = container.add_stream("libx264", rate=RATE)
        stream.width, stream.height = size
        stream.pix_fmt = "yuv420p"
        stream.options = {"preset": "ultrafast", "crf": "18"}
        for index in range(frames):
            frame = np.clip(frame_at(index).astype(np.int16) + noise[index % 3], 0, 255).astype(np.uint8)
            for packet in stream.encode(av.VideoFrame.from_ndarray(frame, format="bgr24")):
                container.mux(packet)
        for packet in stream.encode(None):
            container.mux(packet)
    return path.stat().st_size * 8 / 1e6 / (frames / RATE)


def dual_clip(folder: Path, frames: int) -> tuple[Path, Path, float]:
    """(a)'s clip and rig; the clip's bit rate."""
    world = textured((2048, 4096), 0)
    pictures = []
    for axes, _ in chain(axes_of(0, 0), np.zeros(3), [BACK_TO_BACK]):
        rays, seen = lens_rays((LENS, LENS), F_PX, axes)
        azimuth = np.arctan2(rays[..., 1], rays[..., 0])
        elevation = np.arcsin(np.clip(rays[..., 2], -1, 1))
        map_x = ((math.pi - azimuth) / (2 * math.pi) * world.shape[1] - 0.5).astype(np.float32)
        map_y = ((math.pi / 2 - elevation) / math.pi * world.shape[0] - 0.5).astype(np.float32)
        pictures.append((map_x, map_y, seen))

    def frame_at(index: int) -> np.ndarray:
        turned = np.roll(world, -index * world.shape[1] // 360, axis=1)  # 1 deg a frame
        halves = []
        for map_x, map_y, seen in pictures:
            half = cv2.remap(turned, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
            half[~seen] = 0
            halves.append(half)
        return np.concatenate(halves, axis=1)

    clip = folder / "dual.mp4"
    megabits = write_clip(clip, (2 * LENS, LENS), frames, frame_at)
    rig = rig_of_camchain(camchain(folder / "dual.yaml", (LENS, LENS), F_PX, [BACK_TO_BACK]), side_by_side=True,
                          fov_rad=math.radians(190))  # fmt: skip
    save_rig(rig, folder / "dual.npz")
    return clip, folder / "dual.npz", megabits


def surround_clips(folder: Path, frames: int) -> tuple[list[Path], Path, str, float]:
    """(b)'s four clips, rig and floor SPEC; the clips' bit rate (each)."""
    floor = textured((2048, 2048), 1)  # 16 x 16 m at 128 px/m, centred on the rig
    cameras = chain(axes_of(0, -40), np.array([1.0, 0.0, 1.2]), [QUARTER] * 3)
    middle = np.mean([centre for _, centre in cameras], axis=0)
    lenses = []
    for axes, centre in cameras:
        rays, seen = lens_rays(SURROUND, SURROUND_F_PX, axes)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(rays[..., 2] < -1e-6, -centre[2] / rays[..., 2], np.nan)
        x, y = centre[0] + t * rays[..., 0], centre[1] + t * rays[..., 1]
        map_x = ((x - middle[0] + 8) * 128 - 0.5).astype(np.float32)
        map_y = ((8 - (y - middle[1])) * 128 - 0.5).astype(np.float32)
        sky = ~np.isfinite(map_x) | ~seen
        lenses.append((np.nan_to_num(map_x, nan=-10), np.nan_to_num(map_y, nan=-10), sky, seen))
    clips = [folder / f"cam{k}.mp4" for k in range(4)]
    megabits = 0.0
    for k, (map_x, map_y, sky, seen) in enumerate(lenses):

        def frame_at(index: int, map_x: np.ndarray = map_x, map_y: np.ndarray = map_y, sky: np.ndarray = sky,
                     seen: np.ndarray = seen) -> np.ndarray:  # fmt: skip
            picture = cv2.remap(floor, map_x + 4 * index, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
            picture[sky] = (200, 170, 150)
            picture[~seen] = 0
            return picture

        megabits = write_clip(clips[k], SURROUND, frames, frame_at)
    rig = rig_of_camchain(camchain(folder / "car.yaml", SURROUND, SURROUND_F_PX, [QUARTER] * 3),
                          orientation_rad=(0.0, math.radians(-40), 0.0), camera_position=(1.0, 0.0, 1.2))  # fmt: skip
    save_rig(rig, folder / "car.npz")
    x0, y0 = middle[0], middle[1]
    spec = f"floor:z=0,x={x0 - 5:.3f}:{x0 + 5:.3f},y={y0 - 5:.3f}:{y0 + 5:.3f},size={FLOOR[0]}x{FLOOR[1]}"
    return clips, folder / "car.npz", spec, megabits


def _kept(clip: Path, frames: int) -> bool:
    """Whether ``clip`` is a clip of ``frames`` frames left by an earlier run (``--keep``)."""
    if not clip.is_file():
        return False
    try:
        with av.open(str(clip)) as container:
            return container.streams.video[0].frames == frames
    except av.error.FFmpegError:
        return False


def _floor_spec(rig_path: Path) -> str:
    """(b)'s floor view of the kept rig: 10 x 10 m about its cameras' middle (as :func:`surround_clips` says)."""
    rig = load_rig(rig_path)
    middle = np.mean([table.camera_position for table in rig.tables], axis=0)
    x0, y0 = middle[0], middle[1]
    return f"floor:z=0,x={x0 - 5:.3f}:{x0 + 5:.3f},y={y0 - 5:.3f}:{y0 + 5:.3f},size={FLOOR[0]}x{FLOOR[1]}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=100, help="(a)'s clip length in frames [100: 4 s]")
    parser.add_argument("--surround-frames", type=int, default=250, help="(b)'s clips' length [250: 10 s]")
    parser.add_argument("--repeats", type=int, default=3, help="runs of each, the fastest counts [3]")
    parser.add_argument("--keep", type=Path, help="keep the clips and outputs in this folder (and reuse them)")
    parser.add_argument("--dual-only", action="store_true", help="(a) and its start-up alone, not (b)")
    parser.add_argument("--compile-each-run", action="store_true",
                        help="keep the environment's PYTHONDONTWRITEBYTECODE (see Bytecode)")  # fmt: skip
    parser.add_argument("--before", type=Path, help="also run (a) from this package folder (another checkout's src)")
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="panomap-bench-rig-")) if args.keep is None else args.keep
    folder.mkdir(parents=True, exist_ok=True)
    if not args.compile_each_run:  # (the panomap runs inherit it; ffmpeg ignores it)
        os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
        os.environ["PYTHONPYCACHEPREFIX"] = str(folder / "pycache")
        for source in [None] if args.before is None else [None, args.before]:
            extra = {} if source is None else {"PYTHONPATH": str(source.resolve())}
            subprocess.run([sys.executable, "-c", "import panomap.cli.app, panomap.video.rig"], check=True,
                           env={**os.environ, **extra})  # fmt: skip
    quiet = [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-loglevel", "error", "-y"]
    panomap = [sys.executable, "-m", "panomap", "video"]
    try:
        clip, dual_rig = folder / "dual.mp4", folder / "dual.npz"
        if _kept(clip, args.frames) and dual_rig.is_file():
            print(f"the {2 * LENS} x {LENS} dual-fisheye clip of {args.frames} frames: {clip} (kept)")
        else:
            print(f"making a {2 * LENS} x {LENS} dual-fisheye clip of {args.frames} frames ...", flush=True)
            clip, dual_rig, megabits = dual_clip(folder, args.frames)
            print(f"  {clip} ({megabits:.1f} Mbit/s)")
        baseline = "(a) ffmpeg v360=dfisheye:e"
        ours = "(a) panomap video RIG, equirect"
        first_baseline = "(a) start-up: ffmpeg v360, first frame"
        first_ours = "(a) start-up: panomap video RIG, first frame"
        floor_run = "(b) panomap video RIG, 4 cameras to a floor map"
        decode4 = "(b) decoding the four streams alone, ffmpeg"
        equirect = ["--view", f"equirect:size={EQUIRECT[0]}x{EQUIRECT[1]}"]
        one = str(0.5 / RATE)  # (one frame: --duration takes the frames that start before it)
        runs: dict[str, Callable[[], Timing]] = {
            baseline: timed_command([*quiet, "-i", str(clip), "-vf", V360, *X264, str(folder / "ffmpeg_e.mp4")]),
            ours: timed_command([*panomap, str(dual_rig), str(clip), "-q", "-o", str(folder / "pm_e.mp4"), *equirect]),
            first_baseline: timed_command(
                [*quiet, "-i", str(clip), "-vf", V360, "-frames:v", "1", *X264, str(folder / "ffmpeg_1.mp4")]
            ),
            first_ours: timed_command(
                [*panomap, str(dual_rig), str(clip), "-q", "-o", str(folder / "pm_1.mp4"), *equirect, "--duration", one]
            ),
        }
        before, first_before = "(a) panomap video RIG, equirect, the code before", "(a) start-up: the code before"
        if args.before is not None:
            earlier = ["env", f"PYTHONPATH={args.before.resolve()}", *panomap]
            runs[before] = timed_command(
                [*earlier, str(dual_rig), str(clip), "-q", "-o", str(folder / "pm_before.mp4"), *equirect]
            )
            one_frame = ["-q", "-o", str(folder / "pm_1b.mp4"), *equirect, "--duration", one]
            runs[first_before] = timed_command([*earlier, str(dual_rig), str(clip), *one_frame])
        if not args.dual_only:
            clips = [folder / f"cam{k}.mp4" for k in range(4)]
            car_rig = folder / "car.npz"
            if all(_kept(c, args.surround_frames) for c in clips) and car_rig.is_file():
                spec = _floor_spec(car_rig)
                print(f"the four {SURROUND[0]} x {SURROUND[1]} clips: {folder}/cam0-3.mp4 (kept); floor view {spec}")
            else:
                print(f"making four {SURROUND[0]} x {SURROUND[1]} clips of {args.surround_frames} frames ...",
                      flush=True)  # fmt: skip
                clips, car_rig, spec, car_megabits = surround_clips(folder, args.surround_frames)
                print(f"  {folder}/cam0-3.mp4 ({car_megabits:.1f} Mbit/s each); floor view {spec}")
            decode_args = [a for c in clips for a in ("-i", str(c))]
            maps = [a for k in range(4) for a in ("-map", f"{k}:v")]
            runs[floor_run] = timed_command(
                [*panomap, str(car_rig), *map(str, clips), "-q", "-o", str(folder / "pm_floor.mp4"), "--view", spec]
            )
            runs[decode4] = timed_command([*quiet, *decode_args, *maps, "-f", "null", "-"])
        best = {name: (math.inf, math.inf) for name in runs}
        for _ in range(args.repeats):
            for name, run in runs.items():
                best[name] = min(best[name], run())
        a = first_frame(folder / "pm_e.mp4").astype(np.int16)
        # (v360's equirect is panomap's turned half a turn: camera 0's axis at its edges; measured 111 grey levels
        # apart as they come, 2.8 turned)
        b = np.roll(first_frame(folder / "ffmpeg_e.mp4").astype(np.int16), EQUIRECT[0] // 2, axis=1)
        both = (a.max(axis=2) > 8) & (b.max(axis=2) > 8)
        difference = np.abs(a - b)[both]
        print(
            f"\nsame equirect: where both have a source the first frames differ by {difference.mean():.2f} grey "
            f"levels on average ({np.percentile(difference, 99):.0f} at the 99th percentile); "
            f"{100 * np.mean(a.max(axis=2) > 8):.1f}% / {100 * np.mean(b.max(axis=2) > 8):.1f}% of pixels lit "
            "(panomap / ffmpeg)"
        )
        print(f"\nfastest of {args.repeats} runs, end to end (start-up included):\n")
        print("| run | frames | time | fps | CPU | figure |")
        print("| --- | --- | --- | --- | --- | --- |")
        for name, (seconds, cpu) in best.items():
            frames = 1 if "start-up" in name else args.frames if name.startswith("(a)") else args.surround_frames
            fps = frames / seconds
            if name.startswith("(a)"):
                reference = best[first_baseline if "start-up" in name else baseline][0]
                figure = f"{reference / seconds:.2f} x ffmpeg"
            else:
                figure = f"{fps / RATE:.2f} x real time"
            print(f"| {name} | {frames} | {seconds:.2f} s | {fps:.1f} | {cpu:.2f} s | {figure} |")
        print(
            f"\n(a) speed vs ffmpeg v360 dfisheye: {best[baseline][0] / best[ours][0]:.2f} (target >= 1.0); "
            f"start-up (one frame) {best[first_ours][0]:.2f} s, ffmpeg's {best[first_baseline][0]:.2f} s"
        )
        if args.before is not None:
            print(
                f"    the code before ({args.before}): {best[baseline][0] / best[before][0]:.2f}; start-up "
                f"{best[first_before][0]:.2f} s"
            )
        if not args.dual_only:
            floor_fps = args.surround_frames / best[floor_run][0]
            print(
                f"(b) floor map: {floor_fps:.1f} fps (target >= {RATE}: {floor_fps / RATE:.2f} x real time); "
                f"decoding alone {args.surround_frames / best[decode4][0]:.1f} fps"
            )
    finally:
        if args.keep is None:
            shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
