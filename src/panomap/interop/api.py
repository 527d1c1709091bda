"""``import_calibration``: a calibration file to a pano-mapping table, with where it came from."""

from __future__ import annotations

import hashlib
import math
from pathlib import Path
from typing import Any

import numpy as np

from .. import inputs
from ..errors import PanomapError
from ..table.table import PanoMappingTable
from .readers import Imported, read_calibration
from .table_of_camera import table_of_camera


def check_image_size(imported: Imported, image_size: tuple[int, int] | None, path: str | Path) -> None:
    """Raise unless the images' size (width, height) agrees with the calibration's, where both are known."""
    if image_size is not None and imported.image_size is not None and tuple(image_size) != imported.image_size:
        raise PanomapError(
            f"the calibration is for {imported.image_size[0]} x {imported.image_size[1]} images, "
            f"the image is {image_size[0]} x {image_size[1]}",
            path,
        )


def check_size_known(imported: Imported, image_size: tuple[int, int] | None, path: str | Path) -> None:
    """Raise when neither the file nor the caller gives the images' size: the table would span the model's
    whole range, past the image (an omnidir file: a 2357 px radius for 1280 x 960 images), and have no
    image size to check images against."""
    if imported.image_size is None and image_size is None:
        raise PanomapError(
            "the file gives no image size, so the table would span the model's whole range: "
            "give the image (--image) or its size (--image-size WxH)",
            path,
        )


def could_be_a_mirror_camera(
    imported: Imported, image_size: tuple[int, int] | None, radius_px: float | None = None
) -> bool:
    """Whether a calibration of a model that serves mirror cameras as well as lenses (OCamCalib's, the unified
    model's) could be a mirror camera's: whether it sees beyond 90 deg off its axis within ``radius_px`` of its
    principal point (the image circle, where one was found), else within the circle the frame holds about it.

    A mirror camera is built to see the horizon round its axis and beyond: at their rims the shared OCamCalib
    mirror cameras see 100-134 deg off the axis, a 200 deg fisheye 95-109, the shared OCamCalib fisheye 70-85:
    a lens that stays within 90 deg is no mirror camera's. True where the size and the radius are unknown.
    """
    u0, v0 = imported.model.principal_point
    size = image_size if image_size is not None else imported.image_size
    if radius_px is None:
        if size is None:
            return True
        radius_px = min(u0 + 0.5, size[0] - 0.5 - u0, v0 + 0.5, size[1] - 0.5 - v0)
    if not radius_px > 0.0:
        return True
    # 8 radii out to the circle on 32 azimuths: the widest angle any of them sees.
    phi = np.linspace(0.0, 2.0 * math.pi, 32, endpoint=False)
    r = radius_px * np.linspace(0.5, 1.0, 8)[:, None]
    rays = imported.model.unproject(np.stack([u0 + r * np.cos(phi), v0 + r * np.sin(phi)], axis=-1))
    z = rays[..., 2][np.isfinite(rays[..., 2])]
    return z.size == 0 or bool(np.min(z) < 0.0)


