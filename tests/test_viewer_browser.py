"""The viewer in a real headless Chromium (Playwright driving Debian's ``chromium``), WebGL2 on SwiftShader.

The page's pictures are compared with what the command line makes for the same numbers (``panomap
perspective``, ``panorama``, ``floor``): the same table, conventions and interpolation, so the same
picture to within the GPU's texture filtering. Video is checked the same way on a clip of one still
picture (every frame the same), decoded by the browser (H.264) and by the server (MPEG-4 part 2), to
within the codec's loss. Interaction is checked against the pinhole's closed form.

Without /usr/bin/chromium (or the playwright package) these tests skip, saying why; with the
environment variable CI set they fail instead: CI must install them (``scripts/install-test-deps.sh``).
"""

from __future__ import annotations

import base64
import json
import math
import shlex
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import av
import cv2
import numpy as np
import pytest

from panomap.interop.orient import orient_table
from panomap.simulate import standard_cameras
from panomap.table.file import load_table, save_table
from panomap.video.live import Reconnect
from panomap.viewer.feed import FrameFeed
from panomap.viewer.server import ViewerServer, make_server
from panomap.viewer.source import open_source

from helpers import LIMIT_S, StreamServer, chromium, room_camera_files, run, serving, write_clip

# Chromium on SwiftShader: a second or more a test; the whole module runs with the slow tests.
pytestmark = pytest.mark.slow

# WebGL2 on SwiftShader (the slowest GPU a user can have); videos play without a click.
VIEWER_ARGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--autoplay-policy=no-user-gesture-required"]
SIZE = (480, 480)
RATE = 25
CAMERA = standard_cameras(SIZE, centre=(240.3, 239.6))["equidistant"]
TIMEOUT_MS = 60_000
VIEW = (640, 480)
# Measured: mean 0.003-0.006 grey levels from the CLI's picture for perspectives, 0.0001 for the panorama, 0.03
# for a floor map that
# magnifies the far floor (the GPU's filter weights, in 1/256 steps, round smooth gradients the other way
# from OpenCV's 1/32 steps), none off by more than 2.
SAME_MEAN = 0.1
# A clip's frame shown by the page against the CLI's view of the same frame decoded by PyAV. Browser-decoded:
# against the frame converted by the standard's equations; measured 0.45-0.5 (rounding, chroma at the edges).
BROWSER_VIDEO_MEAN = 1.0
# Server-decoded: the frames go as JPEG (quality 85, a loss of 1.5 grey levels on the frame itself); measured 2.3.
SERVER_VIDEO_MEAN = 3.5


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    yield from chromium(VIEWER_ARGS)


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """cam.npz, omni.png, and clips of omni.png standing still: still.mp4 (H.264), still.avi (MPEG-4
    part 2), and moving.ts (MPEG-TS) for a live stream."""
    folder = tmp_path_factory.mktemp("viewer-browser")
    omni = room_camera_files(folder, CAMERA, SIZE, seed=5)
    write_clip(folder / "still.mp4", [omni] * 100, RATE, options={"crf": "12"})
    write_clip(folder / "still.avi", [omni] * 100, RATE, "mpeg4", bit_rate=20_000_000)  # (near lossless)
    moving = (np.roll(omni, k, axis=1) for k in range(250))
    write_clip(folder / "moving.ts", moving, RATE, container_format="mpegts", options={"crf": "12"})
    return folder


def png_picture(url: str) -> np.ndarray:
    """A PNG data URL's picture (BGR)."""
    assert url.startswith("data:image/png;base64,")
    image = cv2.imdecode(np.frombuffer(base64.b64decode(url.split(",", 1)[1]), np.uint8), cv2.IMREAD_COLOR)
    assert image is not None
    return image


