"""The typed fit report: what a table file stores, read back exactly, and a malformed one refused."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from panomap.calibrate.core.report import FitReport, LandmarkResidual, RadiusUncertainty, table_fit_report
from panomap.calibrate.landmarks.fit import fit_camera
from panomap.calibrate.landmarks.table import create_table
from panomap.errors import PanomapError
from panomap.simulate import standard_cameras
from panomap.table.file import load_table, save_table
from panomap.table.table import PanoMappingTable

from helpers import spread_landmarks

SIZE = (640, 600)
POSITION = (3.0, 2.0, 2.5)


@pytest.fixture(scope="module")
def saved(tmp_path_factory: pytest.TempPathFactory) -> tuple[FitReport, PanoMappingTable, Path]:
    camera = standard_cameras(SIZE, centre=(321.4, 298.2), s=-1, phi0=0.7)["parabolic"]
    landmarks = spread_landmarks(camera, POSITION, 12, np.random.default_rng(5))
    fit = fit_camera(landmarks, POSITION, camera.centre, image_size=SIZE)
    table = create_table(fit, image_size=SIZE, size=(64, 48), info={"sources": {"centre": "given"}})
    path = tmp_path_factory.mktemp("report") / "table.npz"
    save_table(table, path)
    return fit.report(), table, path


def test_the_report_round_trips_through_a_table_file(saved: tuple[FitReport, PanoMappingTable, Path]) -> None:
    report, table, path = saved
    stored = load_table(path).info["fit"]
    # The file holds the report's dict, with the table's radius uncertainty added last.
    assert list(stored) == [*report.to_dict(), "uncertainty"]
    assert json.dumps(stored) == json.dumps(report.to_dict() | {"uncertainty": stored["uncertainty"]})
    typed = FitReport.from_dict(stored)
    assert json.dumps(typed.to_dict()) == json.dumps(stored)
    assert typed.to_dict() == stored
    assert typed == table_fit_report(load_table(path)) == table_fit_report(table)
    assert isinstance(typed.uncertainty, RadiusUncertainty) and len(typed.uncertainty.radius_se_px) == 91
    assert all(isinstance(row, LandmarkResidual) for row in typed.landmarks)
    assert typed.s == -1 and typed.model == table.model.radial.kind and typed.axis == table.model.axis
    assert report.uncertainty is None and "uncertainty" not in report.to_dict()


def test_a_table_without_a_fit_has_no_report(saved: tuple[FitReport, PanoMappingTable, Path]) -> None:
    _, table, _ = saved
    bare = PanoMappingTable(
        table.entries, table.elevation_range, table.model, table.camera_position, None, 0.0, table.outer_radius
    )
    assert table_fit_report(bare) is None


def _broken(stored: dict[str, Any], *path: str | int, value: Any = None, delete: bool = False) -> dict[str, Any]:
    data = copy.deepcopy(stored)
    place: Any = data
    for step in path[:-1]:
        place = place[step]
    if delete:
        del place[path[-1]]
    else:
        place[path[-1]] = value
    return data


@pytest.mark.parametrize(
    ("path", "value", "delete", "message"),
    [
        (("rms_px",), None, True, "lacks rms_px"),
        (("extra",), 1, False, "unexpected entries extra"),
        (("rms_px",), "1.0", False, "'rms_px' in the fit report is not a number"),
        (("s",), 2, False, "s is 2"),
        (("s",), True, False, "'s' in the fit report is not an integer"),
        (("centre",), [1.0], False, "not a pair"),
        (("covariance", 0), [1.0], False, "not a square matrix"),
        (("landmarks", 0, "outlier"), 0, False, "'outlier' in a landmark row is not true or false"),
        (("landmarks", 1, "u"), None, True, "a landmark row lacks u"),
        (("settings", "model_requested"), 3, False, "'model_requested' in the fit settings is not text"),
        (("uncertainty", "radius_se_px"), [1.0], False, "91 elevations and 1 standard errors"),
        (("model_selection_loo_rms_px", "odd1"), "x", False, "selection score of 'odd1'"),
        (("landmarks",), {}, False, "'landmarks' in the fit report is not a list"),
    ],
)
def test_a_malformed_report_is_refused(
    saved: tuple[FitReport, PanoMappingTable, Path], path: tuple[str | int, ...], value: Any, delete: bool, message: str
) -> None:
    stored = load_table(saved[2]).info["fit"]
    with pytest.raises(PanomapError, match="the fit report is malformed") as error:
        FitReport.from_dict(_broken(stored, *path, value=value, delete=delete))
    assert message in error.value.detail


def test_a_report_that_is_not_an_object_is_refused() -> None:
    with pytest.raises(PanomapError, match="the fit report is not an object"):
        FitReport.from_dict([1, 2])
