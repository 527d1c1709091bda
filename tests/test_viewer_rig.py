"""The viewer of a rig (issue 52): the page blends the rig's cameras as ``panomap perspective RIG ...`` does.

A pair of ideal equidistant lenses back to back (tests/test_rig.py's, 190 deg each), their pictures rendered from
a textured world in closed form. Lens 1 sees the world 15% brighter and 24 px turned (a parallax the gains cannot
take away), so the overlap blends two different pictures: a weight or a gain the page gets wrong shows there.
The page's canvas, read back in Chromium on SwiftShader, is compared with the command line's picture of the same
view. Without Chromium these tests skip, saying why (CI=1 makes them fail instead).
"""

from __future__ import annotations

import shlex
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from panomap.interop.rig_of_camchain import rig_of_camchain
from panomap.rig import RigRemapper, camera_maps, load_rig, save_rig
from panomap.viewer.rig_view import open_rig_source
from panomap.viewer.server import make_server
from panomap.views.spec import parse_view_spec
from test_orientation import conventions_axes
from test_rig import BACK_TO_BACK, HALF_FOV, camchain, chain_truth, render_lens, textured_world
from test_viewer_browser import VIEWER_ARGS, Page, cli_picture

from helpers import assert_one_line_error, chromium, run, serving

# Where the page and the command line blend the same pictures with the same weights and gains: the GPU's filter
# (1/256 weights) against OpenCV's (1/32), and the page's distances from the edges (first order) against the
# library's distance transforms. Measured (mean grey levels; share of pixels off by more than 3): see each view.
BAND_MEAN = 0.75
BAND_OFF_BY_3 = 0.05
# Where one camera sees alone: a turned camera's lookup resamples its table (test_viewer_browser's looser check).
OUTSIDE_MEAN = 0.3
VIEWS = [  # (spec, kind's options): across the seam, looking askew at it, the whole sphere
    "perspective:yaw=90,pitch=0,roll=0,fov=90,size=640x480",
    "perspective:yaw=-60,pitch=35,roll=10,fov=100,size=640x480",
    "equirect:yaw=0,pitch=0,roll=0,size=720x360",
]


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    yield from chromium(VIEWER_ARGS)


