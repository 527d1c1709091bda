"""The image circle on every real picture with a known calibration centre (issue 53, item 2).

Run: ``PYTHONPATH=src .venv/bin/python bench/bench_circles_real.py``

For each picture in ``../shared/data`` (not bundled; the bench says so and stops where it is absent) whose camera
has a calibration made by an established tool, runs :func:`find_image_circles` (what ``panomap centre`` and
``panomap import --image`` use) and prints a Markdown table: found, not found, or said to be a full-frame fisheye
(no rim visible); the centre's distance from the calibration's principal point, px; the time. Which answer is
right: a rim where one shows; "full-frame" for the car-park fisheyes (their circles hold the frame: SOURCE.md).

Reference centres, (u, v) 0-based px: OCamCalib ``ocam_model.json`` (``yc_col_0based``, ``xc_row_0based``);
the Mei folder's ``omnidir_calibration.json`` (its primary model's ``K``); BoofCV YAMLs (``cx``, ``cy``); Basalt's
``calibration.json``; OpenCV fisheye YAMLs (``camera_matrix``); the car-park OCam JSONs (``cam_K``); the Insta360
frame's halves (489.8, 479.0) per 960 x 960 half (the source's hand-tuned remap, not a calibration). The
calibrations estimate the optical axis, which may sit a few px off the rim's centre: where the rim's own centre was
measured apart (``RIM_CENTRES``), a second count takes it instead.
"""

from __future__ import annotations

import json
import math
import re
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from panomap.calibrate.circles import NoImageCircle, find_image_circles
from panomap.io.images import read_image

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"

# Rim centres (u, v) px measured apart from the finder where the calibration's centre is not the rim's: each ray's
# crossing of the level halfway between the levels 12-40 px either side of the rim, a soft-L1 circle through them
# (the Insta360 rims also checked by eye on eight 6x crops against both circles). The Insta360 halves' "calibration"
# is a hand-tuned remap 12.9-14.8 px off their rims; the Mei mirror's rim lies 3.3 px off its calibrated axis.
RIM_CENTRES = {
    "img_para_001.png": (641.3, 521.3),
    "insta360 insta360-still-001 lens 0": (476.7, 473.8),
    "insta360 insta360-still-001 lens 1": (476.8, 482.9),
    "insta360 insta360-still-002 lens 0": (476.4, 472.8),
    "insta360 insta360-still-002 lens 1": (477.3, 482.1),
}


def yaml_number(path: Path, key: str) -> float:
    match = re.search(rf"^\s*{key}:\s*([-0-9.eE+]+)", path.read_text(), re.MULTILINE)
    assert match is not None, (path, key)
    return float(match.group(1))


def opencv_matrix(path: Path) -> tuple[float, float]:
    """(cx, cy) of an OpenCV FileStorage YAML's ``camera_matrix``."""
    text = path.read_text()
    block = text[text.index("camera_matrix") :]
    numbers = [float(n) for n in re.findall(r"[-0-9.]+e[-+][0-9]+|[-0-9]+\.[0-9]*", block[block.index("data") :])]
    return numbers[2], numbers[5]


def pictures() -> Iterator[tuple[str, np.ndarray, tuple[float, float] | None, str]]:
    """(name, image, calibration centre, what is expected: 'rim' or 'full-frame')."""
    real = DATA / "real"
    for folder in sorted(real.glob("ocam_*")):
        model = json.loads((folder / "ocam_model.json").read_text())
        image = sorted((folder / "images").iterdir())[0]
        yield image.name, read_image(image), (model["yc_col_0based"], model["xc_row_0based"]), "rim"
    mei = json.loads((real / "mei_paracatadioptric" / "omnidir_calibration.json").read_text())
    k = mei["models"][mei["primary"]]["K"]
    image = real / "mei_paracatadioptric" / "images" / "img_para_001.png"
    yield image.name, read_image(image), (k[0][2], k[1][2]), "rim"
    theta = DATA / "scenes" / "theta_back"
    centre = (yaml_number(theta / "back.yaml", "cx"), yaml_number(theta / "back.yaml", "cy"))
    for image in sorted((theta / "images").iterdir()):
        yield f"theta back {image.name}", read_image(image), centre, "rim"
    pair = DATA / "rigs" / "theta_table_pair"
    front = (yaml_number(pair / "front.yaml", "cx"), yaml_number(pair / "front.yaml", "cy"))
    yield "theta front_table.jpg", read_image(pair / "front_table.jpg"), front, "rim"
    ds = DATA / "scenes" / "ds_building"
    intrinsics = json.loads((ds / "calibration.json").read_text())["value0"]["intrinsics"][0]["intrinsics"]
    yield (
        "ds_building sample.jpg",
        read_image(ds / "images" / "sample.jpg"),
        (intrinsics["cx"], intrinsics["cy"]),
        "rim",
    )
    insta = DATA / "rigs" / "insta360_air_dualfisheye" / "images"
    for image in sorted(insta.iterdir()):
        frame = read_image(image)
        side = frame.shape[0]
        for half in (0, 1):
            yield f"insta360 {image.stem} lens {half}", frame[:, half * side : (half + 1) * side], (489.8, 479.0), "rim"
    surround = DATA / "rigs" / "neozhaoliang_surround_view"
    for name in ("front", "back", "left", "right"):
        centre = opencv_matrix(surround / "yaml" / f"{name}.yaml")
        yield f"surround {name}.png", read_image(surround / "images" / f"{name}.png"), centre, "rim"
    park = DATA / "rigs" / "pjlab_ocam_parking_surround"
    for name in ("Front", "Back", "Left", "Right"):
        param = next(iter(json.loads((park / "intrinsic" / f"{name}.json").read_text()).values()))["param"]
        k = param["cam_K"]["data"]
        yield f"car park {name}.png", read_image(park / "imgs" / f"{name}.png"), (k[0][2], k[1][2]), "full-frame"


def main() -> None:
    if not DATA.is_dir():
        print(f"the shared data is not at {DATA}: nothing to measure")
        return
    print("| picture | expected | answer | centre error, px | off the rim's own centre, px | radius, px | time, s |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    right = own = total = 0
    for name, image, centre, expected in pictures():
        start = time.perf_counter()
        rim = RIM_CENTRES.get(name)
        try:
            found = find_image_circles(image)
            answer, radius = "found", f"{found.outer_radius:.1f}"
            error = f"{math.dist(found.centre, centre):.1f}" if centre is not None else "-"
            off = f"{math.dist(found.centre, rim):.1f}" if rim is not None else "-"
            ok = expected == "rim" and centre is not None and math.dist(found.centre, centre) <= 3.0
            ok_own = expected == "rim" and math.dist(found.centre, rim or centre) <= 3.0
        except NoImageCircle as exc:
            answer = "full-frame" if "no rim is visible (a full-frame" in str(exc) else "not found"
            radius = error = off = "-"
            ok = ok_own = expected == "full-frame" and answer == "full-frame"
        seconds = time.perf_counter() - start
        total += 1
        right += ok
        own += ok_own
        print(f"| {name} | {expected} | {answer} | {error} | {off} | {radius} | {seconds:.2f} |", flush=True)
    print(f"\n{right} of {total} right (a rim within 3 px of the calibration's centre, or full-frame said)")
    print(f"{own} of {total} right where the rim's own centre, measured apart, stands for the calibration's")


if __name__ == "__main__":
    sys.exit(main())
