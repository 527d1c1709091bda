"""``panomap learn``'s server, through its JSON API (urllib against a server thread on port 0).

Ground truth: the bundled room rendered through a simulated hyperbolic-mirror camera
(rotated, mirrored, off-centre) and the room's landmarks at their true pixels, from the
simulated camera's closed-form projection (:mod:`panomap.simulate.example`).
"""

from __future__ import annotations

import http.client
import json
import math
import os
import select
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Iterator
from email.message import Message
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from panomap.calibrate.landmarks.pairs import Landmarks, landmarks_to_csv, landmarks_to_json, read_landmarks
from panomap.cli.app import main
from panomap.errors import PanomapError
from panomap.learn import session as session_module
from panomap.learn.server import LearnServer, json_safe, make_server, serve_in_thread
from panomap.learn.session import Session
from panomap.simulate.example import Example
from panomap.table.file import load_table

SIZE = (480, 480)


class Client:
    """A tiny JSON client for one server."""

    def __init__(self, server: LearnServer) -> None:
        self.url = server.url.rstrip("/")

    def request(
        self, method: str, path: str, body: bytes | None = None, headers: dict[str, str] | None = None
    ) -> tuple[int, bytes]:
        status, _, answer = self.exchange(method, path, body, headers)
        return status, answer

    def exchange(
        self, method: str, path: str, body: bytes | None = None, headers: dict[str, str] | None = None
    ) -> tuple[int, Message, bytes]:
        """Status, headers and body of one request."""
        request = urllib.request.Request(self.url + path, body, headers or {}, method=method)
        try:
            with urllib.request.urlopen(request, timeout=30) as response:
                return response.status, response.headers, response.read()
        except urllib.error.HTTPError as exc:
            return exc.code, exc.headers, exc.read()

    def get(self, path: str) -> Any:
        status, body = self.request("GET", path)
        assert status == 200, body
        return json.loads(body)

    def post(self, path: str, data: Any, headers: dict[str, str] | None = None) -> tuple[int, Any]:
        sent = {"Content-Type": "application/json"} | (headers or {})
        status, body = self.request("POST", path, json.dumps(data).encode(), sent)
        return status, json.loads(body)

    def post_raw(self, path: str, body: bytes, content_type: str = "application/json") -> tuple[int, Any]:
        status, answer = self.request("POST", path, body, {"Content-Type": content_type})
        return status, json.loads(answer)


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    inside = tmp_path / "work"
    inside.mkdir()
    return inside


@pytest.fixture
def client(example: Example, folder: Path) -> Iterator[Client]:
    server = make_server(Session(example.image, "omni.png", folder), port=0)
    thread = serve_in_thread(server)
    yield Client(server)
    server.shutdown()
    server.server_close()
    thread.join(5)


def true_landmarks(example: Example, count: int | None = None) -> list[dict[str, Any]]:
    rows = [
        {"name": name, "u": float(p[0]), "v": float(p[1]), "X": float(w[0]), "Y": float(w[1]), "Z": float(w[2])}
        for name, p, w in zip(example.names, example.pixels, example.world, strict=True)
    ]
    return rows[:count]


def all_files(root: Path) -> set[Path]:
    return {p for p in root.rglob("*")}


@pytest.mark.slow
def test_true_landmarks_fit_with_small_residuals_and_a_panorama(client: Client, example: Example) -> None:
    state = client.get("/api/state")
    assert state["image"] == {"name": "omni.png", "width": SIZE[0], "height": SIZE[1]}
    # The detected centre is within 0.1 px of the simulated camera's (docs/centre.md: a few hundredths).
    assert np.allclose(state["circles"]["centre"], example.camera.centre, atol=0.1)
    assert state["fit"]["ok"] is False and state["fit"]["need"] == 5

    status, answer = client.post(
        "/api/state", {"camera": list(example.camera_position), "landmarks": true_landmarks(example)}
    )
    assert status == 200, answer
    fit = answer["fit"]
    assert fit["ok"], fit["message"]
    assert fit["s"] == -1  # the simulated camera is mirrored
    assert [row["name"] for row in fit["landmarks"]] == list(example.names)
    residuals = np.array([row["residual_px"] for row in fit["landmarks"]])
    # Exact pixels, centre detected to ~0.01 px: every residual is a few hundredths of a pixel.
    assert residuals.max() < 0.05, residuals
    assert not any(row["outlier"] for row in fit["landmarks"])
    # The detected centre is refined with the landmarks, and a clean fit has nothing to diagnose.
    assert fit["centre_refined"] is True and "centre refined with the landmarks" in fit["message"]
    assert fit["diagnosis"] == []
    curve = fit["curve"]
    assert len(curve["elevation_deg"]) == len(curve["radius_px"]) == len(curve["se_px"]) == 91
    # The curve passes through the landmarks (radius from the centre) within the residuals.
    for row in curve["landmarks"]:
        r = np.interp(row["elevation_deg"], curve["elevation_deg"], curve["radius_px"])
        assert abs(r - row["radius_px"]) < 0.1

    status, png = client.request("GET", "/api/panorama.png")
    assert status == 200
    pano = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_UNCHANGED)
    assert pano.shape == (180, 720, 3)
    assert float(pano.mean()) > 40  # the room, not a black fill


