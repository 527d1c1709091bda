"""``panomap video`` against ffmpeg's own ``v360`` filter, on the same clip, in one run.

Run: ``.venv/bin/python bench/bench_video.py [--frames N] [--repeats R] [--keep DIR]``

Makes a 1920 x 1920 H.264 clip of the bundled room seen through a simulated
equidistant fisheye (190 deg, looking down, turning slowly, with sensor noise
so that it has a real camera's bit rate), learns that camera from exact
landmarks below the horizon, with a table from the horizon down to the nadir,
then times, end to end (start-up, map building, decoding, remapping, encoding):

- ffmpeg's ``v360`` filter making the same 2048 x 512 panorama (fisheye in,
  bilinear) with libx264 (preset veryfast, crf 20, yuv420p): the baseline;
- ``panomap video`` making that panorama, same encoder settings, with its
  default float maps and with fixed-point maps;
- ``panomap video`` making a 1280 x 720 perspective view alone, and the
  panorama and that view at once;
- decoding alone, with ffmpeg and with PyAV (threaded), so that the cost of
  unwarping over decoding shows.

The same panorama: ``pitch=90`` turns the fisheye's axis to the panorama's
pole, ``v_fov=180`` with ``v_offset=1`` makes the rows run evenly from the
horizon (top) to the nadir (bottom), the band of panomap's table, and
``h_flip``, ``rorder=pyr``, ``yaw=90`` give panomap's azimuth direction and
start. The run prints how far the two panoramas' first frames differ (a mean
of about 1 grey level: the fitted model against v360's ideal fisheye), so that
both encoders get the same picture to encode.

The clip is 12 s long by default: panomap starts about 0.5 s later than
ffmpeg (Python, NumPy, OpenCV and PyAV load, the table is read and checked,
the maps are built), which weighs on a clip of a few seconds
(``--frames 150``) and not on a recording or a live stream.

Each is run ``repeats`` times, interleaved, and the fastest run counts (the
machine is shared: the fastest is the least disturbed). Ratios are speeds
relative to ffmpeg's in the same run: above 1 is faster than ffmpeg. CPU time
(user + system, all threads) is printed beside each; from it, the floor for
two views: decoding once plus each view's own work (its run alone less
decoding), spread perfectly over the machine's cores.
"""

from __future__ import annotations

import argparse
import math
import os
import resource
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

from panomap.calibrate.landmarks.fit import fit_camera
from panomap.calibrate.landmarks.pairs import Landmarks
from panomap.calibrate.landmarks.table import create_table
from panomap.simulate import load_room, render, standard_cameras
from panomap.simulate.cameras import RadialCamera
from panomap.simulate.sampling import spread_landmarks
from panomap.table.file import save_table

SIZE = (1920, 1920)
RATE = 25
X264 = ["-c:v", "libx264", "-preset", "veryfast", "-crf", "20", "-pix_fmt", "yuv420p"]
PANORAMA = "panorama:size=2048x512"
PERSPECTIVE = "perspective:yaw=30,pitch=-20,fov=90,size=1280x720"


# v360's fisheye input spans the frame's width; the image circle (95 deg off-axis) is 0.94 of it.
FISHEYE_FOV = 2 * 95 / 0.94
V360 = (
    f"v360=input=fisheye:output=equirect:ih_fov={FISHEYE_FOV:.3f}:iv_fov={FISHEYE_FOV:.3f}:"
    "h_fov=360:v_fov=180:pitch=90:v_offset=1:yaw=90:rorder=pyr:h_flip=1:w=2048:h=512:interp=linear"
)


def make_clip(folder: Path, frames: int, rate: int = RATE) -> tuple[Path, Path, float]:
    """The clip (``rate`` frames/s) and its camera's table; returns (clip, table, bit rate in Mbit/s)."""
    room = load_room()
    camera = standard_cameras(SIZE)["equidistant"]
    assert isinstance(camera, RadialCamera)
    omni = render(room, camera, supersample=1)
    x0, y0, z0 = (float(c) for c in room.camera)
    position = (x0, y0, z0)
    horizon = float(camera.radius_of_rho(0.0))
    landmarks = Landmarks(*spread_landmarks(camera, position, 40, np.random.default_rng(0)))
    below = np.hypot(*(landmarks.pixels - np.asarray(camera.centre)).T) < horizon - 1
    landmarks = Landmarks(
        landmarks.pixels[below],
        landmarks.world[below],
        tuple(name for name, keep in zip(landmarks.names, below, strict=True) if keep),
        landmarks.camera,
    )
    fit = fit_camera(landmarks, position, camera.centre, image_size=SIZE)
    table = create_table(fit, image_size=SIZE, cutoff_radius=camera.cutoff_radius, outer_radius=horizon)
    table_path = folder / "fisheye.npz"
    save_table(table, table_path)

    clip = folder / "clip.mp4"
    rng = np.random.default_rng(1)
    with av.open(str(clip), "w") as container:
        stream = container.add_stream("libx264", rate=rate)
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
    megabits = clip.stat().st_size * 8 / 1e6 / (frames / rate)
    return clip, table_path, megabits


Timing = tuple[float, float]  # (wall s, CPU s)


