"""The pano-mapping table (paper 2.2, Algorithm 2): creation, sampling and its file.

Convention: entry (i, j), ``i = 0..M-1`` in azimuth and ``j = 0..N-1`` in
elevation, holds the pixel (u_ij, v_ij) of the ray with
``theta_i = 2*pi*i/M`` and ``rho_j = rho_s + j*(rho_e - rho_s)/N`` (eqs. 5-8).
``entries`` has shape (M, N, 2), float32, in (u, v) order.

Sampling at fractional indices ``fi = theta*M/(2*pi)``,
``fj = (rho - rho_s)*N/(rho_e - rho_s)``:

- ``bilinear`` (default): linear in both, wrapping in azimuth. The table has no
  entry at rho_e itself, so the last cell [rho_{N-1}, rho_e] continues the
  line through the last two entries.
- ``nearest``: floor indices, exactly the paper's eqs. (9), (12), (19), (22).

Rays outside [rho_s, rho_e], or landing outside the image, get NaN.

File: a NumPy ``.npz`` holding ``entries`` and ``meta`` (JSON text with
``format = "panomap-table"``, ``version``, the model, the elevation range,
radii, image size, camera position, the landmarks and the fit report, and the
SHA-256 of ``entries``). Loading checks all of it and that the entries are
what the model gives.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import PanomapError
from .files import write_with
from .fit import CameraFit
from .geometry import TWO_PI, FloatArray, azimuth_elevation
from .model import CameraModel
from .radial import valid_elevation_range

TABLE_FORMAT = "panomap-table"
TABLE_VERSION = 1
SAMPLINGS = ("bilinear", "nearest")
MAX_TABLE_ENTRIES = 50_000_000
# Default sizes stop here: bilinear sampling is then within 1e-3 px of the model.
DEFAULT_MAX_SIZE = (4096, 1024)
# Entries are float32: about 1e-4 px at radii of 2000 px. A loaded table whose
# entries stray further than this from its own model is corrupt.
ENTRY_TOLERANCE_PX = 1e-2


@dataclass(frozen=True)
class PanoMappingTable:
    """An M x N pano-mapping table and what it was made from.

    Parameters
    ----------
    entries : (M, N, 2) float32 ndarray
        Pixel (u, v) of entry (i, j).
    elevation_range : (rho_s, rho_e)
        Elevations (rad) of the table's first row and of the end of its last.
    model : CameraModel
        The fitted model the entries were filled from.
    camera_position : (X0, Y0, Z0)
        O_m in world units.
    image_size : (width, height) or None
        Size of the omni-images this table is for.
    cutoff_radius, outer_radius : float
        The visible annulus, px.
    info : dict
        Provenance (where the centre and radii came from) and the fit report.
    """

    entries: NDArray[np.float32]
    elevation_range: tuple[float, float]
    model: CameraModel
    camera_position: tuple[float, float, float]
    image_size: tuple[int, int] | None
    cutoff_radius: float
    outer_radius: float
    info: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        entries = np.ascontiguousarray(self.entries, dtype=np.float32)
        if entries.ndim != 3 or entries.shape[2] != 2 or entries.shape[0] < 2 or entries.shape[1] < 2:
            raise PanomapError(f"table entries must have shape (M, N, 2) with M, N >= 2, not {entries.shape}")
        rho_s, rho_e = (float(x) for x in self.elevation_range)
        if not (-math.pi / 2 - 1e-9 <= rho_s < rho_e <= math.pi / 2 + 1e-9):
            raise PanomapError(f"table elevation range {rho_s}..{rho_e} rad is not an interval in [-pi/2, pi/2]")
        entries.setflags(write=False)
        object.__setattr__(self, "entries", entries)
        object.__setattr__(self, "elevation_range", (rho_s, rho_e))

    @property
    def size(self) -> tuple[int, int]:
        """(M, N): entries in azimuth and in elevation."""
        return int(self.entries.shape[0]), int(self.entries.shape[1])

    def azimuths(self) -> FloatArray:
        """theta_i = 2*pi*i/M (rad), eq. (5); shape (M,)."""
        m = self.size[0]
        return TWO_PI * np.arange(m) / m

    def elevations(self) -> FloatArray:
        """rho_j = rho_s + j*(rho_e - rho_s)/N (rad), eq. (6); shape (N,)."""
        n = self.size[1]
        rho_s, rho_e = self.elevation_range
        return rho_s + np.arange(n) * (rho_e - rho_s) / n

    def sample(self, theta: ArrayLike, rho: ArrayLike, sampling: str = "bilinear") -> FloatArray:
        """Pixels (..., 2) of rays (azimuth, elevation in rad) read from the table.

        NaN where ``rho`` is outside the table's range, the ray is NaN, or the
        pixel falls outside the image.
        """
        if sampling not in SAMPLINGS:
            raise PanomapError(f"table sampling must be bilinear or nearest, not {sampling!r}")
        theta = np.asarray(theta, dtype=np.float64)
        rho = np.asarray(rho, dtype=np.float64)
        m, n = self.size
        rho_s, rho_e = self.elevation_range
        fi = np.mod(theta, TWO_PI) * (m / TWO_PI)
        fj = (rho - rho_s) * (n / (rho_e - rho_s))
        valid = np.isfinite(fi) & np.isfinite(fj) & (fj >= 0) & (fj <= n)
        fi = np.where(valid, fi, 0.0)
        fj = np.where(valid, fj, 0.0)
        floor_i = np.floor(fi)
        i0 = floor_i.astype(np.intp) % m
        if sampling == "nearest":
            j0 = np.minimum(np.floor(fj).astype(np.intp), n - 1)
            uv = self.entries[i0, j0].astype(np.float64)
        else:
            j0 = np.minimum(np.floor(fj).astype(np.intp), n - 2)
            wi = (fi - floor_i)[..., None]
            wj = (fj - j0)[..., None]
            i1 = (i0 + 1) % m
            e = self.entries
            uv = (1 - wj) * ((1 - wi) * e[i0, j0] + wi * e[i1, j0]) + wj * (
                (1 - wi) * e[i0, j0 + 1] + wi * e[i1, j0 + 1]
            )
        if self.image_size is not None:
            width, height = self.image_size
            u, v = uv[..., 0], uv[..., 1]
            valid &= (u >= -0.5) & (u <= width - 0.5) & (v >= -0.5) & (v <= height - 0.5)
        return np.where(valid[..., None], uv, np.nan)

    def project(self, points: ArrayLike, sampling: str = "bilinear") -> FloatArray:
        """Pixels (..., 2) of world points (..., 3) through the table; NaN where not visible."""
        d = np.asarray(points, dtype=np.float64) - np.asarray(self.camera_position)
        theta, rho = azimuth_elevation(d)
        return self.sample(theta, rho, sampling)

    def metadata(self) -> dict[str, Any]:
        """Everything but the entries, as JSON-ready data (angles in rad)."""
        m, n = self.size
        return {
            "format": TABLE_FORMAT,
            "version": TABLE_VERSION,
            "size": [m, n],
            "elevation_range_rad": list(self.elevation_range),
            "model": self.model.to_dict(),
            "camera_position": list(self.camera_position),
            "image_size": None if self.image_size is None else list(self.image_size),
            "cutoff_radius_px": self.cutoff_radius,
            "outer_radius_px": self.outer_radius,
            "info": self.info,
        }

    def save(self, path: str | Path) -> None:
        """Write the table to ``path`` (an ``.npz``), through a temporary file."""
        meta = self.metadata() | {"entries_sha256": _digest(self.entries)}
        text = json.dumps(meta, indent=1, allow_nan=False)

        def writer(handle: Any) -> None:
            np.savez(handle, entries=self.entries, meta=np.array(text))

        write_with(path, writer)


def fill_entries(
    model: CameraModel, size: tuple[int, int], elevation_range: tuple[float, float]
) -> NDArray[np.float32]:
    """Algorithm 2: entries (M, N, 2) float32 of the table of ``model``.

    ``u_ij = u0 + r_j cos(phi_i)``, ``v_ij = v0 + r_j sin(phi_i)`` with
    ``r_j = f_r(rho_j)`` and ``phi_i = s*theta_i + phi0`` (eqs. 5-8, plus the
    centre and azimuth mapping of the conventions).
    """
    m, n = size
    rho_s, rho_e = elevation_range
    theta = TWO_PI * np.arange(m) / m
    rho = rho_s + np.arange(n) * (rho_e - rho_s) / n
    r = model.radial(rho)
    phi = model.image_angle(theta)
    u0, v0 = model.centre
    entries = np.empty((m, n, 2), dtype=np.float32)
    entries[..., 0] = u0 + np.cos(phi)[:, None] * r[None, :]
    entries[..., 1] = v0 + np.sin(phi)[:, None] * r[None, :]
    return entries


def check_table_size(size: tuple[int, int], what: str = "--size") -> tuple[int, int]:
    """Validate an (M, N) table size."""
    m, n = (int(x) for x in size)
    if m < 4 or n < 2:
        raise PanomapError(f"{what} {m}x{n}: a table needs M >= 4 and N >= 2")
    if m * n > MAX_TABLE_ENTRIES:
        raise PanomapError(f"{what} {m}x{n}: {m * n:,} entries is more than the limit of {MAX_TABLE_ENTRIES:,}")
    return m, n


def create_table(
    fit: CameraFit,
    *,
    size: tuple[int, int] | None = None,
    image_size: tuple[int, int] | None = None,
    cutoff_radius: float | None = None,
    outer_radius: float | None = None,
    info: dict[str, Any] | None = None,
) -> PanoMappingTable:
    """Make the pano-mapping table of a fitted camera.

    Parameters
    ----------
    fit : CameraFit
        The landmark fit.
    size : (M, N), optional
        Default: about one entry per pixel along the image circle (M) and
        along the radius (N).
    image_size : (width, height), optional
        The omni-images' size; limits the default outer radius and marks
        pixels outside the image invalid.
    cutoff_radius : float, optional
        Radius (px) of the self-occlusion disc; default 0 (none).
    outer_radius : float, optional
        Radius (px) of the image circle; default the largest circle about the
        centre inside the image (or reaching the farthest landmark, if that is
        further), or the farthest landmark when there is no image size.

    The elevation range runs from the cut-off radius to the outer radius,
    narrowed to where f_r is monotonic and around the landmarks.
    """
    u0, v0 = fit.model.centre
    r_landmarks = np.hypot(fit.landmarks.pixels[:, 0] - u0, fit.landmarks.pixels[:, 1] - v0)
    sources = dict(info.get("sources", {})) if info else {}
    if cutoff_radius is None:
        cutoff_radius = 0.0
        sources.setdefault("cutoff_radius", "default (none)")
    else:
        sources.setdefault("cutoff_radius", "given")
    if outer_radius is None:
        if image_size is not None:
            width, height = image_size
            inscribed = min(u0 + 0.5, v0 + 0.5, width - 0.5 - u0, height - 0.5 - v0)
            outer_radius = max(float(inscribed), float(r_landmarks.max()))
            sources.setdefault("outer_radius", "default (largest circle inside the image)")
        else:
            outer_radius = float(r_landmarks.max())
            sources.setdefault("outer_radius", "default (farthest landmark)")
    else:
        sources.setdefault("outer_radius", "given")
    cutoff_radius, outer_radius = float(cutoff_radius), float(outer_radius)
    if not (math.isfinite(cutoff_radius) and math.isfinite(outer_radius)) or not 0 <= cutoff_radius < outer_radius:
        raise PanomapError(
            f"the cut-off radius ({cutoff_radius:g} px) must be >= 0 and below the outer radius ({outer_radius:g} px)"
        )
    rho_s, rho_e = valid_elevation_range(fit.model.radial, fit.landmark_range, cutoff_radius, outer_radius)
    if size is None:
        r_span = abs(float(fit.model.radial(rho_e) - fit.model.radial(rho_s)))
        reach = max(float(np.nanmax(np.abs(fit.model.radial(np.array([rho_s, rho_e]))))), 1.0)
        m = min(8 * math.ceil(TWO_PI * reach / 8), DEFAULT_MAX_SIZE[0])
        size = (max(m, 16), min(max(math.ceil(r_span), 16), DEFAULT_MAX_SIZE[1]))
    size = check_table_size(size)
    entries = fill_entries(fit.model, size, (rho_s, rho_e))
    table_info = dict(info or {})
    table_info["sources"] = sources
    table_info["fit"] = fit.report()
    return PanoMappingTable(
        entries=entries,
        elevation_range=(rho_s, rho_e),
        model=fit.model,
        camera_position=fit.camera_position,
        image_size=image_size,
        cutoff_radius=cutoff_radius,
        outer_radius=outer_radius,
        info=table_info,
    )


def _digest(entries: NDArray[np.float32]) -> str:
    return hashlib.sha256(np.ascontiguousarray(entries, dtype="<f4").tobytes()).hexdigest()


def load_table(path: str | Path) -> PanoMappingTable:
    """Read a table file, checking its format, version and contents.

    Raises
    ------
    PanomapError
        Naming the file, when it is missing, not a table, corrupt or
        truncated, of another version, or its entries disagree with its model.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise PanomapError("no such table file", path) from None
    except OSError as exc:
        raise PanomapError(f"cannot read it ({exc.strerror or exc})", path) from None
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as archive:
            names = set(archive.files)
            if not {"entries", "meta"} <= names:
                raise PanomapError("not a panomap table (no entries/meta inside)", path)
            meta_text = str(archive["meta"][()])
            entries = archive["entries"]
    except PanomapError:
        raise
    except (zipfile.BadZipFile, EOFError, ValueError, OSError, KeyError, zipfile.LargeZipFile) as exc:
        raise PanomapError(
            f"not a readable panomap table: corrupt or truncated ({exc.__class__.__name__})", path
        ) from None
    try:
        meta = json.loads(meta_text)
    except json.JSONDecodeError:
        raise PanomapError("the table's metadata is not valid JSON (corrupt)", path) from None
    if not isinstance(meta, dict) or meta.get("format") != TABLE_FORMAT:
        raise PanomapError("not a panomap table (wrong format tag)", path)
    if meta.get("version") != TABLE_VERSION:
        raise PanomapError(
            f"table format version {meta.get('version')!r}; this panomap reads version {TABLE_VERSION}", path
        )
    try:
        return _table_from(meta, entries)
    except PanomapError as exc:
        raise PanomapError(exc.detail, path) from None


