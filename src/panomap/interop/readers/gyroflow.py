"""gyroflow's lens profiles (``gyroflow/lens_profiles``, ``LensProfile`` in gyroflow's ``lens_profile.rs``).

Read: ``fisheye_params`` {``camera_matrix`` (3 x 3 rows: fx, 0, cx / 0, fy, cy / 0, 0, 1),
``distortion_coeffs`` (k1 k2 k3 k4)}, ``calib_dimension`` {``w``, ``h``} (the image size), and the
fields gyroflow reads to change them: ``asymmetrical`` (absent or false: gyroflow puts the principal point
at the image centre (w/2, h/2), whatever the matrix says; so does this reader, with a note),
``distortion_model`` (absent or null: ``opencv_fisheye``, the only one read), ``digital_lens``,
``input_horizontal_stretch``/``input_vertical_stretch`` (1 or absent; anamorphic profiles are refused)
and ``crop`` (fx, fy divided by it). The name fields (``name``, ``camera_brand``, ``camera_model``,
``lens_model``, ``camera_setting``) make the import's note.

The model is ``cv::fisheye``'s (gyroflow's ``OpenCVFisheye``, adapted from OpenCV: theta = atan(r) of
(x/z, y/z), so rays below 90 deg only): opencv-fisheye. gyroflow's pixels are OpenCV's: nothing is
shifted. The file is read within the bounds of :mod:`.json_text`.
"""

from __future__ import annotations

from pathlib import Path

from ...errors import PanomapError
from ..models.kannala_brandt import OpenCVFisheye
from .base import Imported, built, image_size_of, member, numbers, typed_number
from .json_text import load_json
from .yaml_text import brief

READ_MODELS = ("opencv_fisheye",)
NAME_KEYS = ("name", "camera_brand", "camera_model", "lens_model", "camera_setting")


def looks_like(text: str) -> bool:
    """Whether ``text`` reads as a gyroflow profile: a JSON object with ``fisheye_params`` and
    ``calib_dimension`` (found without parsing)."""
    return text.lstrip("\ufeff \t\r\n").startswith("{") and all(
        f'"{key}"' in text for key in ("fisheye_params", "calib_dimension")
    )


def read(text: str, path: str | Path, choice: str | None = None) -> Imported:
    data = load_json(text, path)
    if not isinstance(data, dict):
        raise PanomapError("not a gyroflow lens profile (not a JSON object)", path)
    if "fisheye_params" not in data and "calib_dimension" not in data:
        raise PanomapError("not a gyroflow lens profile (no fisheye_params or calib_dimension)", path)
    model_name = data.get("distortion_model")
    if model_name is not None and model_name not in READ_MODELS:
        raise PanomapError(
            f"distortion_model {brief(model_name)} is not read (it reads {', '.join(READ_MODELS)}, the default)", path
        )
    digital = data.get("digital_lens")
    if digital is not None:
        raise PanomapError(f"digital_lens {brief(digital)} (a lens gyroflow warps digitally) is not read", path)
    for key in ("input_horizontal_stretch", "input_vertical_stretch"):
        if data.get(key) is None:
            continue
        stretch = typed_number(data[key], key, path)
        if stretch > 0.01 and stretch != 1:  # gyroflow takes 0.01 or less as unset (1)
            raise PanomapError(f"{key} is {stretch:g}: an anamorphic profile is not read", path)
    params = member(data, "fisheye_params", path, dict, "an object")
    dimension = member(data, "calib_dimension", path, dict, "an object")
    for key in ("w", "h"):
        if key not in dimension:
            raise PanomapError(f"calib_dimension.{key} is missing", path)
    width, height = (typed_number(dimension[key], f"calib_dimension.{key}", path) for key in ("w", "h"))
    size = image_size_of(width, height, "calib_dimension", path)
    for key in ("camera_matrix", "distortion_coeffs"):
        if key not in params:
            raise PanomapError(f"fisheye_params.{key} is missing", path)
    rows = params["camera_matrix"]
    if not isinstance(rows, list) or len(rows) != 3:
        raise PanomapError(f"fisheye_params.camera_matrix is {brief(rows)}, not 3 rows of 3 numbers", path)
    k = [numbers(row, f"fisheye_params.camera_matrix[{i}]", path, 3) for i, row in enumerate(rows)]
    if k[0][1] != 0 or k[1][0] != 0 or k[2] != [0.0, 0.0, 1.0]:
        raise PanomapError(
            f"fisheye_params.camera_matrix {brief(k)} is not [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]", path
        )
    coefficients = numbers(params["distortion_coeffs"], "fisheye_params.distortion_coeffs", path, 4)
    fx, fy, cx, cy = k[0][0], k[1][1], k[0][2], k[1][2]
    notes = []
    names = [str(data[key]) for key in NAME_KEYS[1:] if isinstance(data.get(key), str) and data[key]]
    if names or isinstance(data.get("name"), str):
        notes.append(f"lens profile {data.get('name') or ' '.join(names)!r}")
    asymmetrical = data.get("asymmetrical", False)
    if not isinstance(asymmetrical, bool):
        raise PanomapError(f"asymmetrical is {brief(asymmetrical)}, not true or false", path)
    if not asymmetrical:
        centre = (size[0] / 2, size[1] / 2)
        if (cx, cy) != centre:
            notes.append(
                f"asymmetrical is false: the principal point is the image centre ({centre[0]:g}, {centre[1]:g}), "
                f"as gyroflow takes it, not the matrix's ({cx:.2f}, {cy:.2f})"
            )
        cx, cy = centre
    crop = data.get("crop")
    if crop is not None:
        crop = typed_number(crop, "crop", path)
        if not crop > 0:
            raise PanomapError(f"crop is {crop:g}, not > 0", path)
        fx, fy = fx / crop, fy / crop
    model = built(OpenCVFisheye, path, fx, fy, cx, cy, *coefficients)
    return Imported(model, "gyroflow", size, notes=tuple(notes))
