"""Writing files safely: everything goes to a temporary name and is renamed when done.

A failed or interrupted write never leaves a half-written output behind.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO, cast

from .errors import PanomapError


@contextmanager
def atomic_output(path: str | Path) -> Iterator[BinaryIO]:
    """Open a temporary file beside ``path``; rename it to ``path`` on success.

    The temporary name keeps ``path``'s suffix, so tools that choose a format
    by suffix see the right one. On any exception the temporary file is removed
    and ``path`` is left as it was.
    """
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise PanomapError("its folder does not exist", path)
    try:
        handle = tempfile.NamedTemporaryFile(
            "wb", dir=directory, prefix=f".{path.name}.", suffix=f".part{path.suffix}", delete=False
        )
    except OSError as exc:
        raise PanomapError(f"cannot write there ({exc.strerror or exc})", path) from None
    temporary = Path(handle.name)
    try:
        with handle:
            yield cast(BinaryIO, handle)
        os.chmod(temporary, _new_file_mode())
        os.replace(temporary, path)
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


def read_text(path: str | Path, encoding: str = "utf-8-sig") -> str:
    """The text of ``path`` (a leading BOM dropped); PanomapError naming it if missing or unreadable."""
    try:
        return Path(path).read_text(encoding=encoding)
    except FileNotFoundError:
        raise PanomapError("no such file", path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise PanomapError(f"cannot read it ({exc.__class__.__name__}: {exc})", path) from None


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
