"""What the learning page works on: the omni-image, its circles, the landmarks, the camera, the last fit.

Convention: pixel (u, v) = (column, row), the centre of the top-left pixel at
(0, 0); world Z up; the camera position is the mirror (lens) centre O_m.

The session holds no geometry: it validates what the page sends (with
:mod:`panomap.learn.validate`), fits with :func:`panomap.calibrate_camera`
(the path ``panomap fit`` takes), and draws previews with the library's views.
Every change refits at once (the page debounces) and then replaces the state.
The fit runs outside the state's lock (changes are fitted one at a time, under
a lock of their own), so the page's reads are answered while a long fit runs;
they see the previous state until the new one is complete.
Files are read and written only in ``folder``, by bare name, atomically; an
existing file is replaced only when the request says ``overwrite``.
"""

from __future__ import annotations

import hashlib
import math
import threading
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..calibrate.boards.detect import find_boards
from ..calibrate.circles import ImageCircles
from ..calibrate.core.report import table_fit_report
from ..calibrate.core.sources import Source
from ..calibrate.landmarks.diagnosis import diagnose
from ..calibrate.landmarks.joint import ImageLines
from ..calibrate.landmarks.pairs import MIN_LANDMARKS, Landmarks, landmarks_to_csv, landmarks_to_json, read_landmarks
from ..calibrate.landmarks.pipeline import (
    CircleChoice,
    calibrate_camera,
    choose_circles,
    image_lines,
    landmarks_past_rim,
    rim_without_landmarks_past_it,
)
from ..camera.radial_models import MODELS
from ..errors import PanomapError
from ..files import write_text_atomic
from ..geometry import inside_image
from ..io.images import encode_png
from ..io.plot import fit_curve
from ..remap import Remapper
from ..table.file import save_table
from ..table.table import PanoMappingTable
from ..views import GenericPanorama, build_map
from .lines import LineLearning, learn_from_lines, line_status
from .validate import (
    MAX_LANDMARKS,
    MAX_WORLD_ABS,
    RequestError,
    file_name,
    finite,
    landmark_name,
    numbers,
    only_keys,
)

LANDMARK_SUFFIXES = (".csv", ".json")
TABLE_SUFFIXES = (".npz",)
PREVIEW_SIZE = (720, 180)
HORIZON_POINTS = 360  # azimuths at which the fit's horizon is sent to the page
FIT_MODELS = ("auto", *MODELS)
# The landmarks' pixel noise the page assumes (calibrate_camera's default), px.
PIXEL_SIGMA = 1.0


@dataclass(frozen=True)
class Entry:
    """One landmark on the page: its pixel (px) and, once typed, its world point (world units)."""

    name: str
    u: float
    v: float
    world: tuple[float, float, float] | None

    def to_dict(self) -> dict[str, Any]:
        x, y, z = self.world if self.world is not None else (None, None, None)
        return {"name": self.name, "u": self.u, "v": self.v, "X": x, "Y": y, "Z": z}


@dataclass(frozen=True)
class Circles:
    """The image centre (u0, v0) and the annulus: cut-off and outer radius, px."""

    centre: tuple[float, float]
    cutoff_radius: float
    outer_radius: float

    def to_dict(self) -> dict[str, Any]:
        return {"centre": list(self.centre), "cutoff_radius": self.cutoff_radius, "outer_radius": self.outer_radius}


