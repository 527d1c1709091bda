"""The viewer's server side: the table's textures, the API and its security, range requests, the decoded frames.

The page itself (the shader) is tested in a real browser in ``test_viewer_browser.py``. Here the
textures are checked against the table's entries by the layout the module documents (closed form),
the API against HTTP, and the frame feed against a clip whose frame times are known.
"""

from __future__ import annotations

import dataclasses
import http.client
import json
import re
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest

from panomap.errors import PanomapError
from panomap.interop.orient import orient_table
from panomap.io.local_web import RequestError
from panomap.simulate import standard_cameras
from panomap.table.table import PanoMappingTable
from panomap.video.live import Reconnect
from panomap.viewer.feed import FrameFeed
from panomap.viewer.server import MAX_RANGE_BYTES, ViewerServer, byte_range, make_server
from panomap.viewer.source import Source, open_source
from panomap.viewer.table_texture import NO_ENTRY, lookup_texture, padded_entries, texture_data
from panomap.views.lookup import direction_lookup

from helpers import (
    LIMIT_S,
    StreamServer,
    assert_one_line_error,
    room_camera_files,
    run,
    serving,
    wait_until,
    write_clip,
)

SIZE = (160, 160)
RATE = 25
CAMERA = standard_cameras(SIZE, centre=(80.2, 79.7))["equidistant"]


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """cam.npz (a table of the simulated camera), omni.png (its picture), clip.avi (2 s at 25 fps, MPEG-4
    part 2: no browser plays it), clip.mp4 (H.264) and clip.ts (MPEG-TS, for a live stream)."""
    folder = tmp_path_factory.mktemp("viewer")
    omni = room_camera_files(folder, CAMERA, SIZE, seed=4)
    moving = [np.roll(omni, 2 * k, axis=1) for k in range(500)]
    write_clip(folder / "clip.avi", moving[:50], RATE, "mpeg4")
    write_clip(folder / "clip.mp4", moving[:50], RATE)
    write_clip(folder / "clip.ts", moving, RATE, container_format="mpegts")
    return folder


@pytest.fixture(scope="module")
def table(work: Path) -> PanoMappingTable:
    from panomap.table.file import load_table

    return load_table(work / "cam.npz")


# ---------------------------------------------------------------------- textures


def test_the_table_texture_holds_each_entry_and_the_next_row_where_the_layout_says(table: PanoMappingTable) -> None:
    m, n = table.size
    entries = table.entries.astype(np.float64)
    texture = texture_data(table)
    width = texture.shape[1] - 1
    rng = np.random.default_rng(1)
    for i, j in [
        (0, 0),
        (m - 1, n - 1),
        (m - 1, 0),
        *zip(rng.integers(0, m, 50), rng.integers(0, n - 1, 50), strict=True),
    ]:
        block, column = divmod(int(i), width)
        texel = texture[block * (n + 1) + int(j), column]
        np.testing.assert_array_equal(texel[:2], entries[i, j])
        below = entries[i, j + 1] if j + 1 < n else 2 * entries[i, n - 1] - entries[i, n - 2]
        np.testing.assert_allclose(texel[2:], below, atol=1e-4)
        # The cell's second column: the next azimuth, wrapping at M.
        right = texture[block * (n + 1) + int(j), column + 1]
        np.testing.assert_array_equal(right[:2], entries[(i + 1) % m, j])


def test_a_wide_table_is_cut_into_blocks_whose_last_column_repeats_the_next_blocks_first(
    table: PanoMappingTable,
) -> None:
    m, n = 5000, 12
    rng = np.random.default_rng(2)
    entries = rng.uniform(0, 150, (m, n, 2)).astype(np.float32)
    wide = dataclasses.replace(table, entries=entries)
    texture = texture_data(wide)
    width = texture.shape[1] - 1
    assert width == 2047 and texture.shape[0] == 3 * (n + 1)
    for i in (0, 2046, 2047, 2048, 4094, 4095, 4999):
        block, column = divmod(i, width)
        np.testing.assert_array_equal(texture[block * (n + 1) + 5, column, :2], entries[i, 5])
        np.testing.assert_array_equal(texture[block * (n + 1) + 5, column + 1, :2], entries[(i + 1) % m, 5])


