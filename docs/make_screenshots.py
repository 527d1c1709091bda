"""Screenshots of ``panomap learn`` in use, for docs/learn.md (a scripted session in headless Chromium).

Run from the repository root: ``.venv/bin/python docs/make_screenshots.py [--lines]`` (needs the test
extra's playwright and Debian's chromium: ``scripts/install-test-deps.sh``). Writes
``docs/img/learn-*.png`` (with ``--lines``, only ``learn-lines.png``: "learn from lines" on a rendered room).

The session: the bundled room through a simulated hyperbolic-mirror camera; 10 landmarks
clicked at their true pixels plus 0.4 px of (seeded) noise, as a person would place them;
one of them given a wrong height (0.5 m off), which the fit flags as an outlier.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from panomap.learn.server import make_server, serve_in_thread  # noqa: E402
from panomap.learn.session import Session  # noqa: E402
from panomap.simulate.example import make_example  # noqa: E402

ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
]
OUT = ROOT / "docs" / "img"
WRONG = 6  # this landmark's Z is typed 0.5 m off


def main() -> None:
    from playwright.sync_api import sync_playwright

    example = make_example((800, 800), count=10, supersample=2)
    rng = np.random.default_rng(7)
    clicked = example.pixels + rng.normal(0.0, 0.4, example.pixels.shape)
    OUT.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as folder, sync_playwright() as playwright:
        session = Session(example.image, "omni.png", folder)
        server = make_server(session, port=0)
        serve_in_thread(server)
        browser = playwright.chromium.launch(executable_path="/usr/bin/chromium", args=ARGS)
        page = browser.new_page(viewport={"width": 1400, "height": 1000}, bypass_csp=True)
        page.goto(server.url)
        page.wait_for_selector("body[data-ready=yes]")
        for axis, value in zip("xyz", example.camera_position, strict=True):
            page.fill(f"#cam-{axis}", repr(value))
        for k, (name, (u, v), world) in enumerate(zip(example.names, clicked, example.world, strict=True)):
            page.evaluate(f"window.panomap.zoomTo({float(u)!r}, {float(v)!r}, 6)")
            point = page.evaluate(f"window.panomap.imageToClient({float(u)!r}, {float(v)!r})")
            page.mouse.click(point["x"], point["y"])
            page.fill("#lm-name", name.replace("_", " ")[:24])
            x, y, z = (float(c) for c in world)
            page.fill("#lm-x", repr(x))
            page.fill("#lm-y", repr(y))
            page.fill("#lm-z", repr(round(z + (0.5 if k == WRONG else 0.0), 3)))
            if k == 8:
                # Placing the ninth: the pointer over it, the magnifier showing it.
                page.wait_for_function("document.body.dataset.synced === 'yes'")
                page.mouse.move(point["x"] + 0.5, point["y"] + 0.5)
                page.mouse.move(point["x"], point["y"])
                page.screenshot(
                    path=str(OUT / "learn-placing.png"), clip={"x": 0, "y": 0, "width": 1400, "height": 700}
                )
        page.evaluate("window.panomap.fitView()")
        page.mouse.move(5, 500)
        page.wait_for_function("document.body.dataset.synced === 'yes'")
        page.wait_for_function(
            "(() => { const p = document.getElementById('panorama');"
            " return !p.hidden && p.complete && p.naturalWidth > 0; })()"
        )
        page.locator("#landmark-table tbody tr").nth(WRONG).click()
        page.screenshot(path=str(OUT / "learn-page.png"))
        page.locator("#fit-panel").screenshot(path=str(OUT / "learn-fit.png"))
        print(page.inner_text("#fit-status"))
        browser.close()
        server.shutdown()
        server.server_close()
    for path in sorted(OUT.glob("learn-*.png")):
        shrink(path)
        print(f"wrote {path.relative_to(ROOT)} ({path.stat().st_size // 1024} KB)")


def lines_screenshot() -> None:
    """``docs/img/learn-lines.png``: "learn from lines" on a rendered room (a tilted hyperbolic mirror, 1200 x
    900, vignetting, sensor noise, JPEG), after a click has set azimuth 0."""
    from playwright.sync_api import sync_playwright

    from panomap.simulate.line_scenes import line_camera, render_line_scene

    camera = line_camera("hyperbolic", 0.75, tilt_deg=2.0, toward_deg=30.0)
    image = render_line_scene(camera, seed=4, supersample=2).image
    zero = camera.project(np.array([[0.87, 0.0, -0.5]]))[0]  # world azimuth 0, 30 deg below the horizon
    with tempfile.TemporaryDirectory() as folder, sync_playwright() as playwright:
        server = make_server(Session(image, "room.png", folder), port=0)
        serve_in_thread(server)
        browser = playwright.chromium.launch(executable_path="/usr/bin/chromium", args=ARGS)
        page = browser.new_page(viewport={"width": 1400, "height": 1000}, bypass_csp=True)
        page.goto(server.url)
        page.wait_for_selector("body[data-ready=yes]")
        page.click("#learn-lines")
        page.wait_for_selector("#lines-status[data-revision='1']")
        page.click("#lines-azimuth")
        point = page.evaluate(f"window.panomap.imageToClient({float(zero[0])!r}, {float(zero[1])!r})")
        page.mouse.click(point["x"], point["y"])
        page.wait_for_selector("#lines-status[data-revision='2']")
        page.mouse.move(5, 500)
        page.screenshot(path=str(OUT / "learn-lines.png"))
        print(page.inner_text("#lines-status"))
        browser.close()
        server.shutdown()
        server.server_close()
    shrink(OUT / "learn-lines.png")


def shrink(path: Path) -> None:
    """Re-save a screenshot with a 256-colour palette (a third of the size; the page has few colours)."""
    from PIL import Image

    with Image.open(path) as image:
        small = image.convert("RGB").quantize(256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    small.save(path, optimize=True)


if __name__ == "__main__":
    if "--lines" not in sys.argv:  # --lines: only docs/img/learn-lines.png
        main()
    lines_screenshot()
