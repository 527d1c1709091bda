"""``panomap batch`` against a plain loop of single ``panomap`` runs over the same inputs, in one run.

Still images: N (default 200) 1920 x 1920 JPEG omni-images of the bundled room through a
simulated 190 deg equidistant fisheye, each turned and noised differently, to two views
(a 2048 x 512 panorama and a 1280 x 720 perspective view). The baseline is what a user
would script today: one ``panomap panorama`` and one ``panomap perspective`` run per image.
Against it, ``panomap batch`` on a local Dask cluster of 1 and of 2 workers, end to end
(cluster start-up included).

Videos: V (default 2) clips of F frames (default 75, 3 s) to the same two views: a loop of
``panomap video`` runs against ``panomap batch`` with 1 and 2 workers.

Every run is a fresh process, timed by wall clock; the ratios are throughput against the
loop's, measured in this same run. Each batch and the video loop run ``--repeat`` times, the
loop and the batches of a repeat one after the other in an order rotated from repeat to
repeat (so that a change of load on the machine hits them alike); each batch run is compared
with its repeat's loop, and the table gives the median run, the median ratio and the worst
(least) ratio. The image loop (two process starts per image) runs once, on every
image or, with ``--loop-images N``, on N of them evenly spread: its runs are independent,
so their throughput is the whole loop's. The machine may be shared: read the ratios, not
the absolute times; the load average is printed. Run:
``python bench/bench_batch.py [--images N] [--videos V] [--frames F] [--repeat R] [--loop-images N]``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import av
import cv2
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
PANORAMA = "panorama:size=2048x512"
PERSPECTIVE = "perspective:yaw=30,pitch=-20,fov=90,size=1280x720,name=door"
COMMANDS = {
    "panorama": ["panorama", "--size", "2048x512"],
    "door": ["perspective", "--yaw", "30", "--pitch", "-20", "--fov", "90", "--size", "1280x720"],
}


def make_inputs(folder: Path, images: int, videos: int, frames: int) -> Path:
    """The table (fisheye.npz), images/NNNN.jpg and videos/clipN.mp4 in ``folder``; returns the table."""
    room = load_room()
    camera = standard_cameras(SIZE)["equidistant"]
    assert isinstance(camera, RadialCamera)
    omni = render(room, camera, supersample=1)
    x, y, z = (float(c) for c in room.camera)
    position = (x, y, z)
    horizon = float(camera.radius_of_rho(0.0))
    landmarks = Landmarks(*spread_landmarks(camera, position, 40, np.random.default_rng(0)))
    below = np.hypot(*(landmarks.pixels - np.asarray(camera.centre)).T) < horizon - 1
    names = tuple(name for name, keep in zip(landmarks.names, below, strict=True) if keep)
    landmarks = Landmarks(landmarks.pixels[below], landmarks.world[below], names, landmarks.camera)
    fit = fit_camera(landmarks, position, camera.centre, image_size=SIZE)
    table = create_table(fit, image_size=SIZE, cutoff_radius=camera.cutoff_radius, outer_radius=horizon)
    save_table(table, folder / "fisheye.npz")
    rng = np.random.default_rng(1)
    noise = rng.normal(0, 4, size=(4, SIZE[1], SIZE[0], 3)).astype(np.int16)

    def frame(index: int, step_deg: float) -> np.ndarray:
        turned = cv2.warpAffine(omni, cv2.getRotationMatrix2D(camera.centre, step_deg * index, 1.0), SIZE)
        return np.clip(turned.astype(np.int16) + noise[index % 4], 0, 255).astype(np.uint8)

    (folder / "images").mkdir()
    for index in range(images):
        cv2.imwrite(str(folder / "images" / f"{index:04d}.jpg"), frame(index, 1.7), [cv2.IMWRITE_JPEG_QUALITY, 92])
    (folder / "videos").mkdir()
    for number in range(videos):
        with av.open(str(folder / "videos" / f"clip{number}.mp4"), "w") as container:
            stream = container.add_stream("libx264", rate=RATE)
            stream.width, stream.height = SIZE
            stream.pix_fmt = "yuv420p"
            stream.options = {"preset": "veryfast", "crf": "18"}
            for index in range(frames):
                picture = av.VideoFrame.from_ndarray(frame(index + 7 * number, 0.4), format="bgr24")
                for packet in stream.encode(picture):
                    container.mux(packet)
            for packet in stream.encode(None):
                container.mux(packet)
    return folder / "fisheye.npz"


def panomap(*args: object) -> None:
    subprocess.run([sys.executable, "-m", "panomap", *map(str, args)], check=True, stdout=subprocess.DEVNULL)


def timed(action: object) -> float:
    started = time.perf_counter()
    action()  # type: ignore[operator]
    return time.perf_counter() - started


def spread(items: list[Path], count: int | None) -> list[Path]:
    """``count`` of ``items``, evenly spread (all of them for None or more than there are)."""
    if count is None or count >= len(items):
        return items
    return [items[round(k * len(items) / count)] for k in range(count)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--images", type=int, default=200, help="still images (default 200)")
    parser.add_argument("--videos", type=int, default=2, help="videos (default 2; 0 for none)")
    parser.add_argument("--frames", type=int, default=75, help="frames per video (default 75)")
    parser.add_argument(
        "--repeat", type=int, default=2, help="runs of each batch and of the video loop (default 2): median and worst"
    )
    parser.add_argument(
        "--loop-images",
        type=int,
        metavar="N",
        help="time the image loop on N of the images, evenly spread (default: all; each run is independent, so "
        "its throughput is that of the whole loop)",
    )
    options = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="bench_batch_"))
    load = os.getloadavg()[0]
    try:
        print(f"making {options.images} images and {options.videos} videos of {options.frames} frames (1920 x 1920)")
        table = make_inputs(folder, options.images, options.videos, options.frames)
        images = sorted((folder / "images").iterdir())
        rows: list[tuple[str, str, list[float], int, list[float]]] = []

        def loop_images(sample: list[Path]) -> None:
            out = folder / "loop"
            out.mkdir()
            for image in sample:
                for name, command in COMMANDS.items():
                    panomap(command[0], table, image, "-o", out / f"{image.stem}_{name}.jpg", *command[1:])

        def batch(inputs: Path, workers: int, tag: str) -> None:
            panomap(
                "batch", inputs, "--table", table, "-o", folder / tag / "{stem}_{name}.mp4", "--view", PANORAMA,
                "--view", PERSPECTIVE, "--workers", workers, "--record", folder / f"{tag}.jsonl", "-q",
            )  # fmt: skip

        def compare(
            kind: str, what: str, inputs: Path, count: int, loop: Callable[[int], float] | None, fixed: float = 0.0
        ) -> None:
            """Each repeat: the loop ``what`` (when ``loop`` is given; else its one time ``fixed``) and a batch of 1
            and of 2 workers, in an order rotated from repeat to repeat, so that a change of load on the machine
            hits every run alike; a run's ratio is taken against the loop of its own repeat."""
            names = ["loop", 1, 2] if loop is not None else [1, 2]
            runs: dict[object, list[float]] = {name: [] for name in names}
            for repeat in range(options.repeat):
                for name in names[repeat % len(names) :] + names[: repeat % len(names)]:
                    if name == "loop":
                        assert loop is not None
                        runs[name].append(loop(repeat))
                    else:
                        tag = f"{kind}{name}_{repeat}"
                        runs[name].append(timed(lambda w=name, t=tag: batch(inputs, w, t)))
            loops = runs.pop("loop", [fixed] * options.repeat)
            rows.append((kind, what, loops, count, loops))
            for name, times in runs.items():
                rows.append((kind, f"panomap batch, {name} worker(s)", times, count, loops))

        if images:
            sample = spread(images, options.loop_images)
            seconds = timed(lambda: loop_images(sample)) * len(images) / len(sample)
            what = "loop of panomap panorama + perspective"
            if len(sample) < len(images):
                what += f" (timed on {len(sample)} of the images)"
            compare("images", what, folder / "images", len(images), None, seconds)
        if options.videos:
            clips = sorted((folder / "videos").iterdir())

            def loop_videos(repeat: int) -> float:
                out = folder / f"vloop{repeat}"
                out.mkdir()
                started = time.perf_counter()
                for clip in clips:
                    panomap(
                        "video", table, clip, "-o", out / f"{clip.stem}_{{name}}.mp4", "--view", PANORAMA,
                        "--view", PERSPECTIVE,
                    )  # fmt: skip
                return time.perf_counter() - started

            compare("videos", "loop of panomap video", folder / "videos", len(clips) * options.frames, loop_videos)
        print()
        end = os.getloadavg()[0]
        print(f"load average (1 min) {load:.2f} at the start, {end:.2f} at the end; {options.repeat} run(s) each")
        print("time: the median run; vs the loop: the median of each run's ratio to its repeat's loop; worst: least")
        print()
        print("| inputs | run | time | throughput | vs the loop | worst |")
        print("| --- | --- | --- | --- | --- | --- |")
        for kind, what, times, count, loops in rows:
            unit = "images/s" if kind == "images" else "frames/s"
            took = statistics.median(times)
            ratios = [loop / run for loop, run in zip(loops, times, strict=True)]
            print(
                f"| {kind} | {what} | {took:.1f} s | {count / took:.2f} {unit} | {statistics.median(ratios):.2f}x "
                f"| {min(ratios):.2f}x |"
            )
    finally:
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
