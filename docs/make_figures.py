"""The manual's pictures of the views, made from the bundled demo (``panomap demo``).

Run from the repository root: ``.venv/bin/python docs/make_figures.py``. Renders the bundled room through the
demo's simulated hyperbolic-mirror ceiling camera, learns the camera from 12 landmarks as ``panomap demo``
does, and writes into ``docs/img/``:

- ``front.png``: the omni-image beside a perspective view and, below them, a cylinder panorama (the README's
  picture);
- ``view-*.jpg``: the omni-image and each view kind, for the gallery (docs/gallery.md).
"""

from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

import panomap  # noqa: E402
from panomap.cli.demo import run_demo  # noqa: E402

OUT = ROOT / "docs" / "img"
GAP = 8  # px between the pictures of front.png
BACKGROUND = (255, 255, 255)


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as folder:
        for line in run_demo(Path(folder)):
            print(line)
        omni = panomap.read_image(Path(folder) / "omni.png")
        table = panomap.load_table(Path(folder) / "table.npz")
    floor, ceiling = -2.45, 2.6 - 2.45  # the room's floor and ceiling, relative to the camera (m)
    band = panomap.Band(floor, ceiling)
    views = {
        "panorama": panomap.GenericPanorama(),
        "cylinder": panomap.CylinderPanorama(2.0, band, (2048, 560)),
        "plane": panomap.PlaneView(1.8, 2.4, band, math.radians(90.0), (800, 860)),
        "perspective": panomap.PerspectiveView(
            yaw_rad=math.radians(250.0),
            pitch_rad=math.radians(-25.0),
            roll_rad=0.0,
            fov_rad=math.radians(95.0),
            size=(960, 720),
        ),
        "down": panomap.PerspectiveView(
            yaw_rad=0.0, pitch_rad=math.radians(-90.0), roll_rad=0.0, fov_rad=math.radians(120.0), size=(720, 720)
        ),
        "floor": panomap.FloorView(0.0, (0.0, 6.0), (0.0, 5.0), (600, 500)),
    }
    pictures = {name: view.remapper(table)(omni) for name, view in views.items()}
    write_jpeg(OUT / "view-omni.jpg", fit_width(omni, 480))
    for name, picture in pictures.items():
        write_jpeg(OUT / f"view-{name}.jpg", fit_width(picture, 720 if name in ("panorama", "cylinder") else 480))
    write_front(omni, pictures["perspective"], pictures["cylinder"])


def fit_width(image: np.ndarray, width: int) -> np.ndarray:
    """``image`` scaled (area-averaged) to ``width`` px wide, its aspect kept."""
    height = round(image.shape[0] * width / image.shape[1])
    return cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA)


def write_jpeg(path: Path, image: np.ndarray) -> None:
    Image.fromarray(cv2.cvtColor(image, cv2.COLOR_BGR2RGB)).save(path, quality=85, optimize=True)
    print(f"wrote {path} ({path.stat().st_size // 1024} kB)")


def write_front(omni: np.ndarray, perspective: np.ndarray, cylinder: np.ndarray) -> None:
    """The omni-image and a perspective view side by side, a cylinder panorama below both; 256 colours."""
    side = 360
    left = cv2.resize(omni, (side, side), interpolation=cv2.INTER_AREA)
    right = cv2.resize(perspective, (480, side), interpolation=cv2.INTER_AREA)
    width = side + GAP + right.shape[1]
    below = fit_width(cylinder, width)
    canvas = np.full((side + GAP + below.shape[0], width, 3), BACKGROUND, dtype=np.uint8)
    canvas[:side, :side] = left
    canvas[:side, side + GAP :] = right
    canvas[side + GAP :, :] = below
    picture = Image.fromarray(cv2.cvtColor(canvas, cv2.COLOR_BGR2RGB)).quantize(colors=256, dither=Image.Dither.NONE)
    path = OUT / "front.png"
    picture.save(path, optimize=True)
    print(f"wrote {path} ({path.stat().st_size // 1024} kB)")


if __name__ == "__main__":
    main()
