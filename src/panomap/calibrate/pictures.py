"""A camera learned from pictures alone: its straight lines and checkerboards, no landmark, no tape measure.

:func:`learn_from_images` is what ``panomap fit -o T --image IMG [--image IMG ...]`` does without landmarks,
and what the learn page's "learn from lines" does on its image: it finds the image circles of the first
picture (stand-ins where no rim shows, :func:`panomap.calibrate.lines.frame_circles.line_circles`), the edge
arcs (:func:`panomap.calibrate.lines.arcs.find_arcs`) and the checkerboards
(:func:`panomap.calibrate.boards.detect.find_boards`) of every picture, chooses between the camera the boards
give and the one the lines give (:func:`panomap.calibrate.boards.choice.learn_camera`), and fills the table
(:func:`panomap.calibrate.lines.table.create_line_table`).

Convention: pixel (u, v) = (column, row), the centre of the top-left pixel at (0, 0); residuals in px.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .. import inputs
from ..camera.radial_models import radial_kind
from ..errors import PanomapError
from ..table.table import PanoMappingTable
from .boards.choice import LearnedCamera, learn_camera
from .boards.detect import Board, find_boards_each
from .circles import ImageCircles
from .core.report import FitReport, table_fit_report
from .landmarks.joint import ImageLines
from .lines.arcs import EdgeArc, find_arcs
from .lines.fit import LineFit, LineFitOptions
from .lines.frame_circles import line_circles
from .lines.orientation import check_scene_pixel, zero_azimuth
from .lines.table import create_line_table


@dataclass(frozen=True)
class LearnedCalibration:
    """What :func:`learn_from_images` made: the table, the fit, and what the fit saw.

    Attributes
    ----------
    table : PanoMappingTable
        The table; its ``info`` holds the provenance (``source``, the images), the fit report
        (:attr:`report`) and the table's own warnings.
    fit : LineFit
        The camera learned, with its line report (``fit.report``: every line used and every arc
        set aside, the checkerboards' corners where boards were used).
    source : {"checkerboards", "lines"}
        What the camera was learned from.
    circles : ImageCircles
        The image circles of the first image the fit started from (stand-ins where it shows no rim:
        the frame's middle or the cut-off disc, the outer circle through the frame's farthest corner).
    arcs : sequence of EdgeArc
        What ``fit.report`` indexes: the edge arcs, or the checkerboards' rows and columns.
    choice : str or None
        Which camera was kept and why, where both the boards' and the lines' were fitted.
    warnings : tuple of str
        What failed and what was done instead (boards that gave no camera), then the table's own
        warnings (where it reaches beyond the fit's data).
    """

    table: PanoMappingTable
    fit: LineFit
    source: str
    circles: ImageCircles
    arcs: Sequence[EdgeArc]
    choice: str | None
    warnings: tuple[str, ...]

    @property
    def report(self) -> FitReport:
        """The fit report the table holds (the one ``panomap info`` prints): the model, the centre's and the
        radius' uncertainty, and the lines' report (``report.lines``)."""
        report = table_fit_report(self.table)
        if report is None:
            raise PanomapError("the table holds no fit report")
        return report


class NotLearned(PanomapError):
    """No camera could be learned from the pictures: the message says why; ``arcs`` (the edge arcs found, each
    with its image's index) and ``circles`` (the first image's) are what the pictures gave, for an overlay."""

    def __init__(self, message: str, source: object | None, arcs: list[EdgeArc], circles: ImageCircles) -> None:
        super().__init__(message, source)
        self.arcs = arcs
        self.circles = circles


def learn_from_images(
    images: Sequence[NDArray[Any]] | NDArray[Any],
    *,
    names: Sequence[str | Path] | None = None,
    camera_height: float | None = None,
    model: str = "auto",
    axis: str = "down",
    handedness: int | None = None,
    azimuth_zero: tuple[float, float] | None = None,
    boards: bool = True,
    info: Mapping[str, Any] | None = None,
    found: ImageLines | None = None,
    progress: Callable[[int, int, str], None] | None = None,
) -> LearnedCalibration:
    """Learn a camera from the straight lines and checkerboards of its pictures, and fill its table.

    No landmark is needed: straight lines in the world (a room's edges, a door's frame) are curved in an
    omni-image in a way only the camera explains, and a checkerboard of any size held before the camera
    adds corners evenly spaced on straight lines at right angles, which fixes the scale straightness
    alone leaves loose. Where boards are found they are fitted first; with fewer than 3 boards the line
    fit is made too, and the camera that explains both is kept (:attr:`LearnedCalibration.choice` says
    which, and why). This is ``panomap fit -o TABLE --image IMG [--image IMG ...]`` without landmarks.

    Parameters
    ----------
    images : sequence of (H, W[, C]) ndarray, or one ndarray
        Pictures of one camera, all of one size (:func:`panomap.read_image` reads a file); more pictures
        give more lines and boards. One array is one picture.
    names : sequence of str or path, optional
        The images' files, one per image: recorded in the table's ``info["images"]`` and named in errors.
    camera_height : float, optional
        The camera's height above the floor (world units): lines know no distance, and the floor,
        cylinder and plane views need one. Default: unknown (the table says so).
    model : str
        ``"auto"`` (chosen by cross-validation over the lines) or a radial model kind's name
        (``"odd3"``, ``"unified"``, ...; not ``"paper"``, which takes the centre as given).
    axis : {"down", "up"}
        The pole the image centre sees (a ceiling camera looks down).
    handedness : {+1, -1}, optional
        The image's handedness ``s``. Default: from the kind of camera the image shows (a cut-off disc,
        the camera's own reflection: a mirror, +1; none: a lens, -1 looking down, +1 looking up).
    azimuth_zero : (u, v), optional
        A pixel (px) that sees world azimuth 0. Default: image angle 0 (+u) is azimuth 0.
    boards : bool
        Look for checkerboards (True) or learn from the lines alone (False).
    info : mapping, optional
        More to store in the table's ``info``, after the provenance.
    found : ImageLines, optional
        The edge arcs, checkerboards and image circles of the one image in ``images``, found beforehand
        (:class:`~panomap.calibrate.landmarks.joint.ImageLines`), taken instead of looking again; its camera is
        learned once and kept, and ``azimuth_zero`` turns it (the learn page, which finds the lines once
        and sets azimuth 0 at every click). ``boards`` is then ignored: the boards it holds are used.
    progress : callable, optional
        Called as ``progress(step, steps, what)`` before each step (``what``: a few words), for a
        progress bar.

    Returns
    -------
    LearnedCalibration
        The table, the fit, what it was learned from, and the warnings.

    Raises
    ------
    TypeError
        ``images`` a file name (a string, a path) or holding one, not arrays (:func:`panomap.read_image`
        reads a file); ``info`` no mapping or holding what JSON cannot.
    PanomapError
        (:class:`NotLearned` where the pictures were searched: with what they gave) An image panomap cannot
        read (a float, empty or raveled array: :func:`panomap.inputs.image`), no image, images of
        different sizes, no image circle and no cut-off disc to start from,
        too few lines (or no two orthogonal families) where the boards give no camera either, a
        ``model`` of ``"paper"``, or a camera whose table cannot be made; naming the image where one
        image is to blame.

    Examples
    --------
    >>> omni = panomap.read_image("room.png")                             # doctest: +SKIP
    >>> learned = panomap.learn_from_images([omni], camera_height=2.45)   # doctest: +SKIP
    >>> panomap.save_table(learned.table, "cam.npz")                      # doctest: +SKIP
    """
    omnis = inputs.pictures(images)
    table_extra = inputs.info(info)
    azimuth_zero = _pair(inputs.optional_numbers(azimuth_zero, 2, "azimuth_zero (u, v)"))
    camera_height = None if camera_height is None else inputs.number(camera_height, "the camera height")
    _check_options(names, camera_height, model, axis, handedness)
    if not omnis:
        raise PanomapError("no image to learn the camera from")
    if names is not None and len(names) != len(omnis):
        raise PanomapError(f"{len(names)} names for {len(omnis)} images: give one name per image")
    if model == "paper":
        raise PanomapError("the paper model takes the centre as given; learning from lines needs another model")
    if found is not None and len(omnis) != 1:
        raise PanomapError(f"the lines found beforehand are one image's, but {len(omnis)} images are given")
    label: list[str | Path | None] = list(names) if names is not None else [None] * len(omnis)
    omnis, label, repeated = _once(_one_size(omnis, label), label)
    options = LineFitOptions(axis=axis, s=handedness, azimuth_zero=azimuth_zero, model=model)
    say = progress or (lambda _step, _steps, _what: None)
    # The steps: each image's edges, each image's boards, the fit, the table.
    steps = 2 * len(omnis) + 2
    if found is None:
        learned, circles = _learn(omnis, label, options, boards, lambda step, what: say(step, steps, what))
    else:
        learned, circles = _learn_found(found, options), found.circles
    say(steps - 1, steps, "filling the table")
    table = create_line_table(
        learned.fit,
        cutoff_radius=circles.cutoff_radius or 0.0,
        outer_radius=circles.outer_radius,
        image_size=(omnis[0].shape[1], omnis[0].shape[0]),
        camera_height=camera_height,
        info=_table_info(learned, names, camera_height, table_extra),
    )
    again = [f"{repeated} of the pictures repeat an earlier one (the same pixels): each counted once"] * bool(repeated)
    warnings = (*again, *learned.notes, *table.info.get("warnings", []))
    return LearnedCalibration(table, learned.fit, learned.source, circles, learned.arcs, learned.choice, warnings)


def _check_options(names: Any, camera_height: float | None, model: Any, axis: Any, handedness: Any) -> None:
    """Refuse, before any picture is searched, options no fit can take (they would fail deep in it, saying
    something else: a model's unknown name as "no radial model fits the lines")."""
    if names is not None and (isinstance(names, str | bytes | Path) or not isinstance(names, Sequence)):
        raise TypeError(f"names must be a list of file names, one per image, not {type(names).__name__} {names!r:.40}")
    if camera_height is not None and camera_height <= 0:
        raise PanomapError(f"the camera height must be positive (world units above the floor), not {camera_height:g}")
    if model != "auto":
        radial_kind(inputs.instance(model, str, "model"))
    if axis not in ("down", "up"):
        raise PanomapError(f"axis must be 'down' or 'up' (the pole the image centre sees), not {axis!r:.40}")
    if handedness is not None and (isinstance(handedness, bool) or handedness not in (1, -1)):
        raise PanomapError(f"handedness must be +1, -1 or None (from the kind of camera), not {handedness!r:.40}")


def _table_info(
    learned: LearnedCamera,
    names: Sequence[str | Path] | None,
    camera_height: float | None,
    info: Mapping[str, Any] | None,
) -> dict[str, Any]:
    """The table's ``info``: what the camera was learned from (and the images' names), then ``info``."""
    table_info: dict[str, Any] = {"source": learned.source}
    if names is not None:
        table_info["images"] = [str(name) for name in names]
    if learned.source == "checkerboards":
        table_info["sources"] = {
            "camera_position": "given (--camera-height)" if camera_height is not None else "unknown (boards' size)",
            "centre": "fitted to the checkerboards' corners",
            "cutoff_radius": "detected",
            "outer_radius": "detected",
        }
    table_info.update(info or {})
    return table_info


def _learn(
    omnis: list[NDArray[Any]],
    names: list[str | Path | None],
    options: LineFitOptions,
    use_boards: bool,
    say: Callable[[int, str], None],
) -> tuple[LearnedCamera, ImageCircles]:
    """The camera of ``omnis`` (their circles, arcs and boards found here) and the first image's circles;
    ``say(step, what)`` before each step (the steps: each image's edges, each image's boards, the fit)."""
    say(0, f"image circles of {_called(names, 0)}")
    try:
        circles = line_circles(omnis[0])
    except PanomapError as exc:
        raise PanomapError(exc.detail, names[0]) from None
    if options.azimuth_zero is not None:  # (before the fit: checked again at the fitted centre)
        try:
            check_scene_pixel(options.azimuth_zero, circles.centre, circles)
        except PanomapError as exc:
            raise PanomapError(exc.detail, names[0]) from None
    edges: list[EdgeArc] = []
    for k, omni in enumerate(omnis):
        say(k, f"edges of {_called(names, k)}")
        edges += find_arcs(omni, circles, image_index=k)
    found_boards: list[Board] = []
    if use_boards:
        say(len(omnis), f"checkerboards in {_called(names, 0)}")
        for k, boards in enumerate(find_boards_each(omnis)):  # searched in threads, given in order
            found_boards += boards
            if k + 1 < len(omnis):
                say(len(omnis) + k + 1, f"checkerboards in {_called(names, k + 1)}")
    try:
        learned = learn_camera(found_boards, edges, circles, options, progress=lambda step: say(2 * len(omnis), step))
    except PanomapError as exc:
        raise NotLearned(exc.detail, names[0] if len(omnis) == 1 else None, edges, circles) from None
    return learned, circles


def _learn_found(lines: ImageLines, options: LineFitOptions) -> LearnedCamera:
    """The camera of one image's lines found beforehand, learned once with ``options`` less the azimuth origin
    (kept in ``lines``), then turned so that ``options.azimuth_zero`` sees world azimuth 0."""
    learned = lines.learned(replace(options, azimuth_zero=None))
    if options.azimuth_zero is None:
        return learned
    fit = learned.fit
    fit = replace(
        fit,
        model=zero_azimuth(fit.model, options.azimuth_zero, lines.circles),
        report=replace(fit.report, azimuth_source="given"),
    )
    return replace(learned, fit=fit)


def _called(names: list[str | Path | None], k: int) -> str:
    """How the progress names image ``k``: its file's name, or its number."""
    name = names[k]
    return Path(name).name if name is not None else f"image {k + 1}"


def _one_size(omnis: list[NDArray[Any]], label: list[str | Path | None]) -> list[NDArray[Any]]:
    """``omnis``, refused (naming the picture) where one is not the first one's size."""
    for k, omni in enumerate(omnis):
        if omni.shape[:2] != omnis[0].shape[:2]:
            first = f"{label[0]}" if label[0] is not None else "the first image"
            raise PanomapError(
                f"is {omni.shape[1]} x {omni.shape[0]}, but {first} is {omnis[0].shape[1]} x "
                f"{omnis[0].shape[0]}: the images of one camera have one size",
                label[k] if label[k] is not None else f"image {k + 1}",
            )
    return omnis


def _once(
    omnis: list[NDArray[Any]], names: list[str | Path | None]
) -> tuple[list[NDArray[Any]], list[str | Path | None], int]:
    """The pictures and their names with every repeat of an earlier picture (the same pixels) left out, and how
    many were: a picture's lines given twice add nothing but time (the command line refuses one picture given
    twice; here each counts once)."""
    import hashlib

    seen: set[tuple[tuple[int, ...], str, str]] = set()
    kept: list[int] = []
    for k, omni in enumerate(omnis):
        array = np.ascontiguousarray(omni)
        key = (array.shape, array.dtype.str, hashlib.sha256(array.data).hexdigest())
        if key not in seen:
            seen.add(key)
            kept.append(k)
    return [omnis[k] for k in kept], [names[k] for k in kept], len(omnis) - len(kept)


def _pair(numbers: tuple[float, ...] | None) -> tuple[float, float] | None:
    return None if numbers is None else (numbers[0], numbers[1])
