"""A batch job: which inputs, through which camera's table, into which views, written where.

Inputs come from globs and folders (one table for all), or from a manifest
(CSV, JSON or YAML) that maps each input to its camera's table, so that
several cameras run in one job::

    input,table,camera                      # CSV: a header, then one row per input
    cams/north/0001.jpg,north.npz,north     # camera: optional (default: the table's stem)

    [{"input": "cams/north/0001.jpg", "table": "north.npz", "camera": "north"}, ...]   # JSON/YAML

Relative paths in a manifest are taken from the manifest's own folder. Inputs are still
images (by suffix: ``.png``, ``.jpg``, ``.tif``, ...) or videos (``.mp4``, ``.mkv``, ...).

A table may be a rig file (``panomap import`` of several cameras): each output is the rig's blended view, as
the view commands and ``panomap video`` make it given the rig. A rig whose pictures share one frame (a dual
fisheye's side-by-side frame) takes each image or video as one input; a rig of separate pictures takes a
folder of them as one input: every image or video found is grouped by its folder, and each folder must hold
one per camera (of one kind), in the rig's order by name, or named after the cameras (``cam0.jpg``, ...); in a
manifest its input is the folder. ``{stem}`` is then the folder's name.

The output template names each output with ``{camera}``, ``{stem}`` (the input's name
without its suffix), ``{name}`` (the view's name) and ``{ext}`` (the input's suffix, without
the dot), as ``{camera}/{stem}_{name}.mp4``. Videos take the template's suffix; still
images keep their own format (the template's suffix is replaced by the input's).

Every path in a job is absolute: on a cluster, every machine must see the same paths
(shared storage).
"""

from __future__ import annotations

import csv
import fnmatch
import hashlib
import io
import json
import re
import string
import unicodedata
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .. import inputs as checks
from ..errors import PanomapError
from ..files import (  # noqa: F401  (IMAGE_SUFFIXES, VIDEO_SUFFIXES, kind_of: the batch's names, kept)
    IMAGE_SUFFIXES,
    VIDEO_SUFFIXES,
    expand_input,
    file_identity,
    kind_of,
    placeholder_text,
    placeholders,
    read_text,
)
from ..remap import check_interpolation
from ..rig.file import is_rig_file, load_rig, rig_index
from ..table.file import is_table_file, load_table
from ..table.sampling import check_sampling
from ..video.output import EncoderSettings, check_frame_size, container_format
from ..views.spec import NamedView

# The characters a camera's name may not hold, as Unicode categories: control, format, line and paragraph
# separators (NUL among them).
CONTROLS = frozenset({"Cc", "Cf", "Zl", "Zp"})

# What a camera's name must be, as the refusals say it.
PLAIN_NAME = "a plain name (no path separators or control characters, not . or ..)"

MANIFEST_SUFFIXES = frozenset({".csv", ".json", ".yaml", ".yml"})
TEMPLATE_KEYS = ("camera", "stem", "name", "ext")


@dataclass(frozen=True)
class BatchInput:
    """One input file, the table of its camera and the camera's name (absolute paths).

    A rig's input (``rig``: the table is a rig file): one frame holding every camera's picture (``path``), or a
    folder (``path``) of one picture per camera, ``pictures`` in the rig's order."""

    path: Path
    table: Path
    camera: str
    rig: bool = False
    pictures: tuple[Path, ...] = ()

    @property
    def sources(self) -> tuple[Path, ...]:
        """The files read: ``pictures``, or the one file."""
        return self.pictures or (self.path,)

    @property
    def is_video(self) -> bool:
        return self.sources[0].suffix.lower() in VIDEO_SUFFIXES

    @property
    def stem(self) -> str:
        """``{stem}``: the file's name less its suffix, or the folder's name."""
        return self.path.name if self.pictures else self.path.stem

    @property
    def suffix(self) -> str:
        """The suffix of the files read (``.jpg``)."""
        return self.sources[0].suffix


