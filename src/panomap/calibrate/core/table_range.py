"""What any fit's table spans and how large it grows by default: shared by the landmarks' table
(:mod:`panomap.calibrate.landmarks.table`) and the lines' (:mod:`panomap.calibrate.lines.table`).

Convention: elevations rad, sizes (M, N) entries.
"""

from __future__ import annotations

import math

# Default sizes stop here: bilinear sampling is then within 1e-3 px of the model.
DEFAULT_MAX_SIZE = (4096, 1024)


def world_range(camera_range: tuple[float, float], tilt_rad: float) -> tuple[float, float]:
    """The world elevations (rad) seen at some azimuth by a camera ``tilt_rad`` off the vertical that sees
    ``camera_range`` in its own axes: each end moves outward by the tilt, up to the poles. (Where the camera
    does not see a world ray of that band, the table's entry is NaN.)
    """
    low, high = camera_range
    return max(low - tilt_rad, -math.pi / 2), min(high + tilt_rad, math.pi / 2)
