"""Terms beyond the radial law: where a real sensor's pixel departs from ``centre + f_r (cos phi, sin phi)``.

Convention: pixels (u, v) px as in :mod:`panomap.geometry`; an *offset* (..., 2) is a pixel minus the image
centre (u0, v0), px. The radial model gives the offset ``(x, y) = f_r(rho) (cos phi, sin phi)``; the terms
move it to the pixel's offset ``(du, dv)``:

- ``decentering`` ``(p1, p2)``, dimensionless (Brown-Conrady's tangential terms, OpenCV's p1, p2), on the
  offset scaled by ``radius_px`` (``xn = x / R``, ``yn = y / R``, ``rn^2 = xn^2 + yn^2``)::

      xt = x + R (2 p1 xn yn + p2 (rn^2 + 2 xn^2))
      yt = y + R (p1 (rn^2 + 2 yn^2) + 2 p2 xn yn)

- ``field`` ``(s1, s2, s3, s4)``, dimensionless (OpenCV's thin-prism terms): a smooth field over the image
  that is not radial, added to the decentred offset::

      xt += R (s1 rn^2 + s2 rn^4),    yt += R (s3 rn^2 + s4 rn^4)

  On boards that leave the image's middle empty (a mirror's annulus) it trades with the centre and the
  boards' poses: its move within the image circle is bounded (``MAX_FIELD``) rather than its coefficients.

- ``smooth`` ``(cx_20 .. cx_03, cy_20 .. cy_12)``, dimensionless: a general low-order field over the image,
  the monomials ``xn^i yn^j`` of degree 2 and 3 (:data:`SMOOTH_POWERS`), added to the decentred offset::

      xt += R sum_k cx_k xn^i_k yn^j_k,    yt += R sum_k cy_k xn^i_k yn^j_k

  but y's ``yn^3``: without it the field holds no radial cubic ``rn^2 (xn, yn)``, which is the radial law's
  (a fit that frees both runs along it, tens of px each way). Its move within the image circle is bounded
  (``MAX_SMOOTH``), and the map it makes must not fold there (its Jacobian's determinant at least
  ``MIN_SMOOTH_DET``): it grows as the cube of the radius beyond the boards, where no corner holds it.

  It holds the decentering's and the field's quadratic parts, so it is chosen instead of them, never with
  them (:mod:`panomap.calibrate.boards.terms`).

- ``aspect`` (a ratio, 1 for square pixels, OpenCV's fx / fy) and ``skew`` (px of u per px of v), an affine
  map of the image plane as OCamCalib's ``c, d, e``::

      du = aspect xt + skew yt,    dv = yt

A general affine map of the plane has four degrees of freedom; its scale is the radial law's and its turn
about the centre the azimuth's (a board's pose turns with it), which leaves these two. Each kind of term is
declared once in :data:`TERM_KINDS`, with its parameters in order; :class:`ImageTerms` holds the values of
those a camera keeps (identity where none is kept). Without terms a camera is rotationally symmetric about
its centre, as the paper's model is.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import PanomapError
from ..geometry import FloatArray

# Newton steps that undo the decentering and field terms, and the step (in units of radius_px) where they stop.
UNDO_STEPS = 30
UNDO_TOLERANCE = 1e-12
# The largest terms a camera may hold: beyond them the map may fold over within the image (a fit that runs
# there has found no sensor's error but a degenerate solution).
MAX_ASPECT_OFFSET = 0.2
MAX_SKEW = 0.2
MAX_DECENTERING = 0.05
# The field's largest move within the image circle, in units of R (its coefficients alone may be larger).
MAX_FIELD = 0.02
# The smooth field's largest move within the image circle (units of R) and the least determinant of its map there.
MAX_SMOOTH = 0.1
MIN_SMOOTH_DET = 0.5
# The smooth field's monomials (i, j): xn^i yn^j, degree 2 then 3, for x; y's, all but yn^3 (module docstring).
SMOOTH_POWERS = ((2, 0), (1, 1), (0, 2), (3, 0), (2, 1), (1, 2), (0, 3))
SMOOTH_TERMS = tuple(("x", i, j) for i, j in SMOOTH_POWERS) + tuple(("y", i, j) for i, j in SMOOTH_POWERS[:-1])


@dataclass(frozen=True)
class TermKind:
    """A kind of term: its name, its parameters in order (with their identity values) and what it models."""

    name: str
    parameters: tuple[str, ...]
    identity: tuple[float, ...]
    description: str


TERM_KINDS: dict[str, TermKind] = {
    kind.name: kind
    for kind in (
        TermKind("aspect", ("aspect",), (1.0,), "pixels taller or wider than square (fx / fy)"),
        TermKind("skew", ("skew",), (0.0,), "the sensor's columns not at right angles to its rows"),
        TermKind("decentering", ("p1", "p2"), (0.0, 0.0), "a lens or mirror off the sensor's axis (p1, p2)"),
        TermKind(
            "field", ("s1", "s2", "s3", "s4"), (0.0,) * 4, "a smooth field over the image, not radial (thin prism)"
        ),
        TermKind(
            "smooth",
            tuple(f"c{axis}{i}{j}" for axis, i, j in SMOOTH_TERMS),
            (0.0,) * len(SMOOTH_TERMS),
            "a general field over the image, the monomials of degree 2 and 3 (but y's yn^3)",
        ),
    )
}
TERMS = tuple(TERM_KINDS)


def check_term_names(names: Sequence[str]) -> tuple[str, ...]:
    """``names`` as a tuple in :data:`TERMS` order, each known and given once."""
    for name in names:
        if name not in TERM_KINDS:
            raise PanomapError(f"unknown image term {name!r} (known: {', '.join(TERMS)})")
    if len(set(names)) != len(names):
        raise PanomapError(f"an image term is given twice in {', '.join(names)}")
    return tuple(name for name in TERMS if name in names)


def parameter_count(names: Sequence[str]) -> int:
    """How many values the terms ``names`` hold."""
    return sum(len(TERM_KINDS[name].parameters) for name in names)


@dataclass(frozen=True)
class ImageTerms:
    """The terms a camera keeps beyond its radial law, and their values.

    Parameters
    ----------
    kept : tuple of str
        The kinds kept, in :data:`TERMS` order (empty: the identity).
    values : tuple of float
        Their parameters in that order (``aspect``; ``skew``; ``p1, p2``; ``s1..s4``).
    radius_px : float
        R, px: the scale of the offsets in the decentering terms (the image circle's radius), > 0.
    """

    kept: tuple[str, ...] = ()
    values: tuple[float, ...] = ()
    radius_px: float = 1.0

    def __post_init__(self) -> None:
        kept = check_term_names(self.kept)
        if kept != tuple(self.kept):
            raise PanomapError(f"image terms must be listed in the order {', '.join(TERMS)}")
        values = tuple(float(v) for v in self.values)
        if len(values) != parameter_count(kept):
            raise PanomapError(f"image terms {', '.join(kept) or '(none)'} take {parameter_count(kept)} values")
        if not all(math.isfinite(v) for v in values):
            raise PanomapError("an image term is not finite")
        if not (math.isfinite(self.radius_px) and self.radius_px > 0):
            raise PanomapError(f"the image terms' radius must be positive, not {self.radius_px!r}")
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "radius_px", float(self.radius_px))

    def beyond_limits(self) -> str | None:
        """Which value lies beyond its limit (the map may fold within the image there), in words; None if none."""
        limits = {"aspect": MAX_ASPECT_OFFSET, "skew": MAX_SKEW, "p1": MAX_DECENTERING, "p2": MAX_DECENTERING}
        named = self.named()
        for axis, (a, b) in (("x", ("s1", "s2")), ("y", ("s3", "s4"))):
            t = np.linspace(0.0, 1.0, 101)  # rn^2 within the image circle: the field's move there, in units of R
            largest = float(np.max(np.abs(named[a] * t + named[b] * t * t)))
            if largest > MAX_FIELD:
                return f"the image field moves {axis} {largest:.3g} R within the image circle (limit {MAX_FIELD} R)"
        if "smooth" in self.kept:
            disc = _disc_points()
            largest = float(np.max(np.hypot(*_smooth_move(disc, named).T)))
            if largest > MAX_SMOOTH:
                return f"the smooth field moves {largest:.3g} R within the image circle (limit {MAX_SMOOTH} R)"
            least = float(np.min(np.linalg.det(self.jacobian(disc * self.radius_px))))
            if least < MIN_SMOOTH_DET:
                return f"the smooth field folds the image within its circle (determinant {least:.3g})"
        for name, value in named.items():
            if name in TERM_KINDS["field"].parameters or name in TERM_KINDS["smooth"].parameters:
                continue
            offset = value - 1.0 if name == "aspect" else value
            if abs(offset) > limits[name]:
                return f"the image term {name} = {value:g} is beyond {limits[name]:g} of its identity"
        return None

    @classmethod
    def identity(cls, radius_px: float = 1.0) -> ImageTerms:
        return cls((), (), radius_px)

    @classmethod
    def of(cls, kept: Sequence[str], values: ArrayLike, radius_px: float) -> ImageTerms:
        """The terms ``kept`` (any order) with ``values`` in :data:`TERMS` order."""
        return cls(check_term_names(kept), tuple(float(v) for v in np.ravel(values)), radius_px)

    @property
    def is_identity(self) -> bool:
        return not self.kept

    def named(self) -> dict[str, float]:
        """Every parameter by name: the kept ones' values, the others' identity."""
        out: dict[str, float] = {}
        values = iter(self.values)
        for name, kind in TERM_KINDS.items():
            for parameter, identity in zip(kind.parameters, kind.identity, strict=True):
                out[parameter] = next(values) if name in self.kept else identity
        return out

    def apply(self, offsets: ArrayLike) -> FloatArray:
        """Offsets (..., 2) px of the pixels from the radial model's offsets (..., 2) px."""
        xy = np.asarray(offsets, dtype=np.float64)
        if self.is_identity:
            return xy.copy()
        p = self.named()
        xt, yt = _decentred(xy[..., 0], xy[..., 1], p, self.radius_px)
        return np.stack([p["aspect"] * xt + p["skew"] * yt, yt], axis=-1)

    def undo(self, offsets: ArrayLike) -> FloatArray:
        """The radial model's offsets (..., 2) px of pixels' offsets (..., 2) px: the inverse of :meth:`apply`.

        The affine part in closed form, the decentering and the field by Newton steps (at most ``UNDO_STEPS``);
        NaN where they do not converge (a pixel far beyond the image, where the terms fold).
        """
        uv = np.asarray(offsets, dtype=np.float64)
        if self.is_identity:
            return uv.copy()
        p = self.named()
        yt = uv[..., 1]
        xt = (uv[..., 0] - p["skew"] * yt) / p["aspect"]
        if all(p[q] == 0.0 for q in ("p1", "p2", *TERM_KINDS["field"].parameters, *TERM_KINDS["smooth"].parameters)):
            return np.stack([xt, yt], axis=-1)
        big = self.radius_px
        x, y = xt.copy(), yt.copy()
        done = np.zeros(x.shape, dtype=bool)
        with np.errstate(invalid="ignore", over="ignore"):
            for _ in range(UNDO_STEPS):
                fx, fy = _decentred(x, y, p, big)
                ex, ey = fx - xt, fy - yt
                (a, b), (c, d) = _decentring_jacobian(x, y, p, big)
                det = a * d - b * c
                sx = (d * ex - b * ey) / det
                sy = (a * ey - c * ex) / det
                x, y = x - sx, y - sy
                done = np.hypot(sx, sy) <= UNDO_TOLERANCE * big
                if np.all(done | ~np.isfinite(x)):
                    break
        good = done & np.isfinite(x) & np.isfinite(y)
        return np.stack([np.where(good, x, np.nan), np.where(good, y, np.nan)], axis=-1)

    def jacobian(self, offsets: ArrayLike) -> FloatArray:
        """d(pixel offset) / d(radial offset), (..., 2, 2): rows du, dv; columns d/dx, d/dy."""
        xy = np.asarray(offsets, dtype=np.float64)
        p = self.named()
        (a, b), (c, d) = _decentring_jacobian(xy[..., 0], xy[..., 1], p, self.radius_px)
        aspect, skew = p["aspect"], p["skew"]
        return np.stack(
            [np.stack([aspect * a + skew * c, aspect * b + skew * d], axis=-1), np.stack([c, d], axis=-1)], axis=-2
        )

    def parameter_jacobian(self, offsets: ArrayLike) -> FloatArray:
        """d(pixel offset) / d(the kept values), (..., 2, len(values)), at radial offsets (..., 2)."""
        xy = np.asarray(offsets, dtype=np.float64)
        p = self.named()
        x, y, big = xy[..., 0], xy[..., 1], self.radius_px
        xt, yt = _decentred(x, y, p, big) if {"aspect", "skew"} & set(self.kept) else (x, y)
        zero = np.zeros_like(x)
        columns: list[tuple[FloatArray, FloatArray]] = []
        for name in self.kept:
            if name == "aspect":
                columns.append((xt, zero))
            elif name == "skew":
                columns.append((yt, zero))
            elif name == "field":  # d(xt, yt) / d s1..s4, then the affine part
                r2 = (x * x + y * y) / big  # R rn^2
                r4 = r2 * r2 / big  # R rn^4
                for dxt, dyt in ((r2, zero), (r4, zero), (zero, r2), (zero, r4)):
                    columns.append((p["aspect"] * dxt + p["skew"] * dyt, dyt))
            elif name == "smooth":  # d(xt, yt) / d cx_k (x moved by R m_k), then / d cy_k, then the affine part
                xp, yp = _powers(x / big), _powers(y / big)
                moves = [(axis, big * xp[i] * yp[j]) for axis, i, j in SMOOTH_TERMS]
                for dxt, dyt in [(m, zero) if axis == "x" else (zero, m) for axis, m in moves]:
                    columns.append((p["aspect"] * dxt + p["skew"] * dyt, dyt))
            else:  # decentering: d(xt, yt)/d p1 and / d p2, then the affine part
                for dxt, dyt in (
                    (2 * x * y / big, (x * x + 3 * y * y) / big),
                    ((3 * x * x + y * y) / big, 2 * x * y / big),
                ):
                    columns.append((p["aspect"] * dxt + p["skew"] * dyt, dyt))
        if not columns:
            return np.zeros((*x.shape, 2, 0))
        return np.stack([np.stack(pair, axis=-1) for pair in columns], axis=-1)

    def largest_shift_px(self, radius_px: float) -> float:
        """The largest distance (px) the terms move a pixel within ``radius_px`` of the centre (sampled)."""
        if self.is_identity:
            return 0.0
        angle = np.linspace(0.0, 2 * math.pi, 361)
        ring = np.stack([np.cos(angle), np.sin(angle)], axis=-1)
        offsets = np.concatenate([ring * radius_px * f for f in (0.25, 0.5, 0.75, 1.0)])
        return float(np.max(np.hypot(*(self.apply(offsets) - offsets).T)))

    def describe(self) -> str:
        """The kept terms and their values in words (``none`` for the identity)."""
        if self.is_identity:
            return "none"
        p = self.named()
        return ", ".join(f"{q} {p[q]:.6g}" for name in self.kept for q in TERM_KINDS[name].parameters)

    def to_dict(self) -> dict[str, Any]:
        return {"kept": list(self.kept), "values": list(self.values), "radius_px": self.radius_px}

    @classmethod
    def from_dict(cls, data: Any) -> ImageTerms:
        try:
            terms = cls(tuple(str(k) for k in data["kept"]), tuple(data["values"]), float(data["radius_px"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise PanomapError(f"the image terms are malformed ({exc})") from None
        beyond = terms.beyond_limits()
        if beyond is not None:
            raise PanomapError(beyond)
        return terms


def _decentred(x: FloatArray, y: FloatArray, p: dict[str, float], big: float) -> tuple[FloatArray, FloatArray]:
    """The offsets (px) moved by the decentering and field terms (module docstring), at radial offsets x, y (px)
    with every parameter ``p`` (:meth:`ImageTerms.named`). A group of terms whose parameters are all zero (most
    fits free one group) is left out: it moves nothing, and its zeros cost a third of the terms' time."""
    xt, yt = x, y
    p1, p2 = p["p1"], p["p2"]
    if p1 != 0.0 or p2 != 0.0:
        xt = xt + (2 * p1 * x * y + p2 * (3 * x * x + y * y)) / big
        yt = yt + (p1 * (x * x + 3 * y * y) + 2 * p2 * x * y) / big
    if any(p[q] != 0.0 for q in TERM_KINDS["field"].parameters):
        r2 = (x * x + y * y) / big  # R rn^2
        r4 = r2 * r2 / big  # R rn^4
        xt = xt + p["s1"] * r2 + p["s2"] * r4
        yt = yt + p["s3"] * r2 + p["s4"] * r4
    if _smooth_kept(p):
        smooth = big * _smooth_move(np.stack([x / big, y / big], axis=-1), p)
        xt = xt + smooth[..., 0]
        yt = yt + smooth[..., 1]
    return xt, yt


def _smooth_kept(p: dict[str, float]) -> bool:
    """Whether any of the smooth field's coefficients in ``p`` is not zero."""
    return any(p[name] != 0.0 for name in TERM_KINDS["smooth"].parameters)


def _smooth_move(normalised: FloatArray, p: dict[str, float]) -> FloatArray:
    """The smooth field's move (..., 2), in units of R, at offsets (..., 2) in units of R."""
    move = np.zeros(normalised.shape, dtype=np.float64)
    if not _smooth_kept(p):
        return move
    xp, yp = _powers(normalised[..., 0]), _powers(normalised[..., 1])
    for axis, i, j in SMOOTH_TERMS:
        c = p[f"c{axis}{i}{j}"]
        if c != 0.0:
            move[..., 0 if axis == "x" else 1] += c * xp[i] * yp[j]
    return move


def _powers(values: FloatArray) -> list[FloatArray]:
    """``values ** k`` for k = 0 .. 3, the smooth field's monomials' factors (each power taken once: the field's
    moves and derivatives took a fifth of the fit's choice of terms raising the same offsets again)."""
    return [values**k for k in range(4)]


def _smooth_derivatives(xn: FloatArray, yn: FloatArray, p: dict[str, float]) -> tuple[FloatArray, ...]:
    """d(smooth move) / d(xn, yn) (dimensionless: the move and the offsets both in units of R):
    (dmx/dxn, dmx/dyn, dmy/dxn, dmy/dyn)."""
    out = [np.zeros(np.shape(xn)) for _ in range(4)]
    if not _smooth_kept(p):
        return tuple(out)
    xp, yp = _powers(xn), _powers(yn)
    for axis, i, j in SMOOTH_TERMS:
        c = p[f"c{axis}{i}{j}"]
        if c == 0.0:
            continue
        row = 0 if axis == "x" else 2
        out[row] = out[row] + c * i * xp[max(i - 1, 0)] * yp[j]
        out[row + 1] = out[row + 1] + c * j * xp[i] * yp[max(j - 1, 0)]
    return tuple(out)


def _disc_points() -> FloatArray:
    """Points (n, 2) over the unit disc (rings and spokes), where the smooth field's move is bounded."""
    radius, angle = np.meshgrid(np.linspace(0.0, 1.0, 21), np.linspace(0.0, 2 * math.pi, 72, endpoint=False))
    return np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=-1).reshape(-1, 2)


def _decentring_jacobian(
    x: FloatArray, y: FloatArray, p: dict[str, float], big: float
) -> tuple[tuple[FloatArray, FloatArray], tuple[FloatArray, FloatArray]]:
    """d(xt, yt) / d(x, y) of :func:`_decentred`: ((dxt/dx, dxt/dy), (dyt/dx, dyt/dy)); a group of terms whose
    parameters are all zero is left out, as there."""
    p1, p2 = p["p1"], p["p2"]
    if p1 != 0.0 or p2 != 0.0:
        cross = (2 * p1 * x + 2 * p2 * y) / big
        a, b, c, d = 1 + (2 * p1 * y + 6 * p2 * x) / big, cross, cross, 1 + (6 * p1 * y + 2 * p2 * x) / big
    else:
        a, d = np.ones(np.shape(x)), np.ones(np.shape(x))
        b, c = np.zeros(np.shape(x)), np.zeros(np.shape(x))
    if any(p[q] != 0.0 for q in TERM_KINDS["field"].parameters):
        rn2 = (x * x + y * y) / (big * big)
        fx = (2 * p["s1"] + 4 * p["s2"] * rn2) / big  # d(field's x)/dx = fx x, /dy = fx y
        fy = (2 * p["s3"] + 4 * p["s4"] * rn2) / big
        a, b, c, d = a + fx * x, b + fx * y, c + fy * x, d + fy * y
    if _smooth_kept(p):
        sxx, sxy, syx, syy = _smooth_derivatives(x / big, y / big, p)
        a, b, c, d = a + sxx, b + sxy, c + syx, d + syy
    return (a, b), (c, d)
