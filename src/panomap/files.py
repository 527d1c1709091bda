"""Writing files safely: everything goes to a temporary name and is renamed when done.

A failed or interrupted write never leaves a half-written output behind:

- each output is written to ``.NAME.PID-XXXXXXXX.partSUFFIX`` in its own
  folder and renamed over ``NAME`` only when complete; any error removes it
  and leaves an existing ``NAME`` as it was. A temporary whose process (PID)
  is gone, left by a run that was killed, is removed by the next write of
  the same output (a process of that PID that started after the file was
  last written is another one: the PID was reused);
- within :func:`all_or_none`, the renames wait for the end of the block: a
  run writes all of its outputs or none;
- an existing output that is read-only is refused (as ``cp`` refuses it), and
  one that is replaced keeps its mode;
- every error names the user's path (never the temporary one) and says why
  ("No space left on device");
- an existing output that is not a regular file (a FIFO, a device node, a socket)
  is refused: renaming over it would replace it, writing through it would block
  or reach the device;
- :func:`check_outputs`, the check every command runs on its outputs before any
  work, refuses an output that is one of the run's inputs (the same file, through
  symbolic or hard links too) or another of its outputs, and one that cannot be
  written.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import stat
import string
import tempfile
import urllib.parse
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path
from typing import IO, BinaryIO, cast

from . import inputs
from .errors import PanomapError

# The (temporary, final) pairs of the innermost all_or_none block, None outside one.
_PENDING: ContextVar[list[tuple[Path, Path]] | None] = ContextVar("panomap_pending_outputs", default=None)


def file_path(value: object) -> Path:
    """``value`` (a str or path-like) as a Path; a TypeError naming what it is otherwise (None, an array, a
    number: :func:`panomap.inputs.path`), before any file is touched."""
    return Path(inputs.path(value, "a file name"))


@contextmanager
def all_or_none() -> Iterator[None]:
    """Keep the outputs written in this block under their temporary names until it ends.

    They are all renamed into place when the block ends normally, and all
    removed when it raises. A block inside another joins the outer one.
    """
    if _PENDING.get() is not None:
        yield
        return
    pending: list[tuple[Path, Path]] = []
    token = _PENDING.set(pending)
    try:
        yield
    except BaseException:
        for temporary, _ in pending:
            temporary.unlink(missing_ok=True)
        raise
    finally:
        _PENDING.reset(token)
    for done, (temporary, path) in enumerate(pending):
        try:
            os.replace(temporary, path)
        except OSError as exc:
            for left, _ in pending[done:]:
                left.unlink(missing_ok=True)
            raise PanomapError(f"cannot write it ({exc.strerror or exc})", path) from None


@contextmanager
def atomic_output(path: str | Path) -> Iterator[BinaryIO]:
    """Open a temporary file beside ``path``; rename it to ``path`` on success.

    The temporary name keeps ``path``'s suffix, so tools that choose a format
    by suffix see the right one. On any exception the temporary file is removed
    and ``path`` is left as it was; an ``OSError`` while writing becomes a
    PanomapError naming ``path``.
    """
    path = file_path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise PanomapError("its folder does not exist", path)
    mode = check_replaceable(path)
    remove_stale_temporaries(path)
    try:
        handle = _open_temporary(directory, path)
    except OSError as exc:
        raise PanomapError(f"cannot write there ({exc.strerror or exc})", path) from None
    temporary = Path(handle.name)
    try:
        try:
            with handle:
                yield cast(BinaryIO, handle)
            os.chmod(temporary, mode)
        except OSError as exc:
            raise PanomapError(f"cannot write it ({exc.strerror or exc})", path) from None
        pending = _PENDING.get()
        if pending is not None:
            pending.append((temporary, path))
            return
        try:
            os.replace(temporary, path)
        except OSError as exc:
            raise PanomapError(f"cannot write it ({exc.strerror or exc})", path) from None
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A temporary path beside ``path`` (same suffix) for writers that open files by name.

    It is renamed to ``path`` when the block ends normally and removed when it
    raises, as with :func:`atomic_output`.
    """
    with atomic_output(path) as handle:
        yield Path(handle.name)


def _open_temporary(directory: Path, path: Path) -> IO[bytes]:
    """The temporary file for ``path`` (a seam: tests replace it to inject write faults)."""
    return tempfile.NamedTemporaryFile(
        "wb", dir=directory, prefix=f".{path.name}.{os.getpid()}-", suffix=f".part{path.suffix}", delete=False
    )


