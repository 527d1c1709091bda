"""What runs on the workers: still images in chunks, a video (or one segment of it), a join.

Every function here is a plain top-level function of plain values (paths, frozen
dataclasses), so that Dask can ship it to any worker. Each worker process keeps the
tables it has loaded and the maps it has built (:data:`_TABLES`, :data:`_REMAPPERS`),
keyed by the table's path and the SHA-256 of its file: every task of a camera after the
first on a worker starts at once (still images reuse the maps too; a video builds its own, as
``panomap video`` does, see :func:`video_table`). Outputs appear atomically (:mod:`panomap.files`).

A rig's input (its table a rig file) is blended as the view commands blend it (:class:`panomap.rig.RigRemapper`,
the gains found in each picture), or as ``panomap video`` does (:func:`panomap.video.rig.unwarp_rig_video`, one
decode per view): the rigs and their remappers are kept as the tables are (:data:`_RIGS`,
:data:`_RIG_REMAPPERS`).
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
import shutil
import time
import traceback
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from fractions import Fraction
from pathlib import Path
from typing import TypeVar

from ..errors import PanomapError
from ..files import all_or_none
from ..io.images import read_image, read_rig_pictures, write_image
from ..remap import Remapper
from ..rig import CameraRig, RigRemapper, camera_maps, load_rig
from ..rig.blend import WRAPPING_KINDS
from ..table.file import load_table
from ..table.table import PanoMappingTable
from ..video.frames import opencv_threads
from ..video.rig import unwarp_rig_video
from ..video.source import Selection
from ..video.unwarp import ViewOutput, unwarp_video
from ..views import build_map
from ..views.spec import NamedView
from .job import Item, Settings
from .record import Done
from .segments import Segment, join_segments

K = TypeVar("K")
V = TypeVar("V")

# Tables (and their maps) a worker keeps: the most recently used, a few cameras at a time.
CACHED_TABLES = 8
_TABLES: OrderedDict[tuple[str, str], PanoMappingTable] = OrderedDict()
_REMAPPERS: OrderedDict[tuple[str, str, str], list[Remapper]] = OrderedDict()
_RIGS: OrderedDict[tuple[str, str], CameraRig] = OrderedDict()
_RIG_REMAPPERS: OrderedDict[tuple[str, str, str], list[RigRemapper]] = OrderedDict()


@dataclass(frozen=True)
class ItemResult:
    """What became of one input: its finished outputs, or the error that stopped it (one line)."""

    input: str
    done: tuple[Done, ...] = ()
    error: str | None = None


@dataclass(frozen=True)
class PartResult:
    """One segment of a video unwarped: its part files (one per view, in view order) and frames."""

    index: int
    paths: tuple[Path, ...]
    offset: Fraction
    frames: int


def _kept(cache: OrderedDict[K, V], key: K, make: Callable[[], V]) -> V:
    """``cache[key]``, made by ``make`` where it is missing; the :data:`CACHED_TABLES` used last are kept."""
    value = cache.get(key)
    if value is None:
        value = make()
        cache[key] = value
        while len(cache) > CACHED_TABLES:
            cache.popitem(last=False)
    cache.move_to_end(key)
    return value


def cached_table(path: Path, digest: str) -> PanoMappingTable:
    """The table at ``path`` whose file has SHA-256 ``digest``, loaded once per worker."""
    return _kept(_TABLES, (str(path), digest), lambda: load_table(path))


def cached_remappers(item: Item, views: Sequence[NamedView], settings: Settings) -> list[Remapper]:
    """Each view's remapper for ``item``'s table, built once per worker.

    Maps are made the exact way (as the view commands make their one map), so that a batch
    output equals the view command's output bit for bit; per worker and camera that is paid once.
    """

    def make() -> list[Remapper]:
        table = cached_table(item.input.table, item.table_sha256)
        size = None if table.image_size is None else (int(table.image_size[0]), int(table.image_size[1]))
        return [
            Remapper(build_map(table, named.view, settings.sampling, exact=True), size, settings.interpolation)
            for named in views
        ]

    return _kept(_REMAPPERS, _views_key(item, views, settings), make)


def cached_rig(path: Path, digest: str) -> CameraRig:
    """The rig at ``path`` whose file has SHA-256 ``digest``, loaded once per worker; its tables fresh objects (their
    arrays shared) at each call, as :func:`video_table` makes them: every view's maps as the commands make them."""
    rig = _kept(_RIGS, (str(path), digest), lambda: load_rig(path))
    return replace(rig, tables=tuple(copy.copy(table) for table in rig.tables))


