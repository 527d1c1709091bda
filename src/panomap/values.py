"""Values read from outside (command line, view specs, landmark files, the learning page).

One check, worded by each caller: a finite real number, at most ``MAX_ABS`` in
size. Nothing panomap reads is that large (a world 1e9 units wide, a pixel 1e9
px away, a video 30 years long): such a number is a typing mistake, and the
arithmetic on it would overflow (NumPy warnings, meaningless output).
"""

from __future__ import annotations

import math
from typing import Any

MAX_ABS = 1e9


class NotFinite(ValueError):
    """A value that is not a finite number.

    ``number`` is False when the value is no number at all, True when it is one
    but NaN, infinite (or a refused bool).
    """

    def __init__(self, value: Any, number: bool) -> None:
        super().__init__(f"{value!r} is not a {'finite number' if number else 'number'}")
        self.value = value
        self.number = number


class TooLarge(NotFinite):
    """A finite number beyond the limit (``limit``)."""

    def __init__(self, value: Any, limit: float) -> None:
        ValueError.__init__(self, f"{value!r} is too large (at most {limit:g} in size)")
        self.value = value
        self.number = True
        self.limit = limit


def finite_number(value: Any, *, bools: bool = True, limit: float = MAX_ABS) -> float:
    """``value`` (a number or its text) as a finite float at most ``limit`` in size; a bool is refused unless ``bools``.

    Raises
    ------
    NotFinite
        When ``float(value)`` fails, or gives NaN or an infinity;
        :class:`TooLarge` (a NotFinite) when it is beyond ``limit``.
    """
    try:
        number = float(value)
    except OverflowError:  # an integer beyond the floats' range: a number, but not a finite float
        raise NotFinite(value, number=True) from None
    except (TypeError, ValueError):
        raise NotFinite(value, number=False) from None
    if not math.isfinite(number) or (isinstance(value, bool) and not bools):
        raise NotFinite(value, number=True)
    if abs(number) > limit:
        raise TooLarge(value, limit)
    return number