class Page:
    """The served page in a browser tab."""

    def __init__(self, browser: Any, server: ViewerServer, fragment: str = "", init_script: str = "") -> None:
        # bypass_csp: the page's Content-Security-Policy forbids eval, which wait_for_function uses.
        self.context = browser.new_context(viewport={"width": 1400, "height": 1000}, bypass_csp=True)
        self.page = self.context.new_page()
        if init_script:  # (run before the page's own scripts)
            self.page.add_init_script(init_script)
        self.page.set_default_timeout(TIMEOUT_MS)
        self.errors: list[str] = []
        self.page.on("pageerror", lambda error: self.errors.append(str(error)))
        self.page.goto(server.url + fragment)
        self.page.wait_for_selector("body[data-ready=yes], body[data-ready=failed]")
        assert self.js("document.body.dataset.ready") == "yes", self.js(
            "document.getElementById('message').textContent"
        )

    def js(self, expression: str) -> Any:
        return self.page.evaluate(expression)

    def set(self, **view: Any) -> dict[str, Any]:
        return dict(self.page.evaluate("(view) => window.panomapView.set(view)", view))

    def pixels(self) -> np.ndarray:
        return png_picture(self.js("window.panomapView.pixels()"))

    def close(self) -> None:
        self.context.close()
        assert self.errors == []


@pytest.fixture
def serve(work: Path) -> Iterator[Any]:
    def viewer(source_name: str, feed_reconnect: Reconnect | None = None, table: str = "cam.npz") -> ViewerServer:
        source = open_source(source_name)
        feed = FrameFeed(source, feed_reconnect) if feed_reconnect is not None else None
        return make_server(load_table(work / table), table, source, port=0, feed=feed)

    with serving() as start:
        yield lambda *args: start(viewer(*args))


def cli_picture(tmp_path: Path, kind: str, source: Path, *options: object, table: str = "cam.npz") -> np.ndarray:
    out = tmp_path / f"{kind}.png"
    result = run(kind, source.parent / table, source, "-o", out, "-q", *options)
    assert result.exit_code == 0, result.output
    image = cv2.imread(str(out), cv2.IMREAD_COLOR)
    assert image is not None
    return image


def mean_difference(a: np.ndarray, b: np.ndarray) -> float:
    assert a.shape == b.shape
    return float(np.mean(np.abs(a.astype(np.int16) - b.astype(np.int16))))


PERSPECTIVES = [  # (yaw, pitch, roll, fov) deg: straight down among them
    (30.0, -20.0, 0.0, 90.0),
    (200.0, -50.0, 10.0, 70.0),
    (0.0, -90.0, 0.0, 100.0),
    (-123.5, -5.0, -20.0, 60.0),
]


def test_the_view_is_the_command_lines_picture(browser: Any, serve: Any, work: Path, tmp_path: Path) -> None:
    page = Page(browser, serve(str(work / "omni.png")))
    try:
        for yaw, pitch, roll, fov in PERSPECTIVES:
            page.set(mode="perspective", yaw=yaw, pitch=pitch, roll=roll, fov=fov, width=VIEW[0], height=VIEW[1])
            expected = cli_picture(
                tmp_path,
                "perspective",
                work / "omni.png",
                "--yaw",
                yaw,
                "--pitch",
                pitch,
                "--roll",
                roll,
                "--fov",
                fov,
                "--size",
                f"{VIEW[0]}x{VIEW[1]}",
            )
            got = page.pixels()
            print(f"perspective {yaw, pitch, roll, fov}: mean difference {mean_difference(got, expected):.4f}")
            assert mean_difference(got, expected) <= SAME_MEAN, (yaw, pitch)
            assert np.abs(got.astype(np.int16) - expected).max() <= 2
            assert expected.mean() > 20  # (a picture, not a black frame)
        page.set(mode="panorama", start=37.0, width=720, height=180)
        expected = cli_picture(tmp_path, "panorama", work / "omni.png", "--start", 37, "--size", "720x180")
        got = page.pixels()
        print(f"panorama: mean difference {mean_difference(got, expected):.4f}")
        assert mean_difference(got, expected) <= SAME_MEAN
        page.set(mode="floor", width=400, height=300)
        command = shlex.split(page.js("window.panomapView.commands().command"))
        assert command[:4] == ["panomap", "floor", "cam.npz", "omni.png"]
        expected = cli_picture(tmp_path, "floor", work / "omni.png", *command[6:])
        got = page.pixels()
        print(f"floor: mean difference {mean_difference(got, expected):.4f}")
        assert mean_difference(got, expected) <= SAME_MEAN
        assert np.abs(got.astype(np.int16) - expected).max() <= 2
    finally:
        page.close()