def import_calibration(
    path: str | Path,
    *,
    format: str | None = None,
    camera: str | None = None,
    axis: str = "down",
    tilt_rad: tuple[float, float] = (0.0, 0.0),
    orientation_rad: tuple[float, float, float] | None = None,
    camera_position: tuple[float, float, float] = (0.0, 0.0, 0.0),
    image_size: tuple[int, int] | None = None,
    cutoff_radius: float | None = None,
    outer_radius: float | None = None,
    size: tuple[int, int] | None = None,
    sources: dict[str, str] | None = None,
    mirror: bool = False,
) -> PanoMappingTable:
    """The pano-mapping table of the calibration in ``path``.

    Parameters
    ----------
    path : path
        OCamCalib ``calib_results.txt``, a Kalibr camchain, an OpenCV FileStorage file of cv::fisheye or
        cv::omnidir, COLMAP ``cameras.txt``, a BoofCV calibration YAML, a Basalt calibration JSON, a
        gyroflow lens profile, a Hugin project or an OpenCalib OCam intrinsic JSON (see
        ``docs/calibration-formats.md``).
    format : {"ocam", "gyroflow", "opencv", "kalibr", "colmap", "boofcv", "basalt", "hugin", "opencalib"}, optional
        Default: recognised from the content.
    camera : str, optional
        A Kalibr camera name (default ``cam0``), a Basalt camera (``cam1`` or ``1``; default the first)
        or a COLMAP camera id (default the first).
    axis : {"down", "up"}
        The optical axis becomes the table's vertical, looking down (default) or up; azimuth 0 lies
        along the calibration's x axis (the image's columns).
    tilt_rad : (tilt, toward)
        The mount: the optical axis ``tilt`` rad off the vertical, toward world azimuth ``toward`` rad.
    orientation_rad : (yaw, pitch, roll), optional
        A camera looking any way (rad): the optical axis along yaw and pitch (0 ahead, -pi/2 straight down),
        the image's right turned by roll, as a perspective view's (docs/conventions.md). Replaces ``axis``
        and ``tilt_rad``.
    camera_position : (X0, Y0, Z0)
        World units.
    image_size : (width, height), optional
        The images' size; must agree with the calibration's when both are known, and is needed when the
        file has none (an OpenCV omnidir file).
    cutoff_radius, outer_radius : float, optional
        The annulus (px about the principal point); default 0 and the model's valid range within the
        image.
    size : (M, N), optional
        Table size; default about one entry per pixel.
    sources : dict, optional
        Where quantities came from (stored in ``info["sources"]``).
    mirror : bool
        A mirror camera (a camera looking into a mirror): its image is the world's mirror image, and so is its
        calibration's frame; the table's handedness is turned to the world's (default: a lens).
    """
    tilt_rad = _tilt(tilt_rad)
    if orientation_rad is not None:
        yaw, pitch, roll = inputs.numbers(orientation_rad, 3, "orientation_rad (yaw, pitch, roll)")
        orientation_rad = (yaw, pitch, roll)
    x0, y0, z0 = inputs.numbers(camera_position, 3, "the camera position (X0, Y0, Z0)")
    camera_position = (x0, y0, z0)
    image_size = inputs.optional_image_size(image_size)
    if sources is not None and not (
        isinstance(sources, dict) and all(isinstance(k, str) and isinstance(v, str) for k, v in sources.items())
    ):
        raise TypeError(f"sources must be a dict of text (quantity: where it came from), not {sources!r:.40}")
    return table_of_imported(
        read_calibration(path, format, camera),
        path,
        axis=axis,
        tilt_rad=tilt_rad,
        orientation_rad=orientation_rad,
        camera_position=camera_position,
        image_size=image_size,
        cutoff_radius=cutoff_radius,
        outer_radius=outer_radius,
        size=size,
        sources=sources,
        mirror=mirror,
    )


def table_of_imported(
    imported: Imported,
    path: str | Path,
    *,
    axis: str = "down",
    tilt_rad: tuple[float, float] = (0.0, 0.0),
    orientation_rad: tuple[float, float, float] | None = None,
    camera_position: tuple[float, float, float] = (0.0, 0.0, 0.0),
    image_size: tuple[int, int] | None = None,
    cutoff_radius: float | None = None,
    outer_radius: float | None = None,
    size: tuple[int, int] | None = None,
    sources: dict[str, str] | None = None,
    mirror: bool = False,
) -> PanoMappingTable:
    """The table of a calibration already read from ``path`` (:func:`read_calibration`: a caller that
    needs the calibration first reads the file once); the parameters as :func:`import_calibration`'s."""
    check_image_size(imported, image_size, path)
    check_size_known(imported, image_size, path)
    size_used = imported.image_size if image_size is None else tuple(image_size)
    record: dict[str, Any] = {
        "file": Path(path).name,
        "sha256": hashlib.sha256(Path(path).read_bytes()).hexdigest(),
        "format": imported.format,
        "pixel_shift_px": imported.pixel_shift_px,
    }
    if imported.camera is not None:
        record["camera"] = imported.camera
    if imported.notes:
        record["notes"] = list(imported.notes)
    info_sources = {"centre": f"imported from {Path(path).name}"} | dict(sources or {})
    info_sources.setdefault("cutoff_radius", "given" if cutoff_radius is not None else "default: none")
    info_sources.setdefault(
        "outer_radius", "given" if outer_radius is not None else "default: the model's valid range in the image"
    )
    try:
        return table_of_camera(
            imported.model,
            axis=axis,
            tilt_rad=tilt_rad,
            orientation_rad=orientation_rad,
            camera_position=camera_position,
            image_size=size_used,  # type: ignore[arg-type]
            cutoff_radius=cutoff_radius,
            outer_radius=outer_radius,
            size=size,
            info={"import": record, "sources": info_sources, "warnings": []},
            mirror=mirror,
        )
    except PanomapError as exc:
        raise PanomapError(exc.detail, path) from None


def _tilt(tilt_rad: Any) -> tuple[float, float]:
    """``tilt_rad`` (tilt, toward) as two finite angles, the tilt at most pi (rad, not degrees)."""
    tilt, toward = inputs.numbers(tilt_rad, 2, "tilt_rad (tilt, toward)")
    if abs(tilt) > math.pi:
        raise PanomapError(f"tilt_rad: a tilt of {tilt:g} rad is more than 180 deg (the angles are in radians)")
    return tilt, toward