class Session:
    """The state behind one ``panomap learn`` server; safe to use from several threads.

    Parameters
    ----------
    image : (H, W[, C]) ndarray
        The omni-image (8- or 16-bit).
    image_name : str
        Shown on the page.
    folder : path-like
        The only folder files are saved to and loaded from.
    landmarks : Landmarks, optional
        Preloaded landmarks.
    camera : (X0, Y0, Z0), optional
        Preloaded camera position (else the landmarks' JSON camera, if any).
    """

    def __init__(
        self,
        image: NDArray[Any],
        image_name: str,
        folder: str | Path,
        landmarks: Landmarks | None = None,
        camera: tuple[float, float, float] | None = None,
    ) -> None:
        self.folder = Path(folder).resolve()
        if not self.folder.is_dir():
            raise PanomapError("not a folder", folder)
        self.image = image
        self.image_name = image_name
        self.image_size = (int(image.shape[1]), int(image.shape[0]))
        self.image_png = encode_png(image)
        # _lock guards the state (short holds only); _fit_lock lets one change be fitted at a time.
        self._lock = threading.Lock()
        self._fit_lock = threading.Lock()
        self._guess_sources = {"centre": Source.FRAME_CENTRE}
        self._found: CircleChoice | None = None  # the circles found, where a rim was
        self._opened_with: CircleChoice | None = None  # what was found when the page opened, rim or not
        self.circles, self.detected, self.circles_note = self._start_circles()
        # The page's first circles, when no rim was found: their centre only starts the fit (refined).
        self._guess = self.circles if self.detected is None else None
        # The rim found, to go back to; and once landmarks lie well outside it, the circles of an image with no rim.
        self._as_found = (self.circles, self.detected, self.circles_note)
        self._without_rim: tuple[Circles, dict[str, Source], str] | None = None
        self.entries: list[Entry] = []
        self.camera = camera
        if landmarks is not None:
            # The same checks as the page's landmarks: names fit a CSV, pixels are in the image.
            try:
                self.entries = self._entries(landmarks.to_records())
            except RequestError as exc:
                raise PanomapError(f"the landmarks to start with: {exc.detail}") from None
            if camera is None and landmarks.camera is not None:
                try:
                    self.camera = self._camera(list(landmarks.camera))
                except RequestError as exc:
                    raise PanomapError(f"the landmarks to start with: {exc.detail}") from None
        self.model = "auto"
        # The image's edge arcs (and their line fit, once made), found at the first fit that needs them.
        self._lines: ImageLines | None = None
        self._boards_looked_for = False
        self._learned: LineLearning | None = None  # the camera learned from lines, once asked for
        self.lines_status: dict[str, Any] = {}
        self.revision = 0
        self.table: PanoMappingTable | None = None
        self.fit_status: dict[str, Any] = {}
        self._preview: tuple[int, bytes] | None = None
        self._commit(self.camera, self.circles, self.entries, self.model)

    # ------------------------------------------------------------------ state

    def _start_circles(self) -> tuple[Circles, dict[str, Any] | None, str | None]:
        width, height = self.image_size
        guess = Circles(((width - 1) / 2, (height - 1) / 2), 0.0, min(width, height) / 2 - 0.5)
        try:
            found = choose_circles(self.image)
        except PanomapError as exc:
            guessed = f"could not find the image circles ({exc.detail}); starting from a guess: drag them into place"
            return guess, None, guessed
        self._opened_with = found
        if found.circles is None:
            # No rim at all (a full-frame fisheye): the frame centre, refined by the landmarks, and as
            # ``panomap fit --image`` does, a table of the whole frame (the outer circle through its corners).
            # A mirror image that overfills the frame shows its cut-off disc: its centre and radius.
            if found.cutoff_disc is not None:
                self._guess_sources = {"centre": Source.CUTOFF_DISC_CENTRE, "cutoff_radius": Source.DETECTED}
                disc = found.cutoff_disc
                whole = Circles(disc.centre, disc.radius, math.hypot(width, height) / 2)
                note = f"{found.warnings[0]}; the outer circle takes in the whole frame" if found.warnings else None
                return whole, None, note
            whole = Circles(guess.centre, 0.0, math.hypot(width, height) / 2)
            note = f"{found.warnings[0]}; the outer circle takes in the whole frame" if found.warnings else None
            return whole, None, note
        self._found = found
        centre, cutoff, outer = found.settled()
        none = found.sources["cutoff_radius"].source is Source.DETECTED_NONE
        note = "no cut-off disc found (a fisheye?): the cut-off radius is 0" if none else None
        return Circles(centre, cutoff, outer), None if found.circles is None else found.circles.to_dict(), note

    def state(self) -> dict[str, Any]:
        """Everything the page shows, as JSON-ready data."""
        with self._lock:
            return self._state()

    def _state(self) -> dict[str, Any]:
        width, height = self.image_size
        return {
            "image": {"name": self.image_name, "width": width, "height": height},
            "circles": self.circles.to_dict() | {"detected": self.detected, "note": self.circles_note},
            "camera": None if self.camera is None else list(self.camera),
            "landmarks": [e.to_dict() for e in self.entries],
            "model": self.model,
            "models": list(FIT_MODELS),
            "folder": str(self.folder),
            "revision": self.revision,
            "fit": self.fit_status,
            "lines": self.lines_status,
        }

    def update(self, data: dict[str, Any]) -> dict[str, Any]:
        """Replace the fields ``data`` holds (camera, circles, landmarks, model), refit, return the state."""
        only_keys(data, ("camera", "circles", "landmarks", "model"), "state")
        given: dict[str, Any] = {}
        if "camera" in data:
            given["camera"] = None if data["camera"] is None else self._camera(data["camera"])
        if "circles" in data:
            given["circles"] = self._circles(data["circles"])
        if "landmarks" in data:
            given["entries"] = self._entries(data["landmarks"])
        if "model" in data:
            if data["model"] not in FIT_MODELS:
                raise RequestError(f"model must be one of {', '.join(FIT_MODELS)}, not {data['model']!r}")
            given["model"] = str(data["model"])
        with self._fit_lock:  # the fields not given are those of the change fitted last
            return self._commit(
                given.get("camera", self.camera),
                given.get("circles", self.circles),
                given.get("entries", self.entries),
                given.get("model", self.model),
            )

    def _commit(
        self,
        camera: tuple[float, float, float] | None,
        circles: Circles,
        entries: list[Entry],
        model: str,
    ) -> dict[str, Any]:
        """Fit these inputs (without the state's lock), then make them and the fit the state; return it.

        Called with ``_fit_lock`` held (or before the session is shared), so
        the revision cannot change during the fit.
        """
        revision = self.revision + 1
        circles = self._rim_checked(circles, entries)
        table, status = self._fit(camera, circles, entries, model, revision)
        with self._lock:
            self.camera, self.circles, self.entries, self.model = camera, circles, entries, model
            self.revision, self.table, self.fit_status = revision, table, status
            return self._state()

    def _rim_checked(self, circles: Circles, entries: list[Entry]) -> Circles:
        """``circles``; or where they are the rim found and two or more landmarks lie well outside it (a circle of
        the scene, not the image circle), the circles ``panomap fit --image`` then takes: the cut-off disc found
        without a rim or the frame's middle, refined, and the whole frame, with a note; back to the rim found when
        the landmarks no longer contradict it. Circles set on the page are left as they are.

        Called with ``_fit_lock`` held (it sets what :meth:`_sources` reads before the fit).
        """
        if self._found is None or self._found.circles is None:
            return circles
        rim_circles, detected, note = self._as_found
        pixels = np.array([[e.u, e.v] for e in entries], dtype=float).reshape(-1, 2)
        contradicted = landmarks_past_rim(self._found.circles.outer, pixels, PIXEL_SIGMA) >= 2
        if contradicted and circles == rim_circles:
            if self._without_rim is None:
                choice = rim_without_landmarks_past_it(self._found, pixels, PIXEL_SIGMA, self.image, None)
                if choice.centre is None or not choice.warnings:  # (not reached: the rim found gives a centre)
                    return circles
                width, height = self.image_size
                whole = Circles(choice.centre, choice.cutoff_radius or 0.0, math.hypot(width, height) / 2)
                sources = {name: origin.source for name, origin in choice.sources.items()}
                self._without_rim = (whole, sources, f"{choice.warnings[0]}; the outer circle takes in the whole frame")
            whole, sources, why = self._without_rim
            with self._lock:
                self.detected, self.circles_note, self._guess, self._guess_sources = None, why, whole, sources
            return whole
        if not contradicted and self._without_rim is not None and circles == self._without_rim[0]:
            with self._lock:
                self.detected, self.circles_note, self._guess = detected, note, None
                self._guess_sources = {"centre": Source.FRAME_CENTRE}
            return rim_circles
        return circles

    @staticmethod
    def _camera(value: Any) -> tuple[float, float, float]:
        x, y, z = numbers(value, 3, "camera", MAX_WORLD_ABS)
        return (x, y, z)

    def _circles(self, value: Any) -> Circles:
        if not isinstance(value, dict):
            raise RequestError("circles must be an object with centre, cutoff_radius, outer_radius")
        only_keys(value, ("centre", "cutoff_radius", "outer_radius"), "circles")
        missing = [k for k in ("centre", "cutoff_radius", "outer_radius") if k not in value]
        if missing:
            raise RequestError(f"circles: missing {', '.join(missing)}")
        width, height = self.image_size
        u0, v0 = numbers(value["centre"], 2, "circles.centre")
        if not inside_image(u0, v0, self.image_size):
            raise RequestError(f"the centre ({u0:g}, {v0:g}) is outside the {width} x {height} image")
        cutoff = finite(value["cutoff_radius"], "circles.cutoff_radius")
        outer = finite(value["outer_radius"], "circles.outer_radius")
        if not 0 <= cutoff < outer <= 2 * math.hypot(width, height):
            raise RequestError(
                f"the radii must satisfy 0 <= cut-off ({cutoff:g}) < outer ({outer:g}) <= twice the image diagonal"
            )
        return Circles((u0, v0), cutoff, outer)

    def _entries(self, value: Any) -> list[Entry]:
        if not isinstance(value, list):
            raise RequestError("landmarks must be a list")
        if len(value) > MAX_LANDMARKS:
            raise RequestError(f"{len(value)} landmarks is more than the limit of {MAX_LANDMARKS}")
        width, height = self.image_size
        entries, seen = [], set()
        for k, item in enumerate(value, start=1):
            what = f"landmark {k}"
            if not isinstance(item, dict):
                raise RequestError(f"{what} must be an object with name, u, v, X, Y, Z")
            only_keys(item, ("name", "u", "v", "X", "Y", "Z"), what)
            name = landmark_name(item.get("name"), what)
            what = f"landmark {k} ({name})"
            if name in seen:
                raise RequestError(f"two landmarks are named {name!r}; names must differ")
            seen.add(name)
            u, v = finite(item.get("u"), f"{what}: u"), finite(item.get("v"), f"{what}: v")
            if not inside_image(u, v, self.image_size):
                raise RequestError(f"{what}: pixel ({u:g}, {v:g}) is outside the {width} x {height} image")
            given = [item.get(c) for c in ("X", "Y", "Z")]
            if all(c is None for c in given):
                world = None
            else:
                x, y, z = (finite(c, f"{what}: {axis}", MAX_WORLD_ABS) for c, axis in zip(given, "XYZ", strict=True))
                world = (x, y, z)
            entries.append(Entry(name, u, v, world))
        return entries

    # ------------------------------------------------------------------ fit

    @staticmethod
    def _complete(entries: list[Entry], camera: tuple[float, float, float] | None) -> Landmarks:
        done = [e for e in entries if e.world is not None]
        return Landmarks(
            np.array([[e.u, e.v] for e in done], dtype=float).reshape(-1, 2),
            np.array([e.world for e in done], dtype=float).reshape(-1, 3),
            tuple(e.name for e in done),
            camera,
        )

    def _fit(
        self,
        camera: tuple[float, float, float] | None,
        circles: Circles,
        entries: list[Entry],
        model: str,
        revision: int,
    ) -> tuple[PanoMappingTable | None, dict[str, Any]]:
        """The table (None without a fit) and the fit's status for these inputs; reads no mutable state."""
        table = None
        landmarks = self._complete(entries, camera)
        waiting = len(entries) - len(landmarks)
        status: dict[str, Any] = {"ok": False, "revision": revision, "complete": len(landmarks)}
        pending = f" ({waiting} still without a world point)" if waiting else ""
        if len(landmarks) < MIN_LANDMARKS:
            need = MIN_LANDMARKS - len(landmarks)
            status |= {"need": need, "message": f"need {need} more landmark(s) with world points to fit{pending}"}
        elif camera is None:
            status |= {"need": 0, "message": "give the camera position X0, Y0, Z0 to fit"}
        else:
            try:
                if self._opened_with is not None and circles == self._as_found[0]:
                    # The circles found, unchanged: fitted as `panomap fit --image` fits with them (the cut-off
                    # disc then looked for again about a fitted centre that ends away from the rim's, say).
                    # The image's straight lines join the fit, as they do in `panomap fit --image`.
                    calibration = calibrate_camera(
                        landmarks,
                        camera,
                        omni=self.image,
                        omni_name=self.image_name,
                        found=self._opened_with,
                        model=model,
                        sources={"camera_position": Source.GIVEN},
                        info=self._info(),
                        lines=self._image_lines() or True,
                    )
                else:
                    calibration = calibrate_camera(
                        landmarks,
                        camera,
                        centre=circles.centre,
                        cutoff_radius=circles.cutoff_radius,
                        outer_radius=circles.outer_radius,
                        image_size=self.image_size,
                        model=model,
                        sources=self._sources(circles),
                        info=self._info(),
                    )
            except PanomapError as exc:
                status |= {"need": 0, "message": f"the fit failed: {exc.detail}"}
            else:
                table = calibration.table
                status = self._fit_report(table, entries, revision, pending) | {
                    "diagnosis": diagnose(
                        calibration.fit, centre_guessed=calibration.sources["centre"].source is Source.FRAME_CENTRE
                    )
                }
                if calibration.fit.lines_note is not None and calibration.fit.lines_note_warns:  # lines left out
                    status["warnings"] = [*status["warnings"], calibration.fit.lines_note]
        return table, status

    def _image_lines(self) -> ImageLines | None:
        """The edge arcs of the image inside the circles found (None where no rim was found), found once.

        Called with ``_fit_lock`` held.
        """
        if self._lines is None and self._found is not None and self._found.circles is not None:
            self._lines = _shared_lines(self.image, self._found.circles)
        return self._lines

    # ------------------------------------------------------------------ learning from lines

    def learn_lines(self, data: dict[str, Any]) -> dict[str, Any]:
        """Learn the camera from the image's straight lines (no landmark needed); return the state.

        A failure (no rim found, too few lines) is the lines' status, with its message, not an error.
        """
        only_keys(data, (), "lines")
        with self._fit_lock:
            lines = self._image_lines()
            if lines is not None and not self._boards_looked_for:  # the checkerboards come first, looked for once
                lines = self._lines = replace(lines, boards=find_boards(self.image), _learned={})
                self._boards_looked_for = True
            with self._lock:
                revision = self.lines_status.get("revision", 0) + 1
            if lines is None:
                learned, status = (
                    None,
                    {
                        "ok": False,
                        "revision": revision,
                        "message": "no image circle was found: learning from lines needs its centre and radius",
                    },
                )
            else:
                try:
                    learned = learn_from_lines(self.image, lines, self.image_name)
                except PanomapError as exc:
                    learned = None
                    status = {"ok": False, "revision": revision, "message": f"learning from lines failed: {exc.detail}"}
                else:
                    status = line_status(learned, lines, revision, _horizon(learned.table))
            with self._lock:
                self._learned, self.lines_status = learned, status
                return self._state()

    def line_azimuth(self, data: dict[str, Any]) -> dict[str, Any]:
        """Set the pixel ``{"u", "v"}`` that sees world azimuth 0 on the camera learned from lines; return the state."""
        only_keys(data, ("u", "v"), "lines azimuth")
        u, v = finite(data.get("u"), "u"), finite(data.get("v"), "v")
        if not inside_image(u, v, self.image_size):
            width, height = self.image_size
            raise RequestError(f"the pixel ({u:g}, {v:g}) is outside the {width} x {height} image")
        with self._fit_lock:
            lines = self._lines
            if self._learned is None or lines is None:
                raise RequestError("no camera learned from lines yet: learn from lines first", 409)
            learned = learn_from_lines(self.image, lines, self.image_name, (u, v))
            with self._lock:
                revision = self.lines_status.get("revision", 0) + 1
                self._learned = learned
                self.lines_status = line_status(learned, lines, revision, _horizon(learned.table))
                return self._state()

    def save_line_table(self, name: Any, overwrite: bool = False) -> str:
        """Write the table of the camera learned from lines (.npz) into the folder; returns the file name.

        An existing file of that name is replaced only if ``overwrite``.
        """
        with self._lock:
            path = self._path(name, TABLE_SUFFIXES, "save line table")
            if self._learned is None:
                raise RequestError("no camera learned from lines to save: learn from lines first", 409)
            self._replaceable(path, overwrite, "save line table")
            table = self._learned.table
            self._write(path, lambda target: save_table(table, target))
            return path.name

    def _sources(self, circles: Circles | None = None) -> dict[str, Source]:
        """The circles (the state's, by default) as detected, or set on the page; the camera position given."""
        circles = self.circles if circles is None else circles
        detected = self.detected
        adjusted = detected is None or (
            tuple(detected["centre"]) != circles.centre
            or detected["outer_radius"] != circles.outer_radius
            or (detected["cutoff_radius"] or 0.0) != circles.cutoff_radius
        )
        how = Source.SET_IN_LEARN if adjusted else Source.DETECTED
        centre = outer = cutoff = how
        if self._guess is not None and circles.centre == self._guess.centre:
            centre = self._guess_sources["centre"]
        if self._guess is not None and circles.cutoff_radius == self._guess.cutoff_radius:
            cutoff = self._guess_sources.get("cutoff_radius", cutoff)
        if self._guess is not None and self.detected is None and circles.outer_radius == self._guess.outer_radius:
            width, height = self.image_size
            if circles.outer_radius == math.hypot(width, height) / 2:
                outer = Source.DEFAULT_WHOLE_FRAME
        return {"centre": centre, "cutoff_radius": cutoff, "outer_radius": outer, "camera_position": Source.GIVEN}

    def _info(self) -> dict[str, Any]:
        info: dict[str, Any] = {"learned_with": f"panomap learn on {self.image_name}"}
        if self.detected is not None:
            info["image_circles"] = self.detected
        return info

    @staticmethod
    def _fit_report(table: PanoMappingTable, entries: list[Entry], revision: int, pending: str) -> dict[str, Any]:
        fit = table_fit_report(table)
        if fit is None:  # (calibrate_camera always writes one)
            raise AssertionError("a table made by calibrate_camera has a fit report")
        curve = fit_curve(table)
        by_name = {row.name: row for row in fit.landmarks}
        rows = []
        for entry in entries:
            row = by_name.get(entry.name)
            if row is not None:
                rows.append(
                    {
                        "name": entry.name,
                        "residual_px": row.residual_px,
                        "outlier": row.outlier,
                        "u_fit": row.u_fit,
                        "v_fit": row.v_fit,
                        "elevation_deg": row.elevation_deg,
                        "azimuth_deg": row.azimuth_deg,
                    }
                )
        m, n = table.size
        outliers = ", ".join(fit.outliers) or "none"
        centre = fit.centre_sentence()
        refined = "" if centre is None else f"; {centre}"
        mount = fit.mount
        if mount is not None:
            refined += "".join(f"; {sentence}" for sentence in mount.sentences())
        if fit.lines is not None:
            refined += f"; {len(fit.lines.lines)} straight lines of the image joined (RMS {fit.lines.rms_px:.2f} px)"
        return {
            "ok": True,
            "revision": revision,
            "complete": len(by_name),
            "need": 0,
            "message": (
                f"model {fit.model}: RMS {fit.rms_px:.3f} px, max {fit.max_px:.3f} px over "
                f"{len(by_name) - len(fit.outliers)} landmarks; outliers: {outliers}{refined}{pending}"
            ),
            "centre": list(fit.centre),
            "centre_refined": fit.settings.refine_centre,
            "model": fit.model,
            "rms_px": fit.rms_px,
            "max_px": fit.max_px,
            "s": fit.s,
            "phi0_deg": fit.phi0_deg,
            "axis": fit.axis,
            "outliers": list(fit.outliers),
            "lines_joined": 0 if fit.lines is None else len(fit.lines.lines),
            "tilt_deg": 0.0 if mount is None else mount.tilt_deg,
            "tilt_toward_deg": 0.0 if mount is None else mount.toward_deg,
            "tilt_se_deg": None if mount is None else mount.tilt_se_deg,
            "camera": list(table.camera_position),
            "camera_refined": mount is not None and mount.position_refined,
            "warnings": table.info.get("warnings", []),
            "table_size": [m, n],
            "elevation_range_deg": [math.degrees(x) for x in table.elevation_range],
            "landmarks": rows,
            "curve": curve,
            "horizon": _horizon(table),
        }

    # ------------------------------------------------------------------ previews and files

    def panorama_png(self) -> bytes:
        """The generic panorama of the current fit, ``PREVIEW_SIZE``, as PNG (cached per fit)."""
        with self._lock:
            if self.table is None:
                raise RequestError(f"no fit yet: {self.fit_status.get('message', '')}", 409)
            if self._preview is None or self._preview[0] != self.revision:
                view = GenericPanorama(PREVIEW_SIZE)
                remap = Remapper(build_map(self.table, view), self.image_size)
                self._preview = (self.revision, encode_png(remap(self.image)))
            return self._preview[1]

    def _path(self, value: Any, suffixes: tuple[str, ...], what: str) -> Path:
        name = file_name(value, suffixes, what)
        path = self.folder / name
        # Belt and braces: a bare name (checked above) cannot leave the folder. A symbolic link
        # of that name is replaced by the atomic write, never written through; loads refuse it.
        if path.parent != self.folder:
            raise RequestError(f"{what}: {name!r} is not in the folder {self.folder}")
        return path

    def _replaceable(self, path: Path, overwrite: bool, what: str) -> None:
        """Refuse a folder of that name, and an existing file unless ``overwrite`` (409, with ``exists``)."""
        if path.is_dir():
            raise RequestError(f"{what}: {path.name!r} is a folder in {self.folder}, not a file; choose another name")
        if (path.exists() or path.is_symlink()) and not overwrite:
            raise RequestError(
                f"{what}: {path.name!r} already exists in {self.folder}; send overwrite to replace it",
                409,
                {"exists": path.name},
            )

    def _write(self, path: Path, write: Any) -> None:
        """Run ``write(path)``; an error names the bare file name, not the server's folder."""
        try:
            write(path)
        except PanomapError as exc:
            raise RequestError(f"{path.name}: {exc.detail}") from None

    def save_landmarks(self, name: Any, overwrite: bool = False) -> str:
        """Write the landmarks (CSV, or JSON with the camera) into the folder; returns the file name.

        An existing file of that name is replaced only if ``overwrite``.
        """
        with self._lock:
            path = self._path(name, LANDMARK_SUFFIXES, "save landmarks")
            waiting = [e.name for e in self.entries if e.world is None]
            if waiting:
                raise RequestError(f"landmark(s) {', '.join(waiting)} have no world point yet; type X, Y, Z first")
            if not self.entries:
                raise RequestError("there are no landmarks to save")
            self._replaceable(path, overwrite, "save landmarks")
            landmarks = self._complete(self.entries, self.camera)
            text = landmarks_to_json(landmarks) if path.suffix.lower() == ".json" else landmarks_to_csv(landmarks)
            self._write(path, lambda p: write_text_atomic(p, text))
            return path.name

    def load_landmarks(self, name: Any) -> dict[str, Any]:
        """Replace the landmarks (and the camera, when the JSON has one) from a file in the folder."""
        path = self._path(name, LANDMARK_SUFFIXES, "load landmarks")
        if path.is_symlink() or not path.is_file():
            raise RequestError(f"load landmarks: there is no file {path.name!r} in {self.folder}", 404)
        try:
            landmarks = read_landmarks(path)
        except PanomapError as exc:
            raise RequestError(f"load landmarks: {path.name}: {exc.detail}") from None
        # The same checks as typed landmarks and camera: names, pixels in the image, the 1e6 limit.
        try:
            entries = self._entries(landmarks.to_records())
            camera = None if landmarks.camera is None else self._camera(list(landmarks.camera))
        except RequestError as exc:
            raise RequestError(f"load landmarks: {path.name}: {exc.detail}") from None
        with self._fit_lock:
            return self._commit(self.camera if camera is None else camera, self.circles, entries, self.model)

    def save_table(self, name: Any, overwrite: bool = False) -> str:
        """Write the current fit's table (.npz) into the folder; returns the file name.

        An existing file of that name is replaced only if ``overwrite``.
        """
        with self._lock:
            path = self._path(name, TABLE_SUFFIXES, "save table")
            if self.table is None:
                raise RequestError(f"no table to save: {self.fit_status.get('message', 'no fit')}", 409)
            self._replaceable(path, overwrite, "save table")
            table = self.table
            self._write(path, lambda target: save_table(table, target))
            return path.name

    def files(self) -> dict[str, list[str]]:
        """The landmark and table files in the folder, by name."""
        names = sorted(p.name for p in self.folder.iterdir() if p.is_file() and not p.name.startswith("."))
        return {
            "landmarks": [n for n in names if n.lower().endswith(LANDMARK_SUFFIXES)],
            "tables": [n for n in names if n.lower().endswith(TABLE_SUFFIXES)],
        }