def looking_ahead(work: Path) -> str:
    """ahead.npz: cam.npz's fisheye (190 deg) turned to look ahead along +X (yaw, pitch and roll 0), its entries
    over the whole sphere (elevations -90..90 deg, NaN behind the camera)."""
    if not (work / "ahead.npz").exists():
        save_table(orient_table(load_table(work / "cam.npz"), 0.0, 0.0, 0.0), work / "ahead.npz")
    return "ahead.npz"


def assert_same_where_both_see(got: np.ndarray, expected: np.ndarray, exact: bool) -> None:
    """The page's picture is the CLI's. ``exact``: as the level camera's (mean and largest difference). Else (a turned
    camera's lookup, a resampling of the table): the black where the camera sees nothing may start up to a lookup
    texel sooner (at most 0.2% of the pixels differ in being black), and within the table's last cell around a pole
    the lookup smooths the table's bilinear reading (at most 0.1% of the pixels seen both ways off by more than 2)."""
    difference = np.abs(got.astype(np.int16) - expected).max(axis=2)
    seen_got, seen_expected = got.max(axis=2) > 0, expected.max(axis=2) > 0
    both = seen_got & seen_expected
    print(
        f"mean difference {mean_difference(got, expected):.4f}, where both see {difference[both].mean():.4f}; "
        f"black in one only {np.mean(seen_got != seen_expected):.5f}, "
        f"off by more than 2 where both see {np.mean(difference[both] > 2):.5f}"
    )
    assert expected.mean() > 20 and both.mean() > 0.3  # (a picture, not a black frame)
    if exact:
        assert mean_difference(got, expected) <= SAME_MEAN and difference.max() <= 2
        return
    assert np.mean(seen_got != seen_expected) <= 0.002
    assert difference[both].mean() <= SAME_MEAN and np.mean(difference[both] > 2) <= 0.001


def test_a_camera_looking_ahead_is_drawn_as_the_command_line_draws_it_the_equirect_too(
    browser: Any, serve: Any, work: Path, tmp_path: Path
) -> None:
    table = looking_ahead(work)
    page = Page(browser, serve(str(work / "omni.png"), None, table))
    try:
        state = page.js("window.panomapView.get()")  # the default view: along the optical axis
        assert (state["mode"], state["yaw"], state["pitch"], state["roll"]) == ("perspective", 0, 0, 0)
        options = ["--size", "640x480"]
        for yaw, pitch, roll, fov, exact in ((0.0, 0.0, 0.0, 90.0, True), (60.0, 35.0, 10.0, 100.0, False)):
            page.set(mode="perspective", yaw=yaw, pitch=pitch, roll=roll, fov=fov, width=640, height=480)
            angles = ["--yaw", yaw, "--pitch", pitch, "--roll", roll, "--fov", fov]
            expected = cli_picture(tmp_path, "perspective", work / "omni.png", *angles, *options, table=table)
            assert_same_where_both_see(page.pixels(), expected, exact)
        # The equirect: upright, the table read itself (exact); turned by a pitch and a roll, through the lookup.
        for yaw, pitch, roll, exact in ((37.0, 0.0, 0.0, True), (-20.0, 25.0, -15.0, False)):
            state = page.set(mode="equirect", yaw=yaw, pitch=pitch, roll=roll, width=720, height=360)
            assert state["mode"] == "equirect"
            words = shlex.split(page.js("window.panomapView.commands().command"))
            assert words[:4] == ["panomap", "equirect", table, "omni.png"]
            expected = cli_picture(tmp_path, "equirect", work / "omni.png", *words[6:], table=table)
            got = page.pixels()
            assert_same_where_both_see(got, expected, exact)
            if exact:
                assert not got[90:270, :100].any()  # (behind the camera, off the poles: black)
    finally:
        page.close()


