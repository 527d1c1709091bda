"""Plain helpers shared by the tests (fixtures are in conftest.py): ``from helpers import ...``.

pytest puts this folder on ``sys.path`` (``tests/`` has no ``__init__.py``, and
conftest.py lives here); ``bench/bench_fit.py`` adds it itself for ``worst_error``.
The ground truth (``panomap.simulate``) imports nothing from the code under test:
what runs that code on it (making ``Landmarks``, fitting, building tables) is here.
"""

from __future__ import annotations

import importlib.util
import math
import os
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType
from typing import Any, TypeVar

import av
import cv2
import imageio_ffmpeg
import numpy as np
import pytest
from click.testing import CliRunner, Result
from numpy.typing import NDArray

from panomap.calibrate.circles import Circle, ImageCircles
from panomap.calibrate.landmarks.fit import CameraFit, fit_camera
from panomap.calibrate.landmarks.pairs import Landmarks, landmarks_to_csv
from panomap.calibrate.landmarks.table import create_table
from panomap.cli.app import main
from panomap.io.local_web import LocalServer, serve_in_thread
from panomap.simulate import sampling
from panomap.simulate.cameras import RadialCamera, SimulatedCamera
from panomap.simulate.scenarios import CAMERA_POSITION, IMAGE_SIZE, Trial
from panomap.table.table import PanoMappingTable

ServerT = TypeVar("ServerT", bound=LocalServer)


def bench_module(name: str) -> ModuleType:
    """``bench/<name>.py`` loaded as the module ``name`` (``bench/`` is no package): its renders, its ground
    truth and its measures, for the tests that pin a bench's figures."""
    path = Path(__file__).resolve().parents[1] / "bench" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up while the file runs
    spec.loader.exec_module(module)
    return module


# ----------------------------------------------------------------------------- the command line, in-process


def run(*args: object) -> Result:
    """``panomap ARGS...`` in-process (each argument through ``str``)."""
    return CliRunner().invoke(main, [str(a) for a in args])


def assert_one_line_error(result: Result, *fragments: str, exit_code: int = 1) -> None:
    """The command failed with ``exit_code`` and wrote one line to stderr, no traceback, holding
    every fragment. The README's promise: 1 for a failure (bad input, a file that cannot be read
    or written, a view the table's camera cannot see), 2 for bad usage (an option missing, unparsable
    or out of range, options that do not go together)."""
    assert result.exit_code == exit_code, f"exit code {result.exit_code}: " + result.output + result.stderr
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


def hyperbolic_inputs(
    folder: Path, size: tuple[int, int], centre: tuple[float, float], count: int, table_name: str
) -> PanoMappingTable:
    """A simulated hyperbolic camera's table learned from ``count`` landmarks (the camera 2.5 m up, its centre
    ``centre`` px in an image of ``size``), saved as ``folder/table_name``, and a random picture of that size,
    ``folder/omni.png``; the table."""
    from panomap.simulate import standard_cameras
    from panomap.table.file import save_table

    camera = standard_cameras(size, centre=centre)["hyperbolic"]
    position = (0.3, -0.2, 2.5)
    marks = spread_landmarks(camera, position, count, np.random.default_rng(3))
    table, _ = learn_table(camera, position, marks, size)
    save_table(table, folder / table_name)
    image = np.random.default_rng(0).integers(0, 255, (*size, 3), dtype=np.uint8)
    cv2.imwrite(str(folder / "omni.png"), image)
    return table


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


# ------------------------------------------------------------------- what a view's pixels see, from its formulas
# Written here from the conventions (docs/conventions.md and each view's docstring), not taken
# from panomap.views: with a simulated camera's projection they are the ground truth of a map.


def centres(count: int) -> NDArray[np.float64]:
    """``(k + 0.5) / count`` for k = 0..count-1: the pixel centres' fractions across a view."""
    return (np.arange(count) + 0.5) / count


def column_azimuths(start_rad: float, width: int) -> NDArray[np.float64]:
    """The panoramas' column azimuths: ``start - 2*pi*(k + 0.5)/W`` (rad), decreasing to the right."""
    return start_rad - 2 * np.pi * centres(width)


