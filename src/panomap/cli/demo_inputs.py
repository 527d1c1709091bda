"""The demo's example inputs: a clip of its camera, two other cameras' calibrations and pictures, a manifest.

The documented commands run on these as printed (``tests/test_doc_blocks.py``): a user reads
``demo-out/camchain.yaml`` as their own camchain. Every picture is the bundled room through the camera its
file describes (:mod:`panomap.simulate.lens_scenes`); the clip turns the demo's ceiling camera about its
axis, which for a camera whose axis is vertical is the picture turned about the image centre.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Iterator
from pathlib import Path

import av
import cv2
import numpy as np
from numpy.typing import NDArray

from ..files import atomic_path, write_text_atomic
from ..io.images import write_image
from ..simulate import Room
from ..simulate.lens_scenes import DoubleSphereLens, EquidistantLens, camera_axes, render_lens

# The clip: CLIP_FRAMES frames at CLIP_RATE frames/s, the camera turned CLIP_TURN_DEG more each frame.
CLIP_FRAMES, CLIP_RATE, CLIP_TURN_DEG = 24, 12, 1.25
# A fisheye looking ahead (Basalt's double sphere, 640 x 480), a little down and rolled, at AHEAD_AT (m).
AHEAD = DoubleSphereLens(fx=190.0, fy=190.0, cx=318.4, cy=241.7, xi=-0.2, alpha=0.6, size=(640, 480))
AHEAD_AT, AHEAD_ORIENTATION_DEG = (1.5, 2.5, 1.4), (0.0, -8.0, 3.0)
# A dual fisheye (two 210 deg equidistant lenses back to back, side by side in one frame), camera 0 looking
# along +X, level, at DUAL_AT (m), off the room's centre (its floor looks the same turned half a turn about it);
# camera 1 turned half a turn about its y axis, at the same point: a real camera's 1-2 cm between its lenses,
# seen against walls 1-3 m away, is a parallax of up to 0.8 deg, which `rig learn` would read as a turn.
LENS = EquidistantLens(f_px=170.0, cx=319.5, cy=319.5, half_fov_rad=math.radians(105.0), size=(640, 640))
DUAL_AT = (2.7, 2.15, 1.5)
BACK = np.diag([-1.0, 1.0, -1.0])  # R of camera 1's T_cn_cnm1: x_1 = R x_0 (t = 0)
DUAL_FRAMES = 6
# The files written here, in the demo's folder.
INPUTS = ("omni.mp4", "ahead.json", "ahead.jpg", "camchain.yaml", "dual.jpg", "dual.mp4", "cams.csv")


def turned(image: NDArray[np.uint8], centre: tuple[float, float], angle_deg: float) -> NDArray[np.uint8]:
    """``image`` turned by ``angle_deg`` counter-clockwise on screen about ``centre`` (u, v) px (bilinear)."""
    matrix = cv2.getRotationMatrix2D(centre, angle_deg, 1.0)
    height, width = image.shape[:2]
    return np.asarray(cv2.warpAffine(image, matrix, (width, height), flags=cv2.INTER_LINEAR), dtype=np.uint8)


def write_clip(path: Path, pictures: Iterable[NDArray[np.uint8]], rate: int) -> None:
    """``pictures`` (BGR, one size) as an H.264 MP4 (yuv420p, crf 18) at ``rate`` frames/s, whole or not at
    all."""
    with atomic_path(path) as temporary, av.open(str(temporary), "w", format="mp4") as container:
        stream = container.add_stream("libx264", rate=rate)
        stream.pix_fmt = "yuv420p"
        stream.options = {"crf": "18", "preset": "veryfast"}
        for index, picture in enumerate(pictures):
            if index == 0:
                stream.height, stream.width = picture.shape[:2]
            frame = av.VideoFrame.from_ndarray(picture, format="bgr24")
            frame.pts = index
            container.mux(stream.encode(frame))
        container.mux(stream.encode(None))


def basalt_text(lens: DoubleSphereLens) -> str:
    """Basalt's calibration JSON of one double sphere camera (``T_imu_cam`` the identity)."""
    intrinsics = {"fx": lens.fx, "fy": lens.fy, "cx": lens.cx, "cy": lens.cy, "xi": lens.xi, "alpha": lens.alpha}
    pose = {"px": 0.0, "py": 0.0, "pz": 0.0, "qx": 0.0, "qy": 0.0, "qz": 0.0, "qw": 1.0}
    value = {
        "T_imu_cam": [pose],
        "intrinsics": [{"camera_type": "ds", "intrinsics": intrinsics}],
        "resolution": [list(lens.size)],
        "vignette": [],
        "calib_accel_bias": [0.0] * 9,
        "calib_gyro_bias": [0.0] * 12,
        "imu_update_rate": 200.0,
        "cam_time_offset_ns": 0,
    }
    return json.dumps({"value0": value}, indent=4) + "\n"