def test_the_equirect_is_picked_in_the_page_and_its_view_is_in_the_address(
    browser: Any, serve: Any, work: Path
) -> None:
    page = Page(browser, serve(str(work / "omni.png")), "#view=equirect&yaw=10&pitch=-5&width=400&height=100")
    try:
        state = page.js("window.panomapView.get()")
        assert (state["mode"], state["yaw"], state["pitch"], state["width"]) == ("equirect", 10, -5, 400)
        page.page.select_option("#mode", "perspective")
        page.page.select_option("#mode", "equirect")  # picked in the page: upright, 2:1
        page.page.wait_for_function("location.hash.startsWith('#view=equirect&yaw=10&pitch=0&roll=0')")
        state = page.js("window.panomapView.get()")
        assert (state["pitch"], state["roll"], state["height"]) == (0, 0, 200)
        assert page.js("window.panomapView.commands().spec") == "equirect:yaw=10,pitch=0,roll=0,size=400x200"
        with pytest.raises(Exception, match="mode must be one of"):
            page.set(mode="cube")
    finally:
        page.close()


# Asks for a view the moment the page defines its API (before the table or the source has arrived), then for
# its pixels: window.firstView, a Promise of {state, url}.
FIRST_VIEW_SCRIPT = """
Object.defineProperty(window, "panomapView", {
  configurable: true,
  set(api) {
    Object.defineProperty(window, "panomapView", { value: api, writable: true, configurable: true });
    window.firstView = api.set(%s).then((state) => api.pixels().then((url) => ({ state, url })));
  },
});
"""


def test_the_first_view_a_script_asks_for_is_drawn_from_the_source(
    browser: Any, serve: Any, work: Path, tmp_path: Path
) -> None:
    view = {"mode": "perspective", "yaw": 30.0, "pitch": -20.0, "roll": 0.0, "fov": 90.0, "width": 640, "height": 480}
    expected = cli_picture(
        tmp_path, "perspective", work / "omni.png", "--yaw", 30, "--pitch", -20, "--fov", 90, "--size", "640x480"
    )
    # The image, and a video whose frames the server decodes (the page is ready before its first frame comes).
    for source, limit in (("omni.png", SAME_MEAN), ("still.avi", 2 * SERVER_VIDEO_MEAN)):
        page = Page(browser, serve(str(work / source)), init_script=FIRST_VIEW_SCRIPT % json.dumps(view))
        try:
            first = page.js("window.firstView")
            assert {key: first["state"][key] for key in view} == view
            got = png_picture(first["url"])
            print(f"{source}: the first view's mean difference {mean_difference(got, expected):.3f}")
            assert mean_difference(got, expected) <= limit, source  # (a black view: 60 and more)
        finally:
            page.close()


def test_the_page_gives_the_command_and_the_view_spec_of_what_it_shows(
    browser: Any, serve: Any, work: Path, tmp_path: Path
) -> None:
    page = Page(browser, serve(str(work / "omni.png")), "#yaw=47.25&pitch=-33.5&roll=4&fov=75&width=320&height=240")
    try:
        state = page.js("window.panomapView.get()")
        assert (state["yaw"], state["pitch"], state["roll"], state["fov"]) == (47.25, -33.5, 4, 75)
        assert page.js("getComputedStyle(document.getElementById('playback')).display") == "none"  # (an image)
        commands = page.js("window.panomapView.commands()")
        assert commands["spec"] == "perspective:yaw=47.25,pitch=-33.5,roll=4,fov=75,size=320x240"
        words = shlex.split(commands["command"])
        assert words[:5] == ["panomap", "perspective", "cam.npz", "omni.png", "-o"]
        expected = cli_picture(tmp_path, "perspective", work / "omni.png", *words[6:])
        assert mean_difference(page.pixels(), expected) <= SAME_MEAN
        page.set(yaw=-10.0, pitch=-60.0)
        page.page.wait_for_function("location.hash.includes('yaw=-10&pitch=-60')")
    finally:
        page.close()


