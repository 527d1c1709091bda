"""Rigs (issue 52): several cameras in one world, imported from a Kalibr camchain, their views blended.

Ground truth is written here from the conventions: ideal equidistant lenses (Kalibr ``pinhole`` +
``equidistant`` with zero coefficients: a ray ``alpha`` from the axis lands ``f alpha`` from the principal point)
whose frames follow the camchain's ``x_n = R x_(n-1) + t``: camera n's axes ``G_n = G_(n-1) R^T`` and centre
``c_n = c_(n-1) - G_(n-1) R^T t``, camera 0's axes from the perspective view's yaw/pitch/roll formula.
"""

from __future__ import annotations

import io
import math
import zipfile
from pathlib import Path

import cv2
import numpy as np
import pytest

from panomap.errors import PanomapError
from panomap.interop.rig_of_camchain import rig_of_camchain
from panomap.rig import RigRemapper, camera_maps, load_rig, save_rig
from panomap.views import EquirectView, FloorView, GenericPanorama
from test_orientation import conventions_axes, equirect_rays

from helpers import assert_one_line_error, run

F_PX, CX, CY, SIDE = 283.6, 479.5, 479.5, 960
HALF_FOV = math.radians(95.0)
BACK_TO_BACK = [[-1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1, -0.02], [0, 0, 0, 1]]


def camchain(path: Path, poses: list[list[list[float]]]) -> Path:
    """A camchain of ``len(poses) + 1`` ideal equidistant lenses, camera n after the first at ``poses[n - 1]``."""
    lines = []
    for k in range(len(poses) + 1):
        lines += [
            f"cam{k}:",
            "  camera_model: pinhole",
            f"  intrinsics: [{F_PX}, {F_PX}, {CX}, {CY}]",
            "  distortion_model: equidistant",
            "  distortion_coeffs: [0.0, 0.0, 0.0, 0.0]",
            f"  resolution: [{SIDE}, {SIDE}]",
        ]
        if k:
            lines += ["  T_cn_cnm1:", *(f"  - {row}" for row in poses[k - 1])]
    path.write_text("\n".join(lines) + "\n")
    return path


def chain_truth(axes0: np.ndarray, centre0: np.ndarray, poses: list[list[list[float]]]) -> list[tuple]:  # type: ignore[type-arg]
    """Each camera's (axes, centre) from the chain, written out."""
    out = [(axes0, centre0)]
    for pose in poses:
        matrix = np.asarray(pose, dtype=float)
        rotation, translation = matrix[:3, :3], matrix[:3, 3]
        axes, centre = out[-1]
        out.append((axes @ rotation.T, centre - axes @ rotation.T @ translation))
    return out