def _temporary_owner(name: str, path: Path) -> int | None:
    """The process id in the name of one of ``path``'s temporaries; None if ``name`` is not one."""
    head, tail = f".{path.name}.", f".part{path.suffix}"
    if not (name.startswith(head) and name.endswith(tail)) or len(name) <= len(head) + len(tail):
        return None
    pid, dash, _ = name[len(head) : -len(tail)].partition("-")
    return int(pid) if dash and pid.isdigit() else None


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def process_start_ticks(pid: int) -> int | None:
    """When process ``pid`` started, in clock ticks since boot (``/proc/PID/stat``); None where unknown (gone,
    or no ``/proc``). With the PID it names one process: a PID is reused, its start time is not."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as handle:
            stat_line = handle.read()
        return int(stat_line[stat_line.rindex(b")") + 2 :].split()[19])  # (field 22; the name may hold spaces)
    except (OSError, ValueError, IndexError):
        return None


def process_started_at(pid: int) -> float | None:
    """When process ``pid`` started (s since the epoch, to about a second); None where unknown."""
    ticks = process_start_ticks(pid)
    if ticks is None:
        return None
    try:
        with open("/proc/stat", "rb") as handle:
            boot = next(int(line.split()[1]) for line in handle if line.startswith(b"btime "))
        return boot + ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, StopIteration):
        return None


# Slack (s) on comparing a process's start with a file's time: the boot time is given to the second, and
# moves with clock adjustments.
_CLOCK_SLACK_S = 2.0


def _owner_alive(pid: int, temporary: Path) -> bool:
    """Whether the process that wrote ``temporary`` (PID ``pid`` in its name) still runs: a process of that PID
    that started after the file was last written is another one (the PID reused, as after a reboot or when
    PIDs wrap: a killed run's temporary would be kept for good)."""
    if not _alive(pid):
        return False
    started = process_started_at(pid)
    if started is None:
        return True
    try:
        written = os.stat(temporary).st_mtime
    except OSError:
        return True
    return started <= written + _CLOCK_SLACK_S


def remove_stale_temporaries(path: str | Path) -> list[Path]:
    """Remove the temporaries of ``path`` that a killed run left (their process is gone, or its PID is
    another process's now); returns them."""
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    removed = []
    try:
        names = [entry.name for entry in os.scandir(directory)]
    except OSError:
        return []
    for name in names:
        pid = _temporary_owner(name, path)
        if pid is not None and pid != os.getpid() and not _owner_alive(pid, directory / name):
            try:
                (directory / name).unlink()
            except OSError:
                continue
            removed.append(directory / name)
    return removed


def temporaries_alive(folder: str | Path) -> bool:
    """Whether ``folder`` holds a temporary (of any output) whose process is still running."""
    try:
        names = [entry.name for entry in os.scandir(folder)]
    except OSError:
        return False
    for name in names:
        if not name.startswith("."):
            continue
        pid = _temporary_owner(name, Path(folder) / _temporary_target(name))
        if pid is not None and (pid == os.getpid() or _owner_alive(pid, Path(folder) / name)):
            return True
    return False


def _temporary_target(name: str) -> str:
    """The output name a temporary's name is for (``.a.mp4.123-xy.part.mp4`` -> ``a.mp4``), or ``""``."""
    head, _, _ = name[1:].rpartition(".part")
    stem, _, _ = head.rpartition(".")
    return stem


def check_replaceable(path: str | Path) -> int:
    """The mode ``path`` will get: its own if it exists, else an ordinary new file's.

    Raises
    ------
    PanomapError
        If ``path`` is a folder, or a file that is read-only (``cp`` refuses it;
        root included, since panomap goes by the mode bits).
    """
    try:
        info = os.stat(path)
    except FileNotFoundError:
        return _new_file_mode()
    except OSError as exc:
        raise PanomapError(f"cannot write it ({exc.strerror or exc})", path) from None
    if stat.S_ISDIR(info.st_mode):
        raise PanomapError("it is a folder, not a file", path)
    if not stat.S_ISREG(info.st_mode):
        raise PanomapError(f"it is {_kind(info.st_mode)}, not a regular file: not replaced (choose a file name)", path)
    if not info.st_mode & stat.S_IWUSR or not os.access(path, os.W_OK):
        raise PanomapError("the file is read-only; not replaced (make it writable or choose another name)", path)
    return stat.S_IMODE(info.st_mode)


def _kind(mode: int) -> str:
    """What a file that is not a regular file is, in words (for errors)."""
    for test, words in (
        (stat.S_ISFIFO, "a FIFO (named pipe)"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return words
    return "a special file"


def check_output(path: str | Path) -> None:
    """Refuse, before any work, an output whose folder is missing or not writable, or that
    cannot be replaced (:func:`check_replaceable`)."""
    path = file_path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise PanomapError("its folder does not exist", path)
    if not os.access(directory, os.W_OK | os.X_OK):
        raise PanomapError("its folder is not writable", path)
    check_replaceable(path)


def check_room(outputs: Iterable[tuple[str | Path, int]], up_to: bool = False) -> None:
    """Refuse, before any work, outputs of known size (``(path, bytes)``: a map, a table) that their disks
    have no room for, the outputs on one disk counted together (each is written whole beside its name before
    it replaces it, so an output it replaces frees nothing). ``up_to``: some sizes are the most the outputs
    may take (an image's pixels, uncompressed; a table of a size still to be chosen), said so.

    Raises
    ------
    PanomapError
        Naming the first output of a disk without room, what the outputs on it need and what it has free.
    """
    needs: dict[int, tuple[Path, Path, int]] = {}
    for given, size in outputs:
        path = Path(given)
        directory = path.parent if str(path.parent) else Path(".")
        try:
            device = directory.stat().st_dev
        except OSError:
            continue  # (a missing folder is check_output's to name)
        first, folder, total = needs.get(device, (path, directory, 0))
        needs[device] = (first, folder, total + size)
    for first, folder, total in needs.values():
        try:
            free = shutil.disk_usage(folder).free
        except OSError:
            continue
        if total > free:
            raise PanomapError(
                f"no room for it: {'up to ' if up_to else ''}{_megabytes(total)} to write, its disk has "
                f"{_megabytes(free)} free",
                first,
            )


def _megabytes(size: int) -> str:
    return f"{size / 1e6:.1f} MB" if size >= 1_000_000 else f"{size / 1e3:.0f} kB"


def check_outputs(
    inputs: Iterable[tuple[str, str | Path | None]], outputs: Iterable[tuple[str, str | Path | None]]
) -> None:
    """The one check every command that writes runs on its outputs before any work.

    No output is one of ``inputs`` or another output (:func:`check_output_paths`: by device and inode,
    through symbolic and hard links and any spelling), and each can be written (:func:`check_output`: its
    folder exists and is writable; it is a new name or a regular, writable file, never a folder, a FIFO or
    a device). Items are ``(what, path)``; a None path is skipped.

    Raises
    ------
    PanomapError
        Naming the output and the problem.
    """
    outputs = list(outputs)
    check_output_paths(inputs, outputs)
    for _, path in outputs:
        if path is not None:
            check_output(path)


def same_input(paths: Sequence[str | Path]) -> tuple[Path, Path, str] | None:
    """The first two of ``paths`` that are one input: the same file (by device and inode: a link, another
    spelling) or two files of the same bytes; as ``(earlier, later, how)``, None where all differ.

    Only files of equal size are read (SHA-256, in blocks), so that distinct files cost a ``stat`` each.
    """
    seen: dict[tuple[object, ...], Path] = {}
    by_size: dict[int, list[Path]] = {}
    digests: dict[Path, str] = {}

    def digest(path: Path) -> str:
        if path not in digests:
            digests[path] = _sha256(path)
        return digests[path]

    for given in paths:
        path = Path(given)
        key = file_identity(path)
        if key in seen:
            return seen[key], path, "the same file"
        seen[key] = path
        try:
            size = os.stat(path).st_size
        except OSError:
            continue
        for other in by_size.get(size, []):
            if digest(path) and digest(other) == digest(path):
                return other, path, "the same bytes"
        by_size.setdefault(size, []).append(path)
    return None


def _sha256(path: Path) -> str:
    """SHA-256 (hex) of the file's bytes; "" where it cannot be read (its reader says why)."""
    digest = hashlib.sha256()
    try:
        with open(path, "rb") as handle:
            while block := handle.read(1 << 20):
                digest.update(block)
    except OSError:
        return ""
    return digest.hexdigest()


def file_identity(path: Path) -> tuple[object, ...]:
    """What makes two paths the same file: device and inode if it exists, else its resolved path."""
    try:
        info = os.stat(path)
    except OSError:
        return ("path", os.path.normcase(os.path.realpath(path)))
    return ("file", info.st_dev, info.st_ino)


def local_file(source: str | Path) -> Path | None:
    """The local file an input names, in any spelling FFmpeg or a shell would accept, or None.

    ``file:`` URLs (``file:///abs/in.mp4``, ``file:in.mp4``; FFmpeg opens what follows ``file:``
    as a path, and a percent-encoded or ``localhost`` spelling is tried too) and a leading ``~``
    are resolved; a spelling that names no existing regular file (a stream URL, a capture device,
    a missing file) gives None. Links are left to :func:`check_output_paths`, which compares files
    by device and inode.
    """
    text = os.fspath(source)
    candidates = [text]
    if text.lower().startswith("file:"):
        parsed = urllib.parse.urlsplit(text)
        candidates = [text[5:]]
        if parsed.netloc in ("", "localhost"):
            from urllib.request import url2pathname  # here, not at the top: it imports http.client, email (14 ms)

            candidates.append(url2pathname(parsed.path))
    for candidate in candidates:
        path = Path(os.path.expanduser(candidate)) if candidate else None
        if path is not None and path.is_file():
            return path
    return None


def placeholders(pattern: str) -> list[tuple[str, str, str]]:
    """The ``{key!conversion:spec}`` fields of an output name pattern, as ``(key, spec, conversion)`` (``""``
    where absent); ``{{`` and ``}}`` are literal braces. Raises ValueError where the pattern is malformed."""
    return [
        (key, spec or "", conv or "") for _, key, spec, conv in string.Formatter().parse(pattern) if key is not None
    ]


def placeholder_text(key: str, spec: str, conversion: str) -> str:
    """A field as written in a pattern: ``{key!conversion:spec}``."""
    return "{" + key + (f"!{conversion}" if conversion else "") + (f":{spec}" if spec else "") + "}"


def fill_pattern(pattern: str, key: str, meaning: str, values: Iterable[str], required: bool = True) -> list[Path]:
    """The file names of an output name ``pattern`` holding ``{key}`` (``meaning``: what it stands for, for the
    message), one for each of ``values``; ``{{`` and ``}}`` are literal braces. ``required``: a pattern without
    ``{key}`` is refused (else it names one file for every value).

    Raises
    ------
    PanomapError
        Where the pattern is malformed, holds any other placeholder (taken literally, a mistyped ``{view}``
        wrote one file for all), or holds no ``{key}`` where it is ``required``.
    """
    try:
        fields = placeholders(pattern)
    except ValueError as exc:
        raise PanomapError(f"{pattern!r} is malformed ({exc}; write a literal brace as {{{{ or }}}})") from None
    for field, spec, conversion in fields:
        if field != key or spec or conversion:
            raise PanomapError(
                f"{pattern!r} has an unknown placeholder {placeholder_text(field, spec, conversion)}: the only one "
                f"is {{{key}}}, {meaning} (write a literal brace as {{{{ or }}}})"
            )
    if required and not fields:
        raise PanomapError(f"{pattern!r} has no {{{key}}} to put {meaning} in")
    return [Path(pattern.format(**{key: value})) for value in values]


def check_output_paths(
    inputs: Iterable[tuple[str, str | Path | None]], outputs: Iterable[tuple[str, str | Path | None]]
) -> None:
    """Refuse an output that is one of the inputs, or that another output also names.

    Each item is ``(what, path)`` (``("the image", "a.png")``); a None path is
    skipped. Paths are compared as files: through symbolic links, hard links
    and different spellings of the same path.

    Raises
    ------
    PanomapError
        Naming the output and what it collides with.
    """
    seen: dict[tuple[object, ...], tuple[str, str, bool]] = {}
    for what, path in inputs:
        if path is not None:
            seen.setdefault(file_identity(Path(path)), (what, str(path), True))
    for what, path in outputs:
        if path is None:
            continue
        key = file_identity(Path(path))
        if key in seen:
            other, other_path, is_input = seen[key]
            if is_input:
                raise PanomapError(f"{what} is {other} ({other_path}): refusing to overwrite an input", path)
            raise PanomapError(f"{what} and {other} ({other_path}) are the same file: give each its own", path)
        seen[key] = (what, str(path), False)


def input_file(path: str | Path, missing: str = "no such file") -> Path:
    """``path``, an input every reader may open: the one check of the files a command reads.

    Raises
    ------
    PanomapError
        Naming it: ``missing`` where there is no such file, "not a file" where it is a folder, a FIFO (the
        read would block until something writes to it), a device (it would never end) or a socket.
    """
    path = file_path(path)
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise PanomapError(missing, path) from None
    except (OSError, ValueError) as exc:
        raise PanomapError(f"cannot read it ({getattr(exc, 'strerror', None) or exc})", path) from None
    if not stat.S_ISREG(info.st_mode):
        raise PanomapError("not a file", path)
    return path


def read_text(path: str | Path, encoding: str = "utf-8-sig") -> str:
    """The text of ``path`` (a leading BOM dropped); PanomapError naming it if missing, not a regular file (a
    FIFO or a device would block or never end), or unreadable."""
    input_file(path)
    try:
        return Path(path).read_text(encoding=encoding)
    except FileNotFoundError:
        raise PanomapError("no such file", path) from None
    except UnicodeDecodeError as exc:
        byte = exc.object[exc.start]
        raise PanomapError(
            f"not a text file (byte 0x{byte:02x} at {exc.start:,} is not {exc.encoding.upper().replace('-SIG', '')}): "
            "a picture or another binary file?",
            path,
        ) from None
    except OSError as exc:
        raise PanomapError(f"cannot read it ({exc.strerror or exc})", path) from None


def _new_file_mode() -> int:
    """The mode an ordinary new file gets (0o666 less the umask); temp files start at 0o600."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def write_bytes_atomic(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file."""
    with atomic_output(path) as handle:
        handle.write(data)


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write UTF-8 ``text`` to ``path`` through a temporary file."""
    write_bytes_atomic(path, text.encode("utf-8"))


def write_with(path: str | Path, writer: Callable[[BinaryIO], None]) -> None:
    """Let ``writer`` fill a temporary file, then rename it to ``path``."""
    with atomic_output(path) as handle:
        writer(handle)


# ----------------------------------------------------------------------------- inputs named by folders and globs

IMAGE_SUFFIXES = frozenset({".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".webp", ".pgm", ".ppm", ".pnm"})
VIDEO_SUFFIXES = frozenset({".mp4", ".m4v", ".mov", ".mkv", ".webm", ".avi", ".ts", ".nut"})


def kind_of(path: Path) -> str | None:
    """``"image"``, ``"video"`` or None, by suffix."""
    suffix = path.suffix.lower()
    return "image" if suffix in IMAGE_SUFFIXES else "video" if suffix in VIDEO_SUFFIXES else None


def expand_input(pattern: str | Path, kinds: tuple[str, ...] = ("image", "video")) -> list[Path]:
    """The files ``pattern`` names, sorted: itself (a file), every file of ``kinds`` inside it, recursively (a
    folder), or those a glob matches (``cams/*.jpg``, ``**`` too). Raises PanomapError naming a pattern that
    names none (``panomap batch`` INPUT, ``panomap fit --image``)."""
    import glob

    what = " or ".join({"image": "image", "video": "video"}[kind] for kind in kinds)
    path = Path(pattern)
    if path.is_dir():
        files = [p for p in path.rglob("*") if p.is_file()]
        matches = sorted(p for p in files if kind_of(p) in kinds)
        if not matches:
            others = sorted({kind for kind in map(kind_of, files) if kind is not None})
            held = f" (it holds {' and '.join(f'{kind}s' for kind in others)})" if others else ""
            raise PanomapError(f"the folder holds no {what}{held}", path)
        return matches
    if path.is_file():
        if kind_of(path) is None:
            raise PanomapError(f"not an {what} file name (unknown suffix)", path)
        return [path]
    matches = sorted(Path(p) for p in glob.glob(str(pattern), recursive=True) if kind_of(Path(p)) in kinds)
    if not matches:
        raise PanomapError(f"matches no {what}" if glob.has_magic(str(pattern)) else "no such file", pattern)
    return matches
