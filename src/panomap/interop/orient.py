"""A table turned to look another way, without a new fit: ``panomap orient``.

Convention: orientation as a perspective view's yaw, pitch and roll (rad; :mod:`panomap.camera.orientation`);
the table's entries stay in the world frame, over every world elevation the camera sees.

The camera's own rays do not change, only where they point in the world: the model gets the rotation
of the new orientation (its handedness and phi0 kept), and the entries are made anew, exactly as the
first table's were: from the model (a fitted table, Algorithm 2) or through the calibration's own
projection (an imported table, :mod:`.table_of_camera`), over the world elevations the turned camera sees.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from .. import inputs
from ..camera.orientation import orientation_of_rotation, world_elevation_range
from ..errors import PanomapError
from ..table.table import PanoMappingTable, check_table, fill_entries
from .models import external_model
from .table_of_camera import project_grid


def orient_table(table: PanoMappingTable, yaw_rad: float, pitch_rad: float, roll_rad: float) -> PanoMappingTable:
    """``table``'s camera looking along yaw, pitch and roll (rad), its entries made anew.

    The table keeps its size (M, N), its annulus, its image size and its information (the orientation
    given is recorded in ``info["orientation"]``); an imported table whose centre was moved since
    (``info["centre moved px"]``, :func:`panomap.rig.overlap.shifted_table`) stays moved. A camera without a
    single viewpoint keeps its ray origins along its (turned) axis.

    Parameters
    ----------
    table : PanoMappingTable
        Any table (fitted, learned or imported).
    yaw_rad, pitch_rad, roll_rad : float
        The new orientation, as a perspective view's (rad; pitch in [-pi/2, pi/2]).

    Raises
    ------
    PanomapError
        If the pitch is outside [-90, 90] deg, or an imported table's calibration cannot be rebuilt.
    """
    check_table(table)
    yaw_rad, pitch_rad, roll_rad = (
        inputs.number(v, n) for v, n in ((yaw_rad, "yaw_rad"), (pitch_rad, "pitch_rad"), (roll_rad, "roll_rad"))
    )
    model = table.model.with_orientation(yaw_rad, pitch_rad, roll_rad)
    camera_range = table.camera_range
    elevation_range = world_elevation_range(camera_range, model.rotation, model.axis)
    turned = model.rotation is not None
    if table.entries_from_model:
        entries = fill_entries(model, table.size, elevation_range, camera_range=camera_range if turned else None)
    else:
        record = table.info["import"]
        try:
            camera = external_model(str(record["model"]), dict(record["parameters"]))
        except (KeyError, TypeError, ValueError):
            raise PanomapError("the table's import record does not give its calibration's model") from None
        entries = project_grid(camera, model, table.size, elevation_range, camera_range if turned else None)
        # A centre moved since the import (panomap.rig.overlap.shifted_table) stays moved: every pixel by the move.
        entries = entries + np.asarray(table.info.get("centre moved px", (0.0, 0.0)), dtype=np.float32)
    info = dict(table.info)
    info["orientation"] = {
        "yaw_deg": math.degrees(yaw_rad),
        "pitch_deg": math.degrees(pitch_rad),
        "roll_deg": math.degrees(roll_rad),
        "source": "given",
    }
    return replace(
        table,
        entries=entries,
        elevation_range=elevation_range,
        model=model,
        info=info,
        camera_elevation_range=camera_range if turned else None,
    )


def turn_table(
    table: PanoMappingTable, rotation: NDArray[np.float64], source: str = "learned from pictures"
) -> PanoMappingTable:
    """``table``'s camera with the rotation ``rotation`` (3, 3; camera to world), its entries made anew as
    :func:`orient_table` makes them (exactly, through an imported table's calibration): what
    :func:`panomap.rig.learn.learn_rotations` and :func:`panomap.rig.place.place_on_floor` take as their
    ``turn``; ``source`` says where the rotation came from (the table's orientation record)."""
    model = table.model
    yaw, pitch, roll = orientation_of_rotation(rotation, model.axis, model.s, model.phi0)
    turned = orient_table(table, yaw, pitch, roll)
    info = dict(turned.info)
    info["orientation"] = {**info["orientation"], "source": source}
    return replace(turned, info=info)