def panorama_directions(
    size: tuple[int, int], start_rad: float, elevation_range: tuple[float, float]
) -> NDArray[np.float64]:
    """(H, W, 3) unit rays of a generic panorama: rows evenly spaced in elevation, highest on top."""
    width, height = size
    low, high = elevation_range
    theta = column_azimuths(start_rad, width)[None, :]
    rho = (high - centres(height) * (high - low))[:, None]
    return np.stack(np.broadcast_arrays(np.cos(rho) * np.cos(theta), np.cos(rho) * np.sin(theta), np.sin(rho)), -1)


def cylinder_points(
    distance: float, band: tuple[float, float], size: tuple[int, int], start_rad: float = 0.0
) -> NDArray[np.float64]:
    """(H, W, 3) points (relative to the camera) of a cylinder panorama's pixels."""
    width, height = size
    theta = column_azimuths(start_rad, width)[None, :]
    z = (band[1] - centres(height) * (band[1] - band[0]))[:, None]
    return np.stack(np.broadcast_arrays(distance * np.cos(theta), distance * np.sin(theta), z), -1)


def plane_points(
    distance: float, plane_width: float, band: tuple[float, float], azimuth_rad: float, size: tuple[int, int]
) -> NDArray[np.float64]:
    """(H, W, 3) points of a plane view: a straight line from the left edge (azimuth + phi/2) to the
    right (azimuth - phi/2), both at ``distance``, with phi = acos(1 - W_p^2 / (2 D^2))."""
    width, height = size
    half = np.arccos(1 - plane_width**2 / (2 * distance**2)) / 2
    left = distance * np.array([np.cos(azimuth_rad + half), np.sin(azimuth_rad + half)])
    right = distance * np.array([np.cos(azimuth_rad - half), np.sin(azimuth_rad - half)])
    xy = left + centres(width)[:, None] * (right - left)
    z = band[1] - centres(height) * (band[1] - band[0])
    return np.stack(np.broadcast_arrays(xy[None, :, 0], xy[None, :, 1], z[:, None]), -1)


def perspective_directions(
    yaw_rad: float, pitch_rad: float, roll_rad: float, fov_rad: float, size: tuple[int, int]
) -> NDArray[np.float64]:
    """(H, W, 3) rays of a pinhole looking at (yaw, pitch), turned by roll (+ dips its right side)."""
    width, height = size
    focal = (width / 2) / np.tan(fov_rad / 2)
    forward = np.array([np.cos(pitch_rad) * np.cos(yaw_rad), np.cos(pitch_rad) * np.sin(yaw_rad), np.sin(pitch_rad)])
    level_right = np.array([np.sin(yaw_rad), -np.cos(yaw_rad), 0.0])
    level_down = np.cross(forward, level_right)
    right = np.cos(roll_rad) * level_right + np.sin(roll_rad) * level_down
    down = np.cos(roll_rad) * level_down - np.sin(roll_rad) * level_right
    x = (np.arange(width) + 0.5 - width / 2) / focal
    y = (np.arange(height) + 0.5 - height / 2) / focal
    return forward + x[None, :, None] * right + y[:, None, None] * down


def floor_points(
    z: float, x: tuple[float, float], y: tuple[float, float], size: tuple[int, int], position: tuple[float, ...]
) -> NDArray[np.float64]:
    """(H, W, 3) points (relative to the camera at ``position``) of a floor view of the world plane
    Z = z: x grows to the right, y upwards (north up)."""
    width, height = size
    xs = x[0] + centres(width) * (x[1] - x[0])
    ys = y[1] - centres(height) * (y[1] - y[0])
    points = np.stack(np.broadcast_arrays(xs[None, :], ys[:, None], np.full((1, 1), float(z))), -1)
    return points - np.asarray(position, dtype=np.float64)


