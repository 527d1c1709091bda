"""Robust spread: the normal-consistent median absolute deviation, the one scale every robust fit uses (a circle's
rim points, a rig's matches and overlap tiles, a surround's grey levels).

For values drawn from a normal distribution of standard deviation sigma, the median of their absolute deviation
is 0.6745 sigma; :data:`MAD_TO_SIGMA` (1 / 0.6745) turns it back into sigma, unmoved by outliers up to half of them.
"""

from __future__ import annotations

from typing import Any, Literal, overload

import numpy as np
from numpy.typing import NDArray

MAD_TO_SIGMA = 1.4826


@overload
def mad_sigma(values: NDArray[Any], *, centre: float | Literal["median"] = 0.0, axis: None = None) -> float: ...


@overload
def mad_sigma(values: NDArray[Any], *, centre: float | Literal["median"] = 0.0, axis: int) -> NDArray[np.float64]: ...


def mad_sigma(
    values: NDArray[Any], *, centre: float | Literal["median"] = 0.0, axis: int | None = None
) -> float | NDArray[np.float64]:
    """The standard deviation a normal distribution of ``values`` would have, from their median absolute deviation.

    Parameters
    ----------
    values : (...) ndarray
        Residuals, distances or levels, in any unit (the result is in the same unit); at least one along ``axis``.
    centre : float or "median"
        What the deviations are taken about: 0 (residuals of a fit, the default), a number, or ``"median"`` (the
        values' own median along ``axis``: a spread about an unknown level).
    axis : int, optional
        The axis the median runs along (the result has that axis removed); all values when None (a float).
    """
    array = np.asarray(values, dtype=np.float64)
    about = np.median(array, axis=axis, keepdims=True) if centre == "median" else float(centre)
    spread = MAD_TO_SIGMA * np.median(np.abs(array - about), axis=axis)
    return float(spread) if axis is None else np.asarray(spread, dtype=np.float64)
