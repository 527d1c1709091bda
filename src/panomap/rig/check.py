"""How well a rig's cameras agree where they overlap, in its pictures: a pose turned the wrong way shows.

A camera's pose inverted or transposed by mistake (a camchain's ``T_cn_cnm1`` written the other way) is still a
rotation, so no check of the file finds it; the pictures do. Each camera's layer of a low-resolution
equirectangular view (:func:`.blend.camera_maps`, the view's rays at infinity, so translations play no part) is
compared with every other camera's where both see: the **zero-normalised cross-correlation** (ZNCC) of their
grey levels over the shared pixels (1 for the same picture up to a gain and an offset, about 0 for unrelated
ones). A rig's agreement is the mean of its pairs' ZNCC weighted by their shared pixels.

:func:`compare_poses` measures a rig as given and each alternative (the same file read with one pose turned
the other way); an alternative that agrees clearly better (by ``CLEARLY_BETTER``, and at least ``AGREES``) is the
suspect.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ..views.equirect import EquirectView
from .blend import RigRemapper, camera_maps
from .rig import CameraRig

# The view the check compares in (W, H): 1.4 deg a pixel, after the layers are halved (2 x 2 px averaged).
CHECK_VIEW_SIZE = (512, 256)
# A pair's overlap counts from this many shared pixels (of the halved view).
MIN_OVERLAP_PX = 100
# An alternative is the suspect when it agrees by this much more than the rig as given, and at least this much.
CLEARLY_BETTER = 0.2
AGREES = 0.5


@dataclass(frozen=True)
class Agreement:
    """A rig's agreement in its pictures.

    Attributes
    ----------
    score : float
        The pairs' ZNCC weighted by their shared pixels; NaN where no two cameras overlap.
    pairs : dict of (i, j) -> (zncc, pixels)
        Each overlapping pair (i < j): its ZNCC and how many pixels of the check's view both see.
    """

    score: float
    pairs: dict[tuple[int, int], tuple[float, int]]


@dataclass(frozen=True)
class PoseComparison:
    """The rig as given against each alternative; ``suspect`` is the alternative's label that agrees clearly
    better, or None."""

    given: Agreement
    alternatives: dict[str, Agreement]
    suspect: str | None


def zncc(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """Zero-normalised cross-correlation of two equal-length samples; NaN where either is flat."""
    a = a - a.mean()
    b = b - b.mean()
    denominator = float(np.sqrt((a * a).sum() * (b * b).sum()))
    return float((a * b).sum() / denominator) if denominator > 1e-9 else float("nan")


def overlap_agreement(rig: CameraRig, pictures: Any, size: tuple[int, int] = CHECK_VIEW_SIZE) -> Agreement:
    """Each overlapping pair's ZNCC in ``pictures`` (one per camera, or the one frame), and the rig's score.

    The layers are made at twice ``size`` and averaged 2 x 2 (so the fisheyes' fine detail does not alias); a
    pixel counts where both cameras see all four of its pixels, one pixel in from the edge of what they see.
    """
    width, height = size
    maps = camera_maps(rig, EquirectView(size=(2 * width, 2 * height)))
    layers = RigRemapper(rig, maps, "linear", wrap=True).layers(pictures)
    greys, seen = [], []
    kernel = np.ones((3, 3), np.uint8)
    for layer, map_uv in zip(layers, maps, strict=True):
        grey = layer.astype(np.float32)
        if grey.ndim == 3:
            grey = grey[..., :3].mean(axis=2) if grey.shape[2] >= 3 else grey[..., 0]
        greys.append(cv2.resize(grey, size, interpolation=cv2.INTER_AREA).astype(np.float64))
        mask = np.all(np.isfinite(map_uv), axis=-1).astype(np.float32)
        whole = cv2.resize(mask, size, interpolation=cv2.INTER_AREA) >= 1.0
        seen.append(cv2.erode(whole.astype(np.uint8), kernel).astype(bool))
    pairs: dict[tuple[int, int], tuple[float, int]] = {}
    for i in range(rig.count):
        for j in range(i + 1, rig.count):
            both = seen[i] & seen[j]
            count = int(both.sum())
            if count < MIN_OVERLAP_PX:
                continue
            value = zncc(greys[i][both], greys[j][both])
            if np.isfinite(value):
                pairs[(i, j)] = (value, count)
    total = sum(count for _, count in pairs.values())
    score = sum(value * count for value, count in pairs.values()) / total if total else float("nan")
    return Agreement(float(score), pairs)


def compare_poses(
    given: CameraRig, alternatives: Mapping[str, CameraRig], pictures: Any, size: tuple[int, int] = CHECK_VIEW_SIZE
) -> PoseComparison:
    """The rig as given and each alternative measured in ``pictures``; the suspect is the best alternative that
    agrees by ``CLEARLY_BETTER`` more than the rig as given (no overlap counts as -1) and at least ``AGREES``."""
    measured = overlap_agreement(given, pictures, size)
    others = {label: overlap_agreement(rig, pictures, size) for label, rig in alternatives.items()}
    baseline = measured.score if np.isfinite(measured.score) else -1.0
    suspect = None
    best = baseline + CLEARLY_BETTER
    for label, agreement in others.items():
        if np.isfinite(agreement.score) and agreement.score >= max(best, AGREES):
            suspect, best = label, agreement.score
    return PoseComparison(measured, others, suspect)