def test_too_few_landmarks_say_how_many_more(client: Client, example: Example) -> None:
    rows = [*true_landmarks(example, 3), {"name": "pending", "u": 10.0, "v": 20.0, "X": None, "Y": None, "Z": None}]
    status, answer = client.post("/api/state", {"camera": list(example.camera_position), "landmarks": rows})
    assert status == 200
    assert answer["fit"]["ok"] is False and answer["fit"]["need"] == 2
    assert "need 2 more landmark(s)" in answer["fit"]["message"]
    assert "1 still without a world point" in answer["fit"]["message"]
    assert answer["landmarks"][3] == {"name": "pending", "u": 10.0, "v": 20.0, "X": None, "Y": None, "Z": None}
    status, answer = client.post("/api/state", {"camera": None, "landmarks": true_landmarks(example)})
    assert answer["fit"]["message"] == "give the camera position X0, Y0, Z0 to fit"
    status, body = client.request("GET", "/api/panorama.png")
    assert status == 409 and "no fit yet" in json.loads(body)["error"]
    status, answer = client.post("/api/table/save", {"name": "cam.npz"})
    assert status == 409 and "no table to save" in answer["error"]


GOOD = {"name": "a", "u": 100.0, "v": 100.0, "X": 1.0, "Y": 2.0, "Z": 0.0}


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (b"{not json", "not valid JSON"),
        (b"[1, 2]", "must be a JSON object"),
        (b'{"camera": [NaN, 1, 2]}', "holds NaN"),
        (b'{"camera": [Infinity, 1, 2]}', "holds Infinity"),
        (b'{"camera": [1e999, 1, 2]}', "camera[0] must be finite"),
        (b'{"camera": ["1", 1, 2]}', 'camera[0] must be a number, not "1"'),
        (b'{"camera": [true, 1, 2]}', "camera[0] must be a number, not true"),
        (b'{"camera": [1, 2]}', "camera must be a list of 3 numbers"),
        (b'{"camera": [1e9, 1, 2]}', "too large"),
        (b'{"camara": [1, 2, 3]}', "unknown field(s) camara"),
        (b'{"model": "cubic"}', "model must be one of auto"),
        (b'{"landmarks": {}}', "landmarks must be a list"),
        (b'{"landmarks": [5]}', "landmark 1 must be an object"),
        (b'{"landmarks": [{"name": "a", "u": 1, "v": 2, "X": 1, "Y": 2, "Z": 3, "W": 1}]}', "unknown field(s) W"),
        (b'{"landmarks": [{"name": "a,b", "u": 1, "v": 2}]}', "without commas"),
        (b'{"landmarks": [{"name": "", "u": 1, "v": 2}]}', "the name must be 1 to 64"),
        (b'{"landmarks": [{"name": "a", "u": 1000, "v": 2}]}', "is outside the 480 x 480 image"),
        (b'{"landmarks": [{"name": "a", "u": -0.6, "v": 2}]}', "is outside the 480 x 480 image"),
        (b'{"landmarks": [{"name": "a", "v": 2}]}', "landmark 1 (a): u must be a number, not null"),
        (b'{"landmarks": [{"name": "a", "u": 1, "v": 2, "X": 1}]}', "landmark 1 (a): Y must be a number"),
        (json.dumps({"landmarks": [GOOD, GOOD]}).encode(), "two landmarks are named 'a'"),
        (json.dumps({"landmarks": [GOOD | {"name": f"n{k}"} for k in range(501)]}).encode(), "more than the limit"),
        (b'{"circles": {"centre": [1, 2], "cutoff_radius": 50, "outer_radius": 40}}', "0 <= cut-off (50) < outer"),
        (b'{"circles": {"centre": [900, 2], "cutoff_radius": 0, "outer_radius": 40}}', "outside the 480 x 480"),
        (b'{"circles": {"centre": [9, 2]}}', "circles: missing cutoff_radius, outer_radius"),
        (b"\xff\xfe", "not UTF-8"),
        (b'{"camera": ' + b"[" * 100_000 + b"]" * 100_000 + b"}", "nested too deeply"),
        (b'{"camera": [' + b"7" * 5000 + b", 1, 2]}", "a number too long to read"),
        (b'{"camera": [1' + b"0" * 400 + b", 1, 2]}", "camera[0] must be finite"),
    ],
)
def test_bad_state_is_refused_with_a_clear_error_and_changes_nothing(client: Client, body: bytes, message: str) -> None:
    before = client.get("/api/state")
    status, answer = client.post_raw("/api/state", body)
    assert status == 400
    assert message in answer["error"], answer
    assert client.get("/api/state") == before