def cached_rig_remappers(item: Item, views: Sequence[NamedView], settings: Settings) -> list[RigRemapper]:
    """Each view's blend of ``item``'s rig (as the view commands make it: its weights wrap on a panorama), built
    once per worker."""

    def make() -> list[RigRemapper]:
        remappers = []
        for named in views:
            rig = cached_rig(item.input.table, item.table_sha256)
            maps = camera_maps(rig, named.view, settings.sampling)
            remappers.append(RigRemapper(rig, maps, settings.interpolation, wrap=named.view.kind in WRAPPING_KINDS))
        return remappers

    return _kept(_RIG_REMAPPERS, _views_key(item, views, settings), make)


def _views_key(item: Item, views: Sequence[NamedView], settings: Settings) -> tuple[str, str, str]:
    """The key of ``item``'s table (or rig) file with these views and settings."""
    return (str(item.input.table), item.table_sha256, repr([*views, settings.interpolation, settings.sampling]))


def describe(exc: BaseException) -> str:
    """An error in one line: a PanomapError's message, or the exception's type and message."""
    if isinstance(exc, PanomapError):
        return " ".join(str(exc).split())
    if isinstance(exc, OSError) and exc.strerror:
        return f"{exc.filename or ''}: {exc.strerror}".lstrip(": ")
    where = traceback.extract_tb(exc.__traceback__)[-1:] if exc.__traceback__ is not None else []
    at = f" (at {Path(where[0].filename).name}:{where[0].lineno})" if where else ""
    return f"{exc.__class__.__name__}: {' '.join(str(exc).split())}{at}"


def finished(item: Item, view: str, path: Path, frames: int, seconds: float) -> Done:
    """The record of one written output: its size, modification time and SHA-256."""
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        while block := handle.read(1 << 20):
            digest.update(block)
    info = path.stat()
    return Done(
        str(path), str(item.input.path), view, item.key, frames, info.st_size, digest.hexdigest(), info.st_mtime_ns,
        round(seconds, 3),
    )  # fmt: skip


def unwarp_images(
    items: Sequence[Item], views: Sequence[NamedView], settings: Settings, raise_errors: bool = False
) -> list[ItemResult]:
    """Unwarp still images into every view; one result per input.

    An input that fails gets its error in its result (the others go on); with
    ``raise_errors`` the first failure is raised instead (so that Dask retries the task).
    OpenCV runs on one thread: a worker is one core.
    """
    results = []
    with opencv_threads(1):
        for item in items:
            started = time.perf_counter()
            try:
                if item.input.rig:
                    rigs = cached_rig_remappers(item, views, settings)
                    pictures = read_rig_pictures(rigs[0].rig, item.input.sources)
                    with all_or_none():
                        for blend, output in zip(rigs, item.outputs, strict=True):
                            write_image(output.path, blend(pictures))
                else:
                    remappers = cached_remappers(item, views, settings)
                    table = cached_table(item.input.table, item.table_sha256)
                    image = read_image(item.input.path, table.image_size, f"the table {item.input.table}")
                    with all_or_none():
                        for remapper, output in zip(remappers, item.outputs, strict=True):
                            write_image(output.path, remapper(image))
                seconds = time.perf_counter() - started
                done = tuple(finished(item, out.view, out.path, 1, seconds) for out in item.outputs)
                results.append(ItemResult(str(item.input.path), done))
            except Exception as exc:
                if raise_errors:
                    raise
                results.append(ItemResult(str(item.input.path), error=describe(exc)))
    return results


