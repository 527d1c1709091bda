"""What a real lens and sensor do to a rendered omni-image: vignetting, a dim side, noise, JPEG.

Convention: pixel (u, v), u the column, v the row, the centre of the top-left pixel at
(0, 0); images are (H, W[, C]) uint8.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from ..errors import PanomapError


def vignette(
    image: NDArray[np.uint8],
    centre: tuple[float, float],
    radius: float,
    falloff: float = 0.5,
    dim: float = 0.0,
    dim_angle: float = 0.0,
) -> NDArray[np.uint8]:
    """Darken an image towards the rim of its image circle, more on one side.

    The gain at distance ``r`` from ``centre`` and image angle ``phi`` is
    ``1 - falloff*(r/radius)**2 - dim*max(0, cos(phi - dim_angle))*(r/radius)**2``:
    at the rim, ``1 - falloff`` all round and ``1 - falloff - dim`` on the dim side.

    Parameters
    ----------
    image : (H, W[, C]) uint8 ndarray
    centre : (u, v), px
        Centre of the image circle.
    radius : float
        Its radius (px), > 0.
    falloff : float
        Darkening at the rim all round, in [0, 1).
    dim : float
        Extra darkening at the rim on the side ``dim_angle`` (rad), with
        ``falloff + dim < 1``.

    Returns
    -------
    (H, W[, C]) uint8 ndarray
    """
    if not (radius > 0 and 0 <= falloff and 0 <= dim and falloff + dim < 1):
        raise PanomapError(f"need radius > 0, falloff, dim >= 0 and falloff + dim < 1; got {radius}, {falloff}, {dim}")
    height, width = image.shape[:2]
    v, u = np.mgrid[0:height, 0:width].astype(np.float64)
    du, dv = u - centre[0], v - centre[1]
    reach = (du**2 + dv**2) / radius**2
    side = np.maximum(0.0, np.cos(np.arctan2(dv, du) - dim_angle))
    gain = np.clip(1.0 - falloff * reach - dim * side * reach, 0.0, 1.0)
    if image.ndim == 3:
        gain = gain[..., None]
    return np.clip(np.rint(image * gain), 0, 255).astype(np.uint8)


def noisy_jpeg(
    image: NDArray[np.uint8], rng: np.random.Generator, noise: float = 5.0, quality: int = 75
) -> NDArray[np.uint8]:
    """Gaussian noise of ``noise`` grey levels, then JPEG at ``quality``, decoded again."""
    if not (noise >= 0 and math.isfinite(noise) and 1 <= quality <= 100):
        raise PanomapError(f"need noise >= 0 and quality in 1..100; got {noise}, {quality}")
    noisy = np.clip(image + rng.normal(0.0, noise, image.shape), 0, 255).astype(np.uint8)
    ok, encoded = cv2.imencode(".jpg", noisy, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise PanomapError("could not encode the JPEG")
    return np.asarray(cv2.imdecode(encoded, cv2.IMREAD_UNCHANGED), dtype=np.uint8)
