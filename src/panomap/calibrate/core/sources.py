"""Where each input of a table came from: its provenance, stored in the table's ``info["sources"]``.

The texts are part of the table file: ``panomap info`` prints them, and files
made by earlier versions hold them.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping
from dataclasses import dataclass

# The quantities a table records the provenance of.
QUANTITIES = ("camera_position", "centre", "cutoff_radius", "outer_radius")


class Source(enum.Enum):
    """Where a camera position, centre or radius came from; the value is its text in the table."""

    GIVEN = "given"
    LANDMARK_FILE = "landmark file"
    DETECTED = "detected"
    DETECTED_NONE = "detected: none (no self-occlusion disc)"
    FRAME_CENTRE = "frame centre (no image circle found)"
    SET_IN_LEARN = "set in panomap learn"
    DEFAULT_NONE = "default (none)"
    DEFAULT_INSIDE_IMAGE = "default (largest circle inside the image)"
    DEFAULT_FARTHEST_LANDMARK = "default (farthest landmark)"
    DEFAULT_WHOLE_FRAME = "default (the whole frame: no image circle in it)"
    CUTOFF_DISC_CENTRE = "the cut-off disc's centre (no rim in the frame)"

    @property
    def is_estimate(self) -> bool:
        """True for a centre that only starts the fit: found in the image, or the frame's middle."""
        return self in (Source.DETECTED, Source.FRAME_CENTRE, Source.CUTOFF_DISC_CENTRE)

    @property
    def is_default(self) -> bool:
        """True for a value the table chose for itself, that no one gave or detected."""
        return self in (
            Source.DEFAULT_NONE,
            Source.DEFAULT_INSIDE_IMAGE,
            Source.DEFAULT_FARTHEST_LANDMARK,
            Source.DEFAULT_WHOLE_FRAME,
        )


@dataclass(frozen=True)
class Origin:
    """A :class:`Source`, and whether the fit then refined the value (the centre, with the landmarks)."""

    source: Source
    refined: bool = False

    def __str__(self) -> str:
        return self.source.value + (", refined with the landmarks" if self.refined else "")


def source_texts(sources: Mapping[str, Origin]) -> dict[str, str]:
    """The provenance as the table stores it: quantity -> text, in the order recorded."""
    return {name: str(origin) for name, origin in sources.items()}
