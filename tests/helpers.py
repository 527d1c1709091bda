"""Plain helpers shared by the tests (fixtures are in conftest.py): ``from helpers import ...``.

pytest puts this folder on ``sys.path`` (``tests/`` has no ``__init__.py``, and
conftest.py lives here); ``bench/bench_fit.py`` adds it itself for ``worst_error``.
The ground truth (``panomap.simulate``) imports nothing from the code under test:
what runs that code on it (making ``Landmarks``, fitting, building tables) is here.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np
from click.testing import CliRunner, Result
from numpy.typing import NDArray

from panomap.calibrate.fit import CameraFit, fit_camera
from panomap.calibrate.landmarks import Landmarks, landmarks_to_csv
from panomap.calibrate.make_table import create_table
from panomap.cli.app import main
from panomap.simulate import sampling
from panomap.simulate.cameras import RadialCamera, SimulatedCamera
from panomap.simulate.scenarios import CAMERA_POSITION, IMAGE_SIZE, Trial
from panomap.table.table import PanoMappingTable

# ----------------------------------------------------------------------------- the command line, in-process


def run(*args: object) -> Result:
    """``panomap ARGS...`` in-process (each argument through ``str``)."""
    return CliRunner().invoke(main, [str(a) for a in args])


def assert_one_line_error(result: Result, *fragments: str, exit_code: int | None = None) -> None:
    """The command failed (with ``exit_code``, or any non-zero one if None) and wrote one line
    to stderr, no traceback, holding every fragment."""
    if exit_code is None:
        assert result.exit_code != 0, result.output + result.stderr
    else:
        assert result.exit_code == exit_code, result.output + result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, result.stderr
    assert "Traceback" not in result.output + result.stderr
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


def write_cli_inputs(folder: Path, camera: SimulatedCamera, position: tuple[float, float, float]) -> None:
    """``folder/lm.csv``: 12 exact landmarks of ``camera`` (seed 5); ``folder/omni.png``: a test
    pattern of its image size (B = u mod 256, G = v mod 256, R = (u + v) mod 256)."""
    landmarks = spread_landmarks(camera, position, 12, np.random.default_rng(5))
    (folder / "lm.csv").write_text(landmarks_to_csv(landmarks))
    width, height = camera.image_size
    v, u = np.mgrid[0:height, 0:width]
    image = np.stack([u % 256, v % 256, (u + v) % 256], axis=-1).astype(np.uint8)
    cv2.imwrite(str(folder / "omni.png"), image)


# ----------------------------------------------------------------------------- ground truth -> the code under test


def spread_landmarks(
    camera: SimulatedCamera,
    camera_position: tuple[float, float, float],
    count: int,
    rng: np.random.Generator,
    **options: Any,
) -> Landmarks:
    """:func:`panomap.simulate.spread_landmarks` (same arguments), as the library's ``Landmarks``."""
    return Landmarks(*sampling.spread_landmarks(camera, camera_position, count, rng, **options))


def learn_table(
    camera: SimulatedCamera,
    camera_position: tuple[float, float, float],
    landmarks: Landmarks,
    image_size: tuple[int, int],
    *,
    model: str = "auto",
    annulus: tuple[float, float] | None = None,
    outer_radius: float | None = None,
    table_size: tuple[int, int] | None = None,
) -> tuple[PanoMappingTable, CameraFit]:
    """The table learned from ``landmarks`` with the camera's true centre and radii, and its fit.

    ``outer_radius`` replaces the camera's; ``annulus`` goes to the fit, ``table_size`` to the table.
    """
    fit = fit_camera(landmarks, camera_position, camera.centre, model=model, image_size=image_size, annulus=annulus)
    table = create_table(
        fit,
        image_size=image_size,
        cutoff_radius=camera.cutoff_radius,
        outer_radius=camera.outer_radius if outer_radius is None else outer_radius,
        size=table_size,
    )
    return table, fit


def worst_error(
    camera: RadialCamera, trial: Trial, points: tuple[NDArray[np.float64], NDArray[np.float64]], model: str = "auto"
) -> float:
    """Worst pixel error (px) over the test points of the table learned from a
    :mod:`panomap.simulate.scenarios` trial (inf if a point is missed)."""
    annulus = (camera.cutoff_radius, camera.outer_radius)
    table, _ = learn_table(
        camera,
        CAMERA_POSITION,
        Landmarks(*trial.landmarks),
        IMAGE_SIZE,
        model=model,
        annulus=annulus,
        table_size=(2048, 512),
    )
    world, truth = points
    error = np.linalg.norm(table.project(world) - truth, axis=1)
    return float(np.max(np.where(np.isnan(error), np.inf, error)))


# Ground-truth bars for the views of the 20-landmark tables in test_ground_truth.py and test_views_more.py
# (exact landmarks, centre given, image rotated and mirrored), a small multiple (3-4x) of the worst
# measured over every view of each kind: 95th percentile and maximum of the pixel error inside the
# landmarks' elevation range. Measured worst (px), p95 / max over cylinder, plane, perspective and floor views:
# equidistant 0.00053 / 0.00065, equisolid 0.00111 / 0.00130, parabolic 0.00079 / 0.00141,
# hyperbolic 0.00182 / 0.00277. A table 0.05 px off, or a map off by one float32 step of the
# angles at the rim, fails them.
VIEW_P95_PX = {"equidistant": 0.0015, "equisolid": 0.003, "parabolic": 0.003, "hyperbolic": 0.006}
VIEW_MAX_PX = {"equidistant": 0.002, "equisolid": 0.004, "parabolic": 0.005, "hyperbolic": 0.01}


def assert_view_errors_within(errors: np.ndarray, camera_name: str) -> None:
    """The 95th percentile and the maximum of ``errors`` (px) within the camera's bars."""
    p95, largest = float(np.percentile(errors, 95)), float(np.max(errors))
    assert p95 < VIEW_P95_PX[camera_name], f"p95 {p95:.5f} px (bar {VIEW_P95_PX[camera_name]})"
    assert largest < VIEW_MAX_PX[camera_name], f"max {largest:.5f} px (bar {VIEW_MAX_PX[camera_name]})"
