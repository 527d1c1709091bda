"""The fit's cost against the number of landmarks: k-fold cross-validation against exact leave-one-out.

Run: ``.venv/bin/python bench/bench_fit_count.py [--counts 10,50,100,200,500,1000] [--exact-up-to 200]``

The scenarios' hyperbolic (xi = 0.9) ceiling camera (1920 x 1920), landmarks on the room's
surfaces with 1 px / 1 cm noise and 5% of them 50 px off. For each count, the
default fit (``fit_camera``: exact leave-one-out up to ``EXACT_LOO_MAX``
landmarks, k-fold above) is timed beside the same fit forced to exact
leave-one-out at every count (the baseline, in the same run, up to
``--exact-up-to`` landmarks: it grows with the square of the count), with the
worst error over the test points and how many of the bad landmarks were
flagged; and the default with the centre refined from a start 1.8 px off the axis (what
``panomap fit --image`` does with the rim's centre). Times are the fastest of ``--repeat`` runs.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from panomap.calibrate.core import selection
from panomap.calibrate.landmarks.fit import fit_camera
from panomap.calibrate.landmarks.pairs import Landmarks
from panomap.simulate.sampling import LandmarkPairs
from panomap.simulate.scenarios import (
    CAMERA_POSITION,
    IMAGE_SIZE,
    Trial,
    make_landmarks,
    scenario_cameras,
    test_points,
)

# worst_error runs the code under test on the scenarios: it lives with the tests' helpers.
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from helpers import worst_error


def timed(
    landmarks: Landmarks, centre: tuple[float, float], repeat: int, refine_centre: bool = False
) -> tuple[float, list[str]]:
    best = math.inf
    outliers: list[str] = []
    for _ in range(repeat):
        start = time.perf_counter()
        fit = fit_camera(landmarks, CAMERA_POSITION, centre, image_size=IMAGE_SIZE, refine_centre=refine_centre)
        best = min(best, time.perf_counter() - start)
        outliers = fit.outliers
    return best, outliers


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--counts", default="10,50,100,200,500,1000")
    parser.add_argument("--exact-up-to", type=int, default=200)
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    camera = scenario_cameras()["hyperbolic-0.9"]
    points = test_points(camera)
    fit_camera(*_warm_up(camera))  # SciPy's import and first calls, outside the timings
    print(
        f"{'landmarks':>9} {'default s':>10} {'exact LOO s':>12} {'ratio':>7} {'worst px':>9} {'flagged':>9} "
        f"{'centre refined s':>17}"
    )
    for count in (int(c) for c in args.counts.split(",")):
        rng = np.random.default_rng(count)
        trial = make_landmarks(camera, count, rng, spread=False)
        pixels = np.array(trial.landmarks.pixels, dtype=np.float64)
        bad = rng.choice(count, count // 20, replace=False)
        pixels[bad] += 50.0 * np.array([0.6, 0.8])
        landmarks = Landmarks(pixels, trial.landmarks.world, trial.landmarks.names)
        default, outliers = timed(landmarks, camera.centre, args.repeat)
        exact = math.nan
        if count <= args.exact_up_to:
            saved = selection.EXACT_LOO_MAX
            selection.EXACT_LOO_MAX = 10**9
            try:
                exact, _ = timed(landmarks, camera.centre, args.repeat)
            finally:
                selection.EXACT_LOO_MAX = saved
        moved = Trial(LandmarkPairs(pixels, trial.landmarks.world, trial.landmarks.names))
        error = worst_error(camera, moved, points)
        flagged = len({landmarks.names[k] for k in bad} & set(outliers))
        ratio = f"{exact / default:6.1f}x" if math.isfinite(exact) else "      -"
        exact_text = f"{exact:12.2f}" if math.isfinite(exact) else f"{'-':>12}"
        # What `fit --image` does: the centre found at the rim (here 1.8 px off the axis) and refined.
        rim = (camera.centre[0] + 1.5, camera.centre[1] - 1.0)
        refined, _ = timed(landmarks, rim, args.repeat, refine_centre=True)
        print(
            f"{count:9d} {default:10.2f} {exact_text} {ratio} {error:9.2f} {flagged:4d}/{bad.size:<4d} {refined:17.2f}"
        )


def _warm_up(camera: object) -> tuple[Landmarks, tuple[float, float, float], tuple[float, float]]:
    trial = make_landmarks(camera, 10, np.random.default_rng(0))  # type: ignore[arg-type]
    return Landmarks(*trial.landmarks), CAMERA_POSITION, camera.centre  # type: ignore[attr-defined]


if __name__ == "__main__":
    main()
