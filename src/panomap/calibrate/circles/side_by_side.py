"""Whether an image's circle is one of two lenses side by side: a dual fisheye's raw frame.

A 360 camera of two fisheyes back to back stores both lenses' pictures side by side, each circle centred in
its half of a frame twice as wide as high. The circle search finds one of them; said alone, it describes
the other half of the frame as beyond the image circle.
"""

from __future__ import annotations

ASPECT_WITHIN = 0.05
"""How far the frame's width may be from twice its height (a share)."""

CENTRED_WITHIN = 0.1
"""How far the circle's centre may be from its half's middle (a share of the half's width)."""


def side_by_side_half(centre: tuple[float, float], image_size: tuple[int, int]) -> str | None:
    """ "left" or "right": the half of a frame twice as wide as high whose middle the circle's ``centre`` (u, v;
    px) is at, as a dual fisheye's lens is in its raw frame (``image_size``: width, height; px); None else."""
    width, height = image_size
    if abs(width / (2.0 * height) - 1.0) > ASPECT_WITHIN:
        return None
    half = width / 2.0
    u, v = centre
    if abs(v - (height - 1) / 2.0) > CENTRED_WITHIN * half:
        return None
    for name, middle in (("left", (half - 1) / 2.0), ("right", half + (half - 1) / 2.0)):
        if abs(u - middle) <= CENTRED_WITHIN * half:
            return name
    return None