def test_entries_the_camera_does_not_see_are_sent_as_no_entry(table: PanoMappingTable) -> None:
    entries = np.array(table.entries)
    entries[3, 4] = np.nan
    padded = padded_entries(dataclasses.replace(table, entries=entries))
    assert (padded[3, 4] == NO_ENTRY).all()
    assert np.isfinite(padded).all()
    n = table.size[1]
    entries = np.array(table.entries)
    entries[7, n - 2] = np.nan  # the extrapolated rows read it
    padded = padded_entries(dataclasses.replace(table, entries=entries))
    assert (padded[7, n] == NO_ENTRY).all() and (padded[7, n + 1] == NO_ENTRY).all()


def test_the_lookup_texture_is_the_lookups_u_and_v(table: PanoMappingTable) -> None:
    made = lookup_texture(table)
    lookup = direction_lookup(table)
    assert made is not None and lookup is not None
    texture, description = made
    side = lookup.u.shape[0]
    assert texture.shape == (side, side, 2) and description["side"] == side
    assert description["scale"] == lookup.scale and description["centre"] == lookup.centre
    ok = np.isfinite(lookup.u) & np.isfinite(lookup.v)
    np.testing.assert_array_equal(texture[..., 0][ok], lookup.u[ok])
    np.testing.assert_array_equal(texture[..., 1][ok], lookup.v[ok])
    assert (texture[~ok] == NO_ENTRY).all()
    assert description["frame"] == np.eye(3).tolist()


