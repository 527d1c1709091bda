"""How long ``import_calibration`` takes for a 1920 x 1920 camera, against making a table from landmarks.

Run: ``.venv/bin/python bench/bench_import.py [--repeats 3]``

The goal (issue 36): an import takes at most 1 s for a 1920 x 1920 camera. Three calibrations of
that size are written to a temporary folder and imported with the defaults (the table about one
entry per pixel, 4096 x ~1000 entries): a 190 deg Kannala-Brandt fisheye in Kalibr's
pinhole-equidistant form, a Mei camera in Kalibr's omni-radtan form, and an OCamCalib fisheye (its
polynomial inverted exactly, the slowest). The baseline, in the same run: the landmark path for the
equidistant camera of the issue's scenarios (the fit of 30 landmarks and ``create_table``). Prints
the median time of each and its ratio to the baseline.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import yaml

from panomap.calibrate.landmarks.fit import fit_camera
from panomap.calibrate.landmarks.pairs import Landmarks
from panomap.calibrate.landmarks.table import create_table
from panomap.interop.api import import_calibration
from panomap.simulate.scenarios import CAMERA_POSITION, IMAGE_SIZE, make_landmarks, scenario_cameras

OCAM_1920 = """#polynomial coefficients for the DIRECT mapping function
5 -5.159665e+02 0.000000e+00 8.662440e-04 -7.192730e-07 1.158809e-09
#polynomial coefficients for the inverse mapping function
3 732.6 378.8 -27.8
#center: "row" and "column", starting from 0 (C convention)
961.3 958.2
#affine parameters "c", "d", "e"
0.998881 -0.002038 0.001079
#image size: "height" and "width"
1920 1920
"""


def camchain(kind: str, intrinsics: list[float], distortion: str, coefficients: list[float]) -> str:
    return yaml.safe_dump(
        {
            "cam0": {
                "camera_model": kind,
                "intrinsics": intrinsics,
                "distortion_model": distortion,
                "distortion_coeffs": coefficients,
                "resolution": list(IMAGE_SIZE),
            }
        }
    )


def median_time(task: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        task()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    camera = scenario_cameras()["equidistant"]
    landmarks = Landmarks(*make_landmarks(camera, 30, np.random.default_rng(0)).landmarks)

    def landmark_path() -> object:
        fit = fit_camera(landmarks, CAMERA_POSITION, camera.centre, image_size=IMAGE_SIZE)
        return create_table(fit, image_size=IMAGE_SIZE, outer_radius=camera.outer_radius)

    baseline = median_time(landmark_path, args.repeats)
    print(f"baseline (fit 30 landmarks + create_table, 1920 x 1920): {baseline:.3f} s")
    with tempfile.TemporaryDirectory() as folder:
        files = {
            "kalibr pinhole-equidistant, 190 deg": (
                "kb.yaml",
                camchain("pinhole", [580.0, 580.0, 959.5, 959.5], "equidistant", [0.01, -0.002, 0.0004, -0.00005]),
            ),
            "kalibr omni-radtan": (
                "omni.yaml",
                camchain("omni", [1.1, 1150.0, 1149.0, 959.2, 960.3], "radtan", [0.05, -0.01, 0.0002, -0.0001]),
            ),
            "ocamcalib calib_results.txt": ("calib_results.txt", OCAM_1920),
        }
        for label, (name, text) in files.items():
            path = Path(folder) / name
            path.write_text(text)
            table = import_calibration(path)
            seconds = median_time(lambda path=path: import_calibration(path), args.repeats)
            m, n = table.size
            verdict = "ok" if seconds <= 1.0 else "OVER 1 s"
            print(f"{label:38s} table {m} x {n}: {seconds:.3f} s ({seconds / baseline:.2f} x baseline) {verdict}")


if __name__ == "__main__":
    main()
