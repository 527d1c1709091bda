"""Rigs from a Hugin project and from a Basalt calibration (issue 52).

The .pto's ground truth is PanoTools' own stack, written out here from libpano13's ``math.c`` and Hugin's
``SpaceTransform::Init`` (pano to image): the panorama's direction at longitude ``lon`` (right) and latitude
``lat`` (up) is turned by ``rotate_erect`` (``lon - y``), made a vector by ``sphere_tp_erect``
(``P = (cos lat sin lon', -sin lat, cos lat cos lon')``, x right, y down, z ahead), turned by ``persp_sphere``
(``M^T P`` with ``M = SetMatrix(-p, 0, -r) = mx(-p) mz(-r)``), projected equidistantly (``f = w / hfov``),
scaled by ``radial`` (``a R^3 + b R^2 + c R + d``, ``R`` the radius over ``min(w, h)/2``), shifted by ``d``, ``e``
and put about the image's centre ``(w/2 - 0.5, h/2 - 0.5)``. panomap's world: the panorama's centre along +X, Z
up, azimuth ``-lon``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from panomap.geometry import azimuth_elevation
from panomap.interop.rig_of_basalt import rig_of_basalt
from panomap.interop.rig_of_pto import rig_of_pto
from panomap.rig import camera_maps, load_rig
from panomap.views import EquirectView
from test_orientation import equirect_rays

from helpers import assert_one_line_error, run

SIDE, HFOV = 1600, 195.0
# Image 0 and 1: (y, p, r, d, e); both share a, b, c (image 1 links them with =0).
LENSES = [(0.0, 3.0, -2.0, 12.5, -7.25), (178.5, -2.0, 1.5, -9.0, 4.5)]
A, B, C = 0.012, -0.035, 0.018


def pto(path: Path, lenses: list[tuple[float, ...]] = LENSES, projection: int = 2) -> Path:
    lines = ["# hugin project file", 'p f2 w3000 h1500 v360 n"TIFF_m c:LZW"', "m g1 i0 f0 m2 p0.00784314"]
    for k, (y, p, r, d, e) in enumerate(lenses):
        radial = f"a{A} b{B} c{C}" if k == 0 else "a=0 b=0 c=0"
        lines.append(
            f"i w{SIDE} h{SIDE} f{projection} v{HFOV if k == 0 else '=0'} Ra0 Rb0 Rc0 Rd0 Re0 Eev0 Er1 Eb1 "
            f"r{r} p{p} y{y} TrX0 TrY0 TrZ0 Tpy0 Tpp0 j0 {radial} d{d} e{e} g0 t0 Va1 Vb0 Vc0 Vd0 Vx0 Vy0 "
            f'Vm5 n"lens{k}.jpg"'
        )
    path.write_text("\n".join(lines) + "\n")
    return path


def panotools_pixels(rays: np.ndarray, lens: tuple[float, ...]) -> np.ndarray:
    """Pixels (..., 2) of world rays through a lens, PanoTools' stack written out; NaN beyond its hfov/2 or off
    its image."""
    y, p, r, d, e = lens
    lon = np.arctan2(-rays[..., 1], rays[..., 0])
    lat = np.arcsin(np.clip(rays[..., 2], -1, 1))
    lon1 = lon - math.radians(y)
    vector = np.stack([np.cos(lat) * np.sin(lon1), -np.sin(lat), np.cos(lat) * np.cos(lon1)], axis=-1)
    a_, c_ = -math.radians(p), -math.radians(r)
    mx = np.array([[1, 0, 0], [0, math.cos(a_), math.sin(a_)], [0, -math.sin(a_), math.cos(a_)]])
    mz = np.array([[math.cos(c_), math.sin(c_), 0], [-math.sin(c_), math.cos(c_), 0], [0, 0, 1]])
    m = mx @ mz
    v2 = np.einsum("ji,...j->...i", m, vector)  # matrix_inv_mult: M^T v
    h = np.hypot(v2[..., 0], v2[..., 1])
    alpha = np.arctan2(h, v2[..., 2])
    f = SIDE / math.radians(HFOV)
    ideal = f * alpha
    big_r = ideal / (SIDE / 2)
    radius = ideal * (A * big_r**3 + B * big_r**2 + C * big_r + (1 - A - B - C))
    h = np.maximum(h, 1e-12)
    uv = np.stack([radius * v2[..., 0] / h + d + SIDE / 2 - 0.5, radius * v2[..., 1] / h + e + SIDE / 2 - 0.5], -1)
    seen = (alpha <= math.radians(HFOV) / 2) & np.all((uv >= -0.5) & (uv <= SIDE - 0.5), axis=-1)
    return np.where(seen[..., None], uv, np.nan)


@pytest.fixture(scope="module")
def project(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return pto(tmp_path_factory.mktemp("pto") / "gear360.pto")


@pytest.mark.slow
def test_a_hugin_project_of_two_fisheyes_is_a_rig_of_its_lenses(project: Path) -> None:
    """Each camera's equirect map lies within 0.05 px of PanoTools' stack over its lens's field (measured
    0.004 px), covering 99.5% of it or more (measured 99.9%); each looks yaw -y, pitch p, roll r (panomap's, of
    PanoTools' y, p, r)."""
    rig = rig_of_pto(project, fov_rad=math.radians(HFOV))
    assert rig.names == ("cam0", "cam1") and rig.info["source"]["format"] == "hugin"
    maps = camera_maps(rig, EquirectView(size=(1440, 720)))
    rays = equirect_rays(1440, 720)
    for table, map_uv, lens in zip(rig.tables, maps, LENSES, strict=True):
        y, p, r = lens[:3]
        expected_angles = np.radians([(-y) % 360, p, r])
        assert np.allclose(table.model.orientation, expected_angles, atol=1e-9)
        expected = panotools_pixels(rays, lens)
        field = np.all(np.isfinite(expected), axis=-1)
        both = field & np.all(np.isfinite(map_uv), axis=-1)
        # The table stops at the field's edge: the last half entry before it has no neighbour to interpolate.
        assert both.sum() / field.sum() > 0.995
        errors = np.hypot(*np.moveaxis(map_uv[both] - expected[both], -1, 0))
        assert errors.max() < 0.05, errors.max()


@pytest.mark.slow
def test_the_import_makes_the_rig_and_refuses_what_it_does_not_read(project: Path, tmp_path: Path) -> None:
    out = tmp_path / "rig.npz"
    result = run("import", project, "-o", out, "--side-by-side", "--fov", str(HFOV))
    assert result.exit_code == 0, result.output + result.stderr
    rig = load_rig(out)
    parameters = rig.tables[1].info["import"]["parameters"]
    assert rig.offsets == ((0, 0), (SIDE, 0)) and rig.tables[1].info["import"]["model"] == "panotools-fisheye"
    assert (parameters["cx"], parameters["cy"]) == (SIDE / 2 - 0.5 - 9.0, SIDE / 2 - 0.5 + 4.5)
    assert parameters["f"] == pytest.approx(SIDE / math.radians(HFOV)) and parameters["a"] == A
    one = run("import", project, "-o", tmp_path / "one.npz", "--camera-name", "1", "--orientation", "0", "0", "0")
    assert one.exit_code == 0, one.output + one.stderr
    assert_one_line_error(run("import", project, "-o", out, "--orientation", "0", "0", "0"), "--orientation",
                          exit_code=2)  # fmt: skip
    equirect = pto(tmp_path / "erect.pto", projection=4)
    assert_one_line_error(run("import", equirect, "-o", out), "projection f4 (equirectangular) is not read")
    sheared = tmp_path / "sheared.pto"
    sheared.write_text(project.read_text().replace(" g0 ", " g0.5 ", 1))
    assert_one_line_error(run("import", sheared, "-o", out), "shear g is 0.5")


def quaternion(axis: tuple[float, float, float], angle_deg: float) -> list[float]:
    """(x, y, z, w) of a turn by ``angle_deg`` about ``axis``."""
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    half = math.radians(angle_deg) / 2
    return [*(k * math.sin(half)), math.cos(half)]


@pytest.mark.slow
def test_a_basalt_calibration_of_two_cameras_is_a_rig_placed_by_t_imu_cam(tmp_path: Path) -> None:
    """Two kb4 cameras whose T_imu_cam turn them 30 deg and 180 + 30 deg about the IMU's y axis, 0.1 m apart:
    camera 1 sits, relative to camera 0, turned 180 deg about camera 0's down axis, 0.1 m along camera 0's
    x (as the poses written out say), with camera 0 where --orientation and --camera put it."""
    intrinsics = {"fx": 280.0, "fy": 280.0, "cx": 479.5, "cy": 479.5, "k1": 0.0, "k2": 0.0, "k3": 0.0, "k4": 0.0}
    poses = []
    for angle, x in ((30.0, 0.0), (210.0, 0.1)):
        q = quaternion((0, 1, 0), angle)
        c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
        # camera 0's x axis in the IMU frame is R_0 e_x = (cos 30, 0, -sin 30): put camera 1 0.1 m along it.
        p = [x * c, 0.0, -x * s]
        poses.append(dict(zip(("px", "py", "pz", "qx", "qy", "qz", "qw"), [*p, *q], strict=True)))
    data = {"value0": {"T_imu_cam": poses, "intrinsics": [{"camera_type": "kb4", "intrinsics": intrinsics}] * 2,
                       "resolution": [[960, 960], [960, 960]]}}  # fmt: skip
    path = tmp_path / "calibration.json"
    path.write_text(json.dumps(data))
    rig = rig_of_basalt(path, orientation_rad=(math.radians(20), 0.0, 0.0), camera_position=(1.0, 2.0, 0.5))
    yaws = [math.degrees(table.model.orientation[0]) for table in rig.tables]
    assert np.allclose(yaws, [20.0, 200.0], atol=1e-9)
    assert np.allclose([table.model.orientation[1:] for table in rig.tables], 0.0, atol=1e-9)
    right0 = np.array([math.sin(math.radians(20)), -math.cos(math.radians(20)), 0.0])
    assert np.allclose(rig.tables[1].camera_position, np.array([1.0, 2.0, 0.5]) + 0.1 * right0, atol=1e-12)
    forward = rig.tables[1].model.pixels(*azimuth_elevation(np.array([-math.cos(0.349066), -math.sin(0.349066), 0])))
    assert np.allclose(forward, (479.5, 479.5), atol=1e-4)
    result = run("import", path, "-o", tmp_path / "rig.npz")
    assert result.exit_code == 0 and "rig of 2 cameras" in result.output, result.output + result.stderr
