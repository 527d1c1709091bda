"""YAML calibration files read within bounds: their size, their nesting and what their aliases expand to.

PyYAML's ``safe_load`` builds an alias as a second reference to its anchor's value, so a file of a few
hundred bytes (``a: &a [x, x, ...]``, ``b: &b [*a, *a, ...]``, ...) is cheap to load and expands to
billions of values the first time anything walks it (formats it, compares it, checks its numbers);
its composer also recurses once per level, so 50000 nested ``[`` end in a ``RecursionError``. Here the
file's events are counted first (PyYAML's parser is a state machine, not recursive): each alias counts
as many values as its anchor's value expands to, and the whole file must stay within
:data:`MAX_EXPANDED_NODES` values and :data:`MAX_DEPTH` levels before it is built.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml

from ...errors import PanomapError

# libyaml's parser and loader where PyYAML has them: the same safe loader, about 100 times faster.
_LOADER: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
# A calibration file is a few kilobytes (a Kalibr camchain of four cameras: under 5 kB, 200 values).
MAX_CHARS = 1_000_000
# Values (scalars, lists, maps) the file may hold once its aliases are expanded, and the nesting depth.
MAX_EXPANDED_NODES = 100_000
MAX_DEPTH = 64
# OpenCV's FileStorage writes ``%YAML:1.0`` (no space), which is not a YAML directive; some projects
# distribute Kalibr camchains with that first line.
_OPENCV_DIRECTIVE = re.compile(r"\A\ufeff?%YAML:1\.\d+[ \t]*\r?\n")


def without_opencv_directive(text: str) -> str:
    """``text`` without OpenCV's ``%YAML:1.0`` first line (the ``---`` after it is plain YAML)."""
    return _OPENCV_DIRECTIVE.sub("", text, count=1)


def check_shape(text: str, path: str | Path) -> None:
    """Raise unless ``text`` is within :data:`MAX_CHARS`, :data:`MAX_DEPTH` and :data:`MAX_EXPANDED_NODES`.

    Raises
    ------
    PanomapError
        Naming the limit passed; ``yaml.YAMLError`` passes through for a file that is not YAML.
    """
    if len(text) > MAX_CHARS:
        raise PanomapError(f"{len(text)} characters: more than a calibration file holds ({MAX_CHARS})", path)
    sizes: dict[str, int] = {}  # anchor -> values its node expands to
    open_nodes: list[tuple[str | None, int]] = []  # (anchor, total before it) of each open list or map
    keys: list[tuple[set[str], list[int]] | None] = []  # each open map's keys so far and its items' count
    total = 0
    for event in yaml.parse(text, Loader=_LOADER):
        if isinstance(event, (yaml.AliasEvent, yaml.ScalarEvent, yaml.SequenceStartEvent, yaml.MappingStartEvent)):
            _check_key_once(event, keys[-1] if keys else None, path)
        if isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
            keys.append((set(), [0]) if isinstance(event, yaml.MappingStartEvent) else None)
        elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)) and keys:
            keys.pop()
        if isinstance(event, yaml.AliasEvent):
            if event.anchor not in sizes:
                break  # an undefined alias: the loader says so
            total += sizes[event.anchor]
        elif isinstance(event, (yaml.ScalarEvent, yaml.SequenceStartEvent, yaml.MappingStartEvent)):
            total += 1
            if isinstance(event, yaml.ScalarEvent):
                if event.anchor is not None:
                    sizes[event.anchor] = 1
            else:
                open_nodes.append((event.anchor, total - 1))
                if len(open_nodes) > MAX_DEPTH:
                    raise PanomapError(f"nested more than {MAX_DEPTH} levels deep: not a calibration file", path)
        elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)) and open_nodes:
            anchor, before = open_nodes.pop()
            if anchor is not None:
                sizes[anchor] = total - before
        if total > MAX_EXPANDED_NODES:
            raise PanomapError(
                f"its aliases expand to more than {MAX_EXPANDED_NODES} values: not a calibration file", path
            )


def _check_key_once(event: Any, mapping: tuple[set[str], list[int]] | None, path: str | Path) -> None:
    """Refuse ``event`` where it is a key its open ``mapping`` (keys so far, items so far) already has: PyYAML
    keeps the last of two, silently (a camchain's camera written twice under one name came out as one camera)."""
    if mapping is None:
        return
    seen, items = mapping
    if items[0] % 2 == 0 and isinstance(event, yaml.ScalarEvent):
        if event.value in seen:
            raise PanomapError(
                f"the key {brief(event.value)} is written twice in one map (line {event.start_mark.line + 1}): "
                "which one is meant is a guess",
                path,
            )
        seen.add(event.value)
    items[0] += 1


def load_yaml(text: str, path: str | Path) -> Any:
    """The YAML document in ``text`` (safe types only), within the bounds of :func:`check_shape`.

    Raises
    ------
    PanomapError
        For text that is not YAML (with its line) or passes a bound.
    """
    text = without_opencv_directive(text)
    try:
        check_shape(text, path)
        return yaml.load(text, Loader=_LOADER)  # (a safe loader)
    except yaml.YAMLError as exc:
        if "maximum nesting depth" in str(exc):  # libyaml's own bound (1000), met while it scans ahead
            raise PanomapError(f"nested more than {MAX_DEPTH} levels deep: not a calibration file", path) from None
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        raise PanomapError(f"not valid YAML{where}", path) from None
    except PanomapError:
        raise
    except ValueError:  # an integer of more digits than Python converts (4300)
        raise PanomapError("holds a number too long to read", path) from None


def brief(value: Any, limit: int = 60) -> str:
    """``repr``-like text of ``value``, at most about ``limit`` characters, without walking more of it.

    A value read from a file can expand (through YAML aliases) to billions of items: ``str`` of it would
    build all of them. Lists and maps are followed only until ``limit`` characters are written.
    """
    parts: list[str] = []
    length = 0

    def add(text: str) -> bool:
        nonlocal length
        parts.append(text)
        length += len(text)
        return length < limit

    def walk(item: Any, depth: int) -> bool:
        if isinstance(item, (list, tuple, dict)):
            if depth > 8:
                return add("...")
            opening, closing = ("{", "}") if isinstance(item, dict) else ("[", "]")
            if not add(opening):
                return False
            entries = item.items() if isinstance(item, dict) else enumerate(item)
            for index, (key, entry) in enumerate(entries):
                if index and not add(", "):
                    return False
                if isinstance(item, dict) and not add(f"{repr(key)[:limit]}: "):
                    return False
                if not walk(entry, depth + 1):
                    return False
            return add(closing)
        return add(repr(item)[:limit])

    complete = walk(value, 0)
    text = "".join(parts)
    return text if complete and len(text) <= limit else text[:limit] + "..."
