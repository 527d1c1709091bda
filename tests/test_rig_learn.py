"""A rig's rotations learned from its pictures (issue 52, item 4 (a)).

Ground truth from outside the code under test: a fine-grained textured world (equirectangular, at infinity)
rendered through two ideal equidistant lenses back to back (``test_rig``'s closed form), the second turned by a
known rotation from where the rig's camchain puts it; what the learning finds is compared with that rotation.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from panomap.camera.orientation import rotation_from_vector
from panomap.errors import PanomapError
from panomap.interop.orient import turn_table
from panomap.interop.rig_of_camchain import rig_of_camchain
from panomap.rig import load_rig
from panomap.rig.learn import learn_rotations, rotation_of, turned_table
from panomap.rig.overlap import cornerness, learn_with_overlap, shifted_table
from panomap.views import EquirectView, build_map
from test_orientation import conventions_axes, equirect_rays
from test_rig import BACK_TO_BACK, CX, CY, F_PX, HALF_FOV, SIDE, camchain, chain_truth, lens_pixels, render_lens

from helpers import assert_one_line_error, run

# The start's error: camera 1 is turned 2.6 deg about a skew axis from where the camchain puts it.
OFF = rotation_from_vector(np.radians([1.5, -1.8, 1.2]))


def angle_deg(rotation: np.ndarray) -> float:  # type: ignore[type-arg]
    return math.degrees(math.acos(min(1.0, (float(np.trace(rotation)) - 1) / 2)))


def fine_world(seed: int = 3) -> np.ndarray:  # type: ignore[type-arg]
    """A 4096 x 2048 world of contrasty noise blurred by 2.5 px: features at every scale SIFT looks at."""
    rng = np.random.default_rng(seed)
    grey = cv2.GaussianBlur(rng.uniform(0, 255, (2048, 4096)).astype(np.float32), (0, 0), 2.5)
    grey = np.clip((grey - grey.mean()) * 6 + 128, 0, 255).astype(np.uint8)
    return cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR)


@pytest.fixture(scope="module")
def dual(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, np.ndarray]:  # type: ignore[type-arg]
    """The camchain of the pair back to back, and a frame of the fine world through the pair, camera 1 off."""
    path = camchain(tmp_path_factory.mktemp("learn") / "dual.yaml", [BACK_TO_BACK])
    truth = chain_truth(conventions_axes(0, 0, 0), np.zeros(3), [BACK_TO_BACK])
    world = fine_world()
    frame = np.concatenate([render_lens(world, truth[0][0]), render_lens(world, OFF @ truth[1][0])], axis=1)
    return path, frame


@pytest.mark.slow
def test_the_rotation_between_two_lenses_is_learned_within_0_05_deg(dual: tuple[Path, np.ndarray]) -> None:  # type: ignore[type-arg]
    """Started 2.6 deg off, the learned turn of camera 1 is within 0.05 deg of the truth (measured 0.0004), with
    thousands of inliers and p90 residual under 0.5 px (measured 0.16: SIFT's localisation); camera 0 stays."""
    path, frame = dual
    rig = rig_of_camchain(path, side_by_side=True, fov_rad=2 * HALF_FOV)
    learned = learn_rotations(rig, frame)
    assert np.array_equal(learned.rotations[0], rotation_of(rig.tables[0]))
    found = learned.rotations[1] @ rotation_of(rig.tables[1]).T
    assert angle_deg(found @ OFF.T) < 0.05
    assert abs(learned.turned_deg[1] - angle_deg(OFF)) < 0.05
    (pair,) = learned.pairs
    assert pair.inliers > 1000 and pair.residual_px_p90 < 0.5
    assert 0 < learned.uncertainty_deg[1] < 0.01
    # The far world all round the ring pins the tilt; the bound (measured 0.016 deg) holds the error.
    assert learned.parallax is not None and learned.parallax.pinned
    assert angle_deg(found @ OFF.T) <= learned.parallax.bound_deg < 0.05
    # The learned rig's table of camera 1 is its lens where it truly looks.
    assert np.allclose(rotation_of(learned.rig.tables[1]), learned.rotations[1], atol=1e-12)


def test_a_turned_table_is_the_table_made_at_that_pose(dual: tuple[Path, np.ndarray]) -> None:  # type: ignore[type-arg]
    """An imported table turned by resampling its own entries: its equirect map lies within 0.05 px (p99) of the
    table the camchain makes at the turned pose (measured 0.01: bilinear twice over one entry per pixel)."""
    path, _ = dual
    rig = rig_of_camchain(path, side_by_side=True, fov_rad=2 * HALF_FOV)
    turned = turned_table(rig.tables[1], OFF @ rotation_of(rig.tables[1]))
    truth = chain_truth(conventions_axes(0, 0, 0), np.zeros(3), [BACK_TO_BACK])
    view = EquirectView(size=(720, 360))
    got = build_map(turned, view.resolved(turned))
    expected = lens_pixels(equirect_rays(720, 360), OFF @ truth[1][0])
    both = np.all(np.isfinite(got), axis=-1) & np.all(np.isfinite(expected), axis=-1)
    assert both.sum() > 0.45 * both.size
    errors = np.hypot(*np.moveaxis(got[both] - expected[both], -1, 0))
    assert np.percentile(errors, 99) < 0.05


@pytest.mark.slow
def test_too_few_matching_features_are_refused_in_one_line(dual: tuple[Path, np.ndarray], tmp_path: Path) -> None:  # type: ignore[type-arg]
    """Featureless pictures: the library refuses naming the pair, and so does ``rig learn``, in one line."""
    path, _ = dual
    rig = rig_of_camchain(path, side_by_side=True, fov_rad=2 * HALF_FOV)
    flat = np.full((SIDE, 2 * SIDE, 3), 128, np.uint8)
    with pytest.raises(PanomapError, match="too few features match between cam0 and cam1"):
        learn_rotations(rig, flat)
    out = tmp_path / "rig.npz"
    assert run("import", path, "-o", out, "--side-by-side", "--fov", "190").exit_code == 0
    picture = tmp_path / "flat.png"
    cv2.imwrite(str(picture), flat)
    assert_one_line_error(run("rig", "learn", out, picture, "-o", tmp_path / "x.npz"), "too few features match")
    assert not (tmp_path / "x.npz").exists()


@pytest.mark.slow
def test_rig_make_and_rig_learn_at_the_command_line(dual: tuple[Path, np.ndarray], tmp_path: Path) -> None:  # type: ignore[type-arg]
    """``rig make`` of two tables side by side, then ``rig learn`` of their frame: the learned file's camera 1
    within 0.05 deg of the truth, its report printed."""
    path, frame = dual
    for k in (0, 1):
        yaw = 0 if k == 0 else 180
        result = run("import", path, "--camera-name", f"cam{k}", "-o", tmp_path / f"cam{k}.npz", "--orientation", yaw,
                     0, 0, "--outer-radius", F_PX * HALF_FOV)  # fmt: skip
        assert result.exit_code == 0, result.output
    made = tmp_path / "made.npz"
    result = run("rig", "make", tmp_path / "cam0.npz", tmp_path / "cam1.npz", "-o", made, "--side-by-side")
    assert result.exit_code == 0, result.output
    picture = tmp_path / "frame.png"
    cv2.imwrite(str(picture), frame)
    out = tmp_path / "learned.npz"
    result = run("rig", "learn", made, picture, "-o", out)
    assert result.exit_code == 0, result.output + result.stderr
    assert "inliers" in result.stdout and "uncertainty" in result.stdout
    assert "not kept" in result.stdout  # the overlap's tiles: nothing decentred
    start, learned = load_rig(made), load_rig(out)
    found = rotation_of(learned.tables[1]) @ rotation_of(start.tables[1]).T
    assert angle_deg(found @ OFF.T) < 0.05


# Camera 1's picture moved by this (px): its lens 2.7 px off the centre its calibration says, as the Ricoh Theta's
# back lens seemed to be (docs/rigs.md, Figures).
DECENTRED = np.array([2.5, -1.0])


@pytest.mark.slow
def test_a_decentred_lens_is_found_by_the_overlap_and_its_table_moved(dual: tuple[Path, np.ndarray]) -> None:  # type: ignore[type-arg]
    """Camera 1's picture moved by 2.7 px (its calibration's centre off by that): the features alone leave the
    pair's residual p90 over 1 px (measured 2.68, the rotation 0.54 deg off: no rotation absorbs a move); the
    overlap's tiles find the move within 0.3 px (measured 0.00), keep it (left-out sectors' along-ring p90 3.16 ->
    0.19 px), the learned rig's table of camera 1 carries it, and the rotation learned anew is within 0.05 deg of
    the truth (measured 0.0006), p90 under 0.5 px (measured 0.18)."""
    path, frame = dual
    rig = rig_of_camchain(path, side_by_side=True, fov_rad=2 * HALF_FOV)
    moved = frame.copy()
    shift = np.float64([[1, 0, DECENTRED[0]], [0, 1, DECENTRED[1]]])
    moved[:, SIDE:] = cv2.warpAffine(frame[:, SIDE:], shift, (SIDE, SIDE), flags=cv2.INTER_CUBIC)
    before = learn_rotations(rig, moved)
    assert before.pairs[0].residual_px_p90 > 1.0, before.pairs[0].describe()
    learned = learn_with_overlap(rig, moved)
    fit = learned.overlap
    assert fit is not None and fit.kept, learned.describe()
    assert np.hypot(*(np.asarray(fit.centre_px) - DECENTRED)) < 0.3, fit.describe()
    assert fit.held_centre_p90_px < 0.5 * fit.held_roll_p90_px, fit.describe()
    found = learned.rotations[1] @ rotation_of(rig.tables[1]).T
    assert angle_deg(found @ OFF.T) < 0.05, angle_deg(found @ OFF.T)
    assert learned.pairs[0].residual_px_p90 < 0.5, learned.pairs[0].describe()
    table = learned.rig.tables[1]
    assert np.allclose(table.info["centre moved px"], fit.centre_px)


@pytest.mark.slow
def test_a_centred_lens_keeps_its_table_and_the_features_rotation(dual: tuple[Path, np.ndarray]) -> None:  # type: ignore[type-arg]
    """Nothing decentred: the overlap's tiles fit a move of camera 1's centre under 0.2 px (measured 0.00) that
    predicts left-out sectors no better (along-ring p90 0.06 px either way), so it is not kept: the rig and
    rotations are the features' (within 0.05 deg of the truth)."""
    path, frame = dual
    rig = rig_of_camchain(path, side_by_side=True, fov_rad=2 * HALF_FOV)
    learned = learn_with_overlap(rig, frame)
    fit = learned.overlap
    assert fit is not None and not fit.kept, learned.describe()
    assert np.hypot(*fit.centre_px) < 0.2, fit.describe()
    features = learn_rotations(rig, frame)
    assert np.array_equal(learned.rotations[1], features.rotations[1])
    assert "centre moved px" not in learned.rig.tables[1].info
    found = learned.rotations[1] @ rotation_of(rig.tables[1]).T
    assert angle_deg(found @ OFF.T) < 0.05


@pytest.mark.slow
def test_a_moved_table_draws_the_moved_picture(dual: tuple[Path, np.ndarray]) -> None:  # type: ignore[type-arg]
    """:func:`shifted_table` of an imported table moves every entry by the move, and records it; turned through its
    calibration (``rig learn``'s way) or by resampling, it stays moved (within the resampling's 0.05 px)."""
    path, _ = dual
    table = rig_of_camchain(path, side_by_side=True, fov_rad=2 * HALF_FOV).tables[1]
    moved = shifted_table(table, DECENTRED)
    both = np.all(np.isfinite(table.entries), axis=-1)
    assert np.allclose(moved.entries[both] - table.entries[both], DECENTRED, atol=1e-4)
    assert moved.info["centre moved px"] == tuple(DECENTRED)
    assert np.allclose(moved.model.centre, np.asarray(table.model.centre) + DECENTRED)
    rotation = OFF @ rotation_of(table)
    for turn, tolerance in ((turn_table, 1e-3), (turned_table, 0.05)):
        plain, kept = turn(table, rotation), turn(moved, rotation)
        both = np.all(np.isfinite(plain.entries), axis=-1) & np.all(np.isfinite(kept.entries), axis=-1)
        assert np.percentile(np.abs(kept.entries[both] - plain.entries[both] - DECENTRED), 99) < tolerance


INSTA360 = Path(__file__).resolve().parents[2] / "shared" / "data" / "rigs" / "insta360_air_dualfisheye"
INSTA360_CHAIN = """
cam0: {camera_model: pinhole, intrinsics: [283.6, 283.6, 489.8, 479.0], distortion_model: equidistant,
       distortion_coeffs: [0, 0, 0, 0], resolution: [960, 960]}
cam1: {camera_model: pinhole, intrinsics: [283.6, 283.6, 489.8, 479.0], distortion_model: equidistant,
       distortion_coeffs: [0, 0, 0, 0], resolution: [960, 960],
       T_cn_cnm1: [[-1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1, 0], [0, 0, 0, 1]]}
"""


@pytest.mark.slow
@pytest.mark.skipif(not INSTA360.is_dir(), reason=f"the shared Insta360 frames are not at {INSTA360}")
def test_a_real_insta360_frame_turns_its_back_lens_as_docs_say(tmp_path: Path) -> None:
    """docs/rigs.md's Insta360 Air street frame, through its author's hand-tuned model (lenses exactly back to
    back): the overlap turns the back lens 3.6 deg (measured 3.59; the pair's 180 deg start less its turn), from
    61 inliers of 131 matches, p90 3.4 px (the hand-tuned model, not the rotation, limits it); its tiles keep no
    move of the centre."""
    (tmp_path / "dual.yaml").write_text(INSTA360_CHAIN)
    rig = rig_of_camchain(tmp_path / "dual.yaml", side_by_side=True, fov_rad=math.radians(190))
    frame = cv2.imread(str(INSTA360 / "images" / "insta360-still-002.png"))
    learned = learn_rotations(rig, frame)
    (pair,) = learned.pairs
    turned = learned.turned_deg[1]
    assert 3.0 < turned < 4.2, turned
    assert pair.inliers >= 45 and pair.residual_px_p90 < 4.0, pair.describe()
    # Its overlap's tiles: a move of the back lens's centre predicts left-out sectors no better (measured 4.0 px
    # by a roll alone, far worse with the move): not kept, the features' rotation stands.
    checked = learn_with_overlap(rig, frame)
    assert checked.overlap is not None and not checked.overlap.kept, checked.overlap
    assert np.array_equal(checked.rotations[1], learned.rotations[1])


@pytest.mark.parametrize("angle_deg", [0.0, 30.0, 90.0, 137.0])
def test_a_tile_holding_an_edge_alone_is_not_textured_both_ways(angle_deg: float) -> None:
    """:func:`cornerness` in closed form: a straight edge (a blurred step at any angle) has one gradient direction,
    so the structure tensor's smaller eigenvalue is 0 (under 0.02 after the pixel grid's sampling); a checkerboard
    corner's gradients run both ways equally (1 in the limit, over 0.8 here); a flat tile has none (0)."""
    v, u = np.mgrid[0:16, 0:16].astype(np.float64) - 7.5
    a = math.radians(angle_deg)
    across = u * math.cos(a) + v * math.sin(a)
    along = -u * math.sin(a) + v * math.cos(a)
    edge = 100 + 60 * np.tanh(across / 1.5)
    corner = 100 + 60 * np.tanh(across / 1.5) * np.tanh(along / 1.5)
    assert cornerness(edge) < 0.02
    assert cornerness(corner) > 0.8
    assert cornerness(np.full((16, 16), 80.0)) == 0.0


@pytest.mark.slow
def test_a_lens_1_percent_long_still_gives_a_rotation_whose_residuals_say_so(dual: tuple[Path, np.ndarray]) -> None:  # type: ignore[type-arg]
    """Camera 1's table 1% longer than the lens that drew the frame: matches sit at the robust weights' cut-off and
    flipped in and out, so Gauss-Newton wandered by ~5e-5 rad and gave up ("did not converge in 50 steps"); with
    the weights kept after 20 steps it settles. The lens is then 0.95 deg off at 95 deg from its axis; the turn
    takes up no more than that (measured 1.01 deg off the truth: the features are not spread evenly round the
    ring), and the residual says the lens is off (p90 over 1 px)."""
    path, frame = dual
    text = path.read_text().split("cam1:")
    here = f"intrinsics: [{F_PX}, {F_PX}, {CX}, {CY}]"
    longer = f"intrinsics: [{F_PX * 1.01}, {F_PX * 1.01}, {CX}, {CY}]"
    assert here in text[1]
    path_long = path.with_name("long.yaml")
    path_long.write_text(text[0] + "cam1:" + text[1].replace(here, longer))
    rig = rig_of_camchain(path_long, side_by_side=True, fov_rad=2 * HALF_FOV)
    learned = learn_rotations(rig, frame)
    found = learned.rotations[1] @ rotation_of(rig.tables[1]).T
    assert angle_deg(found @ OFF.T) < 1.5, angle_deg(found @ OFF.T)
    assert learned.pairs[0].residual_px_p90 > 1.0, learned.pairs[0].describe()
