"""``panomap demo``: the whole method on the bundled room, end to end.

Renders the bundled room through a simulated ceiling camera (rotated and
mirrored, as real ones are), takes landmarks as a user would click them,
fits, saves the table, and writes the paper's three views and its Fig. 7b; then the
example inputs the documented commands use (:mod:`.demo_inputs`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from pathlib import Path

import click
import numpy as np

from ..calibrate.core.sources import Source
from ..calibrate.landmarks.pairs import Landmarks, landmarks_to_csv
from ..calibrate.landmarks.pipeline import calibrate_camera, choose_circles
from ..errors import PanomapError
from ..files import check_outputs, check_room, write_text_atomic
from ..io.images import save_map, write_image
from ..io.overlay import draw_fit_overlay
from ..io.plot import save_fit_plot
from ..remap import Remapper
from ..simulate import load_room, render, standard_cameras
from ..simulate.board_scenes import board_poses, render_board_scene
from ..table.file import save_table
from ..views import Band, CylinderPanorama, GenericPanorama, PlaneView, View, build_map
from .demo_inputs import INPUTS, write_inputs
from .options import FOLDER, say

IMAGE_SIZE = (1024, 1024)
LANDMARK_COUNT = 12
VIEWS = ("panorama", "cylinder", "plane")  # (the views written below, in this order)
# Every file the demo writes into its folder.
OUTPUTS = (
    "omni.png", "landmarks.csv", "table.npz", "fit.png", "fit-overlay.png", "boards.png",
    *(f"{name}{end}" for name in VIEWS for end in (".png", "_map.npy")), *INPUTS,
)  # fmt: skip
# The most the demo writes into its folder (bytes): 37.3 to 41.3 MB measured for its five cameras (the maps,
# 26 MB, the most), with room to spare.
DEMO_BYTES = 48_000_000
# Left in the demo's folder: a folder without it holds no demo's files, and the demo overwrites none of them.
MARK = ".panomap-demo"


def pick_landmarks(
    names: list[str], points: np.ndarray, pixels: np.ndarray, camera_position: np.ndarray, count: int
) -> Landmarks:
    """``count`` visible landmarks spread evenly in elevation, pixels rounded to 0.01 px as clicked."""
    visible = np.flatnonzero(np.all(np.isfinite(pixels), axis=1))
    d = points[visible] - camera_position
    elevation = np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1]))
    order = visible[np.argsort(elevation)]
    chosen = order[np.unique(np.round(np.linspace(0, len(order) - 1, count)).astype(int))]
    return Landmarks(np.round(pixels[chosen], 2), points[chosen], tuple(names[k] for k in chosen))


def run_demo(out: Path, camera_name: str = "hyperbolic") -> Iterator[str]:
    """Run the demo into folder ``out``; yields one line per step for the user."""
    start = time.perf_counter()
    made = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    try:
        check_outputs([], [(name, out / name) for name in OUTPUTS])  # (none a FIFO, a device, read-only)
        _refuse_others_files(out)
        check_room([(out / OUTPUTS[0], DEMO_BYTES)], up_to=True)
    except PanomapError:
        if made:
            out.rmdir()
        raise
    (out / MARK).write_text("panomap demo's folder: `panomap demo` may write its files here again\n")
    room = load_room()
    position = np.asarray(room.camera)
    camera = standard_cameras(IMAGE_SIZE, centre=(517.3, 503.8), s=-1, phi0=0.6)[camera_name]
    omni = render(room, camera, supersample=2)
    write_image(out / "omni.png", omni)
    yield f"rendered the bundled room through a simulated {camera_name} ceiling camera: {out / 'omni.png'}"

    names, points = room.landmarks()
    landmarks = pick_landmarks(names, points, camera.project(points - position), position, LANDMARK_COUNT)
    write_text_atomic(out / "landmarks.csv", landmarks_to_csv(landmarks))
    yield f"picked {len(landmarks)} landmarks spread in elevation: {out / 'landmarks.csv'}"

    found = choose_circles(omni)
    centre, cutoff, outer = found.settled()
    yield (
        f"found the image centre ({centre[0]:.2f}, {centre[1]:.2f}), cut-off radius {cutoff:.2f} px "
        f"and image circle {outer:.2f} px (true: ({camera.centre[0]:.2f}, {camera.centre[1]:.2f}), "
        f"{camera.cutoff_radius:.2f} px, {camera.outer_radius:.2f} px)"
    )
    # Recorded as the centre and radii, then the camera position (the order the table file has always had).
    detected = {name: found.sources[name].source for name in ("centre", "cutoff_radius", "outer_radius")}
    result = calibrate_camera(
        landmarks,
        room.camera,
        centre=centre,
        cutoff_radius=cutoff,
        outer_radius=outer,
        image_size=IMAGE_SIZE,
        sources=detected | {"camera_position": Source.GIVEN},
        info={"image_circles": None if found.circles is None else found.circles.to_dict()},
        models_cover_annulus=False,
    )
    fit, table = result.fit, result.table
    save_table(table, out / "table.npz")
    save_fit_plot(table, out / "fit.png")
    write_image(out / "fit-overlay.png", draw_fit_overlay(omni, table))
    m, n = table.size
    yield (
        f"fitted model {table.model.radial.kind} (s = {table.model.s:+d}, "
        f"phi0 = {math.degrees(table.model.phi0):.2f} deg), "
        f"landmark RMS {fit.rms_px:.3f} px; table {m} x {n}: {out / 'table.npz'}, plot {out / 'fit.png'}, "
        f"the fit drawn on the image {out / 'fit-overlay.png'}"
    )

    floor, ceiling = -room.camera[2], room.height - room.camera[2]
    views: dict[str, View] = {
        "panorama": GenericPanorama(),
        "cylinder": CylinderPanorama(2.0, Band(floor, ceiling), (2048, 560)),
        "plane": PlaneView(1.8, 2.4, Band(floor, ceiling), math.radians(90.0), (800, 860)),
    }
    for name, view in views.items():
        map_uv = build_map(table, view)
        write_image(out / f"{name}.png", Remapper(map_uv, IMAGE_SIZE)(omni))
        save_map(out / f"{name}_map.npy", map_uv)
        line = f"wrote the {name} view: {out / f'{name}.png'} (map {out / f'{name}_map.npy'})"
        surface = view.points(table)
        if surface is not None:
            truth = camera.project(surface)
            errors = np.linalg.norm(map_uv - truth, axis=-1)
            line += (
                f"; against the true camera: median {np.nanmedian(errors):.3f} px, "
                f"p95 {np.nanpercentile(errors, 95):.3f} px"
            )
        yield line
    # A picture to learn the camera from without landmarks (getting-started): checkerboards held before it. Four:
    # three of them leave this mirror's rim loose (their band 2.04 px at 95% at 92 deg off the axis, refused); the
    # fourth pins it (band 1.21 px; the camera learned p90 0.71 / max 0.89 px from the true one).
    boards = render_board_scene(camera, board_poses(camera, 4, seed=3), seed=3, supersample=2)
    write_image(out / "boards.png", boards.image)
    yield f"rendered four checkerboards held before the same camera, to learn it from: {out / 'boards.png'}"
    yield from write_inputs(out, room, omni, camera.centre)
    yield f"done in {time.perf_counter() - start:.1f} s"


def _refuse_others_files(out: Path) -> None:
    """Refuse folder ``out`` where it holds a file of a demo's name (``OUTPUTS``) but no demo's mark: the user's own
    ``table.npz`` or ``landmarks.csv``, which the demo would overwrite."""
    if (out / MARK).exists():
        return
    theirs = [name for name in OUTPUTS if (out / name).exists()]
    if theirs:
        named = ", ".join(theirs[:3]) + (f" and {len(theirs) - 3} more" if len(theirs) > 3 else "")
        raise PanomapError(f"holds {named} (not a demo's), which the demo would overwrite: give another folder", out)


@click.command()
@click.option(
    "-o",
    "--out",
    type=FOLDER,
    default=Path("demo-out"),
    show_default=True,
    help="Folder for everything the demo writes.",
)
@click.option(
    "--camera",
    "camera_name",
    type=click.Choice(["equidistant", "equisolid", "parabolic", "hyperbolic", "spherical"]),
    default="hyperbolic",
    show_default=True,
    help="Simulated ceiling camera to use.",
)
def demo(out: Path, camera_name: str) -> None:
    """Render the bundled room through a simulated ceiling camera, learn it, and unwarp it; write example inputs
    (a clip, a fisheye looking ahead, a dual fisheye, their calibrations, a batch manifest)."""
    for line in run_demo(out, camera_name):
        say(line)
