"""Which image terms beyond the radial law a fit kept, and why: the record a table's ``info`` carries.

Convention: RMS in px; term names as :data:`panomap.camera.image_terms.TERMS`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ...camera.image_terms import TERM_KINDS, check_term_names
from ...errors import PanomapError


@dataclass(frozen=True)
class TermChoice:
    """The image terms kept, and why.

    Attributes
    ----------
    kept : tuple of str
        The terms kept (:data:`panomap.camera.image_terms.TERMS` order).
    tried : tuple of (tuple of str, float)
        Each set of terms tried and its held-out RMS (px; inf where a fold's fit failed), in the order tried.
    folds : int
        Folds of images (0: no choice made, ``reason`` says why).
    reason : str
        Why these terms, in words.
    values : tuple of float
        The kept terms' values fitted to all the images (their parameters in order; empty without terms).
    """

    kept: tuple[str, ...]
    tried: tuple[tuple[tuple[str, ...], float], ...]
    folds: int
    reason: str
    values: tuple[float, ...] = ()

    def held_out_rms_px(self, terms: Sequence[str]) -> float | None:
        """The held-out RMS (px) of the set ``terms``, None where it was not tried."""
        key = check_term_names(terms)
        return next((rms for names, rms in self.tried if names == key), None)

    def sentence(self) -> str:
        parameters = [q for name in self.kept for q in TERM_KINDS[name].parameters]
        kept = ", ".join(f"{q} {v:.5g}" for q, v in zip(parameters, self.values, strict=False)) or ", ".join(self.kept)
        return f"image terms beyond the radial law: {kept or 'none'} ({self.reason})"

    def to_dict(self) -> dict[str, Any]:
        return {
            "kept": list(self.kept),
            "tried": [{"terms": list(names), "held_out_rms_px": _finite_or_none(rms)} for names, rms in self.tried],
            "folds": self.folds,
            "reason": self.reason,
            "values": list(self.values),
        }

    @classmethod
    def from_dict(cls, data: Any) -> TermChoice:
        try:
            tried = tuple(
                (
                    check_term_names([str(n) for n in item["terms"]]),
                    math.inf if item["held_out_rms_px"] is None else float(item["held_out_rms_px"]),
                )
                for item in data["tried"]
            )
            kept = check_term_names([str(n) for n in data["kept"]])
            values = tuple(float(v) for v in data.get("values", ()))
            return cls(kept, tried, int(data["folds"]), str(data["reason"]), values)
        except (KeyError, TypeError, ValueError) as exc:
            raise PanomapError(f"the image terms' choice is malformed ({exc})") from None


def _finite_or_none(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None
