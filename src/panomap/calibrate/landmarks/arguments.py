"""The landmark fit's arguments checked, once, before any work (:func:`panomap.fit_camera`'s).

Convention: pixels (u, v) px as :mod:`panomap.geometry`; angles in degrees where the names say so.
"""

from __future__ import annotations

import math

import numpy as np

from ... import inputs
from ...camera.radial_models import AXES, MODELS, RadialKind, radial_kind
from ...errors import PanomapError
from ...geometry import inside_image
from .mount import given_tilt
from .pairs import MIN_LANDMARKS, Landmarks

AZIMUTH_MODES = ("fit", "paper")


def checked_arguments(
    landmarks: Landmarks,
    camera_position: tuple[float, float, float],
    centre: tuple[float, float],
    model: str,
    azimuth: str,
    axis: str | None,
    image_size: tuple[int, int] | None,
    refine_centre: bool,
    pixel_sigma: float,
    world_sigma: float | None,
    camera_sigma: float | None,
    tilt: str | tuple[float, float],
) -> tuple[RadialKind | None, tuple[float, ...], tuple[float, float], tuple[float, float] | None]:
    """:func:`fit_camera`'s arguments checked: the model asked for (None: automatic), the camera position, the
    starting centre and the tilt given (None unless a pair); PanomapError naming the first that is wrong."""
    if model != "auto" and model not in MODELS:
        raise PanomapError(f"unknown model {model!r}; choose auto or one of {', '.join(MODELS)}")
    if azimuth not in AZIMUTH_MODES:
        raise PanomapError(f"azimuth must be 'fit' or 'paper', not {azimuth!r}")
    if axis is not None and axis not in AXES:
        raise PanomapError(f"axis must be 'down' or 'up', not {axis!r}")
    requested = None if model == "auto" else radial_kind(model)
    if refine_centre and requested is not None and requested.centre_given:
        raise PanomapError(
            f"the {model} model takes the centre as given; refining the centre needs another model than {model!r}"
        )
    inputs.instance(landmarks, Landmarks, "landmarks", " (panomap.read_landmarks reads a file)")
    camera = inputs.numbers(camera_position, 3, "the camera position (X0, Y0, Z0)")
    u0, v0 = inputs.numbers(centre, 2, "the image centre (u0, v0)")
    pixel_sigma = inputs.number(pixel_sigma, "the pixel sigma", limit=math.inf)
    world_sigma = None if world_sigma is None else inputs.number(world_sigma, "the world sigma", limit=math.inf)
    camera_sigma = None if camera_sigma is None else inputs.number(camera_sigma, "the camera sigma", limit=math.inf)
    if not (math.isfinite(pixel_sigma) and pixel_sigma > 0):
        raise PanomapError(f"the pixel sigma must be positive, not {pixel_sigma}")
    if world_sigma is not None and not (math.isfinite(world_sigma) and world_sigma >= 0):
        raise PanomapError(f"the world sigma must be zero or positive, not {world_sigma}")
    if camera_sigma is not None and not (math.isfinite(camera_sigma) and camera_sigma >= 0):
        raise PanomapError(f"the camera sigma must be zero or positive, not {camera_sigma}")
    tilt_given = given_tilt(tilt)
    n = len(landmarks)
    if n < MIN_LANDMARKS:
        raise PanomapError(f"only {n} landmark(s); at least {MIN_LANDMARKS} are needed")
    distinct = len(np.unique(np.hstack([landmarks.pixels, landmarks.world]), axis=0))
    if distinct < MIN_LANDMARKS:  # (a repeated pair adds no constraint: 6 copies of 2 fit any 1-parameter curve)
        raise PanomapError(
            f"only {distinct} distinct landmarks among {n} (the others repeat one, pixel and world point alike); "
            f"at least {MIN_LANDMARKS} are needed"
        )
    image_size = inputs.optional_image_size(image_size)
    if image_size is not None:
        check_inside(landmarks, image_size)
    if float(np.max(np.ptp(landmarks.pixels, axis=0))) == 0.0:
        u, v = landmarks.pixels[0]
        raise PanomapError(
            f"all {n} landmarks are at one pixel ({u:g}, {v:g}); each needs the pixel where its own world point "
            "appears in the image"
        )
    return requested, camera, (u0, v0), tilt_given


def check_inside(landmarks: Landmarks, image_size: tuple[int, int]) -> None:
    """Refuse a landmark outside the image, saying where it is (and whether (u, v) was given as (row, column))."""
    width, height = image_size
    u, v = landmarks.pixels[:, 0], landmarks.pixels[:, 1]
    outside = np.flatnonzero(~inside_image(u, v, image_size))  # (landmarks are finite)
    if outside.size:
        k = outside[0]
        transposed = bool(np.all(inside_image(v, u, image_size)))
        hint = " (read as (row, column) every landmark is inside it: u is the column, v the row)" if transposed else ""
        raise PanomapError(
            f"landmark {landmarks.names[k]!r} at pixel ({u[k]:g}, {v[k]:g}) is outside the {width} x {height} image"
            + hint
        )
