"""Calibration writers, one function per file format: the text of a fitted external model.

- ``ocam``: ``calib_results.txt`` as OCamCalib's ``export_data.m`` writes it (centre row then column,
  from 0);
- ``kalibr``: a camchain with one camera, ``cam0``, on ``rostopic: /cam0/image_raw`` (the topic Kalibr's
  camera-IMU calibration reads the camera's images from; edit it to the bag's);
- ``opencv``: an OpenCV FileStorage YAML with ``K``, ``D`` (and ``xi``), ``image_width``, ``image_height``
  (JSON when the file name ends in ``.json``), written by ``cv2.FileStorage`` itself.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import yaml

from .models.base import ExternalCamera
from .models.double_sphere import DoubleSphere
from .models.eucm import EUCM
from .models.kannala_brandt import KannalaBrandt
from .models.mei import Mei
from .models.ocam import OCam


def ocam_text(model: OCam) -> str:
    def numbers(values: tuple[float, ...]) -> str:
        return " ".join(f"{v:.12e}" for v in values)

    return (
        "#polynomial coefficients for the DIRECT mapping function (ocam_model.ss in MATLAB). "
        "These are used by cam2world\n\n"
        f"{len(model.pol)} {numbers(model.pol)}\n\n"
        "#polynomial coefficients for the inverse mapping function (ocam_model.invpol in MATLAB). "
        "These are used by world2cam\n\n"
        f"{len(model.invpol)} {numbers(model.invpol)}\n\n"
        '#center: "row" and "column", starting from 0 (C convention)\n\n'
        f"{model.xc:.12f} {model.yc:.12f}\n\n"
        '#affine parameters "c", "d", "e"\n\n'
        f"{model.c:.12f} {model.d:.12f} {model.e:.12f}\n\n"
        '#image size: "height" and "width"\n\n'
        f"{model.height} {model.width}\n\n"
    )


def kalibr_text(model: ExternalCamera, image_size: tuple[int, int]) -> str:
    if isinstance(model, Mei):
        camera = (
            "omni",
            [model.xi, model.fx, model.fy, model.cx, model.cy],
            "radtan",
            [model.k1, model.k2, model.p1, model.p2],
        )
    elif isinstance(model, DoubleSphere):
        camera = ("ds", [model.xi, model.alpha, model.fx, model.fy, model.cx, model.cy], "none", [])
    elif isinstance(model, EUCM):
        camera = ("eucm", [model.alpha, model.beta, model.fx, model.fy, model.cx, model.cy], "none", [])
    elif isinstance(model, KannalaBrandt):
        camera = (
            "pinhole",
            [model.fx, model.fy, model.cx, model.cy],
            "equidistant",
            [model.k1, model.k2, model.k3, model.k4],
        )
    else:
        raise TypeError(f"no Kalibr form for {model.name}")
    kind, intrinsics, distortion, coefficients = camera
    data = {
        "cam0": {
            "camera_model": kind,
            "intrinsics": [float(x) for x in intrinsics],
            "distortion_model": distortion,
            "distortion_coeffs": [float(x) for x in coefficients],
            "resolution": [int(image_size[0]), int(image_size[1])],
            "cam_overlaps": [],
            "rostopic": "/cam0/image_raw",
        }
    }
    return str(yaml.safe_dump(data, sort_keys=False, default_flow_style=None))


def opencv_text(model: ExternalCamera, image_size: tuple[int, int], path: str | Path) -> str:
    if isinstance(model, Mei):
        k = np.array([[model.fx, model.skew, model.cx], [0, model.fy, model.cy], [0, 0, 1]])
        d = np.array([[model.k1, model.k2, model.p1, model.p2]])
    elif isinstance(model, KannalaBrandt):
        k = np.array([[model.fx, 0, model.cx], [0, model.fy, model.cy], [0, 0, 1]])
        d = np.array([[model.k1, model.k2, model.k3, model.k4]])
    else:
        raise TypeError(f"no OpenCV form for {model.name}")
    suffix = ".json" if str(path).lower().endswith(".json") else ".yaml"
    storage = cv2.FileStorage(suffix, cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    storage.write("image_width", int(image_size[0]))
    storage.write("image_height", int(image_size[1]))
    storage.write("K", k.astype(np.float64))
    storage.write("D", d.astype(np.float64))
    if isinstance(model, Mei):
        storage.write("xi", float(model.xi))
    return str(storage.releaseAndGetString())