def video_table(item: Item) -> PanoMappingTable:
    """The cached table as a new object (its arrays shared) for one video run.

    :func:`panomap.views.build_map` decides per table object whether a perspective or floor
    map is made the exact way (the first) or from the direction lookup (later ones); a fresh
    object makes every video task's maps exactly those of ``panomap video`` on that input,
    whichever worker runs it and whatever it ran before (so segments join seamlessly).
    """
    return copy.copy(cached_table(item.input.table, item.table_sha256))


def unwarp_whole_video(
    item: Item, views: Sequence[NamedView], settings: Settings, codec_threads: int | None = None
) -> ItemResult:
    """Unwarp one video into every view (one decode); raises on failure (Dask retries it). ``codec_threads``:
    the decoder's and each encoder's threads (default FFmpeg's choice, :func:`panomap.video.unwarp_video`). A rig's
    video is blended once per view (:func:`panomap.video.rig.unwarp_rig_video` makes one view)."""
    if item.input.rig:
        frames, seconds = 0, 0.0
        for named, output in zip(views, item.outputs, strict=True):
            rig = cached_rig(item.input.table, item.table_sha256)
            report = unwarp_rig_video(rig, [str(path) for path in item.input.sources], output.path, named.view,
                                      encoder=settings.encoder, audio=settings.audio, sampling=settings.sampling,
                                      interpolation=settings.interpolation, codec_threads=codec_threads)  # fmt: skip
            frames, seconds = report.frames_written, seconds + report.seconds
        done = tuple(finished(item, out.view, out.path, frames, seconds) for out in item.outputs)
        return ItemResult(str(item.input.path), done)
    table = video_table(item)
    report = unwarp_video(
        table,
        str(item.input.path),
        [ViewOutput(named.view, output.path) for named, output in zip(views, item.outputs, strict=True)],
        encoder=settings.encoder,
        audio=settings.audio,
        sampling=settings.sampling,
        interpolation=settings.interpolation,
        codec_threads=codec_threads,
    )
    done = tuple(finished(item, out.view, out.path, report.frames_written, report.seconds) for out in item.outputs)
    return ItemResult(str(item.input.path), done)


def parts_folder(item: Item) -> Path:
    """Where the segments of ``item``'s outputs wait to be joined: beside its first output."""
    return item.outputs[0].path.parent / ".panomap-parts" / item.key[:20]


def unwarp_segment(
    item: Item, views: Sequence[NamedView], settings: Settings, segment: Segment, codec_threads: int | None = None
) -> PartResult:
    """Unwarp one time segment of a video into a part file per view (MP4, whose edit lists keep
    the timestamps exact); raises on failure (Dask retries it). ``codec_threads`` as for :func:`unwarp_whole_video`."""
    table = video_table(item)
    folder = parts_folder(item)
    folder.mkdir(parents=True, exist_ok=True)
    paths = tuple(folder / f"{segment.index:06d}_{output.view}.mp4" for output in item.outputs)
    report = unwarp_video(
        table,
        str(item.input.path),
        [ViewOutput(named.view, path) for named, path in zip(views, paths, strict=True)],
        encoder=settings.encoder,
        selection=Selection(segment.start_s, segment.duration_s),
        audio=settings.audio,
        sampling=settings.sampling,
        interpolation=settings.interpolation,
        codec_threads=codec_threads,
    )
    return PartResult(segment.index, paths, segment.offset, report.frames_written)


def join_video(item: Item, parts: Sequence[PartResult]) -> ItemResult:
    """Join the segments of every view of ``item`` into its outputs (stream copy), then remove them."""
    started = time.perf_counter()
    ordered = sorted(parts, key=lambda part: part.index)
    expected = sum(part.frames for part in ordered)
    with all_or_none():
        for position, output in enumerate(item.outputs):
            frames = join_segments([(part.paths[position], part.offset) for part in ordered], output.path)
            if frames != expected:
                raise PanomapError(f"the joined video holds {frames} frames, its segments {expected}", output.path)
    seconds = time.perf_counter() - started
    done = tuple(finished(item, output.view, output.path, expected, seconds) for output in item.outputs)
    folder = parts_folder(item)
    shutil.rmtree(folder, ignore_errors=True)
    with contextlib.suppress(OSError):
        folder.parent.rmdir()  # (only when no other video's parts wait there)
    return ItemResult(str(item.input.path), done)
