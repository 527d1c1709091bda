"""``panomap video --view equirect`` against ffmpeg's ``v360=fisheye:e``, on the same clip, in one run.

Run: ``.venv/bin/python bench/bench_equirect.py [--frames N] [--repeats R] [--keep DIR]``

The clip of ``bench_video.py``: 1920 x 1920 H.264 of the bundled room through a simulated equidistant
fisheye (190 deg, with sensor noise so that it has a real camera's bit rate). Its camera, as a calibration
gives it (a Kalibr camchain of the ideal equidistant lens, ``f = 544.25`` px, centre (959.5, 959.5)), is
imported looking ahead (``--orientation 0 0 0``); then, end to end (start-up, maps, decoding, remapping,
encoding with libx264 preset veryfast, crf 20, yuv420p):

- ffmpeg ``v360=input=fisheye:output=equirect`` at 3840 x 1920, bilinear, its field of view set so that its
  ideal fisheye is this lens (202.1 deg across the frame's width): the baseline;
- ``panomap video --view equirect:size=3840x1920``, with float and with fixed-point maps;
- decoding alone (ffmpeg), so that the cost of unwarping and encoding over decoding shows.

The run prints how far the two first frames differ (grey levels), so that both encoders get the same
picture. Each is run ``repeats`` times, interleaved; the fastest counts. Ratios are speeds relative to
ffmpeg's in the same run: above 1 is faster than ffmpeg.
"""

from __future__ import annotations

import argparse
import math
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import imageio_ffmpeg
import numpy as np

from bench_video import SIZE, X264, Timing, first_frame, make_clip, timed_command

F_PX = 854.9052631578946 / (math.pi / 2)
CENTRE = (959.5, 959.5)
OUTPUT = (3840, 1920)
FISHEYE_FOV = 2 * 95 / 0.94
V360 = (
    f"v360=input=fisheye:output=equirect:ih_fov={FISHEYE_FOV:.3f}:iv_fov={FISHEYE_FOV:.3f}:"
    f"w={OUTPUT[0]}:h={OUTPUT[1]}:interp=linear"
)


def import_lens(folder: Path) -> Path:
    """The lens as a Kalibr camchain, imported looking ahead; the table's path."""
    camchain = folder / "camchain.yaml"
    camchain.write_text(
        f"cam0:\n  camera_model: pinhole\n  intrinsics: [{F_PX}, {F_PX}, {CENTRE[0]}, {CENTRE[1]}]\n"
        "  distortion_model: equidistant\n  distortion_coeffs: [0.0, 0.0, 0.0, 0.0]\n"
        f"  resolution: [{SIZE[0]}, {SIZE[1]}]\n"
    )
    table = folder / "ahead.npz"
    subprocess.run(
        [sys.executable, "-m", "panomap", "import", str(camchain), "-o", str(table), "--orientation", "0", "0", "0",
         "--outer-radius", f"{F_PX * math.radians(95):.3f}"],
        check=True, capture_output=True,
    )  # fmt: skip
    return table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=100, help="clip length in frames [100: 4 s]")
    parser.add_argument("--repeats", type=int, default=2, help="runs of each, the fastest counts [2]")
    parser.add_argument("--keep", type=Path, help="keep the clip and outputs in this folder")
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="panomap-bench-equirect-")) if args.keep is None else args.keep
    folder.mkdir(parents=True, exist_ok=True)
    quiet = [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-loglevel", "error", "-y"]
    try:
        print(f"making a {SIZE[0]} x {SIZE[1]} H.264 clip of {args.frames} frames ...", flush=True)
        clip, _, megabits = make_clip(folder, args.frames)
        table = import_lens(folder)
        print(f"clip: {clip} ({megabits:.1f} Mbit/s)")
        spec = f"equirect:size={OUTPUT[0]}x{OUTPUT[1]}"

        def panomap(prefix: str, *options: str) -> Callable[[], Timing]:
            output = str(folder / f"{prefix}_{{name}}.mp4")
            return timed_command(
                [sys.executable, "-m", "panomap", "video", str(table), str(clip), "-q", "-o", output, "--view", spec,
                 *options]
            )  # fmt: skip

        baseline = f"ffmpeg v360=fisheye:e, {OUTPUT[0]} x {OUTPUT[1]}"
        runs: dict[str, Callable[[], Timing]] = {
            baseline: timed_command([*quiet, "-i", str(clip), "-vf", V360, *X264, str(folder / "ffmpeg_e.mp4")]),
            f"panomap video, equirect {OUTPUT[0]} x {OUTPUT[1]}": panomap("pm"),
            f"panomap video, equirect {OUTPUT[0]} x {OUTPUT[1]}, fixed-point maps": panomap("pmf", "--fixed-point"),
            "decode only, ffmpeg": timed_command([*quiet, "-i", str(clip), "-f", "null", "-"]),
        }
        best = {name: (math.inf, math.inf) for name in runs}
        for _ in range(args.repeats):
            for name, run in runs.items():
                best[name] = min(best[name], run())
        ours = first_frame(folder / "pm_equirect.mp4").astype(np.int16)
        theirs = first_frame(folder / "ffmpeg_e.mp4").astype(np.int16)
        both = (ours.max(axis=2) > 8) & (theirs.max(axis=2) > 8)
        difference = np.abs(ours - theirs)[both]
        print(
            f"same panorama: where both have a source, the first frames differ by {difference.mean():.2f} grey "
            f"levels on average; {100 * np.mean(ours.max(axis=2) > 8):.1f}% / "
            f"{100 * np.mean(theirs.max(axis=2) > 8):.1f}% of pixels lit (panomap / ffmpeg)"
        )
        reference = best[baseline][0]
        print(f"\n{args.frames} frames, fastest of {args.repeats} runs, end to end (start-up included):\n")
        print("| run | time | fps | CPU | speed vs ffmpeg v360 |")
        print("| --- | --- | --- | --- | --- |")
        for name, (seconds, cpu) in best.items():
            print(
                f"| {name} | {seconds:.2f} s | {args.frames / seconds:.1f} | {cpu:.2f} s | {reference / seconds:.2f} |"
            )
    finally:
        if args.keep is None:
            shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
