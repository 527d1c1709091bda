"""From landmarks (and an omni-image) to a pano-mapping table: the path ``fit``, ``learn`` and ``demo`` share.

:func:`calibrate_camera` finds the image circles when something is missing and an
omni-image is given, chooses the centre and the radii recording where each
came from (a :class:`~panomap.calibrate.core.sources.Source`), fits the camera
(:func:`panomap.fit_camera`) and fills its table (:mod:`panomap.calibrate.landmarks.table`).
A table saved from the browser is the table ``panomap fit`` makes from the same
landmarks, camera position, centre and radii.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ... import inputs
from ...camera.radial_models import radial_kind
from ...camera.valid_range import annulus_coverage_problem
from ...errors import PanomapError
from ...table.table import PanoMappingTable, check_table_chords, check_table_size
from ..circles import (
    Circle,
    ImageCircles,
    NoImageCircle,
    find_cutoff_about,
    find_cutoff_without_rim,
    find_image_circles,
)
from ..core.noise import rim_slack_px
from ..core.sources import QUANTITIES, Origin, Source, source_texts
from .fit import CameraFit, fit_camera, renamed_keyword
from .joint import ImageLines
from .pairs import Landmarks
from .table import choose_annulus, table_for
from .viewpoint import SphericalMirror


@dataclass(frozen=True)
class CircleChoice:
    """The centre and radii (px) :func:`choose_circles` settled on; None where still open.

    ``sources`` holds those it detected, in the order recorded; ``warnings`` says
    what it could not do (and what it did instead).
    """

    centre: tuple[float, float] | None
    cutoff_radius: float | None
    outer_radius: float | None
    circles: ImageCircles | None
    sources: Mapping[str, Origin]
    warnings: tuple[str, ...] = ()
    # The image was searched and shows no rim (a full-frame fisheye): the whole frame is picture.
    whole_frame: bool = False
    # ... but a cut-off disc (a mirror image that overfills the frame): the centre's start and the cut-off radius.
    cutoff_disc: Circle | None = None

    def settled(self) -> tuple[tuple[float, float], float, float]:
        """(centre, cut-off radius, outer radius); PanomapError when one is still open."""
        if self.centre is None or self.cutoff_radius is None or self.outer_radius is None:
            raise PanomapError("the image centre and radii are not all known")
        return self.centre, self.cutoff_radius, self.outer_radius


@dataclass(frozen=True)
class Calibration:
    """What :func:`calibrate_camera` made.

    Attributes
    ----------
    table : PanoMappingTable
        The table; its ``info`` holds the provenance texts, the fit report and
        the table's own warnings (where it reaches beyond the landmarks).
    fit : CameraFit
        The camera fit.
    sources : mapping of str to Origin
        Where the camera position, centre and radii came from, in the order recorded.
    circles : ImageCircles or None
        The image circles, when they were found.
    warnings : tuple of str
        What could not be done, and what was done instead (e.g. the circles
        not found where the centre was given: the default radii are used).
    notes : tuple of str
        What was chosen that the user should know but need not act on (the landmarks fitted without the
        image's lines where they fit far more tightly than the lines).
    """

    table: PanoMappingTable
    fit: CameraFit
    sources: Mapping[str, Origin]
    circles: ImageCircles | None
    warnings: tuple[str, ...]
    notes: tuple[str, ...] = ()


# Where the fit's centre ends this far (px) from the centre the cut-off disc was looked for about, it is
# looked for again about the fit's.
CUTOFF_AGAIN_PX = 2.0


def _cutoff_about_the_fit(
    omni: NDArray[Any],
    circles: ImageCircles,
    disc: Circle | None,
    fitted: tuple[float, float],
    recorded: Mapping[str, Origin],
) -> tuple[Circle | None, bool]:
    """The cut-off disc, looked for again about the fit's centre where that ended CUTOFF_AGAIN_PX or more
    from where it was looked for (the rim's centre, off the axis where the rim was found wrong; or the disc
    found, off it); and whether it was found only now (none was found about the rim's centre).

    The disc found again is kept where it keeps more of the camera's reflection out of the table (its
    radius less its distance to the fit's centre, :func:`_cutoff_about`, the larger): the reflection is
    everything inside its outermost edge about the axis; a lens ring inside it is a detail of it. On the
    real MiniOmni camera, the rim found 7-11 px off the calibrated axis on three images gave tables cut off
    at 13.9 and 16.1 px and none; about the fit's centre, 26.1-28.1 px, as on the other images (26.6-28.6).
    Only a detected cut-off radius, or one detected as none, is looked for again.
    """
    source = recorded.get("cutoff_radius")
    if source is None or source.source not in (Source.DETECTED, Source.DETECTED_NONE):
        return disc, False
    searched_at = circles.centre if disc is None else disc.centre
    if math.dist(searched_at, fitted) < CUTOFF_AGAIN_PX:
        return disc, False
    again = find_cutoff_about(omni, fitted, circles.outer_radius)
    if again is None or (disc is not None and _cutoff_about(again, fitted) <= _cutoff_about(disc, fitted)):
        return disc, False
    return again, disc is None


def _cutoff_about(disc: Circle, centre: tuple[float, float]) -> float:
    """The table's cut-off radius (px) about the fit's ``centre`` for the cut-off disc found in the image.

    The disc is the camera's own reflection, centred where the image shows it; the fit's centre
    may be a few pixels from there (a refined centre, a rim off the axis). Every pixel outside
    the disc is at least ``radius - d`` from ``centre`` (``d`` the distance between the two
    centres): the table takes that, so that it leaves none of the view out, at the price of up
    to ``2 d`` px of the reflection on one side (on a simulated mirror whose fitted centre ended
    9.5 px from the disc's, the view just outside the disc was missed on one side).
    """
    return max(0.0, disc.radius - math.dist(disc.centre, centre))


# A rim found with landmarks this far past it (a fraction of its radius, beyond the noise) is not the image circle.
RIM_CONTRADICTED_FRACTION = 0.05


def landmarks_past_rim(rim: Circle, pixels: NDArray[np.float64], pixel_sigma: float) -> int:
    """How many of the landmarks' ``pixels`` ((n, 2), px) lie well outside ``rim``: by RIM_CONTRADICTED_FRACTION
    of its radius beyond the noise (:func:`panomap.calibrate.landmarks.fit.rim_slack_px`)."""
    distance = np.hypot(*(np.asarray(pixels, dtype=float).reshape(-1, 2) - np.asarray(rim.centre)).T)
    return int(np.sum(distance > rim.radius * (1 + RIM_CONTRADICTED_FRACTION) + rim_slack_px(pixel_sigma)))


def rim_without_landmarks_past_it(
    choice: CircleChoice,
    pixels: NDArray[np.float64],
    pixel_sigma: float,
    omni: NDArray[Any],
    cutoff_radius: float | None,
) -> CircleChoice:
    """``choice``, or where landmarks lie well outside the rim it found, the choice of an image with no rim.

    Every landmark (``pixels``, (n, 2), px) is a point the camera sees, inside its image circle:
    two or more past the rim found (by RIM_CONTRADICTED_FRACTION of its radius beyond the noise)
    show a circle of the scene (a floor's edge about the nadir of a mirror image that overfills
    the frame, where the walls past it are smooth). The centre then starts at the cut-off disc
    found without a rim, or the frame's middle, and the table takes in the whole frame, with a
    warning.
    """
    circles = choice.circles
    if circles is None or choice.sources.get("outer_radius") != Origin(Source.DETECTED):
        return choice
    outer = circles.outer
    past = landmarks_past_rim(outer, pixels, pixel_sigma)
    if past < 2:
        return choice
    found = (
        f"the circle found at ({outer.centre[0]:.1f}, {outer.centre[1]:.1f}), radius {outer.radius:.1f} px, has "
        f"{past} landmarks well outside it: not the image circle"
    )
    sources = {
        name: origin
        for name, origin in choice.sources.items()
        if name not in ("centre", "outer_radius", "cutoff_radius")
    }
    disc = find_cutoff_without_rim(omni)
    centre, cutoff = choice.centre, cutoff_radius
    if disc is not None and cutoff is None:
        cutoff, sources["cutoff_radius"] = disc.radius, Origin(Source.DETECTED)
    if "centre" in choice.sources:  # found, not given: start again
        height, width = omni.shape[:2]
        if disc is not None:
            centre, sources["centre"] = disc.centre, Origin(Source.CUTOFF_DISC_CENTRE)
            start = f"the cut-off disc's centre ({disc.centre[0]:.1f}, {disc.centre[1]:.1f})"
        else:
            centre, sources["centre"] = ((width - 1) / 2, (height - 1) / 2), Origin(Source.FRAME_CENTRE)
            start = f"the frame centre ({(width - 1) / 2:.1f}, {(height - 1) / 2:.1f})"
        found += f"; starting from {start}, which the landmarks refine"
    return CircleChoice(centre, cutoff, None, None, sources, (found,), whole_frame=True, cutoff_disc=disc)


def _disc_without_landmarks(
    choice: CircleChoice, landmarks: Landmarks, pixel_sigma: float, omni: NDArray[Any]
) -> CircleChoice:
    """``choice``, or where a cut-off disc found without a rim holds landmarks, the choice without it.

    A dark disc in the middle of an image with no rim is taken for the camera's reflection
    (a mirror image that overfills the frame); landmarks inside it show it is the scene (a
    round table under a full-frame fisheye): the frame's middle starts the centre then, and
    the cut-off radius is left to its default, with a warning.
    """
    disc = choice.cutoff_disc
    if disc is None or choice.sources.get("cutoff_radius") != Origin(Source.DETECTED):
        return choice
    distance = np.hypot(*(landmarks.pixels - np.asarray(disc.centre)).T)
    inside = distance < disc.radius - rim_slack_px(pixel_sigma)
    if not inside.any():
        return choice
    height, width = omni.shape[:2]
    middle = ((width - 1) / 2, (height - 1) / 2)
    sources = {name: origin for name, origin in choice.sources.items() if name != "cutoff_radius"}
    centre, start = choice.centre, ""
    if sources.get("centre") == Origin(Source.CUTOFF_DISC_CENTRE):
        sources["centre"] = Origin(Source.FRAME_CENTRE)
        centre, start = middle, f"starting from the frame centre ({middle[0]:.1f}, {middle[1]:.1f}) "
    note = (
        f"no rim is visible, and the dark disc at ({disc.centre[0]:.1f}, {disc.centre[1]:.1f}), radius "
        f"{disc.radius:.1f} px, holds {int(inside.sum())} landmark(s): it is not the camera's own reflection; "
        f"{start}with no cut-off disc"
    )
    return replace(choice, centre=centre, cutoff_radius=None, sources=sources, warnings=(note,), cutoff_disc=None)


def _radii_note(error: PanomapError, cutoff_radius: float | None, outer_radius: float | None) -> str:
    """The warning when the circles are not found but the centre is given: which radii are defaults."""
    missing = [name for name, value in (("cut-off", cutoff_radius), ("outer", outer_radius)) if value is None]
    if len(missing) == 2:
        return f"{error}; using the default radii"
    given = "outer" if missing == ["cut-off"] else "cut-off"
    return f"{error}; using the given {given} radius and the default {missing[0]} one"


def choose_circles(
    omni: NDArray[Any],
    centre: tuple[float, float] | None = None,
    cutoff_radius: float | None = None,
    outer_radius: float | None = None,
    *,
    name: str | Path | None = None,
) -> CircleChoice:
    """The centre and radii: the given ones, the rest found in the omni-image.

    The circles are looked for only when something is missing. When they are
    not found but the centre is given, the radii stay open (for their
    defaults) and a warning says so. A camera that does not see itself (no
    cut-off disc) gets the cut-off radius 0, :attr:`Source.DETECTED_NONE`.

    Parameters
    ----------
    omni : (H, W[, C]) ndarray
        An omni-image of the camera.
    centre : (u0, v0), optional
        The image centre (px), where known; found in ``omni`` otherwise.
    cutoff_radius, outer_radius : float, optional
        The cut-off disc's and the image circle's radii (px), where known; found in ``omni`` otherwise.
    name : str or path, optional
        The omni-image's file, named in errors and warnings.

    Returns
    -------
    CircleChoice
        The centre and radii settled on (None where still open), where each came from, and the warnings.

    Raises
    ------
    TypeError
        ``omni`` no NumPy array, ``centre`` no pair of numbers (a string).
    PanomapError
        An image panomap cannot read (:func:`panomap.inputs.image`), a centre or radius not finite, or,
        when the centre is not given, circles not found (naming the image file ``name``, when given).
    """
    omni = inputs.image(omni, "the omni-image")
    centre = _pair(inputs.optional_numbers(centre, 2, "the image centre (u0, v0)"))
    cutoff_radius, outer_radius = _radii(cutoff_radius, outer_radius)
    if centre is not None and cutoff_radius is not None and outer_radius is not None:
        return CircleChoice(centre, cutoff_radius, outer_radius, None, {})
    try:
        circles = find_image_circles(omni)
    except NoImageCircle as exc:
        error = PanomapError(exc.detail, name)
        if centre is not None:
            found: dict[str, Origin] = {}
            if exc.cutoff is not None and cutoff_radius is None:
                cutoff_radius, found["cutoff_radius"] = exc.cutoff.radius, Origin(Source.DETECTED)
            note = _radii_note(error, cutoff_radius, outer_radius)
            return CircleChoice(
                centre, cutoff_radius, outer_radius, None, found, (note,), whole_frame=True, cutoff_disc=exc.cutoff
            )
        if exc.cutoff is not None:
            disc = exc.cutoff
            u, v = disc.centre
            warning = f"{error}; starting from the cut-off disc's centre ({u:.1f}, {v:.1f}), which the landmarks refine"
            found = {"centre": Origin(Source.CUTOFF_DISC_CENTRE)}
            if cutoff_radius is None:
                cutoff_radius, found["cutoff_radius"] = disc.radius, Origin(Source.DETECTED)
            return CircleChoice(
                disc.centre, cutoff_radius, outer_radius, None, found, (warning,), whole_frame=True, cutoff_disc=disc
            )
        u, v = exc.frame_centre
        warning = f"{error}; starting from the frame centre ({u:.1f}, {v:.1f}), which the landmarks refine"
        frame = {"centre": Origin(Source.FRAME_CENTRE)}
        return CircleChoice(exc.frame_centre, cutoff_radius, outer_radius, None, frame, (warning,), whole_frame=True)
    except PanomapError as exc:
        error = PanomapError(exc.detail, name)
        if centre is None:
            raise error from None
        return CircleChoice(
            centre, cutoff_radius, outer_radius, None, {}, (_radii_note(error, cutoff_radius, outer_radius),)
        )
    sources: dict[str, Origin] = {}
    if centre is None:
        centre, sources["centre"] = circles.centre, Origin(Source.DETECTED)
    if outer_radius is None:
        outer_radius, sources["outer_radius"] = circles.outer_radius, Origin(Source.DETECTED)
    if cutoff_radius is None:
        cutoff_radius = circles.cutoff_radius or 0.0
        sources["cutoff_radius"] = Origin(Source.DETECTED if circles.cutoff else Source.DETECTED_NONE)
    return CircleChoice(centre, cutoff_radius, outer_radius, circles, sources)


def calibrate_camera(
    landmarks: Landmarks,
    camera_position: tuple[float, float, float] | None = None,
    *,
    centre: tuple[float, float] | None = None,
    cutoff_radius: float | None = None,
    outer_radius: float | None = None,
    omni: NDArray[Any] | None = None,
    omni_name: str | Path | None = None,
    image_size: tuple[int, int] | None = None,
    sources: Mapping[str, Source] | None = None,
    info: Mapping[str, Any] | None = None,
    table_size: tuple[int, int] | None = None,
    model: str = "auto",
    azimuth: str = "fit",
    axis: str | None = None,
    refine_centre: bool | None = None,
    pixel_sigma: float = 1.0,
    world_sigma: float | None = None,
    reject_outliers: bool = True,
    models_cover_annulus: bool = True,
    tilt_deg: str | tuple[float, float] = "fit",
    camera_sigma: float | None = None,
    found: CircleChoice | None = None,
    tilt: str | tuple[float, float] | None = None,
    lines: bool | ImageLines = False,
    viewpoint: str | SphericalMirror = "auto",
    orientation_deg: tuple[float, float, float] | None = None,
) -> Calibration:
    """Landmarks (and an omni-image) to a fitted camera and its pano-mapping table.

    Parameters
    ----------
    landmarks : Landmarks
        At least 5 pairs.
    camera_position : (X0, Y0, Z0), optional
        World units; default the landmarks' own (from a JSON landmark file).
    centre : (u0, v0), optional
        Image centre, px; found in ``omni`` when not given.
    cutoff_radius, outer_radius : float, optional
        The visible annulus, px; found in ``omni`` when not given, else their defaults (:func:`panomap.create_table`).
    omni : (H, W[, C]) ndarray, optional
        An omni-image of the camera: its size is the image size, and the image circles are looked for in it when
        the centre or a radius is missing (:func:`choose_circles`).
    omni_name : str or path, optional
        The omni-image's file, named in errors and warnings about it.
    image_size : (width, height), optional
        When no ``omni`` is given (an omni-image's own size wins).
    sources : mapping of str to Source, optional
        Where the given camera position, centre and radii came from, in the order to record them (entries for
        values not given are left out). The rest follow in the order camera position, centre, cut-off and outer
        radius as :attr:`Source.GIVEN` (the camera position :attr:`Source.LANDMARK_FILE` when it is the landmarks'
        own); then those found in ``omni``, then the defaults.
    info : mapping, optional
        More to store in the table's ``info``, after the provenance.
    table_size : (M, N), optional
        Default about one entry per pixel.
    refine_centre : bool, optional
        Refine the centre with the landmarks. Default: when the centre was not given (found in the image, or the
        frame's middle where no image circle is found) and the model does not take the centre as given (``paper``).
    model, azimuth, axis, pixel_sigma, world_sigma, reject_outliers, tilt_deg, camera_sigma, viewpoint, tilt
        As :func:`panomap.fit_camera` (by default the tilt and the camera position are refined where
        cross-validation says the landmarks support it; ``tilt``, deprecated, is ``tilt_deg``'s old spelling).
    orientation_deg : (yaw, pitch, roll), optional
        As :func:`panomap.fit_camera`'s.
    models_cover_annulus : bool
        When both radii are known before the fit, automatic model choice only takes models that run monotonically
        across the annulus (its ``annulus``); False leaves the choice to the landmarks alone (the table still
        checks the given radii).
    found : CircleChoice, optional
        What :func:`choose_circles` found in ``omni`` (given with nothing of the centre and radii) beforehand, taken
        instead of looking again: the learn page finds the circles once, when it opens, and fits as this function
        does with them.
    lines : bool or ImageLines
        True: the lines of ``omni`` join the landmarks in the fit (:mod:`.joint`), each weighted by its noise; where
        they cannot (no image circle, too few lines, lines that disagree) the landmark fit stands, with a warning.
        An :class:`~.joint.ImageLines` of ``omni`` found beforehand is taken instead (the learn page refits often).

    Raises
    ------
    TypeError
        ``landmarks`` no :class:`Landmarks`, ``omni`` no array, a centre or position no numbers, ``info`` not JSON.
    PanomapError
        No camera position or centre, an unreadable image, numbers not finite; the circles', fit's or table's.
    """
    tilt_deg = renamed_keyword("calibrate_camera", "tilt", tilt, "tilt_deg", tilt_deg)
    inputs.instance(landmarks, Landmarks, "landmarks", " (panomap.read_landmarks reads a file)")
    camera_position = _triple(inputs.optional_numbers(camera_position, 3, "the camera position (X0, Y0, Z0)"))
    centre = _pair(inputs.optional_numbers(centre, 2, "the image centre (u0, v0)"))
    cutoff_radius, outer_radius = _radii(cutoff_radius, outer_radius)
    omni = None if omni is None else inputs.image(omni, "the omni-image")
    image_size = inputs.optional_image_size(image_size)
    info = inputs.info(info)
    position = camera_position if camera_position is not None else landmarks.camera
    if position is None:
        raise PanomapError("no camera position: give one, or landmarks that hold it")
    # 1. Sources: where each given value came from.
    given = dict(camera_position=position, centre=centre, cutoff_radius=cutoff_radius, outer_radius=outer_radius)
    recorded = _given_sources(given, sources, position_from_landmarks=camera_position is None)
    # 2. Circles: the centre and radii found in the omni-image where not given.
    choice = CircleChoice(centre, cutoff_radius, outer_radius, None, {})
    if omni is not None:
        image_size = (int(omni.shape[1]), int(omni.shape[0]))
        choice = _circles(omni, omni_name, choice, found, landmarks, pixel_sigma)
        recorded |= choice.sources
    centre = _ready_to_fit(choice, table_size)
    # 3. Fit: the camera model from the landmarks (the centre refined where it was not given).
    camera_fit, line_warnings = _fit(
        landmarks, position, choice, centre, recorded, omni, image_size, lines, refine_centre,
        models_cover_annulus, model=model, azimuth=azimuth, axis=axis, pixel_sigma=pixel_sigma,
        world_sigma=world_sigma, reject_outliers=reject_outliers, tilt_deg=tilt_deg, camera_sigma=camera_sigma,
        viewpoint=viewpoint, orientation_deg=orientation_deg,
    )  # fmt: skip
    cutoff, outer = choice.cutoff_radius, choice.outer_radius
    # 4. The cut-off settled against the fit: the disc measured again about the fitted centre.
    cutoff = _cutoff_settled(omni, choice, camera_fit, cutoff, recorded)
    # 5. Annulus and 6. table.
    table = _table(camera_fit, choice, (cutoff, outer), recorded, size=table_size, image_size=image_size, info=info)
    notes = () if camera_fit.lines_note is None or camera_fit.lines_note_warns else (camera_fit.lines_note,)
    return Calibration(table, camera_fit, recorded, choice.circles, choice.warnings + line_warnings, notes)


def _ready_to_fit(choice: CircleChoice, table_size: tuple[int, int] | None) -> tuple[float, float]:
    """The centre to fit about; refused before the fit where there is none, or where the table of
    ``table_size`` (M, N) given would be too coarse in azimuth at the image circle known (where it ends)."""
    if choice.centre is None:
        raise PanomapError("no image centre: give one, or an omni-image to find it in")
    if table_size is not None and choice.outer_radius is not None:
        check_table_chords(check_table_size(table_size), choice.outer_radius)
    return choice.centre


def _fit(
    landmarks: Landmarks,
    position: tuple[float, float, float],
    choice: CircleChoice,
    centre: tuple[float, float],
    recorded: dict[str, Origin],
    omni: NDArray[Any] | None,
    image_size: tuple[int, int] | None,
    lines: bool | ImageLines,
    refine_centre: bool | None,
    models_cover_annulus: bool,
    *,
    model: str,
    azimuth: str,
    axis: str | None,
    pixel_sigma: float,
    world_sigma: float | None,
    reject_outliers: bool,
    tilt_deg: str | tuple[float, float],
    camera_sigma: float | None,
    viewpoint: str | SphericalMirror,
    orientation_deg: tuple[float, float, float] | None,
) -> tuple[CameraFit, tuple[str, ...]]:
    """The camera fitted to the landmarks about ``centre`` (refined where it was not given: ``recorded`` says
    so), with the image's lines where ``lines`` asks for them; and the warnings about the lines."""
    refine_centre = _refines_centre(refine_centre, recorded["centre"], model)
    if refine_centre:
        recorded["centre"] = Origin(recorded["centre"].source, refined=True)
    cutoff, outer = choice.cutoff_radius, choice.outer_radius
    image_lines, line_warnings = (lines, ()) if isinstance(lines, ImageLines) else _image_lines(omni, choice, lines)
    camera_fit = fit_camera(
        landmarks, position, centre, model=model, azimuth=azimuth, axis=axis, image_size=image_size,
        annulus=None if cutoff is None or outer is None or not models_cover_annulus else (cutoff, outer),
        refine_centre=refine_centre, centre_is_guess=recorded["centre"].source is Source.FRAME_CENTRE,
        pixel_sigma=pixel_sigma, world_sigma=world_sigma, reject_outliers=reject_outliers, tilt_deg=tilt_deg,
        camera_sigma=camera_sigma, lines=image_lines, viewpoint=viewpoint, orientation_deg=orientation_deg,
    )  # fmt: skip
    if camera_fit.lines_note is not None and camera_fit.lines_note_warns:
        line_warnings += (camera_fit.lines_note,)
    return camera_fit, line_warnings


def _table(
    camera_fit: CameraFit,
    choice: CircleChoice,
    radii: tuple[float | None, float | None],
    recorded: dict[str, Origin],
    *,
    size: tuple[int, int] | None,
    image_size: tuple[int, int] | None,
    info: Mapping[str, Any] | None,
) -> PanoMappingTable:
    """The table of ``camera_fit``: the annulus it spans (``radii`` where known), each radius with where it came
    from (recorded in ``recorded`` where it was not), and the table over it, ``info`` after the provenance."""
    # 5. Annulus: the radii the table spans, each with where it came from.
    annulus = choose_annulus(camera_fit, image_size, *radii, whole_frame=choice.whole_frame)
    recorded.setdefault("cutoff_radius", Origin(annulus.cutoff_source))
    recorded.setdefault("outer_radius", Origin(annulus.outer_source))
    # 6. Table.
    table_info: dict[str, Any] = {} if choice.circles is None else {"image_circles": choice.circles.to_dict()}
    table_info["sources"] = source_texts(recorded)
    return table_for(camera_fit, annulus, size=size, image_size=image_size, info=table_info | dict(info or {}))


def _image_lines(
    omni: NDArray[Any] | None, choice: CircleChoice, wanted: bool
) -> tuple[ImageLines | None, tuple[str, ...]]:
    """The edge arcs of ``omni`` for the lines to join the fit (where ``wanted``), or a warning why they cannot."""
    if not wanted:
        return None, ()
    if omni is None:
        return None, ("no image: no line joined the fit",)
    if choice.circles is None:
        return None, ("no image circle found: the lines need its centre and radius, and no line joined the fit",)
    return image_lines(omni, choice.circles), ()


def image_lines(omni: NDArray[Any], circles: ImageCircles) -> ImageLines:
    """The edge arcs of ``omni`` inside ``circles``, for the lines to join a fit."""
    from ..lines.arcs import find_arcs

    return ImageLines(find_arcs(omni, circles), circles)


def _refines_centre(refine_centre: bool | None, centre: Origin, model: str) -> bool:
    """``refine_centre``, or by default: when the centre is an estimate (found in the image, or the frame's
    middle) and ``model`` does not take the centre as given."""
    if refine_centre is not None:
        return refine_centre
    return centre.source.is_estimate and (model == "auto" or not radial_kind(model).centre_given)


def _given_sources(
    given: Mapping[str, object], sources: Mapping[str, Source] | None, position_from_landmarks: bool
) -> dict[str, Origin]:
    """Where each value ``given`` (not None) came from: as ``sources`` says, in its order, else given (the
    camera position from the landmark file where ``position_from_landmarks``)."""
    unknown = sorted(set(sources or {}) - set(QUANTITIES))
    if unknown:
        raise PanomapError(f"sources: unknown quantity {', '.join(unknown)}; they are {', '.join(QUANTITIES)}")
    recorded = {name: Origin(source) for name, source in (sources or {}).items() if given[name] is not None}
    for name in QUANTITIES:
        if given[name] is not None and name not in recorded:
            from_landmarks = name == "camera_position" and position_from_landmarks
            recorded[name] = Origin(Source.LANDMARK_FILE if from_landmarks else Source.GIVEN)
    return recorded


def _circles(
    omni: NDArray[Any],
    omni_name: str | Path | None,
    given: CircleChoice,
    found: CircleChoice | None,
    landmarks: Landmarks,
    pixel_sigma: float,
) -> CircleChoice:
    """The centre and radii ``given``, with what :func:`choose_circles` finds in ``omni`` (or ``found``
    beforehand) where they are missing, checked against the landmarks (no rim or disc with landmarks past it)."""
    if found is not None and (given.centre, given.cutoff_radius, given.outer_radius) != (None, None, None):
        raise PanomapError("the circles found beforehand come without a centre or radii given beside them")
    choice = found or choose_circles(omni, given.centre, given.cutoff_radius, given.outer_radius, name=omni_name)
    choice = rim_without_landmarks_past_it(choice, landmarks.pixels, pixel_sigma, omni, given.cutoff_radius)
    return _disc_without_landmarks(choice, landmarks, pixel_sigma, omni)


def _cutoff_settled(
    omni: NDArray[Any] | None,
    choice: CircleChoice,
    camera_fit: CameraFit,
    cutoff: float | None,
    recorded: dict[str, Origin],
) -> float | None:
    """The cut-off radius (px) once the fit has settled the centre: a disc found in the image measured again
    about the fitted centre (``recorded`` updated where it is found only now), kept where f_r runs that far in."""
    outer = choice.outer_radius
    disc = choice.cutoff_disc if choice.circles is None else choice.circles.cutoff
    if omni is not None and choice.circles is not None and outer is not None:
        disc, found_now = _cutoff_about_the_fit(omni, choice.circles, disc, camera_fit.model.centre, recorded)
        if found_now and disc is not None:
            recorded["cutoff_radius"], cutoff = Origin(Source.DETECTED), disc.radius
    if disc is not None and outer is not None and recorded["cutoff_radius"].source is Source.DETECTED:
        within = _cutoff_about(disc, camera_fit.model.centre)
        # (Only where f_r runs that far in: a model that turns back just inside the disc keeps the disc's radius.)
        slack = rim_slack_px(camera_fit.settings.pixel_sigma_px)
        if not annulus_coverage_problem(camera_fit.model.radial, camera_fit.landmark_range, within, outer, slack):
            cutoff = within
    return cutoff


def _pair(numbers: tuple[float, ...] | None) -> tuple[float, float] | None:
    return None if numbers is None else (numbers[0], numbers[1])


def _triple(numbers: tuple[float, ...] | None) -> tuple[float, float, float] | None:
    return None if numbers is None else (numbers[0], numbers[1], numbers[2])


def _radii(cutoff_radius: Any, outer_radius: Any) -> tuple[float | None, float | None]:
    """The radii given (px), each a finite number or None; both given, the cut-off radius below the outer one
    (refused before any work, not as an annulus no model covers after the fit)."""
    cutoff = None if cutoff_radius is None else inputs.number(cutoff_radius, "the cut-off radius")
    outer = None if outer_radius is None else inputs.number(outer_radius, "the outer radius")
    if cutoff is not None and outer is not None and not 0 <= cutoff < outer:
        raise PanomapError(f"the cut-off radius ({cutoff:g} px) must be >= 0 and below the outer radius ({outer:g} px)")
    return cutoff, outer