def test_requests_that_are_not_json_or_not_here_are_refused(client: Client) -> None:
    status, answer = client.post_raw("/api/state", b"camera=1", "application/x-www-form-urlencoded")
    assert status == 415 and "Content-Type: application/json" in answer["error"]
    # A body announced as larger than 1 MiB is refused before it is read.
    status, body = client.request(
        "POST", "/api/state", b"{}", {"Content-Type": "application/json", "Content-Length": str((1 << 20) + 1)}
    )
    assert status == 413 and "larger than" in json.loads(body)["error"]
    status, body = client.request("GET", "/api/nothing")
    assert status == 404 and json.loads(body)["error"] == "no such API: GET /api/nothing"
    status, body = client.request("GET", "/static/../../etc/passwd")
    assert status == 404
    status, body = client.request("PUT", "/api/state", b"{}", {"Content-Type": "application/json"})
    assert status == 405
    status, body = client.request("GET", "/api/state", headers={"Host": "evil.example:80"})
    assert status == 403 and "loopback" in json.loads(body)["error"]
    for page, kind in (("/", b"<!doctype html>"), ("/static/app.js", b'"use strict"'), ("/static/app.css", b"")):
        status, body = client.request("GET", page)
        assert status == 200 and kind in body


def raw_request(
    client: Client, method: str, path: str, headers: dict[str, str], body: bytes = b""
) -> tuple[int, Any, Any]:
    """One request with exactly ``headers`` (http.client adds no Content-Length of its own here):
    the status, the answer's headers and its JSON (or raw) body."""
    address = urllib.parse.urlsplit(client.url)
    connection = http.client.HTTPConnection(address.hostname, address.port, timeout=30)
    try:
        connection.putrequest(method, path, skip_host="Host" in headers, skip_accept_encoding=True)
        for key, value in headers.items():
            connection.putheader(key, value)
        connection.endheaders(body or None)
        response = connection.getresponse()
        data = response.read()
        kind = response.headers.get("Content-Type", "")
        return response.status, response.headers, json.loads(data) if kind == "application/json" else data
    finally:
        connection.close()


def test_posts_name_the_host_and_give_their_length_and_every_answer_has_its_guards(
    client: Client, example: Example
) -> None:
    """The Host check holds for POSTs too (DNS rebinding would post); a POST with no Content-Length
    is refused (the body cannot be framed); every answer, page or error, forbids caching and
    sniffing and carries the content security policy."""
    before = client.get("/api/state")
    host = urllib.parse.urlsplit(client.url).netloc
    body = json.dumps({"camera": list(example.camera_position)}).encode()
    json_headers = {"Content-Type": "application/json", "Content-Length": str(len(body))}
    status, _, answer = raw_request(client, "POST", "/api/state", {**json_headers, "Host": "evil.example:80"}, body)
    assert status == 403 and "loopback" in answer["error"]
    status, _, answer = raw_request(client, "POST", "/api/state", {"Host": host, "Content-Type": "application/json"})
    assert status == 400 and answer["error"] == "the request has no Content-Length"
    assert client.get("/api/state") == before
    status, _, answer = raw_request(client, "POST", "/api/state", {**json_headers, "Host": host}, body)
    assert status == 200 and answer["camera"] == list(example.camera_position)
    for path in ("/", "/api/state", "/api/image", "/api/nothing"):
        status, headers, _ = raw_request(client, "GET", path, {"Host": host})
        assert status == (404 if path == "/api/nothing" else 200)
        assert headers["Cache-Control"] == "no-store"
        assert headers["X-Content-Type-Options"] == "nosniff"
        assert headers["Content-Security-Policy"].startswith("default-src 'self'")


@pytest.mark.slow
def test_symbolic_links_are_never_followed(client: Client, example: Example, folder: Path) -> None:
    """A link in the folder, to a file outside it: loading refuses it as no file; saving (once told to
    overwrite) replaces the link by a file of its own and leaves the file outside as it was."""
    client.post("/api/state", {"camera": list(example.camera_position), "landmarks": true_landmarks(example)})
    outside = folder.parent / "outside.csv"
    outside.write_text("name,u,v,X,Y,Z\nfar,1,2,3,4,5\n")
    (folder / "linked.csv").symlink_to(outside)
    status, answer = client.post("/api/landmarks/load", {"name": "linked.csv"})
    assert status == 404 and "there is no file 'linked.csv'" in answer["error"]
    # The link is a name already taken: saving asks first (409), and with overwrite replaces the link itself.
    status, answer = client.post("/api/landmarks/save", {"name": "linked.csv"})
    assert status == 409 and answer["exists"] == "linked.csv", answer
    assert (folder / "linked.csv").is_symlink()
    status, answer = client.post("/api/landmarks/save", {"name": "linked.csv", "overwrite": True})
    assert status == 200, answer
    assert not (folder / "linked.csv").is_symlink()
    assert outside.read_text() == "name,u,v,X,Y,Z\nfar,1,2,3,4,5\n"
    assert len((folder / "linked.csv").read_text().splitlines()) == 1 + len(example.names)


