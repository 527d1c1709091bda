"""Where a rig's video spends its time (issue 52): ``unwarp_rig_video`` on one clip, each stage timed.

Run: ``.venv/bin/python bench/bench_rig_stages.py RIG CLIP [--view SPEC] [--output PATH] [--events]``
(``bench/bench_rig.py --dual-only --keep DIR`` leaves ``DIR/dual.npz`` and ``DIR/dual.mp4``, the clip it times).

It wraps, in this process only, the pipeline's queues (how long each thread waits to put or get a frame), the
blend (:class:`panomap.video.rig.RigFrameRemapper`: its set-up and each frame) and the writer's encoder calls, and
samples every 0.25 s each thread's CPU time (``/proc/self/task``) and the machine's idle time (``/proc/stat``).
It prints:

- the start-up: reading the rig, the maps, the blend's set-up, the first blended frame (s from the start);
- each stage's wall time and its own thread's CPU (s): the blend, the encoder calls (x264 works on its own
  threads: the call's wall is mostly waiting for them), and the waits on each queue;
- the CPU of each thread name (FFmpeg's decoder threads are named ``av:h264:...``; x264's and Python's are
  ``python``);
- per second: the cores this process used and the cores the machine left idle (a core idle while this process
  used less than all of them: the pipeline waiting on itself; none idle: the machine's other jobs took them);
- the x264 settings written in the output (its threads, sliced or not), to compare with ffmpeg's output.

Linux only (``/proc``).
"""

from __future__ import annotations

import argparse
import collections
import os
import queue as queue_module
import re
import threading
import time
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any

START = time.perf_counter()
# (start s, thread, what, wall s, thread CPU s or queue size)
EVENTS: list[tuple[float, str, str, float, float]] = []
SAMPLE_S = 0.25


def since_start() -> float:
    """Seconds since this script started."""
    return time.perf_counter() - START


class TimedQueue(queue_module.Queue):  # type: ignore[type-arg]
    """A queue that records how long each put and get waited (an event each, with the queue's size after)."""

    def put(self, item: Any, block: bool = True, timeout: float | None = None) -> None:
        began = since_start()
        super().put(item, block, timeout)
        EVENTS.append((began, threading.current_thread().name, "put", since_start() - began, self.qsize()))

    def get(self, block: bool = True, timeout: float | None = None) -> Any:
        began = since_start()
        name = threading.current_thread().name
        try:
            item = super().get(block, timeout)
        except queue_module.Empty:
            EVENTS.append((began, name, "get", since_start() - began, 0))
            raise
        EVENTS.append((began, name, "get", since_start() - began, self.qsize()))
        return item


def timed(function: Callable[..., Any], what: str) -> Callable[..., Any]:
    """``function`` recording its wall time and its thread's CPU time as an event ``what``."""

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        began, cpu = since_start(), time.thread_time()
        try:
            return function(*args, **kwargs)
        finally:
            EVENTS.append((began, threading.current_thread().name, what, since_start() - began,
                           time.thread_time() - cpu))  # fmt: skip

    return wrapper


def instrument() -> Any:
    """Wrap the pipeline's queues, maps, blend and encoder calls; the module :mod:`panomap.video.rig`."""
    import panomap.video.output as output
    import panomap.video.rig as rig_video

    timed_queue = types.SimpleNamespace(**{k: getattr(queue_module, k) for k in ("Empty", "Full")})
    timed_queue.Queue = TimedQueue
    rig_video.queue = timed_queue  # type: ignore[attr-defined]
    output.queue = timed_queue  # type: ignore[attr-defined]
    rig_video.camera_maps = timed(rig_video.camera_maps, "maps")  # type: ignore[attr-defined]
    remapper = rig_video.RigFrameRemapper
    remapper.__init__ = timed(remapper.__init__, "blend set-up")  # type: ignore[method-assign]
    remapper.__call__ = timed(remapper.__call__, "blend")  # type: ignore[method-assign]
    run = output.Writer.run

    def writer_run(self: Any, stop: threading.Event) -> None:
        stream = self.video

        class Encoding:
            """The writer's stream with its ``encode`` timed."""

            encode = staticmethod(timed(stream.encode, "encode"))

            def __getattr__(self, name: str) -> Any:
                return getattr(stream, name)

        self.video = Encoding()
        try:
            run(self, stop)
        finally:
            self.video = stream

    output.Writer.run = writer_run  # type: ignore[method-assign]
    return rig_video