def assert_map_sees_like_the_camera(map_uv: np.ndarray, camera: SimulatedCamera, points: np.ndarray) -> None:
    """A view's (H, W, 2) map agrees with the camera's true projection of ``points`` (H, W, 3),
    within the camera's ground-truth view bars; NaN exactly where the camera does not see."""
    truth = camera.project(points)
    seen = np.all(np.isfinite(truth), axis=-1)
    assert seen.mean() > 0.3, "the view must see enough of the scene for the test to mean anything"
    mapped = np.all(np.isfinite(map_uv), axis=-1)
    # Pixels the camera sees that the map leaves empty (or the reverse) fail, beyond a one-pixel rim.
    assert np.count_nonzero(seen != mapped) <= 2 * sum(map_uv.shape[:2]), np.count_nonzero(seen != mapped)
    both = seen & mapped
    assert_view_errors_within(np.linalg.norm(map_uv[both] - truth[both], axis=-1), camera.name)


LIMIT_S = 20.0  # the limit on every wait for an event


def wait_until(condition: Callable[[], bool], what: str, limit_s: float = LIMIT_S) -> None:
    deadline = time.monotonic() + limit_s
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"waited {limit_s} s for {what}")
        time.sleep(0.02)


class StreamServer:
    """ffmpeg serving ``clip`` as MPEG-TS in real time over TCP to one client at a time (started by ``start``)."""

    def __init__(self, clip: Path) -> None:
        self.clip = clip
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            self.port = probe.getsockname()[1]
        self.url = f"tcp://127.0.0.1:{self.port}"
        self.process: subprocess.Popen[bytes] | None = None

    def start(self, wait: bool = True) -> None:
        """Start ffmpeg; with ``wait``, return once it listens (it serves the first client only: no probing)."""
        command = [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-loglevel", "error", "-nostdin", "-re"]
        command += ["-i", str(self.clip), "-c", "copy", "-f", "mpegts", f"{self.url}?listen=1"]
        self.process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        if wait:
            wait_until(self.listening, "the server to listen")

    def listening(self) -> bool:
        """True while a socket listens on the port (read from /proc/net/tcp: state 0A)."""
        assert self.process is not None
        if self.process.poll() is not None:
            raise AssertionError(f"the server ended (exit code {self.process.returncode})")
        wanted = f"0100007F:{self.port:04X}"
        lines = Path("/proc/net/tcp").read_text().splitlines()[1:]
        return any(line.split()[1] == wanted and line.split()[3] == "0A" for line in lines)

    def kill(self) -> None:
        """Kill it (SIGKILL): the connection ends as it does when a camera or a network goes away."""
        if self.process is not None and self.process.poll() is None:
            self.process.kill()
            self.process.wait(timeout=LIMIT_S)


# ----------------------------------------------------------------------------- a room camera, its clips


def room_camera_files(folder: Path, camera: SimulatedCamera, size: tuple[int, int], seed: int) -> NDArray[np.uint8]:
    """``folder/cam.npz`` (the table of ``camera`` in the bundled room, learned from 16 spread landmarks drawn
    with ``seed``, at its true centre) and ``folder/omni.png`` (the room through it); returns the picture."""
    from panomap.simulate import load_room, render
    from panomap.table.file import save_table

    room = load_room()
    position = tuple(room.camera)
    landmarks = spread_landmarks(camera, position, 16, np.random.default_rng(seed))
    table, _ = learn_table(camera, position, landmarks, size)
    save_table(table, folder / "cam.npz")
    omni = np.asarray(render(room, camera, supersample=1))
    cv2.imwrite(str(folder / "omni.png"), omni)
    return omni


def write_clip(
    path: Path,
    pictures: Iterable[NDArray[np.uint8]],
    rate: int,
    codec: str = "libx264",
    container_format: str | None = None,
    options: dict[str, str] | None = None,
    bit_rate: int | None = None,
) -> None:
    """``pictures`` (BGR, all one size) as a yuv420p clip at ``rate`` frames/s, picture k at time k / rate."""
    with av.open(str(path), "w", format=container_format) as container:
        video = container.add_stream(codec, rate=rate)
        video.pix_fmt = "yuv420p"
        if options:
            video.options = options
        if bit_rate is not None:
            video.bit_rate = bit_rate
        for index, picture in enumerate(pictures):
            if index == 0:
                video.height, video.width = picture.shape[:2]
            frame = av.VideoFrame.from_ndarray(picture, format="bgr24")
            frame.pts = index
            for packet in video.encode(frame):
                container.mux(packet)
        for packet in video.encode(None):
            container.mux(packet)


# ----------------------------------------------------------------------------- local web servers, a browser

CHROMIUM = Path("/usr/bin/chromium")
# What every test's headless Chromium is started with (each test adds its own: no GPU, or SwiftShader's).
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
]


