"""External camera models, one file per model or family, declared once in :data:`EXTERNAL_MODELS`.

Each is a frozen dataclass of its parameters with ``project`` (rays -> pixels) and ``unproject``
(pixels -> unit rays) in one frame and pixel convention (:mod:`.base`); each file states its
equations and how its tools' own frames and pixels map onto that convention.
"""

from __future__ import annotations

from ...errors import PanomapError
from .base import ExternalCamera
from .colmap_fisheye import FOV, ColmapFOV, ColmapRadialFisheye, ColmapThinPrismFisheye
from .double_sphere import DoubleSphere
from .eucm import EUCM, ColmapEUCM
from .kannala_brandt import KannalaBrandt, OpenCVFisheye
from .kannala_brandt_full import KannalaBrandtFull
from .mei import Mei
from .ocam import OCam
from .ocam_inverse import OCamInverse
from .panotools import PanoToolsFisheye, PanoToolsRectilinear
from .pinhole_radtan import PinholeRadtan


def _registry(*models: type[ExternalCamera]) -> dict[str, type[ExternalCamera]]:
    registry: dict[str, type[ExternalCamera]] = {}
    for model in models:
        if model.name in registry:
            raise AssertionError(f"external camera model {model.name!r} is registered twice")
        registry[model.name] = model
    return registry


# Every external model, by name.
EXTERNAL_MODELS: dict[str, type[ExternalCamera]] = _registry(
    OCam,
    OCamInverse,
    KannalaBrandt,
    OpenCVFisheye,
    KannalaBrandtFull,
    Mei,
    DoubleSphere,
    EUCM,
    ColmapEUCM,
    PinholeRadtan,
    FOV,
    ColmapFOV,
    ColmapRadialFisheye,
    ColmapThinPrismFisheye,
    PanoToolsFisheye,
    PanoToolsRectilinear,
)


def external_model(name: str, parameters: dict[str, object]) -> ExternalCamera:
    """The model ``name`` with ``parameters`` (as :meth:`ExternalCamera.parameters` gives them)."""
    cls = EXTERNAL_MODELS.get(name)
    if cls is None:
        raise PanomapError(f"unknown external camera model {name!r} (known: {', '.join(EXTERNAL_MODELS)})")
    values = {k: tuple(v) if isinstance(v, list) else v for k, v in parameters.items()}
    try:
        return cls(**values)
    except TypeError as exc:
        raise PanomapError(f"{name}: malformed parameters ({exc})") from None


__all__ = ["EXTERNAL_MODELS", "ExternalCamera", "external_model"]