class Sampler:
    """Every :data:`SAMPLE_S`: each thread's CPU (s) by thread id, and (time, process CPU, machine idle) (s)."""

    def __init__(self) -> None:
        self.threads: dict[str, tuple[str, float]] = {}
        self.timeline: list[tuple[float, float, float]] = []
        self.done = threading.Event()
        self.tick = os.sysconf("SC_CLK_TCK")
        self.thread = threading.Thread(target=self.run, name="bench-sampler", daemon=True)

    def sample(self) -> None:
        for tid in os.listdir("/proc/self/task"):
            try:
                stat = Path(f"/proc/self/task/{tid}/stat").read_text()
            except OSError:
                continue
            name, fields = stat[stat.index("(") + 1 : stat.rindex(")")], stat[stat.rindex(")") + 2 :].split()
            self.threads[tid] = (name, (int(fields[11]) + int(fields[12])) / self.tick)
        idle = int(Path("/proc/stat").read_text().split("\n", 1)[0].split()[4]) / self.tick
        self.timeline.append((since_start(), sum(cpu for _, cpu in self.threads.values()), idle))

    def run(self) -> None:
        while not self.done.is_set():
            self.sample()
            time.sleep(SAMPLE_S)


def summary(total_s: float, frames: int, sampler: Sampler) -> None:
    """Print the stages' figures (module docstring)."""
    print(f"{frames} frames in {total_s:.2f} s; this process's CPU {time.process_time():.2f} s")
    for what in ("maps", "blend set-up"):
        for began, _, name, wall, _cpu in EVENTS:
            if name == what:
                print(f"  {what}: from {began:.2f} s, {wall:.2f} s")
    blends = [e for e in EVENTS if e[2] == "blend"]
    if blends:
        walls = sorted(e[3] for e in blends)
        print(f"  first blended frame at {blends[0][0] + blends[0][3]:.2f} s; blend: {len(blends)} frames, "
              f"{sum(walls):.2f} s (median {1e3 * walls[len(walls) // 2]:.0f} ms), its thread's CPU "
              f"{sum(e[4] for e in blends):.2f} s (the luma on a helper thread besides)")  # fmt: skip
    encodes = [e for e in EVENTS if e[2] == "encode"]
    if encodes:
        print(f"  encoder calls: {len(encodes)}, {sum(e[3] for e in encodes):.2f} s, the writer thread's CPU in "
              f"them {sum(e[4] for e in encodes):.2f} s; the last returned at "
              f"{max(e[0] + e[3] for e in encodes):.2f} s")  # fmt: skip
    waits: dict[tuple[str, str], float] = collections.defaultdict(float)
    for _, thread, name, wall, _ in EVENTS:
        if name in ("put", "get"):
            waits[(thread, name)] += wall
    for (thread, name), wall in sorted(waits.items()):
        print(f"  {thread} waited to {name} a frame: {wall:.2f} s")
    by_name: dict[str, float] = collections.defaultdict(float)
    for name, cpu in sampler.threads.values():
        by_name[name] += cpu
    print("CPU by thread name (s):", ", ".join(f"{n} {c:.2f}" for n, c in sorted(by_name.items(), key=lambda x: -x[1])))
    print("per second: t (s), cores this process used, cores the machine left idle")
    step = max(1, round(1 / SAMPLE_S))
    for a, b in zip(sampler.timeline[::step], sampler.timeline[step::step], strict=False):
        span = b[0] - a[0]
        print(f"  {a[0]:6.1f}  {(b[1] - a[1]) / span:.2f}  {(b[2] - a[2]) / span:.2f}")


def x264_settings(path: Path) -> str:
    """The threading x264 wrote into the video at ``path`` (its SEI options), or a note that there is none."""
    found = re.search(rb"threads=\S+ lookahead_threads=\S+ sliced_threads=\S+", path.read_bytes()[:4_000_000])
    return found.group().decode() if found else "(no x264 settings found)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rig", type=Path)
    parser.add_argument("clip", type=Path)
    parser.add_argument("--view", default="equirect:size=3840x1920")
    parser.add_argument("--output", type=Path, default=Path("/tmp/panomap-rig-stages.mp4"))
    parser.add_argument("--events", action="store_true", help="print every event of 5 ms or more too")
    args = parser.parse_args()
    rig_video = instrument()
    from panomap.rig import load_rig
    from panomap.views.spec import parse_view_spec

    sampler = Sampler()
    sampler.thread.start()
    rig = load_rig(args.rig)
    print(f"rig read at {since_start():.2f} s")
    report = rig_video.unwarp_rig_video(rig, [str(args.clip)], args.output, parse_view_spec(args.view)[1])
    total = since_start()
    sampler.done.set()
    sampler.thread.join()
    sampler.sample()
    summary(total, report.frames_written, sampler)
    print("x264:", x264_settings(args.output))
    if args.events:
        for began, thread, name, wall, extra in sorted(EVENTS):
            if wall >= 0.005:
                print(f"{began:8.3f} {thread:>20} {name:>12} {wall:.3f} {extra:.3f}")


if __name__ == "__main__":
    main()
