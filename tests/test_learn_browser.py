"""The learning page in a real headless Chromium (Playwright driving Debian's ``chromium``).

A simulated camera's omni-image is served; the test clicks the true pixels of 8 landmarks
(computed by the simulated camera's closed-form projection), types their world points,
watches the residuals and the panorama preview appear, saves, and checks that the saved
table is the one ``panomap fit`` makes from the saved landmarks.

Without /usr/bin/chromium (or the playwright package) these tests skip, saying why; with
the environment variable CI set they fail instead: CI must install them
(``scripts/install-test-deps.sh``).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from panomap.calibrate.landmarks.pairs import Landmarks, read_landmarks
from panomap.cli.app import main
from panomap.learn.server import LearnServer, make_server
from panomap.learn.session import Session
from panomap.simulate.example import Example
from panomap.table.file import load_table
from test_learn_lines import learned_pixel, room_scene, true_pixel

from helpers import chromium, serving

SIZE = (640, 640)
# Clicks are made zoomed in, at this many CSS px per image pixel.
CLICK_SCALE = 8.0
TIMEOUT_MS = 30_000


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    yield from chromium(["--disable-gpu"])


class Page:
    """The served page in a browser tab, with the page's own transform for clicking."""

    def __init__(self, browser: Any, server: LearnServer) -> None:
        # bypass_csp: the page's Content-Security-Policy forbids eval, which wait_for_function uses.
        self.context = browser.new_context(viewport={"width": 1400, "height": 900}, bypass_csp=True)
        self.page = self.context.new_page()
        self.page.set_default_timeout(TIMEOUT_MS)
        self.errors: list[str] = []
        self.page.on("pageerror", lambda error: self.errors.append(str(error)))
        self.page.goto(server.url)
        self.page.wait_for_selector("body[data-ready=yes]")

    def js(self, expression: str) -> Any:
        return self.page.evaluate(expression)

    def client_point(self, u: float, v: float) -> tuple[float, float]:
        point = self.js(f"window.panomap.imageToClient({float(u)!r}, {float(v)!r})")
        return point["x"], point["y"]

    def wait_synced(self) -> None:
        self.page.wait_for_function("document.body.dataset.synced === 'yes'")

    def landmarks(self) -> list[dict[str, Any]]:
        return list(self.js("window.panomap.state.landmarks"))

    def close(self) -> None:
        self.context.close()
        assert self.errors == []


@pytest.fixture
def serve(tmp_path: Path, example: Example) -> Iterator[Any]:
    with serving() as start:
        yield lambda session: start(make_server(session, port=0))


def contrast_pixels(example: Example, session: Session, count: int) -> list[tuple[int, int]]:
    """``count`` pixels (u, v) inside the annulus whose colour differs most from all 8 neighbours'."""
    image = example.image.astype(int)
    height, width = image.shape[:2]
    inner = image[1:-1, 1:-1]
    least = np.full(inner.shape[:2], 10**6)
    for dv in (-1, 0, 1):
        for du in (-1, 0, 1):
            if dv or du:
                neighbour = image[1 + dv : height - 1 + dv, 1 + du : width - 1 + du]
                least = np.minimum(least, np.abs(inner - neighbour).sum(axis=2))
    v, u = np.mgrid[1 : height - 1, 1 : width - 1]
    (u0, v0), c = session.circles.centre, session.circles
    r = np.hypot(u - u0, v - v0)
    least[(r < c.cutoff_radius + 4) | (r > c.outer_radius - 4)] = -1
    best = np.argsort(least, axis=None)[::-1][:count]
    assert least.flat[best[-1]] > 60  # clearly unlike every neighbour
    return [(int(u.flat[k]), int(v.flat[k])) for k in best]


