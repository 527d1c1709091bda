"""``export_calibration``: a table's camera in another tool's model, fitted to the table, and written.

The table's rays over its valid range (a grid of its entries, every one finite and in the image) are
taken into the camera's own frame (through the mount, then :mod:`.frame`); the format's parameters are
fitted to the table's pixels of them by ``scipy.optimize.least_squares``, from a start the table's
radial model gives (the double sphere from several, the best kept); the largest distance (px) between the
fitted model and the table, on a grid twice as fine as the fit's that runs to both ends of the table's
range (its outermost ring included), is returned and printed. A format whose model cannot hold the camera is refused
with the reason (OpenCV's fisheye: rays at 90 deg or more from the axis). Every format has a single
viewpoint: a table whose rays leave the axis from points apart (format version 4) is refused unless
their spread is negligible (:data:`NEGLIGIBLE_PARALLAX_PX`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..camera.viewpoint import PARALLAX_DISTANCE, parallax_px
from ..errors import PanomapError
from ..files import write_text_atomic
from ..geometry import TWO_PI, FloatArray
from ..table.table import PanoMappingTable, check_table
from .frame import camera_rays
from .models.base import ExternalCamera
from .models.double_sphere import DoubleSphere
from .models.eucm import EUCM
from .models.kannala_brandt import KannalaBrandt
from .models.mei import Mei
from .models.ocam import OCam
from .writers import kalibr_text, ocam_text, opencv_text

# scipy is imported where it is used: its import would cost every command (a video's start-up too) 0.4 s.

# The fit's grid over the table (azimuths, elevations); the check's is twice as fine.
FIT_GRID = (180, 60)
# Degree of OCam's direct polynomial (a1 = 0, as OCamCalib fixes it) and the largest inverse one.
OCAM_DEGREE = 4
OCAM_MAX_INVERSE_DEGREE = 20
# A non-central table is exported (its ray origins dropped) only where dropping them moves a point at
# PARALLAX_DISTANCE (1 world unit: a metre) by under this (px): below any calibration's accuracy. (In a world
# in millimetres the test is stricter, in kilometres looser: the table knows no unit.)
NEGLIGIBLE_PARALLAX_PX = 0.01


@dataclass(frozen=True)
class Exported:
    """A fitted model, the file text, and its largest distance from the table (px) over its range."""

    model: ExternalCamera
    text: str
    max_error_px: float
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class Samples:
    """Rays (n, 3) in the camera's (OpenCV) frame and the table's pixels (n, 2) of them."""

    rays: FloatArray
    uv: FloatArray

    @property
    def max_angle_rad(self) -> float:
        return float(np.max(np.arctan2(np.hypot(self.rays[:, 0], self.rays[:, 1]), self.rays[:, 2])))


def table_samples(table: PanoMappingTable, grid: tuple[int, int]) -> Samples:
    """The table's rays on a ``grid`` (azimuths, elevations) over its range, where its pixel is valid."""
    m, n = grid
    theta = TWO_PI * np.arange(m) / m
    low, high = table.elevation_range
    rho = np.linspace(low, high, n)  # (both ends: the outermost ring and the innermost are the table's too)
    theta, rho = np.meshgrid(theta, rho, indexing="ij")
    uv = table.sample(theta, rho).astype(np.float64)
    theta_c, rho_c = table.model.camera_angles(theta, rho)
    rays = camera_rays(theta_c, rho_c, table.model.axis, table.model.s, table.model.phi0)
    # A ray on the optical axis itself (a table without a cut-off disc starts there) is left out: every model
    # sends it to its principal point, the limit of the ring next to it, but through a 0 / 0 (OCam's atan).
    off_axis = np.hypot(rays[..., 0], rays[..., 1]) > 1e-9
    good = np.all(np.isfinite(uv), axis=-1) & off_axis
    if np.count_nonzero(good) < 20:
        raise PanomapError("the table has too few valid entries to fit a camera model to")
    return Samples(rays[good], uv[good])


def _fit(build: Callable[[FloatArray], ExternalCamera], start: list[float], samples: Samples) -> ExternalCamera:
    """Least-squares parameters of ``build`` (a parameter vector to a model) to the samples."""

    def residuals(p: FloatArray) -> FloatArray:
        try:
            model = build(p)
        except PanomapError:
            return np.full(samples.uv.size, 1e6)
        miss = model.project(samples.rays) - samples.uv
        return np.where(np.isfinite(miss), miss, 1e3).ravel()

    from scipy.optimize import least_squares

    result = least_squares(residuals, np.asarray(start, dtype=np.float64), method="lm", x_scale="jac")
    return build(result.x)