@dataclass(frozen=True)
class Settings:
    """How every input is unwarped: as ``panomap video`` and the view commands take them."""

    encoder: EncoderSettings = EncoderSettings()
    interpolation: str = "linear"
    sampling: str = "bilinear"
    audio: bool = True

    def __post_init__(self) -> None:
        checks.instance(self.encoder, EncoderSettings, "the encoder settings")
        check_interpolation(self.interpolation)
        check_sampling(self.sampling)


@dataclass(frozen=True)
class Output:
    """One output file: the view it holds (by name) and its path."""

    view: str
    path: Path


@dataclass(frozen=True)
class Item:
    """One input and its outputs (one per view), with the key that says what made them.

    ``key`` is a SHA-256 over the input's path, size and modification time, the table's
    checksum, the views and the settings: an output recorded under another key is redone.
    """

    input: BatchInput
    outputs: tuple[Output, ...]
    key: str
    table_sha256: str


@dataclass(frozen=True)
class Job:
    """A whole batch: every input with its outputs, the views and the settings."""

    items: tuple[Item, ...]
    views: tuple[NamedView, ...]
    settings: Settings = field(default_factory=Settings)


def find_inputs(
    patterns: Sequence[str], table: Path | None, camera: str | None = None, exclude: Sequence[str] = ()
) -> list[BatchInput]:
    """The inputs named by ``patterns``: files, folders (every image and video inside, recursively)
    and globs (``cams/*.jpg``, ``**`` too), or one manifest file (``.csv``, ``.json``, ``.yaml``),
    less those matching an ``exclude`` glob (:func:`excluded`).

    Without a manifest, ``table`` is every input's table and ``camera`` (default: the table's
    stem) its camera name. Raises PanomapError naming what matched nothing.

    Parameters
    ----------
    patterns : sequence of str
        Files, folders and globs, or one manifest file mapping each input to its table.
    table : path or None
        Every input's table where no manifest is given (None with a manifest).
    camera : str, optional
        The camera's name in the output template's ``{camera}``.
    exclude : sequence of str
        Globs of inputs to leave out.

    Returns
    -------
    list of BatchInput
        Each input with its table and camera name.
    """
    if isinstance(patterns, str | Path):
        raise TypeError(
            f"patterns must be a list of files, folders or globs, not one {type(patterns).__name__}: [{patterns!r:.40}]"
        )
    table = None if table is None else Path(checks.path(table, "the table file"))
    manifest = check_inputs_and_table(patterns, table)
    if manifest is not None:
        listed = read_manifest(manifest)
        kept = [item for item in listed if not excluded(item.path, exclude)]
        if not kept:
            raise PanomapError("--exclude leaves no input of the manifest", manifest)
        return kept
    assert table is not None
    table = table.absolute()
    found: list[Path] = []
    for pattern in patterns:
        matches = expand_input(pattern)
        wanted = [p for p in matches if not excluded(p, exclude)]
        if not wanted:
            raise PanomapError(f"every image and video it names is excluded ({', '.join(exclude)})", pattern)
        found += wanted
    unique = list(dict.fromkeys(p.absolute() for p in found))
    name = camera if camera is not None else table.stem
    if not is_camera_name(name):
        raise PanomapError(f"the camera name {name!r} must be {PLAIN_NAME}")
    if is_rig_file(table):
        return rig_inputs(unique, table, name)
    return [BatchInput(path, table, name) for path in unique]


def rig_inputs(files: Sequence[Path], rig: Path, camera: str) -> list[BatchInput]:
    """The inputs of the rig file ``rig`` among ``files`` (absolute): each file, where the rig's pictures share one
    frame; else each folder's files, one per camera (module docstring). PanomapError naming a folder that does
    not hold one picture per camera."""
    names, offsets = rig_index(rig)
    if offsets is not None:
        return [BatchInput(path, rig, camera, rig=True) for path in files]
    folders: dict[Path, list[Path]] = {}
    for path in files:
        folders.setdefault(path.parent, []).append(path)
    return [BatchInput(folder, rig, camera, True, rig_pictures(folder, held, names)) for folder, held in
            folders.items()]  # fmt: skip