def files_under(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


@pytest.mark.slow
def test_learning_a_camera_in_the_browser(browser: Any, serve: Any, example: Example, tmp_path: Path) -> None:
    folder = tmp_path / "work"
    folder.mkdir()
    session = Session(example.image, "omni.png", folder)
    view = Page(browser, serve(session))
    page = view.page
    for axis, value in zip("xyz", example.camera_position, strict=True):
        page.fill(f"#cam-{axis}", repr(value))

    # The drawing convention: image pixel (u, v) fills the scale x scale square centred on
    # imageToClient(u, v). Checked on pixels unlike all their neighbours, so that a half-pixel
    # slip would show a neighbour's colour in part of the square.
    for u, v in contrast_pixels(example, session, 3):
        view.js(f"window.panomap.zoomTo({u}, {v}, {CLICK_SCALE})")
        x, y = view.client_point(u, v)
        box = page.locator("#image-canvas").bounding_box()
        half = int(CLICK_SCALE / 2) - 1
        rgba = view.js(
            f"Array.from(document.getElementById('image-canvas').getContext('2d').getImageData("
            f"{round(x - box['x']) - half}, {round(y - box['y']) - half}, {2 * half}, {2 * half}).data)"
        )
        drawn = np.array(rgba, dtype=int).reshape(-1, 4)[:, :3]
        assert np.all(np.abs(drawn - example.image[v, u, ::-1].astype(int)) <= 2), (u, v, drawn, example.image[v, u])

    for k, (name, (u, v), world) in enumerate(zip(example.names, example.pixels, example.world, strict=True)):
        view.js(f"window.panomap.zoomTo({float(u)!r}, {float(v)!r}, {CLICK_SCALE})")
        page.mouse.click(*view.client_point(u, v))
        placed = view.landmarks()[-1]
        # The click lands where the page's transform says pixel (u, v) is: Chromium's pointer
        # positions are fractional CSS px (1/64 steps, 1/512 image px at 8x) and the page rounds
        # to 0.001 px. A half-pixel slip in the pixel-centre convention would be 0.5 px off.
        assert abs(placed["u"] - u) < 0.01 and abs(placed["v"] - v) < 0.01, (placed, u, v)
        assert placed["X"] is None and len(view.landmarks()) == k + 1
        # The magnifier's exact entry: the true sub-pixel position, and the world point.
        page.fill("#lm-name", name)
        page.fill("#lm-u", repr(float(u)))
        page.fill("#lm-v", repr(float(v)))
        for axis, value in zip("xyz", world, strict=True):
            page.fill(f"#lm-{axis}", repr(float(value)))
        if k == 2:
            view.wait_synced()
            assert "need 2 more landmark(s)" in page.inner_text("#fit-status")
            assert page.locator("#panorama").is_hidden()

    view.js("window.panomap.fitView()")
    view.wait_synced()
    assert "model " in page.inner_text("#fit-status") and "outliers: none" in page.inner_text("#fit-status")
    cells = page.locator("#landmark-table td.residual")
    assert cells.count() == 8
    residuals = [float(cells.nth(k).get_attribute("data-residual")) for k in range(8)]
    # Exact pixels, centre detected to ~0.01 px: every residual is a few hundredths of a pixel.
    assert max(residuals) < 0.05, residuals
    page.wait_for_function(
        "(() => { const p = document.getElementById('panorama');"
        " return !p.hidden && p.complete && p.naturalWidth === 720 && p.naturalHeight === 180; })()"
    )
    # The curve canvas was drawn (not the empty-state text only): some of its pixels are the curve's blue.
    blue = view.js(
        "(() => { const c = document.getElementById('curve'); const d = c.getContext('2d')"
        ".getImageData(0, 0, c.width, c.height).data; let n = 0;"
        " for (let i = 0; i < d.length; i += 4) if (d[i] === 31 && d[i + 1] === 119 && d[i + 2] === 180) n++;"
        " return n; })()"
    )
    assert blue > 100

    page.fill("#landmarks-file", "lm.csv")
    page.click("#save-landmarks")
    page.wait_for_selector("#files-status[data-done='lm.csv']")
    page.fill("#table-file", "cam.npz")
    page.click("#save-table")
    page.wait_for_selector("#files-status[data-done='cam.npz']")
    assert files_under(tmp_path) == {"work", "work/lm.csv", "work/cam.npz"}
    # Saving onto an existing file asks first: "Cancel" leaves the file alone, "OK" replaces it.
    asked, answers = [], iter([False, True])
    page.on(
        "dialog", lambda dialog: (asked.append(dialog.message), (dialog.accept if next(answers) else dialog.dismiss)())
    )
    (folder / "lm.csv").write_text("kept\n")
    page.click("#save-landmarks")
    page.wait_for_selector("#files-status[data-done='error']")
    assert "'lm.csv' already exists" in page.inner_text("#files-status")
    assert (folder / "lm.csv").read_text() == "kept\n"
    page.click("#save-landmarks")
    page.wait_for_selector("#files-status[data-done='lm.csv']")
    assert asked == ["lm.csv already exists in the folder. Replace it?"] * 2
    view.close()

    saved = read_landmarks(folder / "lm.csv")
    assert saved.names == example.names
    assert np.array_equal(saved.pixels, example.pixels)  # typed with repr(): exact
    assert np.array_equal(saved.world, example.world)
    # The page fits with the circles it found as `panomap fit --image` does with the same image.
    assert cv2.imwrite(str(tmp_path / "omni.png"), example.image)  # (lossless: the page's pixels)
    result = CliRunner().invoke(
        main,
        [
            "fit",
            str(folder / "lm.csv"),
            "-o",
            str(tmp_path / "cli.npz"),
            "--camera",
            *(repr(c) for c in example.camera_position),
            "--image",
            str(tmp_path / "omni.png"),
        ],
    )
    assert result.exit_code == 0, result.output
    web, cli = load_table(folder / "cam.npz"), load_table(tmp_path / "cli.npz")
    assert web.size == cli.size and web.model.to_dict() == cli.model.to_dict()
    assert web.cutoff_radius == cli.cutoff_radius and web.info["sources"] == cli.info["sources"]
    # Same inputs through the same code path (panomap.calibrate_camera): the float32 entries
    # agree to rounding; 1e-4 px allows a last-digit difference in a threaded BLAS reduction.
    assert np.allclose(web.entries, cli.entries, rtol=0, atol=1e-4)


@pytest.mark.slow
def test_dragging_the_circles_and_editing_landmarks(browser: Any, serve: Any, example: Example, tmp_path: Path) -> None:
    landmarks = Landmarks(example.pixels, example.world, example.names)
    session = Session(example.image, "omni.png", tmp_path, landmarks, example.camera_position)
    assert session.fit_status["ok"]
    view = Page(browser, serve(session))
    page = view.page
    assert page.locator("#landmark-table td.residual[data-residual]").count() == 8
    scale = view.js("window.panomap.view.scale")
    (u0, v0), outer = session.circles.centre, session.circles.outer_radius

    # Zooming: the buttons scale about the middle; the wheel keeps the point under the pointer.
    page.click("#zoom-in")
    assert view.js("window.panomap.view.scale") == pytest.approx(1.5 * scale)
    # (Wheel events carry whole CSS px positions in Chromium, unlike pointer events: use one.)
    x, y = (round(c) for c in view.client_point(300.25, 200.75))
    before = view.js(f"window.panomap.clientToImage({x}, {y})")
    page.mouse.move(x, y)
    page.mouse.wheel(0, -100)
    page.wait_for_function(f"window.panomap.view.scale > {1.5 * scale + 1e-9}")
    assert view.js("window.panomap.view.scale") == pytest.approx(1.5 * 1.25 * scale)
    after = view.js(f"window.panomap.clientToImage({x}, {y})")
    assert after["u"] == pytest.approx(before["u"], abs=1e-9) and after["v"] == pytest.approx(before["v"], abs=1e-9)
    page.click("#zoom-fit")
    assert view.js("window.panomap.view.scale") == pytest.approx(scale)

    # Drag the centre 20 CSS px right and 10 down: it moves by (20, 10) / scale image px.
    x, y = view.client_point(u0, v0)
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + 20, y + 10, steps=4)
    page.mouse.up()
    view.wait_synced()
    # Rounded to 0.001 px by the page, on top of Chromium's 1/64 CSS px pointer steps.
    assert np.allclose(session.circles.centre, (u0 + 20 / scale, v0 + 10 / scale), atol=0.002)
    assert float(page.input_value("#centre-u")) == pytest.approx(session.circles.centre[0], abs=1e-9)

    # Drag the outer circle's rim, due left of the (new) centre, 15 CSS px outwards.
    (u1, v1) = session.circles.centre
    x, y = view.client_point(u1 - outer, v1)
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x - 15, y, steps=4)
    page.mouse.up()
    view.wait_synced()
    assert session.circles.outer_radius == pytest.approx(outer + 15 / scale, abs=0.002)
    assert session.circles.centre == (u1, v1)

    # Drag a landmark 5 CSS px down: the server gets the new pixel, and refits.
    revision = session.revision
    before = view.landmarks()[3]
    x, y = view.client_point(before["u"], before["v"])
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x, y + 5, steps=3)
    page.mouse.up()
    view.wait_synced()
    moved = session.state()["landmarks"][3]
    assert moved["u"] == pytest.approx(before["u"], abs=0.002)
    assert moved["v"] == pytest.approx(before["v"] + 5 / scale, abs=0.002)
    assert session.revision > revision

    # A bad edit (a name already taken) is shown on the page and changes nothing on the server.
    page.fill("#lm-name", example.names[0])
    view.wait_synced()
    message = page.locator("#message")
    assert message.get_attribute("class") == "error"
    assert f"two landmarks are named {example.names[0]!r}" in message.inner_text()
    assert session.state()["landmarks"][3]["name"] == example.names[3]
    page.fill("#lm-name", "renamed")
    view.wait_synced()
    assert session.state()["landmarks"][3]["name"] == "renamed"

    # Delete it, then three more from the list: 5 left still fit, 4 ask for 1 more.
    page.click("#lm-delete")
    view.wait_synced()
    assert [row["name"] for row in session.state()["landmarks"]] == [n for k, n in enumerate(example.names) if k != 3]
    for left in (6, 5, 4):
        assert session.fit_status["ok"], session.fit_status.get("message")
        page.locator("#landmark-table tbody tr").first.click()
        page.click("#lm-delete")
        view.wait_synced()
        assert len(session.state()["landmarks"]) == left
    assert session.fit_status["ok"] is False and session.fit_status["need"] == 1
    assert "need 1 more landmark(s)" in page.inner_text("#fit-status")
    assert page.locator("#panorama").is_hidden()
    view.close()


