"""The Python API's arguments checked at its boundary, once, with a message a user can act on.

What the public functions take from a caller (``docs/api.md``): images, pairs and triples of
numbers (a centre, a camera position), landmarks, lists of pictures and the ``info`` stored in a
table. A wrong *type* (a string for a centre, a file name for an image) is a ``TypeError``; a
value of the right type that cannot be used (a float image, an empty one, a centre of three
numbers or NaN, ``info`` holding NaN) is a :class:`~panomap.errors.PanomapError`. Nothing below
them (OpenCV, NumPy's indexing, ``json``) sees such a value.

Convention: an image is ``(H, W)`` or ``(H, W, C)`` with C in 1, 3, 4 (BGR, BGRA as OpenCV reads
them); a pair of pixel numbers is ``(u, v)``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import PurePath
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .errors import PanomapError
from .values import MAX_ABS, NotFinite, TooLarge, finite_number

IMAGE_DTYPES = (np.dtype(np.uint8), np.dtype(np.uint16))
CHANNELS = (1, 3, 4)
INFO_DEPTH = 32  # levels of nesting in ``info``: far more than any table's (3), far less than Python's stack


def _kind(value: Any) -> str:
    """``value``'s type as a user reads it: ``a str ('517 503')``, ``a list``."""
    name = type(value).__name__
    shown = f" ({value!r:.40})" if isinstance(value, str | bytes | PurePath) else ""
    return f"{'an' if name[0] in 'aeiouAEIOU' else 'a'} {name}{shown}"


def image(value: Any, what: str = "the image", dtypes: tuple[np.dtype[Any], ...] = IMAGE_DTYPES) -> NDArray[Any]:
    """``value`` if it is an image panomap can read: an ndarray of ``dtypes`` (8- or 16-bit), ``(H, W)`` or
    ``(H, W, C)`` with C in 1, 3, 4, at least one pixel.

    Raises
    ------
    TypeError
        Not an ndarray (a file name: :func:`panomap.read_image` reads one).
    PanomapError
        Another dtype, shape or an empty image, saying which.
    """
    if not isinstance(value, np.ndarray):
        hint = ": read the file with panomap.read_image" if isinstance(value, str | PurePath) else ""
        raise TypeError(f"{what} must be a NumPy array (H, W[, C]), not {_kind(value)}{hint}")
    if value.dtype not in dtypes:
        names = ", ".join(str(dtype) for dtype in dtypes[:-1]) + f" or {dtypes[-1]}"
        floats = value.dtype.kind == "f"
        hint = ": scale a 0-1 float image by 255 and convert it, image.astype(np.uint8)" if floats else ""
        raise PanomapError(f"{what} must be 8- or 16-bit ({names}), not {value.dtype}{hint}")
    if value.ndim not in (2, 3) or (value.ndim == 3 and value.shape[2] not in CHANNELS):
        raise PanomapError(
            f"{what} must have shape (H, W) or (H, W, C) with 1, 3 or 4 channels, not {value.shape}"
            + (" (a raveled image: reshape it to (H, W[, C]))" if value.ndim == 1 else "")
        )
    if value.shape[0] == 0 or value.shape[1] == 0:
        raise PanomapError(f"{what} is empty (shape {value.shape})")
    return value


def pictures(value: Any, what: str = "images") -> list[NDArray[Any]]:
    """``value`` (one image, or a sequence of images) as a list of checked images.

    Raises
    ------
    TypeError
        A string or path (a file name, where pictures are wanted), a mapping or no sequence, or an item
        that is not an ndarray.
    PanomapError
        An item that is not an image panomap reads (:func:`image`), naming it by its place.
    """
    if isinstance(value, np.ndarray):
        return [image(value)]
    if isinstance(value, str | bytes | PurePath | Mapping) or not _iterable(value):
        hint = " (read each file with panomap.read_image)" if isinstance(value, str | PurePath) else ""
        raise TypeError(f"{what} must be a list of images (NumPy arrays), not {_kind(value)}{hint}")
    items = list(value)
    return [image(item, f"{what}[{k}]") for k, item in enumerate(items)]


def _count(count: int, finite: str = "") -> str:
    return f"a {finite}number" if count == 1 else f"{count} {finite}numbers"


def numbers(value: Any, count: int, what: str, *, limit: float = MAX_ABS) -> tuple[float, ...]:
    """``value`` as ``count`` finite floats, each at most ``limit`` in size (a centre, a camera position).

    Raises
    ------
    TypeError
        A string (``"517 503"``), a mapping, a non-sequence, or items that are no numbers.
    PanomapError
        Another count of numbers, or one that is NaN, infinite or beyond ``limit``.
    """
    if isinstance(value, str | bytes | Mapping) or not _iterable(value):
        raise TypeError(f"{what} must be {_count(count)}, not {_kind(value)}")
    items = list(value.ravel() if isinstance(value, np.ndarray) else value)
    if len(items) != count:
        raise PanomapError(f"{what} must be {_count(count)}, not {len(items)}")
    checked = []
    for item in items:
        if isinstance(item, str | bytes):
            raise TypeError(f"{what} must be {_count(count)}, not text ({item!r:.40})")
        try:
            checked.append(finite_number(item, bools=False, limit=limit))
        except TooLarge as exc:
            raise PanomapError(f"{what}: {exc}") from None
        except NotFinite as exc:
            if not exc.number:
                raise TypeError(f"{what} must be {_count(count)}, not {_kind(item)}") from None
            raise PanomapError(f"{what} must be {_count(count, 'finite ')}, not {item!r}") from None
    return tuple(checked)