BAD_NAMES = [
    ("/api/landmarks/save", "../x.csv", "bare file name"),
    ("/api/landmarks/save", "..x.csv", "must not contain '..'"),
    ("/api/landmarks/save", "/tmp/x.csv", "bare file name"),
    ("/api/landmarks/save", "sub\\x.csv", "bare file name"),
    ("/api/landmarks/save", "~x.csv", "bare file name"),
    ("/api/landmarks/save", ".x.csv", "must start with a letter or digit"),
    ("/api/landmarks/save", "x.txt", "must end in .csv or .json"),
    ("/api/landmarks/save", "x.npz", "must end in .csv or .json"),
    ("/api/landmarks/save", "", "give a file name"),
    ("/api/landmarks/save", 5, "give a file name"),
    ("/api/landmarks/load", "../x.csv", "bare file name"),
    ("/api/landmarks/load", "missing.csv", "there is no file 'missing.csv'"),
    ("/api/table/save", "../../cam.npz", "bare file name"),
    ("/api/table/save", "cam.csv", "must end in .npz"),
]


@pytest.mark.slow
def test_file_names_stay_in_the_folder(client: Client, example: Example, folder: Path) -> None:
    client.post("/api/state", {"camera": list(example.camera_position), "landmarks": true_landmarks(example)})
    root = folder.parent
    before = all_files(root)
    for path, name, message in BAD_NAMES:
        status, answer = client.post(path, {"name": name})
        assert status == (404 if name == "missing.csv" else 400), (name, answer)
        assert message in answer["error"], (name, answer)
    status, answer = client.post("/api/table/save", {"name": "cam.npz", "folder": "/tmp"})
    assert status == 400 and "unknown field(s) folder" in answer["error"]
    assert all_files(root) == before


@pytest.mark.slow
def test_saved_files_are_what_panomap_fit_makes(client: Client, example: Example, folder: Path) -> None:
    """The saved table equals ``panomap fit --image`` on the saved landmarks, the same image and camera: the page
    fits with the circles it found as the command does (the centre refined, the cut-off disc about it)."""
    root = folder.parent
    before = all_files(root)
    status, answer = client.post(
        "/api/state", {"camera": list(example.camera_position), "landmarks": true_landmarks(example)}
    )
    circles = answer["circles"]
    assert answer["fit"]["ok"]
    for path, name in (
        ("/api/landmarks/save", "lm.csv"),
        ("/api/landmarks/save", "lm.json"),
        ("/api/table/save", "web.npz"),
    ):
        status, reply = client.post(path, {"name": name})
        assert status == 200 and reply == {"wrote": name}
    # Nothing but the three files, all in the folder (the temporary files are gone).
    assert all_files(root) - before == {folder / "lm.csv", folder / "lm.json", folder / "web.npz"}
    csv_landmarks, json_landmarks = read_landmarks(folder / "lm.csv"), read_landmarks(folder / "lm.json")
    for read in (csv_landmarks, json_landmarks):
        assert read.names == example.names
        assert np.array_equal(read.pixels, example.pixels)  # repr() round trip: exact
        assert np.array_equal(read.world, example.world)
    assert json_landmarks.camera == example.camera_position
    assert client.get("/api/files") == {"landmarks": ["lm.csv", "lm.json"], "tables": ["web.npz"]}

    assert cv2.imwrite(str(folder / "omni.png"), example.image)  # (lossless: the page's pixels)
    result = CliRunner().invoke(
        main,
        [
            "fit",
            str(folder / "lm.csv"),
            "-o",
            str(folder / "cli.npz"),
            "--camera",
            *(repr(c) for c in example.camera_position),
            "--image",
            str(folder / "omni.png"),
        ],
    )
    assert result.exit_code == 0, result.output
    web, cli = load_table(folder / "web.npz"), load_table(folder / "cli.npz")
    assert web.size == cli.size and web.elevation_range == cli.elevation_range
    assert web.model.to_dict() == cli.model.to_dict()
    assert web.cutoff_radius == cli.cutoff_radius and web.outer_radius == cli.outer_radius
    assert web.info["sources"] == cli.info["sources"]
    assert tuple(web.model.centre) != tuple(circles["centre"])  # refined from the rim's centre
    # Same inputs to the same code path: the float32 entries agree to rounding (1e-4 px allows
    # for a last-digit difference in a threaded BLAS reduction; they are in fact equal here).
    assert np.allclose(web.entries, cli.entries, rtol=0, atol=1e-4)
    assert web.info["learned_with"] == "panomap learn on omni.png"


