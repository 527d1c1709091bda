"""JSON calibration files (Basalt's, gyroflow's) read within bounds: their size and their nesting.

Python's ``json`` parser recurses once per level (a file of 100000 ``[`` ends in ``RecursionError``) and
reads ``NaN``, ``Infinity`` and integers of any length (thousands of digits are refused with a
``ValueError``); each ends here as one :class:`~panomap.errors.PanomapError` line naming the file.
Non-finite numbers are refused where a reader takes a value (:func:`.base.number`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ...errors import PanomapError
from .yaml_text import MAX_CHARS, MAX_DEPTH


def _depth(text: str) -> int:
    """The deepest nesting of ``[`` and ``{`` outside strings."""
    depth = deepest = 0
    in_string = escaped = False
    for char in text:
        if in_string:
            if escaped:
                escaped = False
            elif char == "\\":
                escaped = True
            elif char == '"':
                in_string = False
        elif char == '"':
            in_string = True
        elif char in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif char in "]}":
            depth -= 1
    return deepest


def _once(pairs: list[tuple[str, Any]], path: str | Path) -> dict[str, Any]:
    """An object's members, refused where a key is written twice (``json`` keeps the last, silently)."""
    data = dict(pairs)
    if len(data) < len(pairs):
        twice = next(key for k, (key, _) in enumerate(pairs) if key in (other for other, _ in pairs[:k]))
        raise PanomapError(f"the key {twice!r} is written twice in one object: which one is meant is a guess", path)
    return data


def load_json(text: str, path: str | Path) -> Any:
    """The JSON document in ``text``, at most :data:`.yaml_text.MAX_CHARS` characters and
    :data:`.yaml_text.MAX_DEPTH` levels deep.

    Raises
    ------
    PanomapError
        For text that is not JSON (with its line) or passes a bound.
    """
    if len(text) > MAX_CHARS:
        raise PanomapError(f"{len(text)} characters: more than a calibration file holds ({MAX_CHARS})", path)
    if _depth(text) > MAX_DEPTH:
        raise PanomapError(f"nested more than {MAX_DEPTH} levels deep: not a calibration file", path)
    try:
        return json.loads(text.lstrip("\ufeff"), object_pairs_hook=lambda pairs: _once(pairs, path))
    except json.JSONDecodeError as exc:
        raise PanomapError(f"not valid JSON (line {exc.lineno}: {exc.msg})", path) from None
    except PanomapError:
        raise
    except ValueError:  # an integer of more digits than Python converts (4300)
        raise PanomapError("holds a number too long to read", path) from None