def rig_pictures(folder: Path, files: Sequence[Path], names: Sequence[str]) -> tuple[Path, ...]:
    """``files`` (of ``folder``) in the rig's order: by the cameras' ``names`` where they are the files' stems,
    else by file name; PanomapError unless there is one per camera, all images or all videos."""
    kinds = {kind_of(path) for path in files}
    if len(files) != len(names) or len(kinds) != 1:
        held = f"{len(files)} {'images and videos' if len(kinds) > 1 else 'files'}"
        raise PanomapError(
            f"a rig's folder holds one picture or video per camera ({len(names)}: {', '.join(names)}), not {held}",
            folder,
        )
    by_stem = {path.stem: path for path in files}
    if set(by_stem) == set(names):
        return tuple(by_stem[name] for name in names)
    return tuple(sorted(files, key=lambda path: path.name))


def check_inputs_and_table(patterns: Sequence[str], table: Path | None) -> Path | None:
    """The manifest among ``patterns``, if they are one; PanomapError when they and ``table`` do not go
    together (a manifest with other inputs or with a table; inputs without a table)."""
    manifests = [p for p in patterns if Path(p).suffix.lower() in MANIFEST_SUFFIXES and Path(p).is_file()]
    if manifests:
        if len(patterns) > 1:
            raise PanomapError("a manifest names every input: give it alone")
        if table is not None:
            raise PanomapError("the manifest names each input's table: give no --table", manifests[0])
        return Path(manifests[0])
    if table is None:
        raise PanomapError("give the table with --table TABLE (or a manifest mapping inputs to tables)")
    return None


def read_manifest(path: Path) -> list[BatchInput]:
    """The inputs of a manifest (see the module docstring); PanomapError naming the file and row."""
    text = read_text(path)
    suffix = path.suffix.lower()
    rows: Any
    try:
        if suffix == ".csv":
            rows = list(csv.DictReader(io.StringIO(text)))
        elif suffix == ".json":
            rows = json.loads(text)
        else:
            import yaml

            rows = yaml.safe_load(text)
    except Exception as exc:  # any parse error is the file's problem
        raise PanomapError(f"not a valid {suffix[1:].upper()} manifest: {' '.join(str(exc).split())}", path) from None
    if not isinstance(rows, list) or not rows:
        raise PanomapError("a manifest must list its inputs (rows of input, table[, camera])", path)
    folder = path.absolute().parent
    inputs = []
    for number, row in enumerate(rows, start=1):
        if not isinstance(row, dict) or not row.get("input") or not row.get("table"):
            raise PanomapError(f"row {number} needs an input and a table", path)
        if None in row:  # (csv.DictReader puts a row's fields past the header's under None)
            problem = "more fields than the header's columns" if suffix == ".csv" else "a key that is null"
            raise PanomapError(f"row {number} has {problem}", path)
        unknown = sorted(str(key) for key in set(row) - {"input", "table", "camera"})
        if unknown:
            raise PanomapError(f"row {number}: unknown column {', '.join(unknown)}", path)
        if any(not isinstance(row[key], (str, int, float)) for key in row if row[key] is not None):
            raise PanomapError(f"row {number}: input, table and camera must be text", path)
        source, table = folder / str(row["input"]), folder / str(row["table"])
        camera = str(row.get("camera") or table.stem)
        if not is_camera_name(camera):
            raise PanomapError(
                f"row {number}: the camera name {camera!r} must be {PLAIN_NAME}",
                path,
            )
        if source.is_dir() and is_rig_file(table):  # (a rig's pictures, one per camera)
            files = sorted(p.absolute() for p in source.iterdir() if p.is_file() and kind_of(p) is not None)
            try:
                inputs += rig_inputs(files, table.absolute(), camera)
            except PanomapError as exc:
                raise PanomapError(f"row {number}: {exc}", path) from None
            continue
        if kind_of(source) is None:
            raise PanomapError(f"row {number}: {row['input']} is not an image or video file name", path)
        inputs.append(BatchInput(source, table, camera, rig=is_rig_file(table)))
    return inputs