def test_loading_landmarks_replaces_them_and_the_camera(client: Client, example: Example, folder: Path) -> None:
    client.post("/api/state", {"camera": list(example.camera_position), "landmarks": true_landmarks(example, 6)})
    assert client.post("/api/landmarks/save", {"name": "six.json"})[0] == 200
    client.post("/api/state", {"camera": [0, 0, 1], "landmarks": []})
    status, state = client.post("/api/landmarks/load", {"name": "six.json"})
    assert status == 200
    assert state["camera"] == list(example.camera_position)
    assert [row["name"] for row in state["landmarks"]] == list(example.names[:6])
    assert state["fit"]["ok"]
    (folder / "bad.csv").write_text("u,v,X\n1,2,3\n")
    status, answer = client.post("/api/landmarks/load", {"name": "bad.csv"})
    assert status == 400 and "bad.csv: the CSV lacks the column(s) Y,Z" in answer["error"]


def test_landmarks_without_world_points_are_not_saved(client: Client, example: Example, folder: Path) -> None:
    rows = [*true_landmarks(example, 5), {"name": "later", "u": 1.0, "v": 1.0}]
    client.post("/api/state", {"camera": list(example.camera_position), "landmarks": rows})
    status, answer = client.post("/api/landmarks/save", {"name": "lm.csv"})
    assert status == 400 and "later have no world point yet" in answer["error"]
    assert not (folder / "lm.csv").exists()


def test_an_image_without_circles_starts_from_a_guess(folder: Path) -> None:
    session = Session(np.full((200, 300), 128, np.uint8), "grey.png", folder)
    state = session.state()
    assert state["circles"]["centre"] == [149.5, 99.5]
    # No rim at all: the frame centre starts the fit and the landmarks refine it; the table takes the whole frame.
    assert state["circles"]["outer_radius"] == pytest.approx(math.hypot(300, 200) / 2)
    assert state["circles"]["cutoff_radius"] == 0.0 and state["circles"]["detected"] is None
    note = state["circles"]["note"]
    assert note.startswith("no image circle found") and "the landmarks refine" in note and "whole frame" in note
    assert session._sources()["centre"].value == "frame centre (no image circle found)"
    assert session._sources()["outer_radius"].value == "default (the whole frame: no image circle in it)"