def _fit_best(
    build: Callable[[FloatArray], ExternalCamera], starts: list[list[float]], samples: Samples
) -> ExternalCamera:
    """:func:`_fit` from each of ``starts``; the model whose largest distance from the samples (px) is the
    least (a start that reaches no valid model is passed over; if none does, its error is raised)."""
    best: tuple[float, ExternalCamera] | None = None
    failure: PanomapError | None = None
    for start in starts:
        try:
            model = _fit(build, start, samples)
        except PanomapError as exc:
            failure = failure or exc
            continue
        miss = np.hypot(*(model.project(samples.rays) - samples.uv).T)
        largest = float(np.max(miss)) if np.all(np.isfinite(miss)) else math.inf
        if best is None or largest < best[0]:
            best = (largest, model)
    if best is None:
        assert failure is not None
        raise failure
    return best[1]


def _start(table: PanoMappingTable) -> tuple[float, float, float]:
    """cx, cy and the focal length (px per rad at the axis) of the table's radial model."""
    radial = table.model.radial
    axis_rho = -math.pi / 2 if table.model.axis == "down" else math.pi / 2
    step = 1e-3 if table.model.axis == "down" else -1e-3
    focal = abs(float(radial(axis_rho + step) - radial(axis_rho))) / 1e-3
    cx, cy = table.model.centre
    return cx, cy, focal


def _fit_kannala_brandt(table: PanoMappingTable, samples: Samples) -> ExternalCamera:
    cx, cy, f = _start(table)
    return _fit(lambda p: KannalaBrandt(*p), [f, f, cx, cy, 0.0, 0.0, 0.0, 0.0], samples)


def _fit_mei(table: PanoMappingTable, samples: Samples, skew: bool) -> ExternalCamera:
    cx, cy, f = _start(table)
    start = [1.0, 2 * f, 2 * f, cx, cy, 0.0, 0.0, 0.0, 0.0] + ([0.0] if skew else [])
    # First without distortion (xi and the focal length are strongly correlated with k1, k2), then all.
    plain = _fit(lambda p: Mei(p[0], p[1], p[2], p[3], p[4]), start[:5], samples)
    assert isinstance(plain, Mei)
    start[:5] = [plain.xi, plain.fx, plain.fy, plain.cx, plain.cy]
    return _fit(lambda p: Mei(*p), start, samples)


# The double sphere's starts (xi, alpha): from one start the fit can stop in a local minimum (issue 44: a
# kalibr-ds export stopped at 11.6 px where another start reached 0.80 px; a simulated 800 x 800 equisolid
# fisheye stops at 0.84 px from (0, 0.5) and reaches 0.002 px from (0.3, 0.5)).
DOUBLE_SPHERE_STARTS = ((0.0, 0.5), (0.3, 0.5), (0.6, 0.6), (0.0, 0.3))


def _fit_double_sphere(table: PanoMappingTable, samples: Samples) -> ExternalCamera:
    cx, cy, f = _start(table)
    starts = [[xi, alpha, f, f, cx, cy] for xi, alpha in DOUBLE_SPHERE_STARTS]
    return _fit_best(lambda p: DoubleSphere(*p), starts, samples)


def _kalibr_eucm(p: FloatArray) -> EUCM:
    """EUCM of parameters ``p`` with alpha below 1, as Kalibr takes it."""
    if not p[0] < 1:
        raise PanomapError(f"eucm: alpha is {p[0]:g}; Kalibr takes it below 1")
    return EUCM(*p)


def _fit_eucm(table: PanoMappingTable, samples: Samples) -> ExternalCamera:
    cx, cy, f = _start(table)
    return _fit(_kalibr_eucm, [0.5, 1.0, f, f, cx, cy], samples)