def lens_pixels(rays: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """Pixels (..., 2) of world rays through an ideal lens with axes ``axes``; NaN beyond 95 deg or off its
    picture."""
    p = rays @ axes
    alpha = np.arccos(np.clip(p[..., 2] / np.linalg.norm(p, axis=-1), -1, 1))
    h = np.maximum(np.hypot(p[..., 0], p[..., 1]), 1e-12)
    uv = np.stack([CX + F_PX * alpha * p[..., 0] / h, CY + F_PX * alpha * p[..., 1] / h], axis=-1)
    seen = (alpha <= HALF_FOV) & np.all((uv >= -0.5) & (uv <= SIDE - 0.5), axis=-1)
    return np.where(seen[..., None], uv, np.nan)


def render_lens(world: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """An ideal lens's picture of a world painted by the equirectangular ``world`` (column 0 at azimuth +180
    deg, falling to the right; row 0 the zenith), black beyond 95 deg."""
    u, v = np.meshgrid(np.arange(SIDE, dtype=float), np.arange(SIDE, dtype=float))
    x, y = u - CX, v - CY
    r = np.maximum(np.hypot(x, y), 1e-9)
    alpha = r / F_PX
    rays = np.stack([np.sin(alpha) * x / r, np.sin(alpha) * y / r, np.cos(alpha)], axis=-1) @ axes.T
    azimuth = np.arctan2(rays[..., 1], rays[..., 0])
    elevation = np.arcsin(np.clip(rays[..., 2], -1, 1))
    height, width = world.shape[:2]
    map_x = ((math.pi - azimuth) / (2 * math.pi) * width - 0.5).astype(np.float32)
    map_y = ((math.pi / 2 - elevation) / math.pi * height - 0.5).astype(np.float32)
    picture = cv2.remap(world, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
    picture[alpha > HALF_FOV] = 0
    return picture


def textured_world(seed: int = 0) -> np.ndarray:
    """A 2048 x 1024 colour world of smooth blobs and sharp vertical and horizontal edges."""
    rng = np.random.default_rng(seed)
    world = cv2.GaussianBlur(rng.uniform(40, 215, (1024, 2048, 3)).astype(np.float32), (0, 0), 12)
    world = (world - world.mean()) * 3 + 128
    for _ in range(60):
        x, y = int(rng.integers(0, 2000)), int(rng.integers(100, 900))
        world[y : y + int(rng.integers(10, 80)), x : x + int(rng.integers(10, 80))] += rng.uniform(-60, 60, 3)
    return np.clip(world, 0, 255).astype(np.uint8)


@pytest.fixture(scope="module")
def dual(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return camchain(tmp_path_factory.mktemp("rig") / "dual.yaml", [BACK_TO_BACK])


@pytest.fixture(scope="module")
def dual_rig(dual: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The dual camchain imported as a rig file of one side-by-side frame (made once: tests copy what they change)."""
    out = tmp_path_factory.mktemp("rig") / "rig.npz"
    assert run("import", dual, "-o", out, "--side-by-side", "--fov", "190").exit_code == 0
    return out


@pytest.mark.slow
def test_a_camchain_places_every_camera_as_its_chain_says(tmp_path: Path) -> None:
    """Three lenses turned 120 deg apart about a tilted axis, with offsets: each camera's table looks along its
    chained axes from its chained centre (its forward ray lands on its principal point, its right ray to the
    right), camera 0 placed by the orientation and position given."""
    c, s = math.cos(2 * math.pi / 3), math.sin(2 * math.pi / 3)
    turn = [[c, 0, s, 0.05], [0, 1, 0, -0.01], [-s, 0, c, 0.03], [0, 0, 0, 1]]
    path = camchain(tmp_path / "three.yaml", [turn, turn])
    orientation = (30.0, -10.0, 5.0)
    rig = rig_of_camchain(
        path,
        orientation_rad=tuple(math.radians(a) for a in orientation),
        camera_position=(1.0, 2.0, 1.5),  # type: ignore[arg-type]
    )
    truth = chain_truth(conventions_axes(*orientation), np.array([1.0, 2.0, 1.5]), [turn, turn])
    for table, (axes, centre) in zip(rig.tables, truth, strict=True):
        assert np.allclose(table.camera_position, centre, atol=1e-12)
        from panomap.geometry import azimuth_elevation

        forward, right = (table.model.pixels(*azimuth_elevation(axes[:, 2] + 0.2 * axes[:, k])) for k in (2, 0))
        assert np.allclose(forward, (CX, CY), atol=1e-6)
        assert right[0] > CX + 50 and abs(right[1] - CY) < 1e-6


def test_each_camera_of_a_dual_fisheye_is_its_lens_and_the_pair_covers_the_sphere(dual: Path) -> None:
    """The equirectangular map of each camera of a back-to-back pair lies within 0.02 px (p99) of its ideal lens
    (measured 0.002), and the two together see every direction (the blend's weights sum to 1 everywhere)."""
    rig = rig_of_camchain(dual, side_by_side=True, fov_rad=2 * HALF_FOV)
    maps = camera_maps(rig, EquirectView(size=(1024, 512)))
    rays = equirect_rays(1024, 512)
    truth = chain_truth(conventions_axes(0, 0, 0), np.zeros(3), [BACK_TO_BACK])
    for map_uv, (axes, _) in zip(maps, truth, strict=True):
        expected = lens_pixels(rays, axes)
        both = np.all(np.isfinite(map_uv), axis=-1) & np.all(np.isfinite(expected), axis=-1)
        errors = np.hypot(*np.moveaxis(map_uv[both] - expected[both], -1, 0))
        assert np.percentile(errors, 99) < 0.02
        assert both.sum() / np.all(np.isfinite(expected), axis=-1).sum() > 0.99
    weights = RigRemapper(rig, maps, wrap=True).weights
    assert np.allclose(weights.sum(axis=0), 1.0, atol=1e-5)


@pytest.mark.slow
def test_the_blend_has_no_step_at_the_seam_with_one_lens_brighter(dual: Path) -> None:
    """A world rendered through the pair, lens 1 15% brighter, with noise: the blended panorama's change
    between neighbouring columns across the overlap is within 2 grey levels of the true world's (measured
    -0.4), where the unblended, unmatched layers step by more than 10 at the seam; the gains find the 15%."""
    rig = rig_of_camchain(dual, side_by_side=True, fov_rad=2 * HALF_FOV)
    world = textured_world()
    truth = chain_truth(conventions_axes(0, 0, 0), np.zeros(3), [BACK_TO_BACK])
    rng = np.random.default_rng(1)
    lenses = [render_lens(world, axes).astype(np.float32) for axes, _ in truth]
    lenses[1] *= 1.15
    frame = np.concatenate(lenses, axis=1) + rng.normal(0, 2, (SIDE, 2 * SIDE, 3))
    frame = np.clip(frame, 0, 255).astype(np.uint8)
    width, height = 2048, 1024
    remapper = RigRemapper(rig, camera_maps(rig, EquirectView(size=(width, height))), wrap=True)
    gains = remapper.gains(frame)
    assert 1.12 < float(np.mean(gains[0] / gains[1])) < 1.18
    blended = remapper(frame, gains).astype(float).mean(axis=2)
    expected = world.astype(float).mean(axis=2) * float(np.mean(gains[0]))
    longitude = math.pi - 2 * math.pi * (np.arange(width) + 0.5) / width
    seam = np.abs(np.abs(longitude) - math.pi / 2) < math.radians(6)
    rows = slice(height // 8, 7 * height // 8)

    def step(image: np.ndarray) -> float:
        return float(np.abs(np.diff(image[rows], axis=1))[:, seam[:-1]].mean())

    assert step(blended) <= step(expected) + 2.0
    # The hard seam without gains: the layers cut at +-90 deg.
    layers = [layer.astype(float).mean(axis=2) for layer in remapper.layers(frame)]
    front = np.abs(longitude) < math.pi / 2
    hard = np.where(front[None, :], layers[0], layers[1])
    cut = np.flatnonzero(front[1:] != front[:-1])  # the two columns before the cut
    assert float(np.abs(hard[rows, cut + 1] - hard[rows, cut]).mean()) > step(expected) + 10


@pytest.mark.slow
def test_the_floor_map_is_exact_for_every_camera_of_a_surround_rig(tmp_path: Path) -> None:
    """Four lenses chained by quarter turns about their own down axis and 1.4 m offsets, camera 0 pitched 40 deg
    down from 1.2 m: every camera's floor map lies within 0.01 px of its lens seeing the floor from its own
    position (measured 0.002)."""
    down = math.radians(40)
    offset = [[0, 0, -1, 1.0], [0, 1, 0, 0], [1, 0, 0, 1.0], [0, 0, 0, 1]]
    path = camchain(tmp_path / "car.yaml", [offset, offset, offset])
    rig = rig_of_camchain(path, orientation_rad=(0.0, -down, 0.0), camera_position=(1.0, 0.0, 1.2))
    truth = chain_truth(conventions_axes(0.0, -40.0, 0.0), np.array([1.0, 0.0, 1.2]), [offset, offset, offset])
    view = FloorView(0.0, (-4.0, 4.0), (-4.0, 4.0), (200, 200))
    for map_uv, (axes, centre) in zip(camera_maps(rig, view), truth, strict=True):
        expected = lens_pixels(view.world_points() - centre, axes)
        both = np.all(np.isfinite(map_uv), axis=-1) & np.all(np.isfinite(expected), axis=-1)
        assert both.sum() > 5000
        assert np.abs(map_uv[both] - expected[both]).max() < 0.01


def test_a_rig_file_round_trips_and_the_commands_take_it(dual: Path, tmp_path: Path) -> None:
    """import makes the rig file; info describes it; equirect takes its frame and writes each camera's layer;
    a wrong number of pictures, --each without {camera} and --save-map-pgm are refused in one line."""
    out = tmp_path / "dual.npz"
    assert run("import", dual, "-o", out, "--side-by-side", "--fov", "190").exit_code == 0
    rig = load_rig(out)
    assert rig.names == ("cam0", "cam1") and rig.offsets == ((0, 0), (SIDE, 0))
    save_rig(rig, tmp_path / "again.npz")
    assert load_rig(tmp_path / "again.npz").tables[1].model == rig.tables[1].model
    info = run("info", out).stdout
    assert "rig of 2 cameras" in info and "overlap up to 10.0 deg" in info
    truth = chain_truth(conventions_axes(0, 0, 0), np.zeros(3), [BACK_TO_BACK])
    frame = np.concatenate([render_lens(textured_world(), axes) for axes, _ in truth], axis=1)
    picture = tmp_path / "frame.png"
    cv2.imwrite(str(picture), frame)
    result = run("equirect", out, picture, "-o", tmp_path / "e.png", "--size", "512x256", "--each",
                 str(tmp_path / "e_{camera}.png"))  # fmt: skip
    assert result.exit_code == 0, result.output
    assert all((tmp_path / f"e_{name}.png").exists() for name in rig.names)
    assert_one_line_error(run("equirect", out, picture, picture, "-o", tmp_path / "x.png"), "one picture", exit_code=2)
    assert_one_line_error(run("equirect", out, picture, "-o", tmp_path / "x.png", "--each", "a.png"), "{camera}",
                          exit_code=2)  # fmt: skip
    assert not (tmp_path / "x.png").exists()


def test_a_rig_whose_table_is_corrupt_is_refused_naming_the_camera_and_the_file(dual: Path, tmp_path: Path) -> None:
    """Each camera's table is checked as a table file is (read in memory, not through a temporary file): an
    entry changed (its checksum), or no table at all, is refused naming the camera and the rig file."""
    out = tmp_path / "dual.npz"
    assert run("import", dual, "-o", out, "--side-by-side", "--fov", "190").exit_code == 0
    with zipfile.ZipFile(out) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    with np.load(io.BytesIO(members["cam1.npz"])) as table:
        arrays = {key: table[key] for key in table.files}
    arrays["entries"][5, 5, 0] += 0.5
    edited = io.BytesIO()
    np.savez(edited, **arrays)
    for name, part, message in (
        ("edited", edited.getvalue(), "camera cam1: the entries do not match their checksum (corrupt)"),
        ("garbage", b"not a table", "camera cam1: not a panomap table (not a .npz archive"),
    ):
        path = tmp_path / f"{name}.npz"
        with zipfile.ZipFile(path, "w") as archive:
            for member, data in members.items():
                archive.writestr(member, part if member == "cam1.npz" else data)
        with pytest.raises(PanomapError) as caught:
            load_rig(path)
        assert str(path) in str(caught.value) and message in str(caught.value)
        assert_one_line_error(run("info", path), "camera cam1", name)


def test_a_pose_that_is_not_a_rotation_is_refused(tmp_path: Path) -> None:
    scaled = [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    path = camchain(tmp_path / "bad.yaml", [scaled])
    result = run("import", path, "-o", tmp_path / "bad.npz")
    assert_one_line_error(result, "cam1.T_cn_cnm1", "not a rotation")


def test_a_view_without_a_size_takes_camera_0s_for_every_camera_of_a_rig(tmp_path: Path) -> None:
    """Two lenses back to back, the second's focal length 10% longer (its table finer): an equirect or a panorama
    given no size is each camera's own default for a single camera, different here, and camera 0's for the rig
    (every camera's map one shape; before, the blend failed on two shapes)."""
    path = camchain(tmp_path / "dual.yaml", [BACK_TO_BACK])
    text = path.read_text().split("cam1:")
    longer = f"intrinsics: [{F_PX * 1.1}, {F_PX * 1.1}, {CX}, {CY}]"
    path.write_text(text[0] + "cam1:" + text[1].replace(f"intrinsics: [{F_PX}, {F_PX}, {CX}, {CY}]", longer))
    rig = rig_of_camchain(path, side_by_side=True, fov_rad=2 * HALF_FOV)
    for view in (EquirectView(), GenericPanorama()):
        own = [view.output_size(table) for table in rig.tables]
        assert own[0] != own[1], own  # the cameras would choose differently
        maps = camera_maps(rig, view)
        assert [m.shape[:2] for m in maps] == [own[0][::-1]] * 2, ([m.shape for m in maps], own)
        RigRemapper(rig, maps, wrap=True)  # the seams' weights take the maps together


def test_pictures_of_a_rig_in_grey_colour_and_alpha_blend_as_their_colour_twins(tmp_path: Path) -> None:
    """Each camera its own file (the Theta pair's way), one grey or with alpha beside one in colour: the view is
    the one of the grey picture repeated into B, G, R and of the colour without its alpha (an opaque alpha added
    to the other where one has it); pictures of two depths are refused in one line naming the file (before: an
    IndexError's traceback)."""
    path = camchain(tmp_path / "dual.yaml", [BACK_TO_BACK])
    out = tmp_path / "rig.npz"
    assert run("import", path, "-o", out, "--fov", "190").exit_code == 0
    truth = chain_truth(conventions_axes(0, 0, 0), np.zeros(3), [BACK_TO_BACK])
    front, back = (render_lens(textured_world(), axes) for axes, _ in truth)
    grey = cv2.cvtColor(front, cv2.COLOR_BGR2GRAY)
    files = {
        "grey.png": grey,
        "grey3.png": np.repeat(grey[..., None], 3, axis=2),
        "back.png": back,
        "back4.png": np.concatenate([back, np.full((*back.shape[:2], 1), 255, np.uint8)], axis=2),
        "back16.png": back.astype(np.uint16) * 257,
    }
    for name, image in files.items():
        cv2.imwrite(str(tmp_path / name), image)

    def equirect(first: str, second: str) -> np.ndarray:
        result = run("equirect", out, tmp_path / first, tmp_path / second, "-o", tmp_path / "e.png", "--size",
                     "256x128")  # fmt: skip
        assert result.exit_code == 0, result.output
        return cv2.imread(str(tmp_path / "e.png"), cv2.IMREAD_UNCHANGED)

    twin = equirect("grey3.png", "back.png")
    assert np.array_equal(equirect("grey.png", "back.png"), twin)
    with_alpha = equirect("grey.png", "back4.png")
    assert with_alpha.shape[2] == 4 and np.array_equal(with_alpha[..., :3], twin)
    result = run("equirect", out, tmp_path / "grey3.png", tmp_path / "back16.png", "-o", tmp_path / "x.png")
    assert_one_line_error(result, "back16.png: its pixels are uint16", "give the rig's pictures alike")
    assert not (tmp_path / "x.png").exists()


def test_a_rig_where_one_cameras_table_is_wanted_is_named_a_rig(dual: Path, dual_rig: Path, tmp_path: Path) -> None:
    """A rig file given to a command of one camera, or to import, is called a rig in one line (before: "no
    entries/meta inside" and a UnicodeDecodeError); a table given to import is called a table."""
    rig = dual_rig
    (tmp_path / "uv.csv").write_text("u,v\n10,20\n")
    for args in (("unproject", rig, tmp_path / "uv.csv", "-o", tmp_path / "rays.csv"),
                 ("export", rig, "-o", tmp_path / "cam.txt", "--format", "ocam")):  # fmt: skip
        assert_one_line_error(run(*args), "rig.npz: a rig of several cameras, not one camera's table")
    assert_one_line_error(run("import", rig, "-o", tmp_path / "x.npz"), "rig.npz: a panomap rig already")
    assert_one_line_error(run("import", rig, "--camera-name", "cam0", "-o", tmp_path / "x.npz"), "a panomap rig")
    one = tmp_path / "one.npz"
    assert run("import", dual, "--camera-name", "cam0", "-o", one).exit_code == 0
    assert_one_line_error(run("import", one, "-o", tmp_path / "x.npz"), "one.npz: a panomap table already")
    assert not (tmp_path / "x.npz").exists()


def _rewritten(rig: Path, out: Path, index: object = None, drop: str | None = None, raw: bytes | None = None) -> Path:
    """``rig`` with its rig.json replaced (``index``, as JSON, or ``raw`` bytes) and/or a member dropped."""
    import json
    import zipfile

    with zipfile.ZipFile(rig) as source, zipfile.ZipFile(out, "w") as target:
        for name in source.namelist():
            if name == drop:
                continue
            data = source.read(name)
            if name == "rig.json" and (index is not None or raw is not None):
                data = raw if raw is not None else json.dumps(index).encode()
            target.writestr(name, data)
    return out


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"drop": "rig.json"}, "not a panomap table (no entries/meta inside)"),
        ({"raw": b"{not json"}, "its rig.json is not valid JSON"),
        ({"index": {"format": "other"}}, "not a panomap rig (rig.json names another format)"),
        ({"index": {"version": 99}}, "rig format version 99"),
        ({"index": {"names": "cam0"}}, "rig.json's names must be a list"),
        ({"index": {"offsets": [[0, 0]]}}, "rig.json's offsets must be one pair of pixel counts per camera"),
        ({"index": {"offsets": [[0, 0], [-5, 0]]}}, "rig.json's offsets must be one pair"),
        ({"index": {"info": [1]}}, "rig.json's info must be an object"),
        ({"drop": "cam1.npz"}, "camera cam1's table (cam1.npz) is missing"),
    ],
)
def test_a_rig_file_whose_index_or_tables_are_wrong_is_refused_in_one_line(
    dual_rig: Path, tmp_path: Path, change: dict, message: str
) -> None:
    import json
    import zipfile

    rig = dual_rig
    with zipfile.ZipFile(rig) as archive:
        index = json.loads(archive.read("rig.json"))
    if "index" in change:
        change = {"index": index | change["index"]}
    bad = _rewritten(rig, tmp_path / "bad.npz", **change)
    assert_one_line_error(run("info", bad), f"bad.npz: {message}" if change.get("drop") != "cam1.npz" else message)


def test_a_rig_index_without_offsets_takes_one_picture_per_camera(dual_rig: Path, tmp_path: Path) -> None:
    """An index written by hand without "offsets" (before: a KeyError's traceback) is a rig whose cameras each
    take their own picture, as "offsets": null says."""
    import json
    import zipfile

    rig = dual_rig
    with zipfile.ZipFile(rig) as archive:
        index = json.loads(archive.read("rig.json"))
    del index["offsets"]
    loaded = load_rig(_rewritten(rig, tmp_path / "own.npz", index=index))
    assert loaded.offsets is None and loaded.names == ("cam0", "cam1")