def test_a_turned_camera_gets_a_lookup_about_its_own_axis(table: PanoMappingTable) -> None:
    """Looking ahead (elevations -90..90 deg: no CLI lookup), the page's lookup is centred on the optical axis
    (+X) and reads the table's own sampling of a ray (here: texels' rays, read at their centres)."""
    ahead = orient_table(table, 0.0, 0.0, 0.0)
    assert direction_lookup(ahead) is None
    made = lookup_texture(ahead)
    assert made is not None
    texture, description = made
    frame = np.asarray(description["frame"])
    np.testing.assert_allclose(frame @ frame.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(frame[2], [-1.0, 0.0, 0.0], atol=1e-12)  # the lookup's centre: the axis
    centre, scale = description["centre"], description["scale"]
    rng = np.random.default_rng(3)
    for _ in range(20):
        x, y = (int(c) for c in rng.integers(0, description["side"], 2))
        p = (np.array([x, y]) - centre) / scale
        q = 1.0 + p @ p
        ray = np.array([2 * p[0] / q, 2 * p[1] / q, (q - 2.0) / q]) @ frame  # the texel's ray, world axes
        theta = np.arctan2(ray[1], ray[0]) % (2 * np.pi)
        expected = ahead.sample(theta, np.arcsin(np.clip(ray[2], -1, 1)))
        if np.isfinite(expected).all():
            np.testing.assert_allclose(texture[y, x], expected, atol=1e-3)
        else:
            assert (texture[y, x] == NO_ENTRY).all()
    assert (texture == NO_ENTRY).any() and (texture != NO_ENTRY).any()


# ---------------------------------------------------------------------- sources


def test_sources_are_told_apart(work: Path) -> None:
    image = open_source(str(work / "omni.png"))
    assert image.kind == "image" and image.size == SIZE and image.image_png is not None
    decoded = cv2.imdecode(np.frombuffer(image.image_png, np.uint8), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(decoded, cv2.imread(str(work / "omni.png"), cv2.IMREAD_UNCHANGED))
    mp4 = open_source(str(work / "clip.mp4"))
    assert (mp4.kind, mp4.mime, mp4.size) == ("video", "video/mp4", SIZE)
    assert mp4.duration_s == pytest.approx(2.0, abs=0.05) and mp4.frame_rate == pytest.approx(RATE)
    avi = open_source(str(work / "clip.avi"))
    assert (avi.kind, avi.mime) == ("video", None)  # the server decodes it
    with pytest.raises(PanomapError, match="no such file"):
        open_source(str(work / "missing.png"))


def test_the_command_refuses_a_source_of_another_size_and_bad_files_in_one_line(work: Path, tmp_path: Path) -> None:
    other = tmp_path / "other.png"
    cv2.imwrite(str(other), np.zeros((100, 120, 3), np.uint8))
    assert_one_line_error(run("view", work / "cam.npz", other, "--port", "0"), "120 x 100", "160 x 160")
    junk = tmp_path / "junk.mp4"
    junk.write_bytes(b"not a video at all" * 10)
    assert_one_line_error(run("view", work / "cam.npz", junk, "--port", "0"), "junk.mp4")
    assert_one_line_error(run("view", tmp_path / "none.npz", work / "omni.png", "--port", "0"), "none.npz")


# ---------------------------------------------------------------------- the API


@pytest.fixture
def serve(table: PanoMappingTable) -> Iterator[object]:
    with serving() as start:
        yield lambda source, feed=None: start(make_server(table, "cam.npz", source, port=0, feed=feed))


def request(
    server: ViewerServer, method: str, path: str, body: bytes | None = None, headers: dict[str, str] | None = None
) -> tuple[int, dict[str, str], bytes]:
    host, port = server.server_address[:2]
    connection = http.client.HTTPConnection(str(host), int(port), timeout=LIMIT_S)
    try:
        connection.request(method, path, body, headers or {})
        answer = connection.getresponse()
        return answer.status, {k.lower(): v for k, v in answer.getheaders()}, answer.read()
    finally:
        connection.close()


def test_the_api_gives_the_table_the_image_and_a_description(
    serve: object, work: Path, table: PanoMappingTable
) -> None:
    server = serve(open_source(str(work / "omni.png")))  # type: ignore[operator]
    status, headers, body = request(server, "GET", "/api/info")
    assert status == 200
    info = json.loads(body)
    assert info["table"]["M"] == table.size[0] and info["table"]["N"] == table.size[1]
    assert info["table"]["rho_s"] == pytest.approx(table.elevation_range[0])
    assert info["source"] == {
        "name": "omni.png",
        "kind": "image",
        "size": list(SIZE),
        "mime": None,
        "duration_s": None,
        "frame_rate": None,
    }
    status, _, body = request(server, "GET", "/api/table.bin")
    assert status == 200 and body == texture_data(table).astype("<f4").tobytes()
    status, _, body = request(server, "GET", "/api/image")
    assert status == 200 and body[:8] == b"\x89PNG\r\n\x1a\n"
    for path in ("/", "/static/viewer.js", "/static/viewer.css"):
        status, headers, _ = request(server, "GET", path)
        assert status == 200
        assert headers["x-frame-options"] == "DENY" and "frame-ancestors 'none'" in headers["content-security-policy"]
    assert request(server, "GET", "/api/video")[0] == 404  # an image has no video
    assert request(server, "GET", "/../cam.npz")[0] == 404
    assert request(server, "GET", "/api/frame")[0] == 404


def test_requests_by_another_name_or_from_another_site_are_refused(serve: object, work: Path) -> None:
    server = serve(open_source(str(work / "clip.avi")))  # type: ignore[operator]
    assert request(server, "GET", "/api/info", headers={"Host": "evil.example:80"})[0] == 403
    body = json.dumps({"paused": True}).encode()
    json_type = {"Content-Type": "application/json"}
    assert request(server, "POST", "/api/playback", body, json_type | {"Origin": "http://evil.example"})[0] == 403
    assert request(server, "POST", "/api/playback", body, {"Content-Type": "text/plain"})[0] == 415
    assert request(server, "POST", "/api/playback", b'{"paused": 1}', json_type)[0] == 400
    assert request(server, "POST", "/api/playback", b'{"speed": 2}', json_type)[0] == 400
    assert request(server, "POST", "/api/playback", body, json_type)[0] == 200


def test_a_video_file_is_served_by_ranges(serve: object, work: Path) -> None:
    server = serve(open_source(str(work / "clip.mp4")))  # type: ignore[operator]
    data = (work / "clip.mp4").read_bytes()
    status, headers, body = request(server, "GET", "/api/video", headers={"Range": "bytes=100-299"})
    assert status == 206 and body == data[100:300]
    assert headers["content-range"] == f"bytes 100-299/{len(data)}" and headers["accept-ranges"] == "bytes"
    status, headers, body = request(server, "GET", "/api/video", headers={"Range": "bytes=-50"})
    assert status == 206 and body == data[-50:]
    status, _, body = request(server, "GET", "/api/video")
    assert status == 200 and body == data
    assert request(server, "GET", "/api/video", headers={"Range": f"bytes={len(data)}-"})[0] == 416
    assert request(server, "POST", "/api/playback", b"{}", {"Content-Type": "application/json"})[0] == 200


def test_byte_ranges_are_read_and_capped() -> None:
    assert byte_range(None, 1000) is None
    assert byte_range("bytes=0-", 1000) == (0, 999)
    assert byte_range("bytes=10-19", 1000) == (10, 19)
    assert byte_range("bytes=990-2000", 1000) == (990, 999)
    assert byte_range("bytes=-10", 1000) == (990, 999)
    assert byte_range("bytes=0-", 10 * MAX_RANGE_BYTES) == (0, MAX_RANGE_BYTES - 1)
    for bad in ("bytes=5-2", "bytes=1000-", "items=0-1", "bytes=0-1,5-9", "bytes=-"):
        with pytest.raises(RequestError):
            byte_range(bad, 1000)


SECURITY_HEADERS = {
    "x-frame-options": "DENY",
    "x-content-type-options": "nosniff",
    "cache-control": "no-store",
}


def assert_refused_safely(status: int, headers: dict[str, str], body: bytes, expected: int) -> None:
    """A refusal with the status ``expected``: a JSON reason and every security header of a normal answer."""
    assert status == expected, (status, body[:200])
    for name, value in SECURITY_HEADERS.items():
        assert headers.get(name) == value, (expected, name, headers)
    assert "frame-ancestors 'none'" in headers.get("content-security-policy", ""), (expected, headers)
    assert headers["content-type"] == "application/json" and json.loads(body)["error"]


def test_ranges_and_seeks_of_thousands_of_digits_are_refused_not_crashed(
    serve: object, work: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    size = (work / "clip.mp4").stat().st_size
    huge = "9" * 5000  # (beyond the 4300 digits Python converts)
    assert byte_range(f"bytes=0-{huge}", size) == (0, size - 1)  # (to the end)
    assert byte_range(f"bytes=-{huge}", size) == (0, size - 1)  # (the last N bytes: all of them)
    assert byte_range(f"bytes={'0' * 5000}5-9", size) == (5, 9)
    with pytest.raises(RequestError) as refused:
        byte_range(f"bytes={huge}-", size)
    assert refused.value.status == 416
    server = serve(open_source(str(work / "clip.mp4")))  # type: ignore[operator]
    for asked in (f"bytes={huge}-", f"bytes={huge}-{huge}"):
        assert_refused_safely(*request(server, "GET", "/api/video", headers={"Range": asked}), 416)
    status, _, body = request(server, "GET", "/api/video", headers={"Range": f"bytes=10-{huge}"})
    assert status == 206 and len(body) == size - 10
    decoded = serve(open_source(str(work / "clip.avi")))  # type: ignore[operator]
    json_type = {"Content-Type": "application/json"}
    for seek in ("1" + "0" * 4000, "1e400", "-1e400", "1e300", "-1"):
        body = f'{{"seek_s": {seek}}}'.encode()
        assert_refused_safely(*request(decoded, "POST", "/api/playback", body, json_type), 400)
    for query in (f"after={huge}", f"after=0&window={huge},0,10,10"):
        assert_refused_safely(*request(decoded, "GET", f"/api/frame?{query}"), 400)
    assert "Traceback" not in capsys.readouterr().err


def raw_request(server: ViewerServer, data: bytes) -> tuple[int, dict[str, str], bytes]:
    """Send ``data`` as it is and read the answer to the connection's end: (status, headers, body)."""
    with socket.create_connection(server.server_address[:2], timeout=LIMIT_S) as sock:
        sock.sendall(data)
        answer = b""
        while chunk := sock.recv(65536):
            answer += chunk
    head, _, body = answer.partition(b"\r\n\r\n")
    lines = head.decode("latin-1").split("\r\n")
    headers = dict(line.split(": ", 1) for line in lines[1:])
    return int(lines[0].split()[1]), {k.lower(): v for k, v in headers.items()}, body


def test_the_http_libraries_own_refusals_carry_the_security_headers(serve: object, work: Path) -> None:
    server = serve(open_source(str(work / "omni.png")))  # type: ignore[operator]
    host = f"Host: 127.0.0.1:{server.server_address[1]}\r\n".encode()
    many = b"".join(f"X-{k}: {k}\r\n".encode() for k in range(120))
    for data, expected in (
        (b"BREW /coffee HTTP/1.1\r\n" + host + b"\r\n", 501),  # an unknown method
        (b"GET /" + b"a" * 70000 + b" HTTP/1.1\r\n" + host + b"\r\n", 414),  # a URL too long
        (b"GET / HTTP/1.1\r\n" + host + many + b"\r\n", 431),  # too many headers
        (b"GET / HTTP/1.1\r\n" + host + b"X-Long: " + b"a" * 65600 + b"\r\n\r\n", 431),  # a header too long
        (b"GET / HTTP/1.x\r\n" + host + b"\r\n", 400),  # a malformed request line
        (b"GET / HTTP/2.0\r\n" + host + b"\r\n", 505),
        (b"GET /\r\n\r\n", 505),  # HTTP/0.9, whose answers have no headers
    ):
        assert_refused_safely(*raw_request(server, data), expected)


def test_the_source_is_opened_once_and_a_swapped_link_serves_the_same_file(
    table: PanoMappingTable, work: Path, tmp_path: Path
) -> None:
    other = tmp_path / "other.bin"
    other.write_bytes(b"another file, not a video" * 100)
    data = (work / "clip.mp4").read_bytes()
    links = {name: tmp_path / name for name in ("clip.mp4", "clip.avi")}
    for name, link in links.items():
        link.symlink_to(work / name)
    with serving() as start:
        played = start(make_server(table, "cam.npz", open_source(str(links["clip.mp4"]))))
        decoded = start(make_server(table, "cam.npz", open_source(str(links["clip.avi"]))))
        for link in links.values():
            link.unlink()
            link.symlink_to(other)
        status, _, body = request(played, "GET", "/api/video", headers={"Range": "bytes=0-"})
        assert status == 206 and body == data
        status, headers, body = request(decoded, "GET", "/api/frame?after=0")
        assert status == 200 and body[:2] == b"\xff\xd8", headers
        assert decoded.feed is not None
        decoded.feed.control(seek_s=1.0)  # (decoding starts again: from the file held, not the name)
        wait_until(lambda: (decoded.feed.status().time_s or 0) >= 1.0 - 1e-6, "the seek")  # type: ignore[union-attr]
        assert decoded.feed.status().state != "failed", decoded.feed.status().message


# ---------------------------------------------------------------------- decoded frames


@pytest.mark.slow
def test_decoded_frames_come_at_the_files_rate_and_pause_and_seek(work: Path) -> None:
    feed = FrameFeed(open_source(str(work / "clip.avi")))
    try:
        first = feed.frame_after(0, LIMIT_S)
        assert first is not None and first.time_s == pytest.approx(0.0, abs=1e-6)
        assert first.image.shape == (SIZE[1], SIZE[0], 3)
        whole = cv2.imdecode(np.frombuffer(feed.jpeg(first), np.uint8), cv2.IMREAD_COLOR)
        assert np.abs(whole.astype(np.int16) - first.image).mean() < 8.0  # (JPEG at 85: 4.1 on this small, sharp frame)
        part = cv2.imdecode(np.frombuffer(feed.jpeg(first, (40, 30, 64, 50)), np.uint8), cv2.IMREAD_COLOR)
        assert part.shape == (50, 64, 3)
        error = np.abs(part.astype(np.int16) - first.image[30:80, 40:104]).mean()
        assert (
            error < 0.5 * np.abs(part.astype(np.int16) - first.image[35:85, 45:109]).mean()
        )  # (that part, JPEG aside)
        started, index, times = time.monotonic(), first.index, []
        while len(times) < 10:
            frame = feed.frame_after(index, LIMIT_S)
            assert frame is not None
            index = frame.index
            times.append(frame.time_s)
        elapsed = time.monotonic() - started
        # Paced: 10 frames of a 25 fps clip take 0.4 s of its time and about as long to come (not at once).
        assert times[-1] - first.time_s >= 0.4 - 1e-6
        assert elapsed >= 0.3
        feed.control(paused=True)
        wait_until(lambda: feed.status().state == "paused", "the pause")
        held = feed.status().index
        time.sleep(0.3)
        assert feed.status().index <= held + 1
        feed.control(paused=False, seek_s=1.5)
        wait_until(lambda: (feed.status().time_s or 0) >= 1.5 - 1e-6, "the seek")
        sought = feed.frame_after(0, LIMIT_S)
        assert sought is not None and 1.5 - 1e-6 <= sought.time_s <= 1.5 + 0.2
        wait_until(lambda: feed.status().state == "ended", "the end")
        assert feed.status().time_s == pytest.approx(1.96, abs=1e-6)
    finally:
        feed.close()
    assert not feed.running


def test_a_page_that_goes_away_frees_the_decoder(work: Path) -> None:
    feed = FrameFeed(open_source(str(work / "clip.avi")), idle_stop_s=0.3)
    try:
        assert feed.frame_after(0, LIMIT_S) is not None
        assert feed.running
        wait_until(lambda: not feed.running, "the decoder to stop when nobody asks")
        assert feed.status().state == "idle"
        # A page that comes back gets frames again, from where the file was.
        frame = feed.frame_after(0, LIMIT_S)
        assert frame is not None and frame.time_s > 0.1
    finally:
        feed.close()


def test_the_frame_api_answers_with_the_frame_and_its_time(serve: object, work: Path) -> None:
    server = serve(open_source(str(work / "clip.avi")))  # type: ignore[operator]
    status, headers, body = request(server, "GET", "/api/frame?after=0")
    assert status == 200 and headers["content-type"] == "image/jpeg" and body[:2] == b"\xff\xd8"
    index = int(headers["x-frame-index"])
    assert float(headers["x-frame-time"]) >= 0 and float(headers["x-frame-age"]) >= 0
    assert headers["x-frame-window"] == f"0,0,{SIZE[0]},{SIZE[1]}"
    status, headers, body = request(server, "GET", f"/api/frame?after={index}&window=150,20,40,300")
    assert status == 200 and int(headers["x-frame-index"]) > index
    assert headers["x-frame-window"] == "150,20,10,140"  # (clipped to the frame)
    assert cv2.imdecode(np.frombuffer(body, np.uint8), cv2.IMREAD_COLOR).shape == (140, 10, 3)
    assert request(server, "GET", "/api/frame?after=0&window=1,2,3")[0] == 400
    assert request(server, "GET", "/api/frame?after=x")[0] == 400
    status, _, body = request(server, "GET", "/api/status")
    assert status == 200 and json.loads(body)["state"] in ("playing", "ended")


def test_a_live_source_that_drops_is_reconnected_and_says_so(work: Path) -> None:
    stream = StreamServer(work / "clip.ts")
    stream.start()
    source = Source(stream.url, "live", SIZE, frame_rate=RATE)
    feed = FrameFeed(source, Reconnect(attempts=40, first_wait_s=0.1, max_wait_s=0.2, timeout_s=5.0))
    try:
        first = feed.frame_after(0, LIMIT_S)
        assert first is not None
        stream.kill()
        wait_until(lambda: feed.status().state == "reconnecting", "the drop to be seen")
        feed.frame_after(first.index, 0.01)  # (a page still asking)
        assert "reconnecting" in feed.status().message
        stream.start(wait=False)  # (the feed's reconnect may take the one client before a wait could see it listen)
        index = feed.status().index

        def newer() -> bool:
            return feed.frame_after(index, 0.5) is not None

        wait_until(newer, "frames after the reconnect")
        assert feed.status().state == "playing"
    finally:
        feed.close()
        stream.kill()


def test_a_live_source_that_never_comes_back_fails_with_a_message(work: Path) -> None:
    stream = StreamServer(work / "clip.ts")  # never started: nothing listens
    feed = FrameFeed(
        Source(stream.url, "live", SIZE), Reconnect(attempts=2, first_wait_s=0.05, max_wait_s=0.05, timeout_s=1.0)
    )
    try:
        assert feed.frame_after(0, 0.1) is None
        wait_until(lambda: feed.status().state == "failed", "the feed to give up")
        assert "did not come back after 2 attempt(s)" in feed.status().message
    finally:
        feed.close()


def test_only_videos_have_frames_to_feed(work: Path) -> None:
    with pytest.raises(PanomapError, match="only a video"):
        FrameFeed(open_source(str(work / "omni.png")))
    live = FrameFeed(Source("tcp://127.0.0.1:9", "live", SIZE))
    with pytest.raises(PanomapError, match="cannot be paused"):
        live.control(paused=True)


def test_the_command_serves_until_ctrl_c(work: Path) -> None:
    process = subprocess.Popen(
        [sys.executable, "-m", "panomap", "view", str(work / "cam.npz"), str(work / "clip.avi"), "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert process.stdout is not None
        line = process.stdout.readline()
        match = re.search(r"showing clip\.avi \(video\) through cam\.npz at http://127\.0\.0\.1:(\d+)/", line)
        assert match, line
        connection = http.client.HTTPConnection("127.0.0.1", int(match.group(1)), timeout=LIMIT_S)
        connection.request("GET", "/api/info")
        answer = connection.getresponse()
        assert answer.status == 200 and json.loads(answer.read())["source"]["kind"] == "video"
        connection.close()
    finally:
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=LIMIT_S)
    assert process.returncode == 0 and "stopped" in out and err == ""
