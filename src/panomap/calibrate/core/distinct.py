"""Pictures that show one view: a fixed camera's frames, whose lines would count twice.

A video of a fixed camera shows the same walls in every frame: pooled, each line would count once a frame, and
the fit's uncertainty (a jackknife over lines, :mod:`panomap.calibrate.lines.agreement`) would take copies for
independent measurements. Two pictures show one view where their thumbnails, each normalised to zero mean and
unit spread (so that exposure and white balance do not count), differ by more than ``CHANGE_SPREADS`` on less
than ``SAME_VIEW_FRACTION`` of their pixels: a person walking by changes about 1% of a thumbnail, exposure and
sensor noise none; a checkerboard held at another place changes 7-10%, a camera that moved its whole picture.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ...geometry import FloatArray

# Thumbnails are this many px on their longer side (area-averaged: noise and JPEG blocks average out).
THUMBNAIL_PX = 96
# A thumbnail pixel has changed where the normalised pictures differ by more than this (their spread's units).
CHANGE_SPREADS = 0.5
# Two pictures show one view where fewer than this fraction of their thumbnail pixels changed.
SAME_VIEW_FRACTION = 0.03


def thumbnail(image: NDArray[Any]) -> FloatArray:
    """(h, w) grey thumbnail of ``image`` ((H, W[, C]), any dtype), ``THUMBNAIL_PX`` on its longer side,
    normalised to zero mean and unit standard deviation (all zeros for a flat picture)."""
    grey = np.asarray(image, dtype=np.float32)
    if grey.ndim == 3:
        grey = grey.mean(axis=2)
    height, width = grey.shape
    scale = THUMBNAIL_PX / max(height, width)
    size = (max(1, round(width * scale)), max(1, round(height * scale)))
    small = cv2.resize(grey, size, interpolation=cv2.INTER_AREA).astype(np.float64)
    spread = float(small.std())
    return (small - small.mean()) / spread if spread > 0 else np.zeros_like(small)


def changed_fraction(first: FloatArray, second: FloatArray) -> float:
    """Fraction of the pixels of two thumbnails (:func:`thumbnail`, one shape) that differ by more than
    ``CHANGE_SPREADS``."""
    return float(np.mean(np.abs(first - second) > CHANGE_SPREADS))


class DistinctViews:
    """The views seen so far, one picture at a time: :meth:`add` says whether a picture shows a new one, so
    that a picture of a view already seen can be dropped as soon as it is decoded (a video's frames)."""

    def __init__(self) -> None:
        self._thumbnails: list[FloatArray] = []

    def add(self, image: NDArray[Any]) -> bool:
        """True (and the view remembered) where ``image`` shows one no earlier picture added shows."""
        small = thumbnail(image)
        if any(
            other.shape == small.shape and changed_fraction(other, small) < SAME_VIEW_FRACTION
            for other in self._thumbnails
        ):
            return False
        self._thumbnails.append(small)
        return True


def distinct_views(images: Sequence[NDArray[Any]]) -> list[int]:
    """Indices (increasing) of the pictures to keep: each picture in turn, unless it shows one view with a
    picture already kept (see the module's docstring). The first is always kept."""
    views = DistinctViews()
    return [k for k, image in enumerate(images) if views.add(image)]
