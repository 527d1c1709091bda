"""Two lenses a little apart: parallax is not read as a turn (issue 52, item 4 (a); :mod:`panomap.rig.parallax`).

Ground truth from outside the code under test: points at known depths seen from two known lens centres (closed
form: each ray the unit vector from its centre), and the bundled room rendered through the demo's dual fisheye
(:mod:`panomap.simulate.lens_scenes`) with its back lens 2 cm behind the front one, turned by a known rotation.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from panomap.camera.orientation import rotation_from_vector
from panomap.cli.demo_inputs import BACK, LENS, camchain_text
from panomap.interop.rig_of_camchain import rig_of_camchain
from panomap.rig.learn import learn_rotations, rotation_of
from panomap.rig.parallax import settle
from panomap.simulate import load_room
from panomap.simulate.lens_scenes import camera_axes, render_lens

SCALE_PX_PER_RAD = 300.0
NOISE_PX = 0.2


def angle_deg(rotation: np.ndarray) -> float:  # type: ignore[type-arg]
    return math.degrees(math.acos(min(1.0, (float(np.trace(rotation)) - 1) / 2)))


def ring_matches(depths: np.ndarray, baseline_m: float, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[type-arg]
    """Camera i's world rays and camera j's (camera j's axes the world's) of points all round the ring square to
    +X (latitudes within 12 deg of it) at ``depths`` (m) from camera i at the origin, camera j ``baseline_m``
    along -X (behind it: each lens ahead of the other along its own axis), camera j's rays with NOISE_PX noise."""
    rng = np.random.default_rng(seed)
    n = len(depths)
    lon, lat = rng.uniform(0, 2 * math.pi, n), np.radians(rng.uniform(-12, 12, n))
    a = np.stack([np.sin(lat), np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon)], axis=1)
    points = a * depths[:, None]
    b = points - np.array([-baseline_m, 0.0, 0.0])
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    b += rng.normal(0, NOISE_PX / SCALE_PX_PER_RAD, b.shape)
    return a, b / np.linalg.norm(b, axis=1, keepdims=True)


@pytest.mark.parametrize("far", [True, False])
def test_the_tilt_is_bounded_by_the_far_matches_and_the_bound_holds_the_truth(far: bool) -> None:
    """Camera j given 0.5 deg off (tilted, as least squares reads parallax): far points all round the ring pin it
    within 0.05 deg, the bound under 0.1 deg (measured 0.024 / 0.051); points 1-3 m away seen 2 cm apart
    (parallax 0.4-1.1 deg) bound it only loosely: the 0.5 deg turn is feasible, kept, and the bound holds it
    (measured 1.19 deg)."""
    rng = np.random.default_rng(5)
    depths = np.full(600, 1e6) if far else rng.uniform(1.0, 3.0, 600)
    a, b = ring_matches(depths, 0.02)
    off = rotation_from_vector(np.radians([0.0, 0.3, -0.4]))
    found = settle(a, b, off, np.array([-1.0, 0.0, 0.0]), SCALE_PX_PER_RAD, 12 / SCALE_PX_PER_RAD)
    error = angle_deg(found.rotation)
    bound = math.hypot(math.degrees(found.tilt_bound_rad), 3 * math.degrees(found.roll_sigma_rad))
    assert error <= bound
    if far:
        assert error < 0.05 and bound < 0.1 and found.pinned
    else:
        assert not found.pinned and bound < 2.0
        assert np.array_equal(found.rotation, off)  # kept whole, as the docstring says: its tilt is feasible


def test_parallax_below_zero_all_round_is_said_not_forced() -> None:
    """Far matches whose parallax is 1 px below zero all round (as a lens 1% long leaves across the ring): no tilt
    lets them be at least zero, so the least squares' turn stands untouched, unbounded, and the reason is said."""
    a, b = ring_matches(np.full(400, 1e6), 0.02)
    b = b + 1.0 / SCALE_PX_PER_RAD * np.array([-1.0, 0.0, 0.0])
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    start = rotation_from_vector(np.radians([0.0, 0.1, 0.0]))
    found = settle(a, b, start, np.array([-1.0, 0.0, 0.0]), SCALE_PX_PER_RAD, 12 / SCALE_PX_PER_RAD)
    assert found.unbounded and math.isinf(found.tilt_bound_rad) and "below zero" in found.why
    assert np.array_equal(found.rotation, start)


@pytest.mark.slow
def test_a_near_room_seen_by_lenses_2_cm_apart_is_not_read_as_a_turn(tmp_path: Path) -> None:
    """The demo's dual fisheye in the bundled room (walls 1-3 m away), its back lens 2 cm behind the front one and
    turned 0.9 deg off the camchain: least squares turned it 0.89 deg from the truth stating 0.10 deg (1 sigma);
    that turn is among the feasible ones, kept, and now stated with its bound (measured 4.8 deg, 1-sigma 2.4): the
    error within both, and the report says the tilt is not pinned and what would pin it."""
    room = load_room()
    path = tmp_path / "dual.yaml"
    path.write_text(camchain_text(LENS))
    axes = camera_axes(0.0, 0.0, 0.0)
    off = rotation_from_vector(np.radians([0.5, -0.6, 0.4]))
    at = np.array([2.7, 2.15, 1.5])
    frame = np.concatenate(
        [render_lens(room, LENS, at, axes), render_lens(room, LENS, at - 0.02 * axes[:, 2], off @ axes @ BACK.T)],
        axis=1,
    )
    rig = rig_of_camchain(path, side_by_side=True, fov_rad=2 * LENS.half_fov_rad)
    learned = learn_rotations(rig, frame)
    error = angle_deg(learned.rotations[1] @ rotation_of(rig.tables[1]).T @ off.T)
    fit = learned.parallax
    assert fit is not None and not fit.pinned
    assert error <= fit.bound_deg and error <= 2 * learned.uncertainty_deg[1]
    assert "a picture with far objects" in learned.describe()[-1]
