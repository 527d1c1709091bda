"""BoofCV's calibration YAML (``CalibrationIO.save``): one camera, its ``model`` named at the top level.

Read, as BoofCV's ``CalibrationIO.load`` reads them: ``model``, ``pinhole`` {fx, fy, cx, cy, skew, width,
height}, and

- ``omnidirectional_universal``: ``mirror_offset`` (xi), ``radial_tangential`` {``radial`` [any count],
  ``t1``, ``t2``}: model mei (k1, k2, p1 = t1, p2 = t2; radial past the second as ``k_more``);
- ``kannala_brandt``: ``symmetric``, ``radial``, ``radial_trig``, ``tangent``, ``tangent_trig``: model
  kannala-brandt-full.

``radial`` and ``t1``/``t2`` may be absent (0, as BoofCV loads them); a Kannala-Brandt coefficient list
absent is empty, and its ``radial_trig``/``tangent_trig`` hold four values or none. BoofCV's frame
and pixels are OpenCV's (x right, y down, the centre of the top-left pixel at (0, 0)): nothing is
shifted. BoofCV's ``pinhole``, ``pinhole_radial_tangential`` and its stereo and rig files are refused
naming the model. The file is read within the bounds of :mod:`.yaml_text`.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from ...errors import PanomapError
from ..models.base import ExternalCamera
from ..models.kannala_brandt_full import KannalaBrandtFull
from ..models.mei import Mei
from .base import Imported, built, image_size_of, member, numbers, typed_number
from .yaml_text import brief, load_yaml

MODELS = ("omnidirectional_universal", "kannala_brandt")
PINHOLE_KEYS = ("fx", "fy", "cx", "cy", "skew", "width", "height")
KB_LISTS = ("symmetric", "radial", "radial_trig", "tangent", "tangent_trig")
# BoofCV's file: ``model:`` and ``pinhole:`` keys at the start of a line (the top level), as CalibrationIO
# writes them (Kalibr's camchain nests ``camera_model:`` under each camera; OpenCV's names no model).
_MODEL = re.compile(r"^model[ \t]*:", re.MULTILINE)
_PINHOLE = re.compile(r"^pinhole[ \t]*:", re.MULTILINE)


def looks_like(text: str) -> bool:
    """Whether ``text`` reads as BoofCV's: top-level ``model:`` and ``pinhole:`` keys (found without parsing)."""
    return _MODEL.search(text) is not None and _PINHOLE.search(text) is not None


def read(text: str, path: str | Path, choice: str | None = None) -> Imported:
    data = load_yaml(text, path)
    if not isinstance(data, dict) or "model" not in data:
        raise PanomapError("not a BoofCV calibration (no top-level model)", path)
    kind = data["model"]
    if kind not in MODELS:
        raise PanomapError(
            f"BoofCV model {brief(kind)} is not read (it reads {', '.join(MODELS)}: the omnidirectional ones)", path
        )
    pinhole = member(data, "pinhole", path, dict, "a mapping")
    for key in PINHOLE_KEYS:
        if key not in pinhole:
            raise PanomapError(f"pinhole.{key} is missing", path)
    fx, fy, cx, cy, skew, width, height = (typed_number(pinhole[k], f"pinhole.{k}", path) for k in PINHOLE_KEYS)
    size = image_size_of(width, height, "pinhole.width x height", path)
    model: ExternalCamera
    if kind == "omnidirectional_universal":
        if "mirror_offset" not in data:
            raise PanomapError("mirror_offset is missing", path)
        xi = typed_number(data["mirror_offset"], "mirror_offset", path)
        distortion = member(data, "radial_tangential", path, dict, "a mapping")
        radial = distortion.get("radial")
        k = numbers(_or_empty(radial), "radial_tangential.radial", path)
        t1, t2 = (typed_number(distortion.get(t, 0.0), f"radial_tangential.{t}", path) for t in ("t1", "t2"))
        k1, k2 = [*k, 0.0, 0.0][:2]
        model = built(Mei, path, xi, fx, fy, cx, cy, k1, k2, t1, t2, skew, tuple(k[2:]))
    else:
        lists = {name: tuple(numbers(_or_empty(data.get(name)), name, path)) for name in KB_LISTS}
        for name in ("radial_trig", "tangent_trig"):
            if len(lists[name]) not in (0, 4):
                raise PanomapError(f"{name} has {len(lists[name])} values, expected 4 (or none)", path)
        if not lists["symmetric"]:
            raise PanomapError("symmetric is missing or empty (the model's radius needs it)", path)
        model = built(
            KannalaBrandtFull,
            path,
            fx,
            fy,
            cx,
            cy,
            skew,
            lists["symmetric"],
            lists["radial"],
            lists["tangent"],
            lists["radial_trig"],
            lists["tangent_trig"],
        )
    return Imported(model, "boofcv", size)


def _or_empty(value: Any) -> Any:
    """An absent (None) coefficient list as BoofCV loads it: empty."""
    return [] if value is None else value