def chromium(extra_args: list[str]) -> Iterator[Any]:
    """Debian's Chromium driven by Playwright, for a module-scoped fixture (``yield from chromium([...])``).

    Without /usr/bin/chromium (or the playwright package) the tests skip, saying why; with the
    environment variable CI set they fail instead: CI must install them (``scripts/install-test-deps.sh``).
    """
    reason = None
    try:
        import playwright.sync_api
    except ImportError:
        reason = "the playwright package is not installed (pip install -e '.[test]')"
    if reason is None and not CHROMIUM.exists():
        reason = f"{CHROMIUM} is missing (Debian's chromium: run scripts/install-test-deps.sh)"
    if reason is not None:
        if os.environ.get("CI"):
            pytest.fail(f"CI must run the browser tests: {reason}")
        pytest.skip(reason)
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS + extra_args)
        yield browser
        browser.close()


@contextmanager
def serving() -> Iterator[Callable[[ServerT], ServerT]]:
    """``start(server)``: serve it in a thread; every server started is stopped when the block ends."""
    servers: list[LocalServer] = []

    def start(server: ServerT) -> ServerT:
        serve_in_thread(server)
        servers.append(server)
        return server

    try:
        yield start
    finally:
        for server in servers:
            server.shutdown()
            server.server_close()


def true_circles(camera) -> ImageCircles:
    outer = Circle(camera.centre, camera.outer_radius, 0.1, 100, 100)
    cutoff = None if camera.cutoff_radius <= 0 else Circle(camera.centre, camera.cutoff_radius, 0.1, 100, 100)
    return ImageCircles(camera.centre, outer, cutoff, None)


def pixel_errors(model, camera, step: int = 12) -> np.ndarray:
    """Distance (px) between each image pixel and where the learned camera puts its true ray.

    The true rays are first mapped by the orthogonal matrix (rotation or reflection) that best
    aligns them with the learned camera's own: what lines leave free (azimuth origin, handedness),
    and the tilt, which is compared separately.
    """
    width, height = camera.image_size
    u, v = np.meshgrid(np.arange(0, width, step), np.arange(0, height, step))
    pixels = np.stack([u.ravel(), v.ravel()], axis=-1).astype(float)
    _, rays = camera.trace(pixels)
    seen = np.all(np.isfinite(rays), axis=1)
    pixels, rays = pixels[seen], rays[seen]
    u0, v0 = model.centre
    radius = np.hypot(pixels[:, 0] - u0, pixels[:, 1] - v0)
    # The learned camera's rays of those pixels: alpha from the axis by inverting f_r numerically.
    alpha_grid = np.linspace(0.0, math.radians(150.0), 20001)
    r_grid = np.abs(model.radial(alpha_grid - math.pi / 2))
    rising = np.concatenate([[True], np.diff(r_grid) > 0]) & np.isfinite(r_grid)
    last = int(np.argmin(rising)) if not rising.all() else rising.size
    alpha = np.interp(radius, r_grid[:last], alpha_grid[:last])
    phi = np.arctan2(pixels[:, 1] - v0, pixels[:, 0] - u0)
    learned = np.stack([np.sin(alpha) * np.cos(phi), np.sin(alpha) * np.sin(phi), np.cos(alpha)], axis=-1)
    left, _, right = np.linalg.svd(learned.T @ rays)
    mapped = rays @ (left @ right).T
    alpha_true = np.arccos(np.clip(mapped[:, 2], -1.0, 1.0))
    phi_true = np.arctan2(mapped[:, 1], mapped[:, 0])
    r_true = np.abs(model.radial(alpha_true - math.pi / 2))
    predicted = np.stack([u0 + r_true * np.cos(phi_true), v0 + r_true * np.sin(phi_true)], axis=-1)
    return np.hypot(*(predicted - pixels).T)
