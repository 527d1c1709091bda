"""A rig: several cameras, a pano-mapping table each, in one world frame (a 360 camera, a car's surround view).

Convention (docs/conventions.md, "A rig"): every camera's table is in the world frame, with its own position
O_m (``table.camera_position``) and orientation (``table.model``: :mod:`panomap.camera.orientation`). Its
pictures come one per camera, in the rig's order, or in one frame holding them all: camera k's picture is then
the rectangle of ``table.image_size`` whose top-left pixel is ``offsets[k]`` in the frame (a dual-fisheye frame
holds its cameras side by side, camera 0 on the left).
"""

from __future__ import annotations

import math
import unicodedata
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import PanomapError, printable
from ..geometry import FloatArray
from ..table.table import PanoMappingTable, check_table

# At most this many cameras in a rig.
MAX_CAMERAS = 16

# A camera's name is at most this long: it goes into file names (a view's file for each camera).
MAX_NAME_CHARS = 64


def check_camera_name(name: str) -> str:
    """``name`` where it can name a camera: 1 to :data:`MAX_NAME_CHARS` characters, not blank, ``.`` or ``..``,
    without a path separator or a control character (a camera's name goes into file names: ``cams/{camera}.png``
    must not leave its folder)."""
    bad = [char for char in name if char in "/\\" or unicodedata.category(char) in ("Cc", "Cf", "Zl", "Zp")]
    if bad or not name.strip() or name in (".", "..") or len(name) > MAX_NAME_CHARS:
        shown = f"'{printable(name[:MAX_NAME_CHARS])}" + ("...'" if len(name) > MAX_NAME_CHARS else "'")
        raise PanomapError(
            f"camera name {shown} cannot name a file: 1 to {MAX_NAME_CHARS} characters, no / or \\, no control "
            "characters, not blank, . or .."
        )
    return name


@dataclass(frozen=True)
class CameraRig:
    """Several cameras in one world frame.

    Parameters
    ----------
    tables : tuple of PanoMappingTable
        One per camera, in the rig's order; each with its image size.
    names : tuple of str
        The cameras' names (``cam0``...), unique.
    offsets : tuple of (x, y), optional
        Where each camera's picture sits in one frame holding them all (px, its top-left pixel); None: each
        camera's picture is its own image.
    info : dict
        Where the rig came from (its calibration file, how its world was placed).
    """

    tables: tuple[PanoMappingTable, ...]
    names: tuple[str, ...]
    offsets: tuple[tuple[int, int], ...] | None = None
    info: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if isinstance(self.tables, PanoMappingTable) or isinstance(self.names, str | bytes):
            raise TypeError("a rig takes a sequence of tables and one of names (tables=(table,), names=('cam0',))")
        tables = tuple(check_table(table) for table in self.tables)
        if not 1 <= len(tables) <= MAX_CAMERAS:
            raise PanomapError(f"a rig has 1 to {MAX_CAMERAS} cameras, not {len(tables)}")
        names = tuple(check_camera_name(str(name)) for name in self.names)
        twice = sorted({name for name in names if names.count(name) > 1})
        if len(names) != len(tables) or twice:
            named = f" ({', '.join(twice)} twice)" if twice else f" ({len(names)} names, {len(tables)} cameras)"
            raise PanomapError(f"a rig needs one name per camera, each its own{named}")
        for name, table in zip(names, tables, strict=True):
            if table.image_size is None:
                raise PanomapError(f"the rig's camera {name} has no image size")
        object.__setattr__(self, "tables", tables)
        object.__setattr__(self, "names", names)
        if self.offsets is not None:
            offsets = tuple((int(x), int(y)) for x, y in self.offsets)
            if len(offsets) != len(tables) or any(x < 0 or y < 0 for x, y in offsets):
                raise PanomapError("a rig's frame needs one non-negative offset per camera")
            object.__setattr__(self, "offsets", offsets)

    @property
    def count(self) -> int:
        """How many cameras."""
        return len(self.tables)

    @property
    def frame_size(self) -> tuple[int, int] | None:
        """(width, height) of the one frame holding every camera's picture; None where each has its own image."""
        if self.offsets is None:
            return None
        width = max(x + table.image_size[0] for (x, _), table in zip(self.offsets, self.tables, strict=True))  # type: ignore[index]
        height = max(y + table.image_size[1] for (_, y), table in zip(self.offsets, self.tables, strict=True))  # type: ignore[index]
        return width, height

    @property
    def reference(self) -> FloatArray:
        """The point views of a rig are seen from (3,): camera 0's position (world units)."""
        return np.asarray(self.tables[0].camera_position, dtype=np.float64)

    def optical_axes(self) -> FloatArray:
        """Each camera's optical axis (k, 3), unit, world axes."""
        from ..camera.orientation import optical_axis

        return np.stack([optical_axis(table.model.rotation, table.model.axis) for table in self.tables])

    def half_fields_deg(self) -> FloatArray:
        """Each camera's largest angle from its optical axis that it sees (deg), from its table's own range."""
        out = []
        for table in self.tables:
            low, high = table.camera_range
            out.append(math.degrees(high + math.pi / 2 if table.model.axis == "down" else math.pi / 2 - low))
        return np.asarray(out)

    def describe(self) -> list[str]:
        """Lines for ``panomap info``: the cameras, where each sits and looks, what each sees, the overlaps."""
        axes = self.optical_axes()
        fields = self.half_fields_deg()
        frame = self.frame_size
        lines = [
            f"rig of {self.count} camera{'s' if self.count != 1 else ''}"
            + (f", their pictures side by side in one {frame[0]} x {frame[1]} frame" if frame is not None else "")
        ]
        for k, (name, table) in enumerate(zip(self.names, self.tables, strict=True)):
            yaw, pitch, roll = (math.degrees(a) for a in table.model.orientation)
            x, y, z = table.camera_position
            size = table.image_size
            where = "" if self.offsets is None else f" at ({self.offsets[k][0]}, {self.offsets[k][1]}) in the frame"
            lines.append(
                f"  {name}: {size[0]} x {size[1]} px{where}; at ({x:.4g}, {y:.4g}, {z:.4g}), looking yaw {yaw:.2f}, "  # type: ignore[index]
                f"pitch {pitch:.2f}, roll {roll:.2f} deg; sees {fields[k]:.1f} deg off its axis "
                f"({2 * fields[k]:.0f} deg across)"
            )
        for i in range(self.count):
            for j in range(i + 1, self.count):
                between = math.degrees(math.acos(float(np.clip(axes[i] @ axes[j], -1, 1))))
                overlap = fields[i] + fields[j] - between
                if overlap > 0:
                    lines.append(
                        f"  {self.names[i]} and {self.names[j]}: axes {between:.1f} deg apart, overlap up to "
                        f"{overlap:.1f} deg"
                    )
        return lines