# The edge arcs (and line fits) of the last few images served, by the image's digest and circles: a session
# opened again on the same image (a restarted page, a test suite's many sessions) finds its lines once.
_LINES_KEPT = 4
_lines_lock = threading.Lock()
_lines_seen: dict[tuple[str, str], ImageLines] = {}


def _shared_lines(image: NDArray[Any], circles: ImageCircles) -> ImageLines:
    """The :class:`ImageLines` of ``image`` inside ``circles``, found once per image and circles."""
    key = (hashlib.sha256(np.ascontiguousarray(image).tobytes()).hexdigest(), repr(circles.to_dict()))
    with _lines_lock:
        if key not in _lines_seen:
            if len(_lines_seen) >= _LINES_KEPT:
                del _lines_seen[next(iter(_lines_seen))]
            _lines_seen[key] = image_lines(image, circles)
        return _lines_seen[key]


def _horizon(table: PanoMappingTable) -> list[list[float] | None] | None:
    """Where the table puts the world's horizon (elevation 0): a pixel [u, v] (px) at each of HORIZON_POINTS
    azimuths from 0 (a null where the camera does not see it), for the page to draw; None when the table's
    elevations do not reach it. Off-centre on a tilted camera, it shows the tilt."""
    low, high = table.elevation_range
    if not low <= 0.0 <= high:
        return None
    theta = np.linspace(0.0, 2 * math.pi, HORIZON_POINTS, endpoint=False)
    pixels = np.asarray(table.sample(theta, np.zeros_like(theta)), dtype=np.float64)
    return [[float(u), float(v)] if math.isfinite(u) and math.isfinite(v) else None for u, v in pixels.tolist()]