@pytest.mark.slow
def test_the_command_serves_until_interrupted(tmp_path: Path, example: Example) -> None:
    cv2.imwrite(str(tmp_path / "omni.png"), example.image)
    (tmp_path / "lm.json").write_text(
        landmarks_to_json(Landmarks(example.pixels, example.world, example.names, (0.0, 0.0, 9.0)))
    )
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1] / "src"))
    command = ["learn", "omni.png", "--port", "0", "--camera", "3.1", "2.4", "2.45", "--landmarks", "lm.json"]
    process = subprocess.Popen(
        [sys.executable, "-m", "panomap", *command],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert process.stdout is not None
        # (No line within 60 s fails the test instead of hanging it.)
        assert select.select([process.stdout], [], [], 60)[0], "the server printed nothing"
        line = process.stdout.readline()
        assert line.startswith("panomap learn: serving omni.png at http://127.0.0.1:"), line
        url = line.split(" at ")[1].split()[0]
        with urllib.request.urlopen(url + "api/state", timeout=30) as response:
            state = json.loads(response.read())
        # --camera wins over the JSON's camera.
        assert state["camera"] == [3.1, 2.4, 2.45] and state["folder"] == str(tmp_path.resolve())
        assert [row["name"] for row in state["landmarks"]] == list(example.names)
        assert state["fit"]["ok"]
    finally:
        process.send_signal(signal.SIGINT)
        try:
            out, err = process.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            # Never leave the server running (into later tests); say what it printed.
            process.kill()
            out, err = process.communicate()
            pytest.fail(f"the server did not stop within 30 s of SIGINT; stdout {out!r}, stderr {err!r}")
    assert process.returncode == 0, err
    assert out.strip() == "panomap learn: stopped" and err == ""


def test_the_command_fails_in_one_line(tmp_path: Path) -> None:
    result = CliRunner().invoke(main, ["learn", str(tmp_path / "none.png"), "--port", "0"])
    assert result.exit_code == 1
    assert result.stderr.strip() == f"panomap: error: {tmp_path / 'none.png'}: no such image file"
    cv2.imwrite(str(tmp_path / "omni.png"), np.zeros((64, 64), np.uint8))
    result = CliRunner().invoke(main, ["learn", str(tmp_path / "omni.png"), "--dir", str(tmp_path / "nowhere")])
    assert result.exit_code == 1 and "the folder does not exist" in result.stderr
    (tmp_path / "far.csv").write_text("name,u,v,X,Y,Z\nfar,100,5,1,2,3\n")
    result = CliRunner().invoke(main, ["learn", str(tmp_path / "omni.png"), "--landmarks", str(tmp_path / "far.csv")])
    assert result.exit_code == 1
    assert result.stderr.strip() == (
        "panomap: error: the landmarks to start with: landmark 1 (far): pixel (100, 5) is outside the 64 x 64 image"
    )
    result = CliRunner().invoke(main, ["learn", str(tmp_path / "omni.png"), "--port", "70000"])
    assert result.exit_code == 2 and "70000 is not in the range" in result.stderr


def test_reports_with_nan_are_sent_as_null() -> None:
    assert json_safe({"a": [1.0, float("nan")], "b": (float("inf"), "x", 2)}) == {"a": [1.0, None], "b": [None, "x", 2]}


def test_a_port_in_use_is_refused_with_a_reason(example: Example, folder: Path) -> None:
    session = Session(example.image, "omni.png", folder)
    first = make_server(session, port=0)
    try:
        with pytest.raises(PanomapError, match=r"cannot listen on 127.0.0.1:\d+ .*choose another port"):
            make_server(session, port=first.server_address[1])
    finally:
        first.server_close()


# ----------------------------------------------------------------------------- hardening (issue 14)


@pytest.fixture
def served(example: Example, folder: Path) -> Iterator[Any]:
    """``start(**make_server options)``: a server for the example image, stopped at the end."""
    started: list[tuple[LearnServer, threading.Thread]] = []

    def start(serve: bool = True, **options: Any) -> LearnServer:
        server = make_server(Session(example.image, "omni.png", folder), **options)
        started.append((server, serve_in_thread(server) if serve else threading.Thread()))
        return server

    yield start
    for server, thread in started:
        if thread.is_alive():
            server.shutdown()
            thread.join(5)
        server.server_close()


def test_a_silent_connection_is_closed_after_the_idle_timeout(served: Any) -> None:
    server = served(idle_timeout_s=0.5, port=0)
    with socket.create_connection(server.server_address[:2], timeout=30) as conn:
        conn.sendall(b"GET /api/state HTTP/1.1\r\n")  # ... and never the rest: a stalled client
        # The server closes it (EOF) after half a second; without a timeout this recv waits 30 s and fails.
        assert conn.recv(1024) == b""


def test_a_client_sending_a_byte_every_half_second_is_cut_off_at_the_request_deadline(served: Any) -> None:
    # The timeout was per read: a byte every few seconds kept the connection (and its thread) for ever.
    server = served(idle_timeout_s=5.0, request_deadline_s=1.0, port=0)
    request = b"GET /api/state HTTP/1.1\r\nHost: x\r\nX-Slow: " + b"a" * 200
    with socket.create_connection(server.server_address[:2], timeout=30) as conn:
        started = time.monotonic()
        closed_after = None
        for byte in request:
            try:
                conn.sendall(bytes([byte]))
            except (BrokenPipeError, ConnectionResetError):
                closed_after = time.monotonic() - started
                break
            readable, _, _ = select.select([conn], [], [], 0.5)
            if readable and conn.recv(1024) == b"":
                closed_after = time.monotonic() - started
                break
        # Cut off at the 1 s deadline (a read waits at most what is left of it), far before the 100 s the
        # 200 bytes would take, and before the 5 s idle timeout could have mattered.
        assert closed_after is not None and closed_after < 3.0, closed_after


def test_three_hundred_idle_connections_hold_no_thread_and_the_page_is_still_answered(served: Any) -> None:
    # Every connection had a thread until it closed: 304 threads for 300 idle connections.
    server = served(idle_timeout_s=30.0, port=0)
    before = threading.active_count()
    connections = [socket.create_connection(server.server_address[:2], timeout=10) for _ in range(150)]
    try:
        for conn in connections[:75]:
            conn.sendall(b"GET /api/fi")  # half a request line: parked, waiting for the rest
        deadline = time.monotonic() + 10
        while server.open_connections < 150 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert server.open_connections == 150
        assert threading.active_count() - before <= 10  # the pool (8) and a little, never one a connection
        host = f"{server.server_address[0]}:{server.server_address[1]}"
        with socket.create_connection(server.server_address[:2], timeout=10) as conn:
            conn.sendall(f"GET /api/files HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n".encode())
            answer = b""
            while chunk := conn.recv(65536):
                answer += chunk
        assert answer.startswith(b"HTTP/1.1 200 "), answer[:200]
    finally:
        for conn in connections:
            conn.close()


def test_thirty_concurrent_connections_are_all_answered(served: Any) -> None:
    # Thirty clients connect before the server accepts any: all must fit in the listen queue
    # (with socketserver's backlog of 5 the kernel drops the others' SYNs and they time out).
    server = served(serve=False, port=0)
    connections = [socket.create_connection(server.server_address[:2], timeout=3) for _ in range(30)]
    thread = serve_in_thread(server)
    try:
        host = f"{server.server_address[0]}:{server.server_address[1]}"
        for conn in connections:
            conn.settimeout(30)
            conn.sendall(f"GET /api/files HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n".encode())
        for conn in connections:
            answer = b""
            while chunk := conn.recv(65536):
                answer += chunk
            assert answer.startswith(b"HTTP/1.1 200 "), answer[:200]
    finally:
        for conn in connections:
            conn.close()
        server.shutdown()
        thread.join(5)


def test_a_long_fit_does_not_block_reading_the_state(
    client: Client, example: Example, monkeypatch: pytest.MonkeyPatch
) -> None:
    fitting, release = threading.Event(), threading.Event()
    real = session_module.calibrate_camera

    def held_fit(*args: Any, **kwargs: Any) -> Any:
        fitting.set()
        assert release.wait(60), "the test never released the fit"
        return real(*args, **kwargs)

    monkeypatch.setattr(session_module, "calibrate_camera", held_fit)
    before = client.get("/api/state")
    answers: list[tuple[int, Any]] = []
    body = {"camera": list(example.camera_position), "landmarks": true_landmarks(example)}
    update = threading.Thread(target=lambda: answers.append(client.post("/api/state", body)))
    update.start()
    try:
        assert fitting.wait(30)
        # While the fit waits, the page's reads are answered, with the state before the change.
        assert client.get("/api/state") == before
        assert client.get("/api/files") == {"landmarks": [], "tables": []}
        status, _ = client.request("GET", "/api/image")
        assert status == 200
    finally:
        release.set()
        update.join(60)
    assert answers and answers[0][0] == 200 and answers[0][1]["fit"]["ok"]
    after = client.get("/api/state")
    assert after["revision"] == before["revision"] + 1 and after["fit"]["ok"]


def test_every_answer_forbids_framing(client: Client) -> None:
    for method, path, body in (
        ("GET", "/", None),
        ("GET", "/static/app.js", None),
        ("GET", "/api/state", None),
        ("GET", "/api/image", None),
        ("GET", "/api/nothing", None),
        ("POST", "/api/state", b"{}"),
        ("POST", "/api/state", b"{bad"),
        ("PUT", "/api/state", b"{}"),
    ):
        status, headers, _ = client.exchange(method, path, body, {"Content-Type": "application/json"})
        assert headers["X-Frame-Options"] == "DENY", (method, path, status)
        assert "frame-ancestors 'none'" in headers["Content-Security-Policy"], (method, path, status)


def test_a_foreign_origin_cannot_change_anything(client: Client, example: Example, folder: Path) -> None:
    client.post("/api/state", {"camera": list(example.camera_position), "landmarks": true_landmarks(example)})
    before = client.get("/api/state")
    own = "http://" + client.url.split("://")[1]
    for origin in ("http://evil.example", "null", own + ".evil.example", own.replace("http:", "https:")):
        for path, body in (
            ("/api/state", {"camera": [0, 0, 1]}),
            ("/api/landmarks/save", {"name": "lm.csv"}),
            ("/api/table/save", {"name": "cam.npz"}),
        ):
            status, answer = client.post(path, body, {"Origin": origin})
            assert status == 403 and "another site's page" in answer["error"], (origin, path, answer)
    assert client.get("/api/state") == before and not list(folder.iterdir())
    # The page's own origin (a browser sends it) and none (a script) are served.
    assert client.post("/api/landmarks/save", {"name": "lm.csv"}, {"Origin": own})[0] == 200
    assert client.post("/api/table/save", {"name": "cam.npz"})[0] == 200


def test_saving_onto_an_existing_file_needs_overwrite(client: Client, example: Example, folder: Path) -> None:
    client.post("/api/state", {"camera": list(example.camera_position), "landmarks": true_landmarks(example)})
    for path, name in (
        ("/api/landmarks/save", "lm.csv"),
        ("/api/landmarks/save", "lm.json"),
        ("/api/table/save", "cam.npz"),
    ):
        (folder / name).write_text("kept")
        status, answer = client.post(path, {"name": name})
        assert status == 409 and answer["exists"] == name, answer
        assert f"'{name}' already exists" in answer["error"] and "overwrite" in answer["error"]
        assert (folder / name).read_text() == "kept"
        status, answer = client.post(path, {"name": name, "overwrite": "yes"})
        assert status == 400 and "overwrite must be true or false" in answer["error"]
        assert (folder / name).read_text() == "kept"
        status, answer = client.post(path, {"name": name, "overwrite": True})
        assert status == 200 and answer == {"wrote": name}
    assert read_landmarks(folder / "lm.csv").names == example.names
    assert load_table(folder / "cam.npz").size is not None
    # A folder of that name is never replaced, overwrite or not: 400 with the reason, no traceback.
    (folder / "sub.csv").mkdir()
    for overwrite in (False, True):
        status, answer = client.post("/api/landmarks/save", {"name": "sub.csv", "overwrite": overwrite})
        assert status == 400 and "'sub.csv' is a folder" in answer["error"], answer
    assert (folder / "sub.csv").is_dir()


def test_an_ipv6_host_is_served(served: Any) -> None:
    try:
        server = served(host="::1", port=0)
    except PanomapError as exc:  # a machine without IPv6: nothing to test
        if "address" in str(exc).lower() and not socket.has_ipv6:
            pytest.skip(f"no IPv6 here: {exc}")
        raise
    assert server.url.startswith("http://[::1]:")
    assert served(host="[::1]", port=0).url.startswith("http://[::1]:")  # as written in a URL
    client = Client(server)
    assert client.get("/api/state")["image"]["name"] == "omni.png"
    status, answer = client.post("/api/state", {"model": "auto"}, {"Origin": server.url.rstrip("/")})
    assert status == 200, answer


def test_formula_names_are_escaped_in_csv_and_read_back(client: Client, example: Example, folder: Path) -> None:
    names = ["=HYPERLINK(1)", "+1", "-2", "@SUM(A1)", "plain", "a-b"]
    rows = [row | {"name": name} for row, name in zip(true_landmarks(example), names, strict=False)]
    status, _ = client.post("/api/state", {"camera": list(example.camera_position), "landmarks": rows})
    assert status == 200
    status, answer = client.post("/api/landmarks/save", {"name": "lm.csv"})
    assert status == 200, answer
    cells = [line.split(",")[0] for line in (folder / "lm.csv").read_text().splitlines()[1:]]
    # OWASP: a cell a spreadsheet would run starts with a single quote instead.
    assert cells == ["'=HYPERLINK(1)", "'+1", "'-2", "'@SUM(A1)", "plain", "a-b"]
    assert read_landmarks(folder / "lm.csv").names == tuple(names)
    # The library's writer round-trips any name, commas and quotes too.
    odd = ("a,b", 'say "hi"', "\tTAB", "-", "'=quoted", "'")
    path = folder / "odd.csv"
    path.write_text(landmarks_to_csv(Landmarks(example.pixels[:6], example.world[:6], odd)))
    assert read_landmarks(path).names == odd


def test_a_landmark_file_meets_the_limits_of_typed_input(
    client: Client, example: Example, folder: Path, tmp_path: Path
) -> None:
    far = Landmarks(example.pixels, example.world, example.names, (1e9, 0.0, 2.0))
    (folder / "far.json").write_text(landmarks_to_json(far))
    before = client.get("/api/state")
    status, answer = client.post("/api/landmarks/load", {"name": "far.json"})
    assert (
        status == 400
        and answer["error"] == "load landmarks: far.json: camera[0] = 1e+09 is too large (at most 1e+06 in size)"
    )
    assert client.get("/api/state") == before
    cv2.imwrite(str(tmp_path / "omni.png"), example.image)
    result = CliRunner().invoke(main, ["learn", str(tmp_path / "omni.png"), "--landmarks", str(folder / "far.json")])
    assert result.exit_code == 1
    assert result.stderr.strip() == (
        "panomap: error: the landmarks to start with: camera[0] = 1e+09 is too large (at most 1e+06 in size)"
    )


def test_a_tilted_camera_is_fitted_and_said_on_the_page(client: Client, example: Example) -> None:
    """Landmarks of the example camera tilted 2 deg toward azimuth 120 deg (the same image: the circles are
    the camera's): the page's fit finds the tilt and says it, with a residual near zero."""
    import math

    from panomap.simulate.cameras import TiltedCamera, mount_rotation

    tilted = TiltedCamera(example.camera, mount_rotation(math.radians(2.0), math.radians(120.0)))
    pixels = tilted.project(example.world - np.asarray(example.camera_position))
    seen = np.all(np.isfinite(pixels), axis=1)
    rows = [
        {"name": name, "u": float(p[0]), "v": float(p[1]), "X": float(w[0]), "Y": float(w[1]), "Z": float(w[2])}
        for name, p, w, keep in zip(example.names, pixels, example.world, seen, strict=True)
        if keep
    ]
    assert len(rows) >= len(example.names) - 1
    status, answer = client.post("/api/state", {"camera": list(example.camera_position), "landmarks": rows})
    assert status == 200, answer
    fit = answer["fit"]
    assert fit["ok"], fit["message"]
    # Measured: 2.000 deg toward 120.0 deg, residuals below 0.05 px (the centre refined from the rim's).
    assert fit["tilt_deg"] == pytest.approx(2.0, abs=0.01)
    assert fit["tilt_toward_deg"] == pytest.approx(120.0, abs=0.5)
    assert "tilt (fitted): the optical axis is 2.00" in fit["message"]
    assert max(row["residual_px"] for row in fit["landmarks"]) < 0.05
    # The horizon the page draws is where the tilted camera sees it (up to 5 px off the level camera's here).
    theta = np.linspace(0.0, 2 * math.pi, len(fit["horizon"]), endpoint=False)
    truth = tilted.project(np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], axis=-1))
    level = example.camera.project(np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], axis=-1))
    drawn = np.array([point if point is not None else [np.nan, np.nan] for point in fit["horizon"]])
    both = np.all(np.isfinite(drawn), axis=1) & np.all(np.isfinite(truth), axis=1)
    assert both.mean() > 0.9
    assert np.max(np.linalg.norm(drawn[both] - truth[both], axis=1)) < 0.5
    assert np.max(np.linalg.norm(level[both] - truth[both], axis=1)) > 3