@pytest.fixture(scope="module")
def rig_files(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """dual.npz (one frame: frame.png), pair.npz (a picture each: cam0.png, cam1.png; 1.5 m above the floor)."""
    folder = tmp_path_factory.mktemp("viewer-rig")
    chain = camchain(folder / "dual.yaml", [BACK_TO_BACK])
    save_rig(rig_of_camchain(chain, side_by_side=True, fov_rad=2 * HALF_FOV), folder / "dual.npz")
    save_rig(rig_of_camchain(chain, fov_rad=2 * HALF_FOV, camera_position=(0.0, 0.0, 1.5)), folder / "pair.npz")
    world = textured_world()
    truth = chain_truth(conventions_axes(0, 0, 0), np.zeros(3), [BACK_TO_BACK])
    lenses = [render_lens(world, truth[0][0]), render_lens(np.roll(world, 24, axis=1), truth[1][0])]
    lenses[1] = np.clip(lenses[1].astype(np.float32) * 1.15, 0, 255).astype(np.uint8)
    cv2.imwrite(str(folder / "frame.png"), np.concatenate(lenses, axis=1))
    for k, lens in enumerate(lenses):
        cv2.imwrite(str(folder / f"cam{k}.png"), lens)
    return folder


def differences(got: np.ndarray, expected: np.ndarray, where: np.ndarray) -> tuple[float, float]:
    """(mean grey levels, share of pixels off by more than 3 in a channel) over the pixels ``where``."""
    difference = np.abs(got.astype(np.int16) - expected)[where]
    return float(difference.mean()), float(np.mean(difference.max(axis=-1) > 3))


def library_views(folder: Path, rig_name: str, pictures: list[str], spec: str) -> dict[str, np.ndarray]:
    """The library's own pictures of the view: the pixels it blends from two cameras (``band``), and, for
    comparison, the blend without gains and the hard cut (each pixel from the camera that counts most)."""
    rig = load_rig(folder / rig_name)
    view = parse_view_spec(spec)[1]
    remapper = RigRemapper(rig, camera_maps(rig, view), wrap=view.kind == "equirect")
    frames = [cv2.imread(str(folder / name), cv2.IMREAD_COLOR) for name in pictures]
    layers = remapper.layers(frames)
    strongest = np.argmax(remapper.weights, axis=0)
    return {
        "band": (remapper.weights > 0.02).sum(axis=0) >= 2,
        "no gains": remapper.blend(layers, np.ones((rig.count, 3))),
        "hard cut": np.choose(strongest[..., None], layers),
    }


def assert_the_blend(got: np.ndarray, expected: np.ndarray, library: dict[str, np.ndarray], what: str) -> None:
    """The page's picture is the command line's: within BAND_MEAN in the overlap blended, and within OUTSIDE_MEAN
    elsewhere; the same picture blended without gains, or cut hard, is far from it there."""
    band = library["band"]
    mean, off = differences(got, expected, band)
    others = {name: differences(library[name], expected, band)[0] for name in ("no gains", "hard cut")}
    outside = float(np.abs(got.astype(np.int16) - expected)[~band].mean())
    print(f"{what}: in the overlap ({band.mean():.3f} of the view) mean {mean:.3f} grey levels, off by more than 3 "
          f"{off:.4f} (without gains {others['no gains']:.2f}, cut hard {others['hard cut']:.2f}); elsewhere "
          f"{outside:.4f}")  # fmt: skip
    assert band.mean() > 0.02 and expected.mean() > 40  # (the overlap is in view, and a picture)
    assert mean <= BAND_MEAN and off <= BAND_OFF_BY_3 and outside <= OUTSIDE_MEAN, what
    assert min(others.values()) > 3 * BAND_MEAN  # (what a wrong gain or weight would give)


@pytest.mark.slow
def test_the_view_of_a_rig_is_the_command_lines_picture(browser: Any, rig_files: Path, tmp_path: Path) -> None:
    """A dual-fisheye frame: the page's perspective views across the seam and askew, and its equirect, are the
    command line's blend (same weights, same gains) within RIG_MEAN grey levels on average; the layers
    unblended (camera 0 where it sees) differ from it by far more in the overlap."""
    rig = load_rig(rig_files / "dual.npz")
    with serving() as start:
        rig_view, source = open_rig_source(rig, "dual.npz", [str(rig_files / "frame.png")])
        server = start(make_server(rig.tables[0], "dual.npz", source, rig=rig_view))
        page = Page(browser, server)
        try:
            for spec in VIEWS:
                kind, _, rest = spec.partition(":")
                values = dict(item.split("=") for item in rest.split(","))
                width, height = (int(n) for n in values.pop("size").split("x"))
                view = {key: float(value) for key, value in values.items()} | {"width": width, "height": height}
                page.set(mode=kind, strip=False, **view)
                words = shlex.split(page.js("window.panomapView.commands().command"))
                assert words[:4] == ["panomap", kind, "dual.npz", "frame.png"]
                assert page.js("window.panomapView.commands().spec") == spec
                expected = cli_picture(tmp_path, kind, rig_files / "frame.png", *words[6:], table="dual.npz")
                library = library_views(rig_files, "dual.npz", ["frame.png"], spec)
                assert_the_blend(page.pixels(), expected, library, spec)
        finally:
            page.close()


@pytest.mark.slow
def test_a_rig_with_a_picture_per_camera_and_its_floor_map(browser: Any, rig_files: Path, tmp_path: Path) -> None:
    """A rig whose cameras each have their own picture (laid out in one texture for the page): its perspective
    view and its floor map (each camera seeing the floor from its own position) are the command line's."""
    rig = load_rig(rig_files / "pair.npz")
    names = [str(rig_files / "cam0.png"), str(rig_files / "cam1.png")]
    with serving() as start:
        rig_view, source = open_rig_source(rig, "pair.npz", names)
        server = start(make_server(rig.tables[0], "pair.npz", source, rig=rig_view))
        page = Page(browser, server)
        try:
            for view in ({"mode": "perspective", "yaw": 95.0, "pitch": -20.0, "roll": 0.0, "fov": 80.0},
                         {"mode": "floor"}):  # fmt: skip
                page.set(strip=False, width=480, height=360, **view)
                words = shlex.split(page.js("window.panomapView.commands().command"))
                assert words[:5] == ["panomap", view["mode"], "pair.npz", "cam0.png", "cam1.png"]
                expected = cli_picture(tmp_path, view["mode"], rig_files / "cam0.png", rig_files / "cam1.png",
                                       *words[7:], table="pair.npz")  # fmt: skip
                spec = page.js("window.panomapView.commands().spec")
                library = library_views(rig_files, "pair.npz", ["cam0.png", "cam1.png"], spec)
                assert_the_blend(page.pixels(), expected, library, spec)
        finally:
            page.close()


def test_a_rigs_wrong_pictures_are_refused_in_one_line(rig_files: Path) -> None:
    """panomap view RIG: two pictures for a rig of one frame, one for a rig of two, a frame of the wrong size."""
    dual, pair = rig_files / "dual.npz", rig_files / "pair.npz"
    frame, cam0 = rig_files / "frame.png", rig_files / "cam0.png"
    assert_one_line_error(run("view", dual, frame, frame, "--port", "0"), "share one frame")
    assert_one_line_error(run("view", pair, cam0, "--port", "0"), "one picture per camera", "cam0, cam1")
    assert_one_line_error(run("view", dual, cam0, "--port", "0"), "960 x 960", "1920 x 960")
    assert_one_line_error(run("view", rig_files / "cam0.png", cam0, cam0, "--port", "0"), "one source", exit_code=2)


def test_a_grey_picture_beside_a_colour_one_is_shown_as_its_colour_twin(rig_files: Path, tmp_path: Path) -> None:
    """panomap view RIG grey.png colour.png: the page's picture is that of the grey one repeated into B, G, R
    (before: refused, "the rig's pictures differ in channels or depth"); a 16-bit one beside an 8-bit one is
    refused naming it."""
    import panomap

    pair = load_rig(rig_files / "pair.npz")
    grey = cv2.cvtColor(cv2.imread(str(rig_files / "cam0.png")), cv2.COLOR_BGR2GRAY)
    cv2.imwrite(str(tmp_path / "grey.png"), grey)
    cv2.imwrite(str(tmp_path / "grey3.png"), np.repeat(grey[..., None], 3, axis=2))
    cv2.imwrite(str(tmp_path / "deep.png"), cv2.imread(str(rig_files / "cam1.png")).astype(np.uint16) * 257)
    cam1 = str(rig_files / "cam1.png")
    _, from_grey = open_rig_source(pair, "pair.npz", [str(tmp_path / "grey.png"), cam1])
    _, twin = open_rig_source(pair, "pair.npz", [str(tmp_path / "grey3.png"), cam1])
    assert from_grey.image_png == twin.image_png
    with pytest.raises(panomap.PanomapError, match=r"deep\.png: its pixels are uint16, those of .*grey3\.png uint8"):
        open_rig_source(pair, "pair.npz", [str(tmp_path / "grey3.png"), str(tmp_path / "deep.png")])
