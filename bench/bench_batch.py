"""``panomap batch`` against a plain loop of single ``panomap`` runs over the same inputs, in one run.

Still images: N (default 200) 1920 x 1920 JPEG omni-images of the bundled room through a
simulated 190 deg equidistant fisheye, each turned and noised differently, to two views
(a 2048 x 512 panorama and a 1280 x 720 perspective view). The baseline is what a user
would script today: one ``panomap panorama`` and one ``panomap perspective`` run per image.
Against it, ``panomap batch`` on a local Dask cluster of 1 and of 2 workers, end to end
(cluster start-up included).

Videos: V (default 2) clips of F frames (default 75, 3 s) to the same two views: a loop of
``panomap video`` runs against ``panomap batch`` with 2 workers.

Every run is a fresh process, timed by wall clock; the ratios are throughput against the
loop's, measured in this same run. The machine may be shared: read the ratios, not the
absolute times. Run: ``python bench/bench_batch.py [--images N] [--videos V] [--frames F]``.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import av
import cv2
import numpy as np

from panomap.calibrate.fit import fit_camera
from panomap.calibrate.landmarks import Landmarks
from panomap.calibrate.make_table import create_table
from panomap.simulate import load_room, render, standard_cameras
from panomap.simulate.cameras import RadialCamera
from panomap.simulate.sampling import spread_landmarks

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
    position = tuple(float(c) for c in room.camera)
    horizon = float(camera.radius_of_rho(0.0))
    landmarks = Landmarks(*spread_landmarks(camera, position, 40, np.random.default_rng(0)))
    below = np.hypot(*(landmarks.pixels - np.asarray(camera.centre)).T) < horizon - 1
    names = tuple(name for name, keep in zip(landmarks.names, below, strict=True) if keep)
    landmarks = Landmarks(landmarks.pixels[below], landmarks.world[below], names, landmarks.camera)
    fit = fit_camera(landmarks, position, camera.centre, image_size=SIZE)
    table = create_table(fit, image_size=SIZE, cutoff_radius=camera.cutoff_radius, outer_radius=horizon)
    table.save(folder / "fisheye.npz")
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--images", type=int, default=200, help="still images (default 200)")
    parser.add_argument("--videos", type=int, default=2, help="videos (default 2; 0 for none)")
    parser.add_argument("--frames", type=int, default=75, help="frames per video (default 75)")
    options = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="bench_batch_"))
    try:
        print(f"making {options.images} images and {options.videos} videos of {options.frames} frames (1920 x 1920)")
        table = make_inputs(folder, options.images, options.videos, options.frames)
        images = sorted((folder / "images").iterdir())
        rows = []

        def loop_images() -> None:
            out = folder / "loop"
            out.mkdir()
            for image in images:
                for name, command in COMMANDS.items():
                    panomap(command[0], table, image, "-o", out / f"{image.stem}_{name}.jpg", *command[1:])

        def batch(inputs: Path, workers: int, tag: str) -> None:
            panomap(
                "batch", inputs, "--table", table, "-o", folder / tag / "{stem}_{name}.mp4", "--view", PANORAMA,
                "--view", PERSPECTIVE, "--workers", workers, "--record", folder / f"{tag}.jsonl", "-q",
            )  # fmt: skip

        if images:
            seconds = timed(loop_images)
            rows.append(("images", "loop of panomap panorama + perspective", seconds, len(images), seconds))
            for workers in (1, 2):
                took = timed(lambda w=workers: batch(folder / "images", w, f"images{w}"))
                rows.append(("images", f"panomap batch, {workers} worker(s)", took, len(images), seconds))
        if options.videos:
            clips = sorted((folder / "videos").iterdir())
            frames = len(clips) * options.frames

            def loop_videos() -> None:
                out = folder / "vloop"
                out.mkdir()
                for clip in clips:
                    panomap(
                        "video", table, clip, "-o", out / f"{clip.stem}_{{name}}.mp4", "--view", PANORAMA,
                        "--view", PERSPECTIVE,
                    )  # fmt: skip

            video_loop = timed(loop_videos)
            rows.append(("videos", "loop of panomap video", video_loop, frames, video_loop))
            took = timed(lambda: batch(folder / "videos", 2, "videos2"))
            rows.append(("videos", "panomap batch, 2 workers", took, frames, video_loop))
        print()
        print("| inputs | run | time | throughput | vs the loop |")
        print("| --- | --- | --- | --- | --- |")
        for kind, what, took, count, baseline in rows:
            unit = "images/s" if kind == "images" else "frames/s"
            print(f"| {kind} | {what} | {took:.1f} s | {count / took:.2f} {unit} | {baseline / took:.2f}x |")
    finally:
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
