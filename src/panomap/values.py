"""Values read from outside (command line, view specs, landmark files, the learning page).

One check, worded by each caller: a finite real number.
"""

from __future__ import annotations

import math
from typing import Any


class NotFinite(ValueError):
    """A value that is not a finite number.

    ``number`` is False when the value is no number at all, True when it is one
    but NaN, infinite (or a refused bool).
    """

    def __init__(self, value: Any, number: bool) -> None:
        super().__init__(f"{value!r} is not a {'finite number' if number else 'number'}")
        self.value = value
        self.number = number


def finite_number(value: Any, *, bools: bool = True) -> float:
    """``value`` (a number or its text) as a finite float; a bool is refused unless ``bools``.

    Raises
    ------
    NotFinite
        When ``float(value)`` fails, or gives NaN or an infinity.
    """
    try:
        number = float(value)
    except OverflowError:  # an integer beyond the floats' range: a number, but not a finite float
        raise NotFinite(value, number=True) from None
    except (TypeError, ValueError):
        raise NotFinite(value, number=False) from None
    if not math.isfinite(number) or (isinstance(value, bool) and not bools):
        raise NotFinite(value, number=True)
    return number
