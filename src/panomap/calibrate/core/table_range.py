"""What any fit's table spans and how large it grows by default: shared by the landmarks' table
(:mod:`panomap.calibrate.landmarks.table`) and the lines' (:mod:`panomap.calibrate.lines.table`).

Convention: elevations rad, sizes (M, N) entries.
"""

from __future__ import annotations

from ...camera.model import CameraModel
from ...camera.orientation import world_elevation_range

# Default sizes stop here: bilinear sampling is then within 1e-3 px of the model.
DEFAULT_MAX_SIZE = (4096, 1024)


def world_range(camera_range: tuple[float, float], model: CameraModel) -> tuple[float, float]:
    """The world elevations (rad) seen at some azimuth by ``model``'s camera, which sees ``camera_range`` in
    its own axes: :func:`panomap.camera.orientation.world_elevation_range`, for any orientation. (Where the
    camera does not see a world ray of that band, the table's entry is NaN.)
    """
    return world_elevation_range(camera_range, model.rotation, model.axis)
