"""``panomap learn``'s "learn from lines", through its JSON API (urllib against a server thread on port 0).

Ground truth: a room (with two boards) rendered through a hyperbolic-mirror camera
(:mod:`panomap.simulate.line_scenes`, vignetting, sensor noise, JPEG), whose rays are known from the simulated
camera's closed-form projection:
the camera learned from the image's lines, its azimuth set by a click, is compared with it in px.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from panomap.cli.app import main
from panomap.learn.server import make_server, serve_in_thread
from panomap.learn.session import Session
from panomap.simulate.cameras import TiltedCamera
from panomap.simulate.line_scenes import line_camera, render_line_scene
from panomap.table.file import load_table
from test_learn import Client

SCALE = 0.4  # 640 x 480
ELEVATION_DEG = -30.0


@pytest.fixture(scope="module")
def room() -> tuple[TiltedCamera, np.ndarray]:
    return room_scene()


def room_scene() -> tuple[TiltedCamera, np.ndarray]:
    """The rendered room with two checkerboards held in it: a room's lines alone, seen by a camera looking down,
    cannot pin it (they run along and across its axis: docs/lines.md), and the page says so."""
    from panomap.simulate.board_scenes import board_poses, render_board_scene

    camera = line_camera("hyperbolic", SCALE, tilt_deg=0.0, toward_deg=30.0)
    image = render_board_scene(camera, board_poses(camera, 2, seed=34), seed=4, supersample=2).image
    return camera, image if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)


def serve(image: np.ndarray, folder: Path) -> Iterator[Client]:
    server = make_server(Session(image, "room.png", folder), port=0)
    thread = serve_in_thread(server)
    yield Client(server)
    server.shutdown()
    server.server_close()
    thread.join(5)


@pytest.fixture
def client(room: tuple[TiltedCamera, np.ndarray], tmp_path: Path) -> Iterator[Client]:
    yield from serve(room[1], tmp_path)


def true_pixel(camera: TiltedCamera, azimuth_deg: float, elevation_deg: float = ELEVATION_DEG) -> np.ndarray:
    """Where the true camera sees the world direction at ``azimuth_deg``, ``elevation_deg`` (its own equations)."""
    a, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    return camera.project(np.array([[math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)]]))[0]


def learned_pixel(model: Any, azimuth_deg: float, elevation_deg: float = ELEVATION_DEG) -> np.ndarray:
    return np.asarray(model.pixels(math.radians(azimuth_deg), math.radians(elevation_deg)), dtype=float)


@pytest.mark.slow
def test_learn_from_lines_then_a_click_sets_azimuth_zero_and_the_table_is_the_commands(
    client: Client, room: tuple[TiltedCamera, np.ndarray], tmp_path: Path
) -> None:
    """The page learns the camera from the room's boards and lines (a level camera: the room's lines alone cannot
    pin it; centre within 1 px of the truth, the camera level), draws every line used and set aside, and after a
    click at the true pixel of world azimuth 0 puts world azimuth 90 deg within 2.5 px of the truth (the azimuth
    origin is arbitrary until then: more than 20 px before the click). The saved table is ``panomap fit --image
    --azimuth-zero U V``'s."""
    camera, image = room
    status, state = client.post("/api/lines", {})
    assert status == 200, state
    lines = state["lines"]
    assert lines["ok"] and lines["revision"] == 1, lines
    assert lines["boards"] == 2 and lines["lines_used"] >= 20 and lines["rms_px"] < 0.3
    assert len(lines["used"]) == lines["lines_used"] and all(line["points"] for line in lines["used"])
    assert len(lines["rejected"]) == lines["arcs_rejected"]
    assert math.dist(lines["centre"], camera.centre) < 1.0
    assert abs(lines["tilt_deg"]) < 0.5  # (boards know no vertical: the camera is taken as level, as it is)
    assert any(sentence.startswith("azimuth 0 is image angle 0") for sentence in lines["sentences"])
    assert client.get("/api/state")["lines"] == lines  # the state holds it

    status, reply = client.post("/api/lines/save", {"name": "before.npz"})
    assert status == 200
    before = load_table(tmp_path / "before.npz").model
    assert np.linalg.norm(learned_pixel(before, 90.0) - true_pixel(camera, 90.0)) > 20.0

    click = true_pixel(camera, 0.0)
    status, state = client.post("/api/lines/azimuth", {"u": float(click[0]), "v": float(click[1])})
    assert status == 200, state
    assert state["lines"]["revision"] == 2 and state["lines"]["azimuth_zero"] == [float(click[0]), float(click[1])]
    status, reply = client.post("/api/lines/save", {"name": "lines.npz"})
    assert status == 200 and reply == {"wrote": "lines.npz"}
    web = load_table(tmp_path / "lines.npz")
    for azimuth in (90.0, 180.0, 270.0):
        assert np.linalg.norm(learned_pixel(web.model, azimuth) - true_pixel(camera, azimuth)) < 2.5
    status, reply = client.post("/api/lines/save", {"name": "lines.npz"})
    assert status == 409 and reply["exists"] == "lines.npz"

    assert cv2.imwrite(str(tmp_path / "room.png"), image)  # (lossless: the page's pixels)
    command = ["fit", "-o", str(tmp_path / "cli.npz"), "--image", str(tmp_path / "room.png")]
    result = CliRunner().invoke(main, [*command, "--azimuth-zero", repr(float(click[0])), repr(float(click[1]))])
    assert result.exit_code == 0, result.output
    cli = load_table(tmp_path / "cli.npz")
    assert web.model.to_dict() == cli.model.to_dict() and web.size == cli.size
    assert np.allclose(web.entries, cli.entries, rtol=0, atol=1e-4, equal_nan=True)