def test_dragging_turns_the_view_by_the_pinholes_angle_and_a_click_on_the_strip_looks_there(
    browser: Any, serve: Any, work: Path
) -> None:
    page = Page(browser, serve(str(work / "omni.png")))
    try:
        page.set(mode="perspective", yaw=0.0, pitch=-30.0, roll=0.0, fov=90.0, width=640, height=360, strip=True)
        box = page.page.locator("#canvas").bounding_box()
        scale = 640 / box["width"]  # canvas px per CSS px
        x, y = box["x"] + box["width"] / 2, box["y"] + 100
        mouse = page.page.mouse
        mouse.move(x, y)
        mouse.down()
        mouse.move(x + 50, y + 20, steps=5)
        mouse.up()
        state = page.js("window.panomapView.get()")
        # One px at the centre of a pinhole of focal f = (W/2)/tan(fov/2) turns it by atan(1/f).
        per_px = math.degrees(2 * math.atan(math.tan(math.radians(45)) / 320))
        assert state["yaw"] == pytest.approx(50 * scale * per_px, rel=1e-3)
        assert state["pitch"] == pytest.approx(-30 + 20 * scale * per_px, rel=1e-3)
        page.page.mouse.wheel(0, 200)
        page.page.wait_for_function("window.panomapView.get().fov < 89 || window.panomapView.get().fov > 91")
        assert page.js("window.panomapView.get().fov") == pytest.approx(90 * math.exp(0.2), rel=1e-6)
        # Keys: arrows pan and tilt by 2 deg, E rolls, + zooms in by 1.1.
        page.set(yaw=0.0, pitch=-30.0, roll=0.0, fov=90.0)
        page.page.locator("#canvas").focus()
        for key in ("ArrowLeft", "ArrowUp", "e", "+"):
            page.page.keyboard.press(key)
        page.page.wait_for_function("window.panomapView.get().roll === 2")
        state = page.js("window.panomapView.get()")
        assert (state["yaw"], state["pitch"], state["roll"]) == (2, -28, 2)
        assert state["fov"] == pytest.approx(90 / 1.1)
        # The strip (a panorama W x W/4 below the view, centred on the view's yaw): a click looks at its point.
        page.set(yaw=10.0, pitch=-30.0, fov=90.0)
        table = load_table(work / "cam.npz")
        rho_s, rho_e = table.elevation_range
        strip = 160
        theta_deg, rho_deg = -35.0, math.degrees(rho_e - 0.25 * (rho_e - rho_s))
        k = (10.0 + 180.0 - theta_deg) * 640 / 360  # the strip's column of azimuth theta (from its left edge)
        l_row = 360 + (rho_e - math.radians(rho_deg)) / (rho_e - rho_s) * strip
        mouse.click(box["x"] + k / scale, box["y"] + l_row / scale)
        state = page.js("window.panomapView.get()")
        assert state["yaw"] == pytest.approx(theta_deg, abs=0.6)
        assert state["pitch"] == pytest.approx(rho_deg, abs=0.6)
    finally:
        page.close()


