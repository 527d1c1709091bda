"""Running a job on Dask distributed: a local cluster by default, or an existing one.

Without a scheduler address (argument or ``DASK_SCHEDULER_ADDRESS``), the job starts an
in-process :class:`distributed.LocalCluster` of one single-threaded worker process per core
(forked from a fork server that has imported panomap, see :mod:`panomap.batch.forkserver`) and stops
it at the end. With an address, the same tasks go to that cluster's workers,
which must see the job's paths (shared storage) and have panomap installed.

The tasks (:mod:`panomap.batch.tasks`): still images in chunks, one task per video, or one
per time segment of a video plus a join; each retried ``retries`` times (a worker that dies
takes its tasks with it: the scheduler gives them to another). An image that fails in its
chunk is tried again alone. Only this process writes the record, as results come in, so
that a job stopped at any point (``stop``, a signal, a kill) is resumed by running it
again: what is complete is skipped, the rest is redone.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from .. import inputs
from ..errors import PanomapError
from ..files import check_output
from .forkserver import SCHEDULER_VARIABLE, can_fork_serve, start_fork_server
from .job import Item, Job
from .leftovers import tidy
from .record import Failed, Record
from .segments import Probe, plan_segments, probe
from .tasks import ItemResult, PartResult, describe, join_video, unwarp_images, unwarp_segment, unwarp_whole_video

# The local cluster's workers (measured: docs/scaling.md, "Where the batch lost"):
# - forked from a fork server that has imported Dask, NumPy, OpenCV, PyAV and panomap once (start_fork_server),
#   not each a fresh interpreter importing them again; the cluster then stops in 0.1-0.2 s, not 1.3-1.8 s;
# - without Dask's MALLOC_TRIM_THRESHOLD_ of 64 KiB (it turns off glibc's adaptive mmap threshold: every frame
#   in fresh pages, three times the page faults) or its statistical profiler (every thread's stack each 10 ms),
#   and with its event-loop tick and system monitor slowed (20 ms, 0.5 s): a video task of 100 frames
#   (1920 x 1920, two views) takes 14.3 CPU-s, not 17.8 (14.8 in a plain process).
LOCAL_WORKERS = {
    "distributed.worker.multiprocessing-method": "forkserver",
    "distributed.worker.profile.enabled": False,
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "5s",
}


@dataclass(frozen=True)
class Progress:
    """Where a job stands: inputs and frames done, of how many (frames: None while unknown)."""

    inputs_done: int
    inputs_total: int
    frames_done: int
    frames_total: int | None


@dataclass
class BatchReport:
    """What a run of a job did."""

    inputs: int = 0
    skipped: int = 0
    done: int = 0
    outputs: int = 0
    frames: int = 0
    failed: list[Failed] = field(default_factory=list)
    interrupted: bool = False
    seconds: float = 0.0
    workers: int = 0
    dashboard: str | None = None

    @property
    def ok(self) -> bool:
        """Every input of the job is complete."""
        return not self.failed and not self.interrupted


def scheduler_address(address: str | None) -> str | None:
    """The scheduler to use: ``address``, else ``DASK_SCHEDULER_ADDRESS``, else None (a local cluster)."""
    return address or os.environ.get(SCHEDULER_VARIABLE) or None


def _has_dashboard() -> bool:
    try:
        import bokeh  # noqa: F401
    except ImportError:
        return False
    return True


@contextlib.contextmanager
def connect(address: str | None, workers: int | None = None, timeout_s: float = 20.0) -> Iterator[Any]:
    """A Dask client: of the scheduler at ``address``, or of a local cluster of ``workers``
    single-threaded worker processes (default: one per core), stopped on exit."""
    import dask
    from distributed import Client, LocalCluster

    if address is not None:
        try:
            client = Client(address, timeout=timeout_s)
        except (OSError, TimeoutError, ValueError) as exc:
            raise PanomapError(f"cannot reach the Dask scheduler at {address} ({describe(exc)})") from None
        with client:
            yield client
        return
    count = workers or os.cpu_count() or 1
    settings = {key: value for key, value in LOCAL_WORKERS.items() if can_fork_serve() or "multiprocessing" not in key}
    with dask.config.set(settings):  # (for the cluster's life: a worker that dies is started the same way)
        start_fork_server()
        with (
            LocalCluster(
                n_workers=count,
                threads_per_worker=1,
                processes=True,
                # A free port, whether or not bokeh serves a dashboard there: None meant Dask's default 8787
                # for its HTTP server, and where that is taken (another Dask, a second batch) a three-line
                # warning from distributed, and a socket left open.
                dashboard_address=":0",
                silence_logs=logging.CRITICAL,  # a failing task is reported here, in one line
            ) as cluster,
            Client(cluster) as client,
        ):
            yield client


def codec_threads(address: str | None, workers: int) -> int | None:
    """Threads for each video task's decoder and encoders: on a local cluster of several workers, the cores
    shared among them (one each on a machine of as many cores as workers: two videos at once on two cores
    then run about 3% faster than with FFmpeg's thread per core each, docs/scaling.md); else FFmpeg's
    choice (None: a cluster's workers are sized by whoever started them)."""
    if address is not None or workers < 2:
        return None
    return max(1, (os.cpu_count() or 1) // workers)


def chunk_size(images: int, workers: int) -> int:
    """Images per task: about four tasks per worker (so that a slow or lost worker costs little), 1 to 16."""
    return max(1, min(16, math.ceil(images / (4 * max(1, workers)))))


@dataclass(frozen=True)
class RunSettings:
    """How a job is run: ``scheduler`` (or ``DASK_SCHEDULER_ADDRESS``) names an existing cluster, else a local one
    of ``workers`` processes (default: one per core) runs it; ``force`` redoes complete inputs; a failing input
    is tried ``retries`` more times; videos longer than ``segment_s`` seconds are split into segments of that
    length; ``chunk`` still images go in a task (default :func:`chunk_size`)."""

    scheduler: str | None = None
    workers: int | None = None
    force: bool = False
    retries: int = 2
    segment_s: float | None = None
    chunk: int | None = None

    def __post_init__(self) -> None:
        for what, value, least in (
            ("workers", self.workers, 1),
            ("retries", self.retries, 0),
            ("chunk", self.chunk, 1),
        ):
            if value is not None and inputs.whole_numbers((value,), 1, what)[0] < least:
                raise PanomapError(f"{what} must be {least} or more, not {value}")
        if self.segment_s is not None and not inputs.number(self.segment_s, "segment_s") > 0:
            raise PanomapError(f"segment_s must be more than 0 s, not {self.segment_s}")


@dataclass(frozen=True)
class RunHooks:
    """What a run tells its caller, and how it is stopped: ``progress`` as results come in, ``warn`` for each
    failure as it happens, ``on_dashboard`` the Dask dashboard's address when there is one; setting ``stop``
    cancels what has not finished."""

    progress: Callable[[Progress], None] | None = None
    stop: threading.Event = field(default_factory=threading.Event)
    warn: Callable[[str], None] = lambda message: None
    on_dashboard: Callable[[str], None] | None = None


def run_job(
    job: Job,
    record: Record,
    settings: RunSettings | None = None,
    *,
    progress: Callable[[Progress], None] | None = None,
    stop: threading.Event | None = None,
    warn: Callable[[str], None] | None = None,
    on_dashboard: Callable[[str], None] | None = None,
    **options: Any,
) -> BatchReport:
    """Run ``job`` as ``settings`` say (:class:`RunSettings`; its fields may also be given as keywords,
    ``scheduler=...``), skipping the inputs ``record`` holds as complete (all of them with ``force``).

    Every output is checked before any work (its folder made; an output that cannot be
    replaced is refused; a folder made that holds nothing at the end, as for an input that
    failed, is removed). What killed runs left beside the job's outputs is removed when the run
    starts and when it ends (:func:`panomap.batch.leftovers.tidy`). A failing input is tried
    ``retries`` more times, then recorded as failed, and the job goes on. ``progress``, ``stop``,
    ``warn`` and ``on_dashboard``: :class:`RunHooks`.

    Parameters
    ----------
    job : Job
        What :func:`panomap.make_job` made.
    record : Record
        The job's record of finished outputs, updated as each finishes.
    settings : RunSettings, optional
        Where and how to run (scheduler, workers, segments, retries, ``force``).
    progress : callable, optional
        Called with the progress as results come in.
    stop : threading.Event, optional
        Set it to cancel what has not finished.
    warn : callable, optional
        Called with one line for each failure as it happens.
    on_dashboard : callable, optional
        Called with the Dask dashboard's address, where there is one.
    **options
        Fields of :class:`RunSettings`, replacing those of ``settings``.

    Returns
    -------
    BatchReport
    """
    settings = replace(settings or RunSettings(), **options)
    hooks = RunHooks(progress, stop or threading.Event(), warn or (lambda message: None), on_dashboard)
    run = _Run(job, record, settings, hooks)
    tidy(job, record.complete)  # (what killed runs left: before any work, so a full disk is not made worse)
    try:
        return run.run()
    finally:
        tidy(job, record.complete)  # (and what their workers, outliving them, left while this run ran)
        run.clean_up()


class _Run:
    """One run of a job: prepared (checks, folders, probes), submitted to Dask, its results collected (a chunk
    that failed retried image by image), then cleaned up after."""

    def __init__(self, job: Job, record: Record, settings: RunSettings, hooks: RunHooks) -> None:
        self.job, self.record, self.settings, self.hooks = job, record, settings, hooks
        self.address = scheduler_address(settings.scheduler)
        self.report = BatchReport(inputs=len(job.items))
        self.made: list[Path] = []  # the folders made for the outputs (outermost first)
        self.kinds: dict[Any, tuple[str, Any]] = {}  # each future: its kind and what it carries
        self.done = {"inputs": 0, "frames": 0}
        self.total = 0
        self.frames_total: int | None = None
        self.started = time.perf_counter()

    def run(self) -> BatchReport:
        pending = self.prepare()
        images = [item for item in pending if not item.input.is_video]
        probes = self.probe_videos(pending)
        if images or probes:
            known = [info.frames for info in probes.values()]
            self.frames_total = None if None in known else len(images) + sum(frame or 0 for frame in known)
            self.total = len(images) + len(probes)
            with connect(self.address, self.settings.workers) as client:
                self.submit(client, images, probes)
                self.collect(client)
        self.report.seconds = time.perf_counter() - self.started
        return self.report

    def prepare(self) -> list[Item]:
        """The record checked against the job's files, the inputs still to do, their outputs' folders made and
        the outputs checked."""
        for item in self.job.items:
            for path, what in [(item.input.path, "an input"), (item.input.table, "a table")] + [
                (output.path, "an output") for output in item.outputs
            ]:
                if path.absolute() == self.record.path:
                    raise PanomapError(
                        f"the record would be {what} of the job: give --record another file", self.record.path
                    )
        pending = [item for item in self.job.items if self.settings.force or not self.record.complete(item)]
        if self.address is None and pending:
            start_fork_server()  # (its imports overlap the checks below and the import of Dask)
        self.report.skipped = len(self.job.items) - len(pending)
        for item in pending:
            for output in item.outputs:
                missing = [f for f in (output.path.parent, *output.path.parent.parents) if not f.exists()]
                try:
                    output.path.parent.mkdir(parents=True, exist_ok=True)
                    self.made.extend(reversed(missing))  # (outermost first)
                except OSError as exc:
                    raise PanomapError(f"cannot make its folder ({exc.strerror or exc})", output.path) from None
                check_output(output.path)
        return pending

    def probe_videos(self, pending: list[Item]) -> dict[Item, Probe]:
        """Each pending video's length and frames; one that cannot be probed is recorded as failed."""
        probes: dict[Item, Probe] = {}
        for item in pending:
            if item.input.is_video:
                try:
                    probes[item] = probe(item.input.sources[0])
                except PanomapError as exc:
                    failure = Failed(str(item.input.path), item.key, describe(exc))
                    self.record.add_failed(failure)
                    self.report.failed.append(failure)
                    self.hooks.warn(f"failed: {failure.error}")
        return probes

    def submit(self, client: Any, images: list[Item], probes: dict[Item, Probe]) -> None:
        """Every task: images in chunks, each video whole or in segments and a join."""
        job, retries = self.job, self.settings.retries
        self.report.workers = len(client.scheduler_info().get("workers", {}))
        link = getattr(client, "dashboard_link", None) if _has_dashboard() else None
        if link and self.hooks.on_dashboard is not None:
            self.report.dashboard = link
            self.hooks.on_dashboard(link)
        size = self.settings.chunk or chunk_size(len(images), self.report.workers)
        threads = codec_threads(self.address, self.report.workers)
        for first in range(0, len(images), size):
            group = images[first : first + size]
            future = client.submit(unwarp_images, group, job.views, job.settings, retries=retries, pure=False)
            self.kinds[future] = ("images", group)
        for item, info in probes.items():
            # (a rig's video whole: its inputs are read in step from their starts)
            length = None if item.input.rig else self.settings.segment_s
            segments = plan_segments(info, length) if length is not None else []
            if len(segments) > 1:
                parts = [
                    client.submit(
                        unwarp_segment, item, job.views, job.settings, s, threads, retries=retries, pure=False
                    )
                    for s in segments
                ]
                for part_future in parts:
                    self.kinds[part_future] = ("segment", item)
                self.kinds[client.submit(join_video, item, parts, retries=retries, pure=False)] = ("video", item)
            else:
                future = client.submit(
                    unwarp_whole_video, item, job.views, job.settings, threads, retries=retries, pure=False
                )
                self.kinds[future] = ("video", item)

    def collect(self, client: Any) -> None:
        """Take the results as they come, until every task has ended or ``stop`` is set (the rest cancelled)."""
        from distributed import as_completed

        waiting = as_completed(list(self.kinds))
        while not waiting.is_empty() and not self.report.interrupted:
            if self.hooks.stop.is_set():
                self.interrupt(client)
                break
            if not waiting.has_ready():
                time.sleep(0.05)
                continue
            for future in waiting.next_batch(block=False):
                if self.hooks.stop.is_set():
                    # Stopped while taking a batch of results: the rest are not recorded (a rerun redoes them),
                    # and the job is interrupted even when that batch held every result left.
                    self.interrupt(client)
                    break
                for again in self.take(client, future):
                    waiting.add(again)

    def interrupt(self, client: Any) -> None:
        self.report.interrupted = True
        client.cancel(list(self.kinds))

    def take(self, client: Any, future: Any) -> list[Any]:
        """One finished task's result recorded; returns the tasks submitted again (a failed chunk's images)."""
        kind, payload = self.kinds[future]
        error = future.status == "error"
        if kind == "segment":
            if not error:
                part: PartResult = future.result()
                self.advance(0, part.frames)
            return []
        if kind in ("video", "single"):
            if error:
                self.fail(payload, describe(future.exception()))
            else:
                self.finish(future.result() if kind == "video" else future.result()[0], payload)
            return []
        if error:  # a whole chunk failed (after its retries): each image alone
            results = [ItemResult(str(item.input.path), error="retry") for item in payload]
        else:
            results = future.result()
        again = []
        for item, outcome in zip(payload, results, strict=True):
            if outcome.error is None:
                self.finish(outcome, item)
                continue
            job = self.job
            retry = client.submit(
                unwarp_images, [item], job.views, job.settings, True, retries=self.settings.retries, pure=False
            )
            self.kinds[retry] = ("single", item)
            again.append(retry)
        return again

    def advance(self, inputs: int, frames: int) -> None:
        self.done["inputs"] += inputs
        self.done["frames"] += frames
        if self.hooks.progress is not None:
            self.hooks.progress(Progress(self.done["inputs"], self.total, self.done["frames"], self.frames_total))

    def finish(self, result: ItemResult, item: Item) -> None:
        self.record.add_done(result.done)
        self.report.done += 1
        self.report.outputs += len(result.done)
        frames = result.done[0].frames if result.done else 0
        self.report.frames += frames
        self.advance(1, 0 if item.input.is_video else frames)

    def fail(self, item: Item, error: str) -> None:
        if str(item.input.path) not in error:
            error = f"{item.input.path}: {error}"
        failure = Failed(str(item.input.path), item.key, error)
        self.record.add_failed(failure)
        self.report.failed.append(failure)
        self.hooks.warn(f"failed: {error}")  # (as it happens; the report lists them all)
        self.advance(1, 0)

    def clean_up(self) -> None:
        """The folders made for outputs that never came (where empty) removed."""
        for folder in reversed(self.made):  # (the deepest first)
            with contextlib.suppress(OSError):
                folder.rmdir()  # only where empty
