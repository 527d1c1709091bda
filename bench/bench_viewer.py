"""``panomap view`` in headless Chromium on SwiftShader (a software GPU, the slowest a user can have), against the
CPU's way in the same run.

On a simulated 1920 x 1920 fisheye (the table and clip of ``bench_video.py``, here at 30 frames/s):

1. **Views/s**: 1280 x 720 perspective views set one after another through ``window.panomapView.set`` (each
   resolved once drawn), against the CPU making the same views (``build_map`` + ``Remapper``, what ``panomap
   perspective`` does per picture less the file I/O). Target: 30 views/s. Then the same camera turned to look
   ahead (``orient_table``: yaw, pitch and roll 0, entries over the whole sphere): perspective views, and
   1280 x 720 equirects (upright, and turned by a pitch and a roll), each against the CPU's.
2. **Drag to picture**: mouse drags of the view; time from each pointer event to the view drawn (ms).
3. **Video**: the 1920 x 1920 H.264 clip played by the browser, one 1280 x 720 view: frames shown per second,
   against the clip's rate (target: its rate, up to 30 fps).
4. **Live**: the clip served in real time over TCP by ffmpeg (a camera), decoded by the server and sent frame by
   frame: frames shown per second, and the latency from a frame decoded to it drawn (ms).
6. **A rig** (``--rig``): two ideal equidistant lenses back to back (190 deg, 960 x 960 each, one 1920 x 960
   frame) against camera 0 of it alone, the same 1280 x 720 views looking about the horizon and equirects: views
   drawn per second (from the page's fastest draw, ``stats().drawMs.min``: what a drag costs, least
   disturbed by the machine's load), and views/s through
   ``set`` (which for a rig also waits for the server's gains of each new view).
5. **Memory**: the server's resident memory over a live stream of ``--minutes`` (sampled every few seconds: first,
   last, largest), and the decoder freed when the page closes.

The numbers depend on the machine's load: run it on an otherwise idle machine. ``--quick``: a short clip, few
views, a 20 s stream.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path
from typing import Any

import av
import cv2
import imageio_ffmpeg
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_video import make_clip
from panomap.interop.orient import orient_table
from panomap.remap import Remapper
from panomap.table.file import load_table
from panomap.table.table import PanoMappingTable
from panomap.viewer.server import ViewerServer, make_server, serve_in_thread
from panomap.viewer.source import open_source
from panomap.views import PerspectiveView, View, build_map
from panomap.views.equirect import EquirectView

CHROMIUM = "/usr/bin/chromium"
ARGS = [
    "--headless",
    "--no-sandbox",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-dev-shm-usage",
    "--autoplay-policy=no-user-gesture-required",
]
RATE = 30
VIEW = (1280, 720)


def open_page(browser: Any, server: ViewerServer, fragment: str = "") -> Any:
    page = browser.new_page(viewport={"width": 1400, "height": 1000}, bypass_csp=True)
    page.set_default_timeout(120_000)
    page.goto(server.url + fragment)
    page.wait_for_selector("body[data-ready=yes], body[data-ready=failed]")
    if page.evaluate("document.body.dataset.ready") != "yes":
        raise SystemExit("the page failed: " + page.evaluate("document.getElementById('message').textContent"))
    return page


# The views timed, k = 0, 1, ...: (mode, yaw, pitch, roll) deg. Perspective: the bench's first (looking down);
# "ahead": looking about the horizon, as a camera looking ahead is looked through.
SEQUENCES = {
    "perspective": lambda k: ("perspective", 3.0 * k, -30.0 + k % 20, 0.0),
    "perspective ahead": lambda k: ("perspective", 3.0 * k, -10.0 + k % 20, 0.0),
    "equirect": lambda k: ("equirect", 3.0 * k, 0.0, 0.0),
    "equirect turned": lambda k: ("equirect", 3.0 * k, 10.0 + k % 20, 5.0),
}


def views_per_second(browser: Any, server: ViewerServer, count: int, sequence: str = "perspective") -> float:
    """Views/s of ``count`` views of ``SEQUENCES[sequence]`` set one after another, each awaited until drawn."""
    page = open_page(browser, server)
    views = []
    for k in range(count + 1):
        mode, yaw, pitch, roll = SEQUENCES[sequence](k)
        views.append({"mode": mode, "yaw": yaw, "pitch": pitch, "roll": roll, "fov": 90})
    script = """async ([views, width, height]) => {
      await window.panomapView.set({...views[0], width, height, strip: false});
      const started = performance.now();
      for (const view of views.slice(1)) await window.panomapView.set(view);
      return (performance.now() - started) / 1000;
    }"""
    seconds = page.evaluate(script, [views, *VIEW])
    page.close()
    return count / seconds


def cpu_view(sequence: str, k: int) -> View:
    mode, yaw, pitch, roll = (np.radians(x) if isinstance(x, float) else x for x in SEQUENCES[sequence](k))
    if mode == "perspective":
        return PerspectiveView(yaw, pitch, roll, np.radians(90), VIEW)
    return EquirectView(yaw, pitch, roll, VIEW)


def cpu_views_per_second(
    table: PanoMappingTable, image: np.ndarray, count: int, sequence: str = "perspective"
) -> float:
    started = time.perf_counter()
    for k in range(count):
        Remapper(build_map(table, cpu_view(sequence, k)))(image)
    return count / (time.perf_counter() - started)


def drag_to_picture(browser: Any, server: ViewerServer, moves: int) -> dict[str, float]:
    page = open_page(browser, server, f"#width={VIEW[0]}&height={VIEW[1]}")
    box = page.locator("#canvas").bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 3
    page.mouse.move(x, y)
    page.mouse.down()
    for k in range(moves):
        page.mouse.move(x + 3 * (k % 60) - 90, y + (k % 7))
        page.wait_for_timeout(16)
    page.mouse.up()
    page.wait_for_timeout(200)
    stats = page.evaluate("window.panomapView.stats().dragToPictureMs")
    page.close()
    return stats


def play(browser: Any, server: ViewerServer, seconds: float) -> dict[str, Any]:
    page = open_page(browser, server, f"#yaw=30&pitch=-20&fov=90&strip=0&width={VIEW[0]}&height={VIEW[1]}")  # one view
    first = page.evaluate("window.panomapView.stats()")
    started = time.monotonic()
    page.wait_for_timeout(seconds * 1000)
    last = page.evaluate("window.panomapView.stats()")
    wall = time.monotonic() - started
    page.close()
    return {
        "shown_per_s": (last["sourceFrames"] - first["sourceFrames"]) / wall,
        "clip_s_per_s": ((last["frameTime"] or 0) - (first["frameTime"] or 0)) / wall,
        "latency_ms": last["latencyMs"],
        "decoded_by": last["decodedBy"],
    }


def decode_floor(browser: Any, server: ViewerServer, seconds: float) -> float:
    """Frames/s Chromium presents of the clip with nothing drawn (its decoder's rate here: the floor)."""
    page = browser.new_page()
    page.set_content("<video id=v muted playsinline></video>")
    script = """async ([url, ms]) => {
      const v = document.getElementById('v');
      let n = 0;
      const count = () => { n++; v.requestVideoFrameCallback(count); };
      v.requestVideoFrameCallback(count);
      v.src = url;
      await v.play();
      await new Promise((r) => setTimeout(r, ms));
      return n / (ms / 1000);
    }"""
    rate = float(page.evaluate(script, [server.url + "api/video", seconds * 1000]))
    page.close()
    return rate


def live_stream(clip: Path) -> tuple[subprocess.Popen[bytes], str]:
    """ffmpeg serving ``clip`` in a loop, in real time, as MPEG-TS over TCP (one client)."""
    import socket

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    url = f"tcp://127.0.0.1:{port}"
    command = [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-loglevel", "error", "-nostdin", "-re"]
    command += ["-stream_loop", "-1", "-i", str(clip), "-c", "copy", "-f", "mpegts", f"{url}?listen=1"]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(1.0)
    return process, url


class ViewerProcess:
    """``panomap view TABLE SOURCE --port 0`` as a user runs it, in its own process."""

    def __init__(self, table_path: Path, source: str) -> None:
        command = [sys.executable, "-m", "panomap", "view", str(table_path), source, "--port", "0"]
        self.process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        assert self.process.stdout is not None
        line = self.process.stdout.readline()
        match = re.search(r"(http://127\.0\.0\.1:\d+/)", line)
        if match is None:
            raise SystemExit(
                f"panomap view did not start: {line}{self.process.stderr.read() if self.process.stderr else ''}"
            )
        self.url = match.group(1)

    def rss_mb(self) -> float:
        for line in Path(f"/proc/{self.process.pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
        return float("nan")

    def seconds_until_idle(self, limit_s: float) -> float:
        """Seconds until the server says its decoder is idle (no page asks any more)."""
        started = time.monotonic()
        while time.monotonic() - started < limit_s:
            with urllib.request.urlopen(self.url + "api/status", timeout=10) as answer:
                if json.load(answer)["state"] == "idle":
                    break
            time.sleep(0.2)
        return time.monotonic() - started

    def stop(self) -> None:
        self.process.send_signal(signal.SIGINT)
        try:
            self.process.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            self.process.kill()


def summary(values: dict[str, float] | None) -> str:
    if not values:
        return "none"
    return f"median {values['median']:.0f}, p90 {values['p90']:.0f}, max {values['max']:.0f} (n {values['count']})"


def views_ahead(browser: Any, table: PanoMappingTable, image: np.ndarray, folder: Path, views: int) -> None:
    """Part 1 again, the camera turned to look ahead (its table over the whole sphere)."""
    ahead = orient_table(table, 0.0, 0.0, 0.0)
    image_path = folder / "omni.png"
    server = make_server(ahead, "ahead.npz", open_source(str(image_path)))
    serve_in_thread(server)
    try:
        print(f"   the camera turned to look ahead (table {ahead.size[0]} x {ahead.size[1]}, elevations -90..90 deg):")
        for sequence in ("perspective ahead", "equirect", "equirect turned"):
            gpu = views_per_second(browser, server, views, sequence)
            cpu = cpu_views_per_second(ahead, image, max(5, views // 5), sequence)
            print(
                f"   {sequence:18} browser {gpu:5.1f} views/s (target 30), CPU {cpu:5.1f} views/s, "
                f"ratio browser / CPU {gpu / cpu:.2f}"
            )
    finally:
        server.shutdown()
        server.server_close()


def draws_per_second(browser: Any, server: ViewerServer, count: int, sequence: str) -> tuple[float, float]:
    """(views drawn per second from the page's fastest draw, views/s through ``set``) of ``count`` views (the
    fastest draw: what the GPU's work takes, least disturbed by other work on the machine)."""
    page = open_page(browser, server)
    views = []
    for k in range(count + 1):
        mode, yaw, pitch, roll = SEQUENCES[sequence](k)
        views.append({"mode": mode, "yaw": yaw, "pitch": pitch, "roll": roll, "fov": 90})
    script = """async ([views, width, height]) => {
      await window.panomapView.set({...views[0], width, height, strip: false});
      const before = window.panomapView.stats().views;
      const started = performance.now();
      for (const view of views.slice(1)) await window.panomapView.set(view);
      const seconds = (performance.now() - started) / 1000;
      return [window.panomapView.stats().drawMs.min, seconds];
    }"""
    fastest_ms, seconds = page.evaluate(script, [views, *VIEW])
    page.close()
    return 1000.0 / fastest_ms, count / seconds


def dual_fisheye(folder: Path) -> tuple[Any, Path, Path]:
    """(the rig, its frame, camera 0's picture): two ideal equidistant lenses back to back, 190 deg each, seeing a
    smooth random world (the content does not change the GPU's work)."""
    from panomap.interop.rig_of_camchain import rig_of_camchain

    lens = (
        "  camera_model: pinhole\n  intrinsics: [283.6, 283.6, 479.5, 479.5]\n  distortion_model: equidistant\n"
        "  distortion_coeffs: [0, 0, 0, 0]\n  resolution: [960, 960]\n"
    )
    pose = "  T_cn_cnm1: [[-1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -1, -0.02], [0, 0, 0, 1]]\n"
    (folder / "dual.yaml").write_text(f"cam0:\n{lens}cam1:\n{lens}{pose}")
    rig = rig_of_camchain(folder / "dual.yaml", side_by_side=True, fov_rad=np.radians(190))
    rng = np.random.default_rng(0)
    frame = cv2.GaussianBlur(rng.uniform(0, 255, (960, 1920, 3)).astype(np.float32), (0, 0), 6)
    frame = np.clip((frame - 128) * 6 + 128, 0, 255).astype(np.uint8)
    cv2.imwrite(str(folder / "frame.png"), frame)
    cv2.imwrite(str(folder / "cam0.png"), frame[:, :960])
    return rig, folder / "frame.png", folder / "cam0.png"


def views_of_a_rig(options: argparse.Namespace) -> None:
    """Part 6 (``--rig``): a dual fisheye's views beside its camera 0's alone."""
    from playwright.sync_api import sync_playwright

    from panomap.viewer.rig_view import open_rig_source

    views = 20 if options.quick else 100
    with tempfile.TemporaryDirectory() as temporary:
        folder = Path(temporary)
        rig, frame, cam0 = dual_fisheye(folder)
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            single = make_server(rig.tables[0], "cam0.npz", open_source(str(cam0)))
            rig_view, source = open_rig_source(rig, "dual.npz", [str(frame)])
            both = make_server(rig.tables[0], "dual.npz", source, rig=rig_view)
            for server in (single, both):
                serve_in_thread(server)
            print(f"6. a rig of two 190 deg lenses (one 1920 x 960 frame) against its camera 0 alone, {VIEW[0]} x "
                  f"{VIEW[1]} views:")  # fmt: skip
            try:
                for sequence in ("perspective ahead", "equirect", "equirect turned"):
                    one = draws_per_second(browser, single, views, sequence)
                    two = draws_per_second(browser, both, views, sequence)
                    print(
                        f"   {sequence:18} drawn/s: one camera {one[0]:5.1f}, the rig {two[0]:5.1f} (ratio "
                        f"{two[0] / one[0]:.2f}); through set: {one[1]:5.1f} and {two[1]:5.1f} views/s"
                    )
            finally:
                for server in (single, both):
                    server.shutdown()
                    server.server_close()
            browser.close()
    print(f"(load average at the end: {', '.join(f'{x:.2f}' for x in os.getloadavg())})")


def views_only(options: argparse.Namespace) -> None:
    """Part 1 alone (``--views-only``)."""
    from playwright.sync_api import sync_playwright

    views = 20 if options.quick else 100
    with tempfile.TemporaryDirectory() as temporary:
        folder = Path(temporary)
        clip, table_path, _ = make_clip(folder, 2, RATE)
        table = load_table(table_path)
        with av.open(str(clip)) as container:
            image = next(container.decode(video=0)).to_ndarray(format="bgr24")
        cv2.imwrite(str(folder / "omni.png"), image)
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            server = make_server(table, table_path.name, open_source(str(folder / "omni.png")))
            serve_in_thread(server)
            try:
                gpu = views_per_second(browser, server, views)
                cpu = cpu_views_per_second(table, image, max(5, views // 5))
                print(
                    f"1. {VIEW[0]} x {VIEW[1]} views, looking down: browser {gpu:.1f} views/s, CPU {cpu:.1f} views/s,"
                )
                print(f"   ratio browser / CPU {gpu / cpu:.2f}")
            finally:
                server.shutdown()
                server.server_close()
            views_ahead(browser, table, image, folder, views)
            browser.close()
    print(f"(load average at the end: {', '.join(f'{x:.2f}' for x in os.getloadavg())})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="A short clip, few views, a 20 s stream.")
    parser.add_argument("--minutes", type=float, default=10.0, help="Length of the live stream for memory (min).")
    parser.add_argument("--views-only", action="store_true", help="Only part 1, the views/s.")
    parser.add_argument("--rig", action="store_true", help="Only part 6, a rig's views beside one camera's.")
    options = parser.parse_args()
    if not Path(CHROMIUM).exists():
        raise SystemExit(f"{CHROMIUM} is missing (Debian's chromium: scripts/install-test-deps.sh)")
    if options.rig:
        views_of_a_rig(options)
        return
    if options.views_only:
        views_only(options)
        return
    from playwright.sync_api import sync_playwright

    frames = 60 if options.quick else 300
    views = 20 if options.quick else 100
    stream_s = 20.0 if options.quick else 60.0 * options.minutes
    with tempfile.TemporaryDirectory() as temporary:
        folder = Path(temporary)
        print(f"making a 1920 x 1920 clip of {frames} frames at {RATE} fps and its table ...", flush=True)
        clip, table_path, megabits = make_clip(folder, frames, RATE)
        table = load_table(table_path)
        with av.open(str(clip)) as container:
            image = next(container.decode(video=0)).to_ndarray(format="bgr24")
        image_path = folder / "omni.png"
        cv2.imwrite(str(image_path), image)
        print(f"clip: {megabits:.1f} Mbit/s; table {table.size[0]} x {table.size[1]}", flush=True)
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            server = make_server(table, table_path.name, open_source(str(image_path)))
            serve_in_thread(server)
            try:
                gpu = views_per_second(browser, server, views)
                cpu = cpu_views_per_second(table, image, max(5, views // 5))
                print(f"\n1. views of {VIEW[0]} x {VIEW[1]} set one after another through the API:")
                print(
                    f"   browser (SwiftShader) {gpu:.1f} views/s (target 30); "
                    f"CPU (build_map + remap) {cpu:.1f} views/s;"
                )
                print(f"   ratio browser / CPU {gpu / cpu:.2f}")
                views_ahead(browser, table, image, folder, views)
                drag = drag_to_picture(browser, server, 60 if options.quick else 240)
                print(f"2. drag to picture (ms): {summary(drag)}")
            finally:
                server.shutdown()
                server.server_close()

            server = make_server(table, table_path.name, open_source(str(clip)))
            serve_in_thread(server)
            try:
                floor = decode_floor(browser, server, min(frames / RATE - 0.5, 8.0))
                result = play(browser, server, min(frames / RATE - 0.5, 8.0))
                print(f"3. the 1920 x 1920 H.264 clip at {RATE} fps, decoded by the {result['decoded_by']}, one view:")
                print(
                    f"   {result['shown_per_s']:.1f} frames shown/s, {result['clip_s_per_s']:.2f} s of clip per s "
                    f"(ratio to its rate {result['shown_per_s'] / RATE:.2f})"
                )
                print(
                    f"   the floor: Chromium presents {floor:.1f} frames/s of it with nothing drawn "
                    f"(ratio shown / floor {result['shown_per_s'] / floor:.2f})"
                )
            finally:
                server.shutdown()
                server.server_close()

            process, url = live_stream(clip)
            viewer = ViewerProcess(table_path, url)
            try:
                page = browser.new_page(viewport={"width": 1400, "height": 1000}, bypass_csp=True)
                page.set_default_timeout(120_000)
                page.goto(viewer.url + f"#yaw=30&pitch=-20&fov=90&width={VIEW[0]}&height={VIEW[1]}")
                page.wait_for_selector("body[data-ready=yes]")
                page.wait_for_function("window.panomapView.stats().sourceFrames > 0")
                samples = [(0.0, viewer.rss_mb())]
                started = time.monotonic()
                first = page.evaluate("window.panomapView.stats().sourceFrames")
                while time.monotonic() - started < stream_s:
                    time.sleep(min(15.0, stream_s / 8))
                    samples.append(((time.monotonic() - started) / 60, viewer.rss_mb()))
                stats = page.evaluate("window.panomapView.stats()")
                shown = (stats["sourceFrames"] - first) / (time.monotonic() - started)
                page.close()
                freed = viewer.seconds_until_idle(30.0)
                print(f"4. live stream (MPEG-TS over TCP at {RATE} fps, decoded by the server, JPEG to the page):")
                print(f"   {shown:.1f} frames shown/s; latency decoded -> drawn (ms): {summary(stats['latencyMs'])}")
                curve = ", ".join(f"{minute:.1f} min {mb:.0f}" for minute, mb in samples[:: max(1, len(samples) // 8)])
                settled = [mb for minute, mb in samples if minute >= 1.0] or [samples[-1][1]]
                print(
                    f"5. the server's (panomap view's) memory over {stream_s / 60:.1f} min, MB: {curve}, "
                    f"last {samples[-1][1]:.0f}; from the first minute on it stayed within "
                    f"{max(settled) - min(settled):.0f} MB"
                )
                print(f"   the page closed: the decoder stopped after {freed:.1f} s (idle limit 10 s)")
            finally:
                viewer.stop()
                process.kill()
            browser.close()
    print(f"\n(load average at the end: {', '.join(f'{x:.2f}' for x in os.getloadavg())})")


if __name__ == "__main__":
    main()