def _fit_ocam(table: PanoMappingTable, samples: Samples) -> ExternalCamera:
    """OCam's centre and affine by least squares, its pol (a1 = 0, as OCamCalib fixes it) solved linearly
    inside (each sample's pol(r) must be z r / hypot(x, y) of its ray, px); then invpol fitted to pol's
    inverse until it is within 0.01 px."""
    if table.image_size is None:
        raise PanomapError("the table has no image size: an OCamCalib file needs the image's height and width")
    width, height = table.image_size
    cx, cy, _ = _start(table)
    # The rays in OCam's frame: (x, y, z) = (y, x, -z) of the OpenCV frame.
    x, y, z = samples.rays[:, 1], samples.rays[:, 0], -samples.rays[:, 2]
    powers = [0, *range(2, OCAM_DEGREE + 1)]

    def solve(p: FloatArray) -> tuple[FloatArray, FloatArray]:
        xc, yc, c, d, e = p
        drow, dcol = samples.uv[:, 1] - xc, samples.uv[:, 0] - yc
        det = c - d * e
        xp, yp = (drow - d * dcol) / det, (-e * drow + c * dcol) / det
        r, horizontal = np.hypot(xp, yp), np.hypot(x, y)
        target = z * r / horizontal
        design = np.stack([r**k for k in powers], axis=-1)
        coefficients, *_ = np.linalg.lstsq(design, target, rcond=None)
        # The radius through pol, and the direction: (x', y') must be along (x, y) (px off that line).
        across = (xp * y - yp * x) / horizontal
        return coefficients, np.concatenate([design @ coefficients - target, across])

    from scipy.optimize import least_squares

    p = least_squares(lambda p: solve(p)[1], [cy, cx, 1.0, 0.0, 0.0], x_scale=[1.0, 1.0, 1e-3, 1e-3, 1e-3]).x
    coefficients, _ = solve(p)
    pol = (float(coefficients[0]), 0.0, *(float(a) for a in coefficients[1:]))
    xc, yc, c, d, e = (float(v) for v in p)
    model = OCam(pol, (1.0,), xc, yc, c, d, e, height, width)
    # invpol: rho = sum p_k t^k over the samples' OCam elevations t.
    _, nodes_t = model._inverse
    t = np.linspace(nodes_t[0], min(nodes_t[-1], _max_ocam_elevation(samples)), 2000)
    r = model.radius_of_elevation(t)
    for degree in range(6, OCAM_MAX_INVERSE_DEGREE + 1):
        invpol = np.polynomial.polynomial.Polynomial.fit(t, r, degree).convert().coef
        if np.max(np.abs(np.polynomial.polynomial.polyval(t, invpol) - r)) < 0.01:
            break
    return OCam(pol, tuple(float(v) for v in invpol), xc, yc, c, d, e, height, width)


def _max_ocam_elevation(samples: Samples) -> float:
    """Highest OCam elevation (rad) of the samples' rays: OCam's z is -z here."""
    return float(np.max(np.arctan2(-samples.rays[:, 2], np.hypot(samples.rays[:, 0], samples.rays[:, 1]))))


def _refuse_opencv_fisheye(samples: Samples) -> str | None:
    widest = math.degrees(samples.max_angle_rad)
    if widest >= 90.0:
        return (
            f"the camera sees rays {widest:.1f} deg from its axis; cv2.fisheye computes theta = atan(|(x/z, y/z)|), "
            "so it holds rays below 90 deg only (a field of view under 180 deg): try kalibr-equidistant, "
            "opencv-omnidir or ocam"
        )
    return None


def _fitted(fit: Fitter, table: PanoMappingTable, samples: Samples, format: str) -> ExternalCamera:
    """``fit(table, samples)``; a solver's failure on entries no camera makes (an edited imported table:
    its entries are guarded by their checksum only) becomes one line."""
    try:
        return fit(table, samples)
    except (np.linalg.LinAlgError, PanomapError, ValueError, FloatingPointError) as exc:
        detail = exc.detail if isinstance(exc, PanomapError) else f"{exc.__class__.__name__}: {exc}"
        raise PanomapError(
            f"{format} cannot be fitted to this table ({' '.join(detail.split())[:120]}): "
            "its entries are not a camera's (an edited table?)"
        ) from None


def _refuse_ray_origins(table: PanoMappingTable, format: str) -> None:
    """Raise where ``table``'s rays leave the axis from points apart (not negligibly): ``format``, as every
    export format, has a single viewpoint, and its file would drop them without a word."""
    viewpoint = table.model.viewpoint
    if viewpoint is None:
        return
    low, high = table.camera_range
    spread = viewpoint.excursion(low, high)
    parallax = parallax_px(table.model.radial, viewpoint, (low, high))
    if parallax < NEGLIGIBLE_PARALLAX_PX:
        return
    raise PanomapError(
        f"{format} has a single viewpoint, and this table's rays leave the axis over {spread:.4g} world units "
        f"({1000 * spread:.1f} mm where the world is in metres): its model would be up to {parallax:.2f} px "
        f"off at a distance of {PARALLAX_DISTANCE:g}; not exported (no export format holds ray origins)"
    )