def _table_from(meta: dict[str, Any], entries: NDArray[Any]) -> PanoMappingTable:
    try:
        m, n = (int(x) for x in meta["size"])
        if entries.dtype != np.float32 or entries.shape != (m, n, 2):
            raise PanomapError(
                f"entries have shape {entries.shape} {entries.dtype}, metadata says ({m}, {n}, 2) float32"
            )
        if meta.get("entries_sha256") != _digest(entries):
            raise PanomapError("the entries do not match their checksum (corrupt)")
        model = CameraModel.from_dict(meta["model"])
        rho_s, rho_e = (float(x) for x in meta["elevation_range_rad"])
        image_size = meta["image_size"]
        table = PanoMappingTable(
            entries=entries,
            elevation_range=(rho_s, rho_e),
            model=model,
            camera_position=tuple(float(x) for x in meta["camera_position"]),  # type: ignore[arg-type]
            image_size=None if image_size is None else (int(image_size[0]), int(image_size[1])),
            cutoff_radius=float(meta["cutoff_radius_px"]),
            outer_radius=float(meta["outer_radius_px"]),
            info=dict(meta.get("info") or {}),
        )
    except PanomapError:
        raise
    except (KeyError, TypeError, ValueError) as exc:
        raise PanomapError(
            f"the table's metadata is incomplete or malformed ({exc.__class__.__name__}: {exc})"
        ) from None
    expected = fill_entries(table.model, (m, n), table.elevation_range)
    if not np.all(np.isfinite(entries)) or float(np.max(np.abs(expected - entries))) > ENTRY_TOLERANCE_PX:
        raise PanomapError("the entries disagree with the table's own model (corrupt)")
    return table