def optional_numbers(value: Any, count: int, what: str) -> tuple[float, ...] | None:
    """:func:`numbers`, None passing through."""
    return None if value is None else numbers(value, count, what)


def number(value: Any, what: str, *, limit: float = MAX_ABS) -> float:
    """One finite float at most ``limit`` in size; TypeError for no number, PanomapError for NaN or beyond."""
    return numbers((value,), 1, what, limit=limit)[0]


def whole_numbers(value: Any, count: int, what: str, *, limit: float = MAX_ABS) -> tuple[int, ...]:
    """:func:`numbers`, each a whole number (``64`` or ``64.0``, not ``64.7``): a size in pixels.

    Raises
    ------
    TypeError
        As :func:`numbers` (text, a bool, no sequence).
    PanomapError
        As :func:`numbers`, or a number with a fraction (it would be cut silently).
    """
    checked = numbers(value, count, what, limit=limit)
    if any(not item.is_integer() for item in checked):
        shown = " x ".join(f"{item:g}" for item in checked)
        raise PanomapError(f"{what} must be whole numbers, not {shown}")
    return tuple(int(item) for item in checked)


def optional_image_size(value: Any, what: str = "the image size (W, H)") -> tuple[int, int] | None:
    """``value`` as a (width, height) of whole positive pixels, None passing through (:func:`whole_numbers`)."""
    if value is None:
        return None
    width, height = whole_numbers(value, 2, what)
    if width <= 0 or height <= 0:
        raise PanomapError(f"{what} must be positive, not {width} x {height}")
    return width, height


def points(value: Any, columns: int, what: str) -> NDArray[np.float64]:
    """``value`` as a float64 array of shape ``(..., columns)``: pixels (u, v), points (x, y, z). NaN and
    infinities pass (a point with no answer gets NaN back); the shape and the type are checked.

    Raises
    ------
    TypeError
        Text, None, or items that are no real numbers (objects, complex numbers).
    PanomapError
        Ragged rows, or a last axis of another length than ``columns`` (one (u, v) is ``[u, v]``).
    """
    shape = "(..., 2) (u, v)" if columns == 2 else f"(..., {columns})"
    if value is None or isinstance(value, str | bytes | Mapping):
        raise TypeError(f"{what} must be an array of shape {shape}, not {_kind(value)}")
    try:
        array = np.asarray(value)
    except ValueError:
        raise PanomapError(f"{what} must be an array of shape {shape}: its rows differ in length") from None
    if array.dtype.kind not in "biuf":
        raise TypeError(f"{what} must be real numbers, not {array.dtype} (shape {shape})")
    if array.ndim == 0 or array.shape[-1] != columns:
        raise PanomapError(f"{what} must have shape {shape}, not {array.shape}")
    return np.asarray(array, dtype=np.float64)


def path(value: Any, what: str) -> Any:
    """``value`` if it is a file name (a str or path-like); a TypeError naming what it is otherwise."""
    if not isinstance(value, str | PurePath) and not hasattr(value, "__fspath__"):
        raise TypeError(f"{what} must be a str or a path, not {_kind(value)}")
    return value


def instance(value: Any, kind: type, what: str, hint: str = "") -> Any:
    """``value`` if it is a ``kind``; a TypeError naming what it is, and ``hint``, otherwise."""
    if not isinstance(value, kind):
        raise TypeError(f"{what} must be a {kind.__name__}, not {_kind(value)}{hint}")
    return value


def info(value: Any, what: str = "info") -> dict[str, Any]:
    """``value`` (a mapping, or None for an empty one) if JSON holds it as a table stores it: text keys; values
    None, bool, int, finite float, str, lists (tuples) and mappings of them, at most ``INFO_DEPTH`` deep.

    Raises
    ------
    TypeError
        Not a mapping, a key that is not text, or a value JSON cannot hold (an object, a set, a NumPy
        scalar or array: convert it with ``float()``, ``.tolist()``), naming where it is.
    PanomapError
        A number that is NaN, infinite or no float holds, or nesting deeper than ``INFO_DEPTH``.
    """
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise TypeError(f"{what} must be a mapping (a dict), not {_kind(value)}")
    _json_safe(value, what, 0)
    return dict(value)


def _json_safe(value: Any, where: str, depth: int) -> None:
    if depth > INFO_DEPTH:
        raise PanomapError(f"{where} is nested more than {INFO_DEPTH} levels deep")
    if value is None or isinstance(value, bool | str):
        return
    if isinstance(value, int | float):
        try:
            good = math.isfinite(float(value))
        except OverflowError:
            good = False
        if not good:
            raise PanomapError(f"{where} is {value!r:.40}, not a finite number (a table stores finite floats)")
        return
    if isinstance(value, Mapping):
        for key, item in value.items():
            if not isinstance(key, str):
                raise TypeError(f"{where} has the key {key!r:.40} ({type(key).__name__}): keys must be text")
            _json_safe(item, f"{where}[{key!r:.40}]", depth + 1)
        return
    if isinstance(value, list | tuple):
        for k, item in enumerate(value):
            _json_safe(item, f"{where}[{k}]", depth + 1)
        return
    hint = " (convert it: float(x), x.tolist())" if isinstance(value, np.generic | np.ndarray) else ""
    raise TypeError(f"{where} is {_kind(value)}, which a table's JSON cannot hold{hint}")


def _iterable(value: Any) -> bool:
    try:
        iter(value)
    except TypeError:
        return False
    return True
