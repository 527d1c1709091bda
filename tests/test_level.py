"""``panomap level`` (issue 51): pitch and roll from the pictures' vertical lines, the yaw kept, the stated
certainty honest.

Ground truth is made here, not by the code under test: a world whose vertical edges are known (an
equirectangular picture: a vertical world line is one of its columns) or a real 360-degree photograph
(``../shared/data/panoramas``, skipped where absent), seen through the ideal equidistant fisheye of
``test_orientation`` at a known orientation, rendered with ``cv2.remap`` from closed-form rays.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from panomap.calibrate.level import level_table
from panomap.errors import PanomapError
from test_orientation import CX, CY, F_PX, HALF_FOV_DEG, HEIGHT, WIDTH, conventions_axes, oriented_table, write_camchain

from helpers import assert_one_line_error, run

PANORAMAS = Path(__file__).resolve().parents[2] / "shared" / "data" / "panoramas"


def render(equirect: np.ndarray, orientation: tuple[float, float, float]) -> np.ndarray:
    """The equidistant fisheye's picture of a world painted by ``equirect`` (column 0 at azimuth +180 deg,
    azimuth falling to the right; row 0 the zenith), looking along ``orientation`` (deg)."""
    u, v = np.meshgrid(np.arange(WIDTH, dtype=float), np.arange(HEIGHT, dtype=float))
    x, y = u - CX, v - CY
    r = np.maximum(np.hypot(x, y), 1e-9)
    alpha = r / F_PX
    camera = np.stack([np.sin(alpha) * x / r, np.sin(alpha) * y / r, np.cos(alpha)], axis=-1)
    world = camera @ conventions_axes(*orientation).T
    azimuth = np.arctan2(world[..., 1], world[..., 0])
    elevation = np.arcsin(np.clip(world[..., 2], -1, 1))
    height, width = equirect.shape[:2]
    map_x = ((math.pi - azimuth) / (2 * math.pi) * width - 0.5).astype(np.float32)
    map_y = ((math.pi / 2 - elevation) / math.pi * height - 0.5).astype(np.float32)
    picture = cv2.remap(equirect, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
    picture[alpha > math.radians(HALF_FOV_DEG)] = 0
    return picture


def striped_world(seed: int = 0) -> np.ndarray:
    """A 2048 x 1024 equirectangular world of vertical edges (bands of grey at random azimuths, each over a
    random span of elevations) on a faint random texture."""
    rng = np.random.default_rng(seed)
    world = cv2.GaussianBlur(rng.uniform(90, 110, (1024, 2048)).astype(np.float32), (0, 0), 4)
    for _ in range(40):
        column, width = int(rng.integers(0, 2000)), int(rng.integers(8, 40))
        top, bottom = sorted(rng.integers(100, 924, 2))
        world[top:bottom, column : column + width] += rng.choice([-60.0, 60.0])
    return np.clip(world, 0, 255).astype(np.uint8)


def axis_error_deg(found: tuple[float, float, float], truth: tuple[float, float, float]) -> float:
    """How far (deg) the levelled camera's vertical lies from the truth's, in the camera's axes (yaw-free)."""
    up_found = conventions_axes(*found).T @ [0.0, 0.0, 1.0]
    up_true = conventions_axes(*truth).T @ [0.0, 0.0, 1.0]
    return math.degrees(math.acos(min(1.0, float(up_found @ up_true))))


@pytest.fixture(scope="module")
def camchain(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_camchain(tmp_path_factory.mktemp("level") / "camchain.yaml")


@pytest.mark.parametrize(
    ("truth", "start"),
    [((20.0, 5.0, -3.0), (20.0, 12.0, 3.0)), ((100.0, -55.0, 12.0), (100.0, -48.0, 4.0))],
    ids=["ahead", "down-askew"],
)
def test_level_finds_the_vertical_of_a_world_of_vertical_edges(camchain: Path, truth, start) -> None:  # type: ignore[no-untyped-def]
    """From 8-10 deg off, the vertical is found within 0.1 deg (measured 0.01-0.03), the stated 95% bound holds
    it, and the yaw is the start's."""
    picture = render(striped_world(), truth)
    result = level_table(oriented_table(camchain, start), [picture])
    error = axis_error_deg(result.orientation_deg, truth)
    assert error < 0.1
    assert error <= result.uncertainty_deg
    assert result.orientation_deg[0] == pytest.approx(start[0])
    assert result.vertical_lines >= 10


@pytest.mark.slow
def test_a_picture_without_verticals_is_refused(camchain: Path, tmp_path: Path) -> None:
    """A world of horizontal bands only: refused in one line that says no vertical lines were found."""
    world = np.full((1024, 2048), 100, np.uint8)
    for row in range(150, 900, 90):
        world[row : row + 30] = 180
    picture = render(world, (0.0, 0.0, 0.0))
    with pytest.raises(PanomapError, match="vertical lines found"):
        level_table(oriented_table(camchain, (0.0, 5.0, 0.0)), [picture])
    table, image = tmp_path / "t.npz", tmp_path / "flat.png"
    cv2.imwrite(str(image), picture)
    assert run("import", camchain, "-o", table, "--orientation", "0", "5", "0").exit_code == 0
    assert_one_line_error(run("level", table, image, "-o", tmp_path / "out.npz"), "vertical lines found")
    assert not (tmp_path / "out.npz").exists()


@pytest.mark.slow
@pytest.mark.skipif(not PANORAMAS.is_dir(), reason=f"no panoramas at {PANORAMAS} (../shared is not beside the repo)")
@pytest.mark.parametrize("name", ["sun360_hotelroom_hohonet.png", "eso_alma_correlator_room.jpg"])
def test_level_on_real_photographs(camchain: Path, name: str) -> None:
    """Real rooms re-projected through the fisheye looking ahead and down: the vertical within 0.6 deg of the
    photograph's frame (measured 0.2-0.47 deg; the photographs' own verticals lean 0.2-0.3 deg the same way
    in every view of them, which no picture of them can tell)."""
    photograph = cv2.imread(str(PANORAMAS / name))
    for truth, start in (((20.0, 5.0, -3.0), (20.0, 11.0, 2.0)), ((0.0, -60.0, 0.0), (0.0, -54.0, 4.0))):
        result = level_table(oriented_table(camchain, start), [render(photograph, truth)])
        assert axis_error_deg(result.orientation_deg, truth) < 0.6