@pytest.mark.slow
def test_learning_from_lines_in_the_browser(browser: Any, serve: Any, tmp_path: Path) -> None:
    """ "learn from lines" on a rendered room with boards (a hyperbolic mirror): the report and the lines drawn, then
    "set azimuth 0 by a click" on the true pixel of world azimuth 0 (it adds no landmark), and the line table
    saved: its world azimuth 90 deg within 2.5 px of the truth (``tests/test_learn_lines.py`` measures 0.84)."""
    camera, image = room_scene()
    folder = tmp_path / "work"
    folder.mkdir()
    view = Page(browser, serve(Session(image, "room.png", folder)))
    page = view.page
    assert page.locator("#lines-azimuth").is_disabled() and page.locator("#save-lines-table").is_disabled()
    page.click("#learn-lines")
    page.wait_for_selector("#lines-status[data-revision='1']")
    lines = view.js("window.panomap.state.lines")
    assert lines["ok"] and lines["boards"] == 2 and lines["lines_used"] >= 20, lines["message"]
    assert page.inner_text("#lines-status").startswith("learned from")
    assert page.locator("#lines-report li").count() >= 4
    green = view.js(
        "(() => { const c = document.getElementById('image-canvas'); const d = c.getContext('2d')"
        ".getImageData(0, 0, c.width, c.height).data; let n = 0;"
        " for (let i = 0; i < d.length; i += 4) if (d[i] === 52 && d[i + 1] === 199 && d[i + 2] === 89) n++;"
        " return n; })()"
    )
    assert green > 200  # the lines used are drawn

    u, v = (float(x) for x in true_pixel(camera, 0.0))
    view.js(f"window.panomap.zoomTo({u!r}, {v!r}, {CLICK_SCALE})")
    page.click("#lines-azimuth")
    # The report above the image (longer with boards) can push the image's foot below the window, and a press
    # on the image focuses it, which scrolls it into view between the press and the release: scroll first.
    view.js("document.getElementById('image-canvas').scrollIntoView({block: 'nearest'})")
    page.mouse.click(*view.client_point(u, v))
    page.wait_for_selector("#lines-status[data-revision='2']")
    zero = view.js("window.panomap.state.lines.azimuth_zero")
    assert abs(zero[0] - u) < 0.01 and abs(zero[1] - v) < 0.01, (zero, u, v)
    assert view.landmarks() == []  # the click set the azimuth; it added no landmark
    page.fill("#lines-file", "lines.npz")
    page.click("#save-lines-table")
    page.wait_for_selector("#files-status[data-done='lines.npz']")
    view.close()
    table = load_table(folder / "lines.npz")
    assert np.linalg.norm(learned_pixel(table.model, 90.0) - true_pixel(camera, 90.0)) < 2.5