def _refuse_absurd(max_error_px: float, image_size: tuple[int, int] | None, format: str, name: str) -> None:
    """Raise when the fitted model misses the table by more than the image's diagonal (px): no camera's
    entries do that, and the file would be meaningless."""
    diagonal = math.hypot(*image_size) if image_size is not None else math.inf
    if not max_error_px <= diagonal:
        raise PanomapError(
            f"{format} cannot hold this table: the best {name} model misses its entries by {max_error_px:.3g} px, "
            f"more than the image's diagonal ({diagonal:.0f} px); its entries are not a camera's (an edited table?)"
        )


Fitter = Callable[[PanoMappingTable, Samples], ExternalCamera]
Refusal = Callable[[Samples], "str | None"]
# Every export format: (fit, file kind, refusal).
FORMATS: dict[str, tuple[Fitter, str, Refusal]] = {
    "ocam": (_fit_ocam, "ocam", lambda s: None),
    "opencv-fisheye": (_fit_kannala_brandt, "opencv", _refuse_opencv_fisheye),
    "opencv-omnidir": (lambda t, s: _fit_mei(t, s, skew=True), "opencv", lambda s: None),
    "kalibr-omni": (lambda t, s: _fit_mei(t, s, skew=False), "kalibr", lambda s: None),
    "kalibr-ds": (_fit_double_sphere, "kalibr", lambda s: None),
    "kalibr-eucm": (_fit_eucm, "kalibr", lambda s: None),
    "kalibr-equidistant": (_fit_kannala_brandt, "kalibr", lambda s: None),
}


def export_calibration(table: PanoMappingTable, path: str | Path, format: str) -> Exported:
    """Fit ``format``'s model to ``table`` over its valid range and write it to ``path``.

    Returns the fitted model and the largest distance (px) between it and the table on a check grid
    twice as fine as the fit's.

    Parameters
    ----------
    table : PanoMappingTable
        The camera's table.
    path : str or path
        The file to write.
    format : {"ocam", "opencv-fisheye", "opencv-omnidir", "kalibr-omni", "kalibr-ds", "kalibr-eucm", \
"kalibr-equidistant"}
        The other tool's model and file (the manual's "Calibrations in and out" page).

    Raises
    ------
    PanomapError
        For an unknown format, one that cannot hold the camera (the reason: a table whose rays leave the
        axis from points apart, as every format has a single viewpoint), or a table without an image size
        where the format needs one; nothing is written then.
    """
    check_table(table)
    if format not in FORMATS:
        raise PanomapError(f"unknown export format {format!r} (known: {', '.join(FORMATS)})")
    fit, kind, refusal = FORMATS[format]
    _refuse_ray_origins(table, format)
    samples = table_samples(table, FIT_GRID)
    reason = refusal(samples)
    if reason:
        raise PanomapError(f"{format} cannot hold this camera: {reason}")
    if kind != "ocam" and table.image_size is None:
        raise PanomapError(f"the table has no image size: a {format} file needs the image's width and height")
    model = _fitted(fit, table, samples, format)
    check = table_samples(table, (2 * FIT_GRID[0], 2 * FIT_GRID[1]))
    # What the file's own equations give: OCamCalib's world2cam goes through invpol.
    projected = model.world2cam(check.rays) if isinstance(model, OCam) else model.project(check.rays)
    miss = np.hypot(*(projected - check.uv).T)
    if not np.all(np.isfinite(miss)):
        unseen = np.degrees(np.arctan2(np.hypot(check.rays[:, 0], check.rays[:, 1]), check.rays[:, 2]))[
            ~np.isfinite(miss)
        ]
        raise PanomapError(
            f"{format} cannot hold this camera: the best {model.name} model does not see its rays from "
            f"{unseen.min():.1f} deg from the axis on (the table reaches {math.degrees(check.max_angle_rad):.1f} "
            "deg); make the table's range smaller (import --outer-radius) or choose another format"
        )
    max_error = float(np.max(miss))
    _refuse_absurd(max_error, table.image_size, format, model.name)
    notes: list[str] = []
    if format == "kalibr-equidistant" and check.max_angle_rad >= math.pi / 2:
        notes.append(
            "Kalibr's own pinhole projection divides by z: it handles only this camera's rays in front of it "
            "(below 90 deg); the file's equations hold beyond"
        )
    assert table.image_size is not None
    if kind == "ocam":
        assert isinstance(model, OCam)
        text = ocam_text(model)
    elif kind == "kalibr":
        text = kalibr_text(model, table.image_size)
    else:
        text = opencv_text(model, table.image_size, path)
    write_text_atomic(path, text)
    return Exported(model, text, max_error, tuple(notes))