def _cpu(who: int) -> float:
    usage = resource.getrusage(who)
    return usage.ru_utime + usage.ru_stime


def timed_command(command: list[str]) -> Callable[[], Timing]:
    def run() -> Timing:
        cpu = _cpu(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        result = subprocess.run(command, capture_output=True, text=True, check=False)
        elapsed = time.perf_counter() - start
        if result.returncode != 0:
            raise SystemExit(f"failed: {' '.join(command)}\n{result.stderr}")
        return elapsed, _cpu(resource.RUSAGE_CHILDREN) - cpu

    return run


def pyav_decode(clip: Path) -> Callable[[], Timing]:
    def run() -> Timing:
        cpu = _cpu(resource.RUSAGE_SELF)
        start = time.perf_counter()
        with av.open(str(clip)) as container:
            stream = container.streams.video[0]
            stream.thread_type = "AUTO"
            for _ in container.decode(stream):
                pass
        return time.perf_counter() - start, _cpu(resource.RUSAGE_SELF) - cpu

    return run


def first_frame(path: Path) -> np.ndarray:
    with av.open(str(path)) as container:
        frame = next(container.decode(video=0))
        return frame.to_ndarray(format="bgr24")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=300, help="clip length in frames [300: 12 s]")
    parser.add_argument("--repeats", type=int, default=3, help="runs of each, the fastest counts [3]")
    parser.add_argument("--keep", type=Path, help="keep the clip and outputs in this folder")
    args = parser.parse_args()

    folder = Path(tempfile.mkdtemp(prefix="panomap-bench-video-")) if args.keep is None else args.keep
    folder.mkdir(parents=True, exist_ok=True)
    ffmpeg = imageio_ffmpeg.get_ffmpeg_exe()
    quiet = [ffmpeg, "-hide_banner", "-loglevel", "error", "-y"]

    def panomap(prefix: str, *options: str) -> Callable[[], Timing]:
        output = str(folder / f"{prefix}_{{name}}.mp4")
        return timed_command(
            [sys.executable, "-m", "panomap", "video", str(table), str(clip), "-q", "-o", output, *options]
        )

    try:
        print(f"making a {SIZE[0]} x {SIZE[1]} H.264 clip of {args.frames} frames ...", flush=True)
        clip, table, megabits = make_clip(folder, args.frames)
        print(f"clip: {clip} ({megabits:.1f} Mbit/s at {RATE} fps)")
        baseline = "ffmpeg v360, panorama 2048 x 512"
        runs: dict[str, Callable[[], Timing]] = {
            baseline: timed_command([*quiet, "-i", str(clip), "-vf", V360, *X264, str(folder / "ffmpeg_pano.mp4")]),
            "panomap video, panorama 2048 x 512": panomap("pm", "--view", PANORAMA),
            "panomap video, panorama 2048 x 512, fixed-point maps": panomap("pmf", "--view", PANORAMA, "--fixed-point"),
            "panomap video, perspective 1280 x 720 alone": panomap("pmp", "--view", PERSPECTIVE),
            "panomap video, panorama + perspective 1280 x 720": panomap(
                "pm2", "--view", PANORAMA, "--view", PERSPECTIVE
            ),
            "decode only, ffmpeg": timed_command([*quiet, "-i", str(clip), "-f", "null", "-"]),
            "decode only, PyAV (threaded)": pyav_decode(clip),
        }
        best = {name: (math.inf, math.inf) for name in runs}
        for _ in range(args.repeats):
            for name, run in runs.items():
                best[name] = min(best[name], run())
        ours = first_frame(folder / "pm_panorama.mp4").astype(np.int16)
        theirs = first_frame(folder / "ffmpeg_pano.mp4").astype(np.int16)
        difference = np.abs(ours - theirs)
        print(
            f"same panorama: first frames differ by {difference.mean():.2f} grey levels on average, "
            f"{100 * np.mean(difference.max(axis=2) <= 16):.1f}% of pixels by at most 16"
        )
        reference = best[baseline][0]
        print(f"\n{args.frames} frames, fastest of {args.repeats} runs, end to end (start-up included):\n")
        print("| run | time | fps | CPU | speed vs ffmpeg v360 |")
        print("| --- | --- | --- | --- | --- |")
        for name, (seconds, cpu) in best.items():
            print(
                f"| {name} | {seconds:.2f} s | {args.frames / seconds:.1f} | {cpu:.2f} s | {reference / seconds:.2f} |"
            )
        cores = os.cpu_count() or 1
        decode = best["decode only, PyAV (threaded)"][1]
        views = [best["panomap video, panorama 2048 x 512"][1], best["panomap video, perspective 1280 x 720 alone"][1]]
        floor = (decode + sum(cpu - decode for cpu in views)) / cores
        print(
            f"\ntwo views, CPU floor: decoding {decode:.2f} s + each view's own "
            f"{' + '.join(f'{cpu - decode:.2f}' for cpu in views)} s over {cores} cores = {floor:.2f} s "
            f"at best: speed vs ffmpeg v360 at most {reference / floor:.2f}"
        )
    finally:
        if args.keep is None:
            shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
