"""``panomap import --fov`` for one lens: its table stops where the lens sees half the field of view off its axis.

A 360 camera's lens calibrated alone (the Theta's BoofCV files) must not bring its black rim into a rig's blend;
``--fov 188`` says where to stop without working out the radius by hand. Ground truth: an ideal equidistant lens,
whose image radius is ``f * angle`` off the axis (closed form, not the code under test).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from panomap.table.file import load_table

from helpers import assert_one_line_error, run

F_PX, CENTRE, SIDE = 283.6, (479.5, 471.25), 960


def equidistant_yaml(path: Path, distortion_model: str = "equidistant") -> Path:
    path.write_text(
        f"cam0: {{camera_model: pinhole, intrinsics: [{F_PX}, {F_PX}, {CENTRE[0]}, {CENTRE[1]}], "
        f"distortion_model: {distortion_model}, distortion_coeffs: [0, 0, 0, 0], resolution: [{SIDE}, {SIDE}]}}\n"
    )
    return path


@pytest.mark.parametrize("fov_deg", [150.0, 190.0])
def test_fov_stops_the_table_at_half_the_field_off_the_axis(tmp_path: Path, fov_deg: float) -> None:
    calibration = equidistant_yaml(tmp_path / "lens.yaml")
    result = run("import", calibration, "-o", tmp_path / "lens.npz", "--orientation", "0", "0", "0",
                 "--fov", fov_deg)  # fmt: skip
    assert result.exit_code == 0, result.output + result.stderr
    table = load_table(tmp_path / "lens.npz")
    truth_px = F_PX * math.radians(fov_deg / 2)  # equidistant: r = f * angle
    # (an equidistant profile is linear: the radius comes out exact, measured 0.0 px)
    assert abs(table.outer_radius - truth_px) < 1e-6, (table.outer_radius, truth_px)
    assert table.info["sources"]["outer_radius"] == f"--fov {fov_deg:g} deg"
    # Near its rim (3 px in, all round) the table's rays lie fov/2 - 3 px / f off the axis (+X: looking ahead);
    # within 1.5e-3 deg, about 3x the worst measured (3.8e-4 and 5.6e-4 deg: the table's bilinear reading).
    turn = np.radians(np.arange(0.0, 360.0, 15.0))
    uv = np.stack([CENTRE[0] + (truth_px - 3) * np.cos(turn), CENTRE[1] + (truth_px - 3) * np.sin(turn)], axis=1)
    azimuth, elevation = (np.asarray(a) for a in table.unproject(uv))
    off_axis_deg = np.degrees(np.arccos(np.cos(elevation) * np.cos(azimuth)))
    np.testing.assert_allclose(off_axis_deg, fov_deg / 2 - math.degrees(3 / F_PX), atol=1.5e-3)


@pytest.mark.parametrize(("model", "fov_deg", "reach_deg"), [("radtan", 200, 90.0), ("equidistant", 400, 180.0)])
def test_fov_beyond_the_model_is_refused(tmp_path: Path, model: str, fov_deg: float, reach_deg: float) -> None:
    """A pinhole model cannot see 100 deg off its axis, nor any lens 200: refused, naming the file, nothing written."""
    calibration = equidistant_yaml(tmp_path / "lens.yaml", distortion_model=model)
    result = run("import", calibration, "-o", tmp_path / "x.npz", "--orientation", "0", "0", "0", "--fov", fov_deg)
    assert_one_line_error(result, "lens.yaml", f"--fov {fov_deg}", f"at most {reach_deg:.1f} deg off its axis")
    assert len(result.stderr.strip()) <= 160 + len(str(calibration)), result.stderr
    assert not (tmp_path / "x.npz").exists()


@pytest.mark.parametrize("other", [["--outer-radius", "400"], ["--mirror"]])
def test_fov_with_another_bound_or_a_mirror_is_refused_in_one_line(tmp_path: Path, other: list[str]) -> None:
    calibration = equidistant_yaml(tmp_path / "lens.yaml")
    result = run("import", calibration, "-o", tmp_path / "x.npz", "--fov", 190, *other)
    assert_one_line_error(result, "--fov", exit_code=2)
    assert not (tmp_path / "x.npz").exists()