@pytest.mark.parametrize(
    ("path", "body", "status", "message"),
    [
        ("/api/lines/azimuth", {"u": 10.0, "v": 10.0}, 409, "learn from lines first"),
        ("/api/lines/save", {"name": "x.npz"}, 409, "learn from lines first"),
        ("/api/lines/azimuth", {"u": 1000.0, "v": 10.0}, 400, "outside the 640 x 480 image"),
        ("/api/lines/azimuth", {"u": "a", "v": 10.0}, 400, "u must be a number"),
        ("/api/lines/azimuth", {"u": 1.0, "v": 1.0, "w": 1}, 400, "unknown field(s) w"),
        ("/api/lines", {"go": True}, 400, "unknown field(s) go"),
        ("/api/lines/save", {"name": "../x.npz"}, 400, "bare file name"),
    ],
)
def test_lines_requests_are_checked(client: Client, path: str, body: Any, status: int, message: str) -> None:
    got, answer = client.post(path, body)
    assert got == status and message in answer["error"], answer


def test_lines_requests_from_another_site_are_refused(client: Client) -> None:
    status, answer = client.post("/api/lines", {}, {"Origin": "http://evil.example"})
    assert status == 403 and "another site" in answer["error"]
    status, body = client.request("POST", "/api/lines", b"{}", {"Content-Type": "text/plain"})
    assert status == 415 and b"JSON" in body
    assert client.get("/api/state")["lines"] == {}  # nothing learned


@pytest.mark.slow
def test_a_room_without_lines_is_the_status_not_an_error(tmp_path: Path) -> None:
    """The dark room (a rim, nothing straight in it): the status says how many lines were found and what the
    image needs; no table to save."""
    camera = line_camera("hyperbolic", SCALE)
    image = render_line_scene(camera, "dark", seed=1, supersample=1).image
    for client in serve(image, tmp_path):
        status, state = client.post("/api/lines", {})
        assert status == 200
        lines = state["lines"]
        assert lines["ok"] is False and "straight" in lines["message"] and "needed" in lines["message"], lines
        status, answer = client.post("/api/lines/save", {"name": "x.npz"})
        assert status == 409 and "learn from lines first" in answer["error"]
        assert not (tmp_path / "x.npz").exists()


@pytest.mark.slow
def test_learn_from_lines_takes_the_checkerboards_first(tmp_path: Path) -> None:
    """An image with three boards held before the camera: the page learns from them, as ``panomap fit --image``
    does (four grids found, three kept), draws their rows and columns, and its camera is the command's.

    Measured: 3 boards kept, their band 1.25 px at 95% at 90 deg; p90 1.12 / max 1.36 px over the whole annulus
    against the true camera (the field they span is 53-89 deg off the axis; the rest is extrapolated). Two boards
    in it (this test's until their projection uncertainty was told) are refused, 2.7 px at 95% at 90 deg, though
    their camera lay p90 0.39 / max 0.46 px from the true one: the band says what the corners pin, not how lucky
    one draw of them was; four (seed 30) are 1.89 px and p90 1.94 px off.
    """
    from panomap.simulate.board_scenes import board_poses, render_board_scene

    from helpers import pixel_errors

    camera = line_camera("hyperbolic", 0.5, tilt_deg=2.0)
    image = render_board_scene(camera, board_poses(camera, 3, seed=30), seed=1, supersample=2).image
    if image.ndim == 2:
        image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    for client in serve(image, tmp_path):
        status, state = client.post("/api/lines", {})
        assert status == 200, state
        lines = state["lines"]
        assert lines["ok"], lines
        assert lines["boards"] == 3 and "checkerboard" in lines["message"]
        assert all(len(line["points"]) == 1 and len(line["points"][0]) >= 2 for line in lines["used"])
        status, saved = client.post("/api/lines/save", {"name": "boards.npz"})
        assert status == 200, saved
    learned = load_table(tmp_path / "boards.npz").model
    errors = pixel_errors(learned, camera, step=4)
    assert np.percentile(errors, 90) < 1.5
    assert errors.max() < 2.0
    cv2.imwrite(str(tmp_path / "boards.png"), image)
    result = CliRunner().invoke(main, ["fit", "-o", str(tmp_path / "cli.npz"), "--image", str(tmp_path / "boards.png")])
    assert result.exit_code == 0, result.output
    command = load_table(tmp_path / "cli.npz").model
    assert command.centre == pytest.approx(learned.centre, abs=1e-6)
    assert command.radial.coefficients == pytest.approx(learned.radial.coefficients, rel=1e-9)