def is_camera_name(name: str) -> bool:
    """Whether ``name`` can stand for ``{camera}`` in an output path: one plain file name, so that the
    outputs stay under the template's folder, without control characters (an escape sequence in a folder's
    name rewrites the terminal of whoever lists it)."""
    plain = not any(c in name for c in "/\\") and not any(unicodedata.category(c) in CONTROLS for c in name)
    return bool(name) and name not in (".", "..") and plain


def check_template(template: str) -> None:
    """Refuse a template with an unknown key, a format spec or conversion, or one that could not tell views
    apart."""
    try:
        fields = placeholders(template)
    except ValueError as exc:
        raise PanomapError(f"the output template {template!r} is malformed ({exc})") from None
    unknown = sorted({key for key, _, _ in fields if key not in TEMPLATE_KEYS})
    if unknown:
        raise PanomapError(
            f"the output template {template!r} has an unknown key {{{unknown[0]}}} (keys: "
            + ", ".join(f"{{{key}}}" for key in TEMPLATE_KEYS)
            + ")"
        )
    for key, spec, conversion in fields:
        if spec or conversion:
            raise PanomapError(
                f"the output template {template!r} has {placeholder_text(key, spec, conversion)}: its keys take "
                "no format spec or conversion"
            )
    if not Path(template).suffix:
        raise PanomapError(f"the output template {template!r} needs a file suffix (e.g. .mp4)")


def output_path(template: str, item: BatchInput, view: str) -> Path:
    """The output of ``view`` for ``item`` (absolute); still images keep their own suffix."""
    path = Path(template.format(camera=item.camera, stem=item.stem, name=view, ext=item.suffix.lstrip(".")))
    if not item.is_video:
        path = path.with_suffix(item.suffix)
    return path.absolute()


def output_pattern(template: str, cameras: Iterable[str], views: Iterable[str]) -> re.Pattern[str]:
    """A pattern that every output of ``template`` matches (absolute paths, as :func:`output_path` makes
    them), for these cameras and views, whatever the input's stem and suffix: what an earlier run of the
    same job wrote, even of an input since removed."""
    base = Path(template).absolute().as_posix()
    stem_less = base[: len(base) - len(Path(base).suffix)]

    def choice(names: Iterable[str]) -> str:
        return "(?:" + "|".join(re.escape(name) for name in sorted(set(names), key=len, reverse=True)) + ")"

    fields = {"camera": choice(cameras), "name": choice(views), "stem": r"[^/]+", "ext": r"[^/]*"}
    parts = [
        re.escape(literal) + (fields[key] if key is not None else "")
        for literal, key, _, _ in string.Formatter().parse(stem_less)
    ]
    return re.compile("".join(parts) + r"\.[^/.]+")


def without_outputs(
    inputs: Sequence[BatchInput], views: Sequence[NamedView], template: str
) -> tuple[list[BatchInput], list[BatchInput]]:
    """``(kept, dropped)``: the inputs that are outputs of this job (of these views and cameras under
    ``template``) dropped. A folder or glob that holds the job's own output folder found the outputs of
    the last run as inputs on the next (and failed on them)."""
    pattern = output_pattern(template, [item.camera for item in inputs], [view.name for view in views])
    kept: list[BatchInput] = []
    dropped: list[BatchInput] = []
    for item in inputs:
        (dropped if pattern.fullmatch(item.path.absolute().as_posix()) else kept).append(item)
    return kept, dropped


def excluded(path: Path, patterns: Sequence[str]) -> bool:
    """Whether ``path`` matches one of the ``--exclude`` globs: by its name, its path relative to the
    working folder, or its absolute path (``*`` crosses folders, as in ``fnmatch``)."""
    absolute = path.absolute()
    try:
        relative = absolute.relative_to(Path.cwd().absolute()).as_posix()
    except ValueError:
        relative = absolute.as_posix()
    names = (absolute.name, relative, absolute.as_posix())
    return any(fnmatch.fnmatchcase(name, pattern) for pattern in patterns for name in names)


def file_digest(path: Path, chunk: int = 1 << 20) -> str:
    """SHA-256 of a file's bytes (hex)."""
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        while block := handle.read(chunk):
            digest.update(block)
    return digest.hexdigest()