def bt601_frame(frame: av.VideoFrame) -> np.ndarray:
    """A limited-range BT.601 4:2:0 frame as 8-bit BGR by the standard's equations (chroma centred on 128, upsampled
    bilinearly with samples at the centres of their 2 x 2 pixels), in floating point: FFmpeg's swscale, fixed point,
    is about 1 grey level darker."""
    planes = frame.to_ndarray(format="yuv420p").astype(np.float64)
    height, width = frame.height, frame.width
    luma = planes[:height]
    chroma = planes[height:].reshape(2, height // 2, width // 2)
    u, v = (cv2.resize(c, (width, height), interpolation=cv2.INTER_LINEAR) for c in chroma)
    y = (luma - 16) * 255 / 219
    u, v = (u - 128) * 255 / 224, (v - 128) * 255 / 224
    bgr = np.stack([y + 1.772 * u, y - 0.344136 * u - 0.714136 * v, y + 1.402 * v], axis=-1)
    return np.clip(np.rint(bgr), 0, 255).astype(np.uint8)


def video_picture_matches(page: Page, work: Path, tmp_path: Path, clip: str, limit: float) -> None:
    """The view of the playing clip is the CLI's view of its frame (every frame is the same): the frame converted by
    the standard's equations for the browser's decoding, as the server decodes it (swscale) for the server's."""
    with av.open(str(work / clip)) as container:
        frame = next(container.decode(video=0))
    picture = bt601_frame(frame) if clip.endswith(".mp4") else frame.to_ndarray(format="bgr24")
    cv2.imwrite(str(tmp_path / "frame.png"), picture)
    (tmp_path / "cam.npz").write_bytes((work / "cam.npz").read_bytes())
    page.page.wait_for_function("window.panomapView.stats().sourceFrames >= 5", timeout=TIMEOUT_MS)
    # Without the strip, a frame goes up only where the view reads it (its window; the server sends only that):
    # after a turn of the paused video the view must still see the whole of what it shows.
    page.set(mode="perspective", yaw=200.0, pitch=-60.0, roll=0.0, fov=60.0, width=VIEW[0], height=VIEW[1], strip=False)
    count = page.js("window.panomapView.stats().sourceFrames")
    page.page.wait_for_function(f"window.panomapView.stats().sourceFrames >= {count + 2}")
    page.page.click("#play")
    page.page.wait_for_function("document.getElementById('play').textContent === 'Play'")
    window = page.js("window.panomapView.stats().sourceWindow")
    assert window[2] * window[3] < 0.5 * SIZE[0] * SIZE[1], window  # (a window, not the whole frame)
    page.set(yaw=30.0, pitch=-20.0, fov=90.0)
    expected = cli_picture(
        tmp_path, "perspective", tmp_path / "frame.png", "--yaw", 30, "--pitch", -20, "--fov", 90, "--size", "640x480"
    )
    got = page.pixels()
    print(f"{clip}: mean difference {mean_difference(got, expected):.3f}")
    assert mean_difference(got, expected) <= limit
    assert abs(float(np.mean(got.astype(np.float64) - expected))) <= limit / 2  # (no colour bias)


def test_a_video_the_browser_plays_is_shown_frame_by_frame(
    browser: Any, serve: Any, work: Path, tmp_path: Path
) -> None:
    page = Page(browser, serve(str(work / "still.mp4")))
    try:
        video_picture_matches(page, work, tmp_path, "still.mp4", BROWSER_VIDEO_MEAN)
        stats = page.js("window.panomapView.stats()")
        assert stats["decodedBy"] == "browser" and stats["frameTime"] > 0
    finally:
        page.close()


def test_a_video_the_browser_cannot_play_is_decoded_by_the_server(
    browser: Any, serve: Any, work: Path, tmp_path: Path
) -> None:
    page = Page(browser, serve(str(work / "still.avi")))
    try:
        video_picture_matches(page, work, tmp_path, "still.avi", SERVER_VIDEO_MEAN)
        stats = page.js("window.panomapView.stats()")
        assert stats["decodedBy"] == "server" and stats["latencyMs"]["count"] >= 5
    finally:
        page.close()


def test_a_live_stream_that_drops_says_so_and_comes_back(browser: Any, serve: Any, work: Path) -> None:
    stream = StreamServer(work / "moving.ts")
    stream.start()
    try:
        server = serve(stream.url, Reconnect(attempts=40, first_wait_s=0.1, max_wait_s=0.2, timeout_s=5.0))
        page = Page(browser, server)
        try:
            page.page.wait_for_function("window.panomapView.stats().sourceFrames >= 3")
            stream.kill()
            page.page.wait_for_function(
                "document.getElementById('source-state').textContent.includes('reconnecting')", timeout=LIMIT_S * 1000
            )
            stream.start(wait=False)  # (the page's reconnect may take the one client before a wait could see it listen)
            count = page.js("window.panomapView.stats().sourceFrames")
            page.page.wait_for_function(f"window.panomapView.stats().sourceFrames > {count + 3}")
            page.page.wait_for_function("document.getElementById('source-state').textContent === ''")
        finally:
            page.close()
    finally:
        stream.kill()
