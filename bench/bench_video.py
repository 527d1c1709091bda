"""``panomap video`` against ffmpeg's own ``v360`` filter, on the same clip, in one run.

Run: ``.venv/bin/python bench/bench_video.py [--frames N] [--repeats R] [--keep DIR]``

Makes a 1920 x 1920 H.264 clip of the bundled room seen through a simulated
equidistant fisheye (190 deg, turning slowly, with sensor noise so that it has
a real camera's bit rate), learns that camera from exact landmarks, then times,
end to end (start-up, map building, decoding, remapping, encoding):

- ffmpeg's ``v360`` filter (fisheye in, equirectangular 2048 x 512 out,
  bilinear) with libx264 (preset veryfast, crf 20, yuv420p): the baseline;
- ``panomap video`` making a 2048 x 512 panorama, same encoder settings, with its
  default float maps and with fixed-point maps;
- ``panomap video`` making that panorama and a 1280 x 720 perspective view at once;
- decoding alone, with ffmpeg and with PyAV (threaded), so that the cost of
  unwarping over decoding shows.

Each is run ``repeats`` times, interleaved, and the fastest run counts (the
machine is shared: the fastest is the least disturbed). Ratios are speeds
relative to ffmpeg's in the same run: above 1 is faster than ffmpeg.
"""

from __future__ import annotations

import argparse
import math
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import av
import cv2
import imageio_ffmpeg
import numpy as np

from panomap.fit import fit_camera
from panomap.simulate import load_room, render, standard_cameras
from panomap.simulate.sampling import spread_landmarks
from panomap.table import create_table

SIZE = (1920, 1920)
RATE = 25
X264 = ["-c:v", "libx264", "-preset", "veryfast", "-crf", "20", "-pix_fmt", "yuv420p"]
PANORAMA = "panorama:size=2048x512"
PERSPECTIVE = "perspective:yaw=30,pitch=-20,fov=90,size=1280x720"


def make_clip(folder: Path, frames: int) -> tuple[Path, Path, float]:
    """The clip and its camera's table; returns (clip, table, bit rate in Mbit/s)."""
    room = load_room()
    camera = standard_cameras(SIZE)["equidistant"]
    omni = render(room, camera, supersample=1)
    position = tuple(room.camera)
    landmarks = spread_landmarks(camera, position, 20, np.random.default_rng(0))
    fit = fit_camera(landmarks, position, camera.centre, image_size=SIZE)
    table = create_table(fit, image_size=SIZE, cutoff_radius=camera.cutoff_radius, outer_radius=camera.outer_radius)
    table_path = folder / "fisheye.npz"
    table.save(table_path)

    clip = folder / "clip.mp4"
    rng = np.random.default_rng(1)
    with av.open(str(clip), "w") as container:
        stream = container.add_stream("libx264", rate=RATE)
        stream.width, stream.height = SIZE
        stream.pix_fmt = "yuv420p"
        stream.options = {"preset": "veryfast", "crf": "18"}
        noise = rng.normal(0, 4, size=(4, SIZE[1], SIZE[0], 3)).astype(np.int16)
        for index in range(frames):
            turn = cv2.getRotationMatrix2D(camera.centre, 0.4 * index, 1.0)
            frame = cv2.warpAffine(omni, turn, SIZE, flags=cv2.INTER_LINEAR)
            frame = np.clip(frame.astype(np.int16) + noise[index % 4], 0, 255).astype(np.uint8)
            for packet in stream.encode(av.VideoFrame.from_ndarray(frame, format="bgr24")):
                container.mux(packet)
        for packet in stream.encode(None):
            container.mux(packet)
    megabits = clip.stat().st_size * 8 / 1e6 / (frames / RATE)
    return clip, table_path, megabits


def wall_time(command: list[str]) -> float:
    start = time.perf_counter()
    result = subprocess.run(command, capture_output=True, text=True, check=False)
    elapsed = time.perf_counter() - start
    if result.returncode != 0:
        raise SystemExit(f"failed: {' '.join(command)}\n{result.stderr}")
    return elapsed