def camchain_text(lens: EquidistantLens) -> str:
    """Kalibr's camchain of two ``lens`` back to back, camera 1 with its ``T_cn_cnm1``."""
    camera = (
        "  camera_model: pinhole\n"
        f"  intrinsics: [{lens.f_px}, {lens.f_px}, {lens.cx}, {lens.cy}]\n"
        "  distortion_model: equidistant\n"
        "  distortion_coeffs: [0.0, 0.0, 0.0, 0.0]\n"
        f"  resolution: [{lens.size[0]}, {lens.size[1]}]\n"
    )
    rows = [[*BACK[k], 0.0] for k in range(3)] + [[0.0, 0.0, 0.0, 1.0]]
    chain = "".join(f"  - [{', '.join(f'{x:g}' for x in row)}]\n" for row in rows)
    return f"cam0:\n{camera}cam1:\n{camera}  T_cn_cnm1:\n{chain}"


def dual_frame(room: Room) -> NDArray[np.uint8]:
    """The dual fisheye's frame: camera 0's picture on the left, camera 1's on the right."""
    axes = camera_axes(0.0, 0.0, 0.0)
    return np.concatenate(
        [render_lens(room, LENS, DUAL_AT, axes), render_lens(room, LENS, DUAL_AT, axes @ BACK.T)], axis=1
    )


def write_inputs(out: Path, room: Room, omni: NDArray[np.uint8], centre: tuple[float, float]) -> Iterator[str]:
    """Write :data:`INPUTS` into ``out``; yields one line per step. ``omni`` is the demo's picture, its
    camera's axis vertical through ``centre`` (u, v) px."""
    write_clip(out / "omni.mp4", (turned(omni, centre, k * CLIP_TURN_DEG) for k in range(CLIP_FRAMES)), CLIP_RATE)
    yield (
        f"wrote a {CLIP_FRAMES / CLIP_RATE:g} s clip of the same camera turning {CLIP_TURN_DEG * CLIP_RATE:g} deg/s: "
        f"{out / 'omni.mp4'}"
    )
    write_text_atomic(out / "ahead.json", basalt_text(AHEAD))
    write_image(out / "ahead.jpg", render_lens(room, AHEAD, AHEAD_AT, camera_axes(*AHEAD_ORIENTATION_DEG)))
    yield (
        f"rendered the room through a fisheye looking ahead, {-AHEAD_ORIENTATION_DEG[1]:g} deg down and rolled "
        f"{AHEAD_ORIENTATION_DEG[2]:g} deg: {out / 'ahead.jpg'}, its Basalt calibration {out / 'ahead.json'}"
    )
    write_text_atomic(out / "camchain.yaml", camchain_text(LENS))
    frame = dual_frame(room)
    write_image(out / "dual.jpg", frame)
    write_clip(out / "dual.mp4", (frame for _ in range(DUAL_FRAMES)), CLIP_RATE)
    yield (
        f"rendered the room through a dual fisheye (two lenses back to back, side by side): {out / 'dual.jpg'} "
        f"(a still clip {out / 'dual.mp4'}), its Kalibr camchain {out / 'camchain.yaml'}"
    )
    rows = "".join(f"{name},table.npz,ceiling\n" for name in ("omni.png", "boards.png", "omni.mp4"))
    write_text_atomic(out / "cams.csv", "input,table,camera\n" + rows)
    yield f"wrote a batch manifest of the ceiling camera's picture, boards and clip: {out / 'cams.csv'}"
