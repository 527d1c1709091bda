"""Checks on everything the learning page sends: JSON bodies, numbers, landmarks, file names.

Every check raises :class:`RequestError` with a message for the page; the
server answers it with HTTP 400 (or the error's ``status``) and
``{"error": message}``.
"""

from __future__ import annotations

import json
import re
from typing import Any

from ..io.local_web import MAX_BODY_BYTES, RequestError, only_keys, parse_body
from ..values import NotFinite, TooLarge, finite_number

# (RequestError, parse_body and only_keys are the local web tools' own, io.local_web: used here and by the server.)
__all__ = [
    "MAX_BODY_BYTES",
    "RequestError",
    "file_name",
    "finite",
    "landmark_name",
    "numbers",
    "only_keys",
    "parse_body",
]

MAX_LANDMARKS = 500
MAX_NAME_LENGTH = 64
# World coordinates beyond this are typing mistakes, not rooms.
MAX_WORLD_ABS = 1e6
# A landmark name goes into a CSV cell unquoted: no separators, quotes or control characters.
NAME_PATTERN = re.compile(r"[^,\"'\x00-\x1f\x7f]{1,64}")
# A file name the page may save or load: a bare name in the server's folder.
FILE_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")


def finite(value: Any, what: str, limit: float | None = None) -> float:
    """A finite JSON number (not a bool, not a string), at most ``limit`` in size."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise RequestError(f"{what} must be a number, not {json.dumps(value)[:40]}")
    try:
        number = finite_number(value)
    except TooLarge as exc:
        raise RequestError(f"{what} = {value:g} is too large (at most {exc.limit:g} in size)") from None
    except NotFinite:
        raise RequestError(f"{what} must be finite") from None
    if limit is not None and abs(number) > limit:
        raise RequestError(f"{what} = {number:g} is too large (at most {limit:g} in size)")
    return number


def numbers(value: Any, count: int, what: str, limit: float | None = None) -> tuple[float, ...]:
    """A JSON list of ``count`` finite numbers."""
    if not isinstance(value, list) or len(value) != count:
        raise RequestError(f"{what} must be a list of {count} numbers")
    return tuple(finite(v, f"{what}[{k}]", limit) for k, v in enumerate(value))


def landmark_name(value: Any, what: str) -> str:
    """A landmark name: 1-64 characters, none of them a comma, quote or control character."""
    if not isinstance(value, str) or not NAME_PATTERN.fullmatch(value.strip()):
        raise RequestError(
            f"{what}: the name must be 1 to {MAX_NAME_LENGTH} characters without commas, quotes or control "
            f"characters, not {json.dumps(value)[:40]}"
        )
    return value.strip()


def file_name(value: Any, suffixes: tuple[str, ...], what: str) -> str:
    """A bare file name with one of ``suffixes``: no folder, no ``..``, no absolute path."""
    if not isinstance(value, str) or not value:
        raise RequestError(f"{what}: give a file name")
    if "/" in value or "\\" in value or value.startswith("~"):
        raise RequestError(f"{what}: {value!r} must be a bare file name, without a folder")
    if ".." in value:
        raise RequestError(f"{what}: {value!r} must not contain '..'")
    if not FILE_PATTERN.fullmatch(value):
        raise RequestError(
            f"{what}: {value!r} must start with a letter or digit and hold only letters, digits, '.', '-', '_' "
            "(at most 100 characters)"
        )
    if not value.lower().endswith(suffixes):
        raise RequestError(f"{what}: {value!r} must end in {' or '.join(suffixes)}")
    return value