def make_job(
    inputs: Iterable[BatchInput], views: Sequence[NamedView], template: str, settings: Settings = Settings()
) -> Job:
    """The job: every input's outputs and key, checked before any work.

    Raises PanomapError for a template with an unknown key, a missing input or table, two
    outputs of one path, or an output that is an input.

    Parameters
    ----------
    inputs : iterable of BatchInput
        What :func:`find_inputs` found.
    views : sequence of NamedView
        The views every input is unwarped into.
    template : str
        Each output's path, with the keys ``{camera}``, ``{stem}`` (the input's file name less its suffix),
        ``{name}`` (the view's) and ``{ext}`` (the input's suffix), e.g. ``out/{camera}/{stem}_{name}.mp4``.
    settings : Settings
        How each output is made (encoder, frames, sampling), part of each output's key in the record.

    Returns
    -------
    Job
    """
    if isinstance(views, str) or not all(isinstance(view, NamedView) for view in views):
        raise TypeError("views must be a list of NamedView(name, view) (parse_view_spec makes one of a spec)")
    if not views:
        raise PanomapError("give at least one view")
    check_template(template)
    inputs = list(inputs)
    if not inputs:
        raise PanomapError("the job has no input")
    names = [view.name for view in views]
    if len(views) > 1 and "{name}" not in template:
        raise PanomapError("with several views the output template needs {name}, e.g. '{stem}_{name}.mp4'")
    tables: dict[Path, str] = {}
    seen: dict[Path, str] = {}
    # The inputs and their tables, as files: through links and other spellings.
    sources = {file_identity(p) for item in inputs for p in item.sources} | {file_identity(i.table) for i in inputs}
    described = json.dumps([repr(view) for view in views]) + repr(settings)
    items = []
    for item in inputs:
        for source in item.sources:
            if not source.is_file():
                raise PanomapError("no such input file" if not source.exists() else "not a file", source)
        if item.table not in tables:
            if not item.table.is_file():
                raise PanomapError("no such table file", item.table)
            if not (is_rig_file(item.table) or is_table_file(item.table)):
                load_table(item.table)  # (refused here, in one line, not by every input's task on the cluster)
            tables[item.table] = file_digest(item.table)
        outputs = []
        for name in names:
            path = output_path(template, item, name)
            if file_identity(path) in sources:
                raise PanomapError(f"the output of {item.path} is an input: refusing to overwrite it", path)
            if item.is_video:
                container_format(path)  # (a video's output named .png: refused before the cluster starts)
            if path in seen and seen[path] == str(item.path):  # (a manifest listing it twice)
                raise PanomapError(f"{item.path} is listed twice for this output: list it once", path)
            if path in seen:
                raise PanomapError(
                    f"two outputs would be this file ({seen[path]} and {item.path}): put {{stem}} or {{camera}} "
                    "in the template",
                    path,
                )
            seen[path] = str(item.path)
            outputs.append(Output(name, path))
        files = "".join(f"{p}\0{p.stat().st_size}\0{p.stat().st_mtime_ns}\0" for p in item.sources)
        key = hashlib.sha256(f"{files}{tables[item.table]}\0{described}".encode()).hexdigest()
        items.append(Item(item, tuple(outputs), key, tables[item.table]))
    return Job(tuple(items), tuple(views), settings)


def check_video_views(inputs: Iterable[BatchInput], views: Sequence[NamedView], encoder: EncoderSettings) -> None:
    """Refuse, before any work, a view whose frames the video encoder cannot encode (too wide for it), once for
    the job rather than for each of its videos: its size from each video's table (a rig's camera 0's).

    Raises PanomapError naming the view, in the encoder's words."""
    tried: set[tuple[int, int]] = set()
    tables: set[Path] = set()
    for item in inputs:
        if not item.is_video or item.table in tables:
            continue
        tables.add(item.table)
        reference = load_rig(item.table).tables[0] if is_rig_file(item.table) else load_table(item.table)
        for named in views:
            size = named.view.output_size(reference)
            if size in tried:
                continue
            tried.add(size)
            try:
                check_frame_size(encoder, size)
            except PanomapError as exc:
                raise PanomapError(f"{named.name}: {exc.detail}") from None