def pyav_decode(clip: Path) -> Callable[[], float]:
    def run() -> float:
        start = time.perf_counter()
        with av.open(str(clip)) as container:
            stream = container.streams.video[0]
            stream.thread_type = "AUTO"
            for _ in container.decode(stream):
                pass
        return time.perf_counter() - start

    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=150, help="clip length in frames [150]")
    parser.add_argument("--repeats", type=int, default=3, help="runs of each, the fastest counts [3]")
    parser.add_argument("--keep", type=Path, help="keep the clip and outputs in this folder")
    args = parser.parse_args()

    folder = Path(tempfile.mkdtemp(prefix="panomap-bench-video-")) if args.keep is None else args.keep
    folder.mkdir(parents=True, exist_ok=True)
    ffmpeg = imageio_ffmpeg.get_ffmpeg_exe()
    panomap = [sys.executable, "-m", "panomap", "video"]
    try:
        print(f"making a {SIZE[0]} x {SIZE[1]} H.264 clip of {args.frames} frames ...", flush=True)
        clip, table, megabits = make_clip(folder, args.frames)
        print(f"clip: {clip} ({megabits:.1f} Mbit/s at {RATE} fps)")
        # v360's fisheye input spans the frame's width; the image circle (95 deg off-axis) is 0.94 of it.
        fov = 2 * 95 / 0.94
        v360 = (
            f"v360=input=fisheye:output=equirect:ih_fov={fov:.2f}:iv_fov={fov:.2f}:h_fov=360:v_fov=90:"
            f"pitch=-45:w=2048:h=512:interp=linear"
        )
        runs: dict[str, Callable[[], float]] = {
            "ffmpeg v360, panorama 2048 x 512": lambda: wall_time(
                [
                    ffmpeg,
                    "-hide_banner",
                    "-loglevel",
                    "error",
                    "-y",
                    "-i",
                    str(clip),
                    "-vf",
                    v360,
                    *X264,
                    str(folder / "ffmpeg_pano.mp4"),
                ]
            ),
            "panomap video, panorama 2048 x 512": lambda: wall_time(
                [*panomap, str(table), str(clip), "-q", "-o", str(folder / "pm_{name}.mp4"), "--view", PANORAMA]
            ),
            "panomap video, panorama 2048 x 512, fixed-point maps": lambda: wall_time(
                [
                    *panomap,
                    str(table),
                    str(clip),
                    "-q",
                    "-o",
                    str(folder / "pmf_{name}.mp4"),
                    "--view",
                    PANORAMA,
                    "--fixed-point",
                ]
            ),
            "panomap video, panorama + perspective 1280 x 720": lambda: wall_time(
                [
                    *panomap,
                    str(table),
                    str(clip),
                    "-q",
                    "-o",
                    str(folder / "pm2_{name}.mp4"),
                    "--view",
                    PANORAMA,
                    "--view",
                    PERSPECTIVE,
                ]
            ),
            "decode only, ffmpeg": lambda: wall_time(
                [ffmpeg, "-hide_banner", "-loglevel", "error", "-i", str(clip), "-f", "null", "-"]
            ),
            "decode only, PyAV (threaded)": pyav_decode(clip),
        }
        best = {name: math.inf for name in runs}
        for _ in range(args.repeats):
            for name, run in runs.items():
                best[name] = min(best[name], run())
        baseline = best["ffmpeg v360, panorama 2048 x 512"]
        print(f"\n{args.frames} frames, fastest of {args.repeats} runs, end to end (start-up included):\n")
        print("| run | time | fps | speed vs ffmpeg v360 |")
        print("| --- | --- | --- | --- |")
        for name, seconds in best.items():
            print(f"| {name} | {seconds:.2f} s | {args.frames / seconds:.1f} | {baseline / seconds:.2f} |")
    finally:
        if args.keep is None:
            shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
