"""Issue 55, class I: the Python API's wrong inputs get a PanomapError (or a TypeError for a wrong type).

Before, a float image, an empty, 4-D or raveled one reached OpenCV (``cv2.error``) or NumPy's indexing
(``IndexError``, a reshape's ``ValueError``); a centre given as ``"517 503"`` failed to unpack; landmarks as a
list or a file name raised ``AttributeError``; ``learn_from_images("x.png")`` ``AttributeError``; NaN or an
object in a table's ``info`` came out of ``json`` as its own ``ValueError``/``TypeError``. Every public function
of ``panomap.__all__`` that takes an image, a centre, landmarks or ``info`` is fuzzed here with such inputs:
only PanomapError or TypeError comes out, with one line that names what is wrong (``panomap.inputs``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import panomap
from panomap.simulate import standard_cameras

from helpers import learn_table, spread_landmarks

SIZE = (160, 160)
POSITION = (0.3, -0.2, 2.5)
GOOD = np.zeros((SIZE[1], SIZE[0], 3), np.uint8)
FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


class Chain(tuple):  # type: ignore[type-arg]
    """(landmarks, fit, table), shown short (Hypothesis prints a failing example's arguments)."""

    def __repr__(self) -> str:
        return "Chain(hyperbolic camera, 30 landmarks)"


@pytest.fixture(scope="module")
def chain() -> Chain:
    camera = standard_cameras(SIZE, centre=(80.4, 79.1))["hyperbolic"]
    marks = spread_landmarks(camera, POSITION, 30, np.random.default_rng(5))
    table, fit = learn_table(camera, POSITION, marks, SIZE, table_size=(64, 48))
    return Chain((marks, fit, table))


def refused(call: Callable[[], Any], *names: str) -> str:
    """The message of the PanomapError or TypeError ``call`` raises (anything else, or nothing, fails): one
    line, naming one of ``names`` where given."""
    with pytest.raises((panomap.PanomapError, TypeError)) as caught:
        call()
    message = str(caught.value)
    assert message and "\n" not in message, message
    assert not names or any(name in message for name in names), message
    return message


def readable(image: Any, dtypes: tuple[type, ...] = (np.uint8, np.uint16)) -> bool:
    """Whether ``image`` is one panomap reads (8- or 16-bit, (H, W[, 1|3|4]), not empty)."""
    return (
        isinstance(image, np.ndarray)
        and image.dtype in dtypes
        and (image.ndim == 2 or (image.ndim == 3 and image.shape[2] in (1, 3, 4)))
        and image.size > 0
    )


DTYPES = st.sampled_from([np.float32, np.float64, np.int8, np.int16, np.int64, np.bool_, np.uint8, np.uint16])
ARRAYS = hnp.arrays(DTYPES, hnp.array_shapes(min_dims=0, max_dims=5, min_side=0, max_side=6))
NOT_ARRAYS = st.sampled_from(["x.png", Path("x.png"), None, 3, [[1, 2], [3, 4]], b"\x89PNG", {"image": 1}])
# The ones the issue names: a float image, an empty one, a 4-D one, a raveled one.
NAMED = [GOOD.astype(np.float64), GOOD[:0], GOOD[None], GOOD.ravel(), GOOD[..., :2]]


def image_calls(
    chain: tuple[Any, Any, Any], tmp_path: Path
) -> dict[str, Callable[[Any], Any]]:  # each public function that takes an image, with the rest right
    marks, _, table = chain
    remapper = panomap.GenericPanorama(size=(32, 8)).remapper(table)
    return {
        "find_image_circles": panomap.find_image_circles,
        "choose_circles": panomap.choose_circles,
        "calibrate_camera": lambda image: panomap.calibrate_camera(marks, POSITION, omni=image),
        "learn_from_images([image])": lambda image: panomap.learn_from_images([image]),
        "learn_from_images(image)": panomap.learn_from_images,
        "write_image": lambda image: panomap.write_image(tmp_path / "out.png", image),
        "Remapper": remapper,
    }


@pytest.mark.parametrize("image", NAMED, ids=["float", "empty", "4-D", "raveled", "2 channels"])
def test_the_images_the_issue_names_are_refused_by_every_function(chain, tmp_path: Path, image: Any) -> None:
    for name, call in image_calls(chain, tmp_path).items():
        message = refused(lambda call=call: call(image), "must", "empty")
        assert "cv2" not in message and "OpenCV" not in message, (name, message)
    assert not (tmp_path / "out.png").exists()


@FUZZ
@given(image=st.one_of(ARRAYS, NOT_ARRAYS))
def test_images_panomap_cannot_read_are_refused_by_every_function(chain, tmp_path: Path, image: Any) -> None:
    if readable(image):
        return
    for name, call in image_calls(chain, tmp_path).items():
        if name == "Remapper" and readable(image, (np.uint8, np.uint16, np.float32)):
            continue  # (a remapper takes float32 frames too)
        if name == "calibrate_camera" and image is None:
            continue  # (no omni-image: the centre must be given, and is missing)
        refused(lambda call=call: call(image), "must", "empty")


NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(-(10**30), 10**30), st.text(max_size=4), st.none()
)
CENTRES = st.one_of(
    st.sampled_from(["517 503", "517,503", b"12", {"u": 1, "v": 2}, 5, None, math.nan, object()]),
    st.lists(NUMBERS, max_size=4).map(tuple),
)


def numbers_are_good(centre: Any, count: int = 2) -> bool:
    if isinstance(centre, str | bytes) or not isinstance(centre, tuple) or len(centre) != count:
        return False
    return all(
        isinstance(c, int | float) and not isinstance(c, bool) and math.isfinite(c) and abs(c) <= 1e9 for c in centre
    )


@FUZZ
@given(centre=CENTRES)
def test_centres_that_are_no_two_numbers_are_refused(chain, centre: Any) -> None:
    if numbers_are_good(centre):
        return
    marks, _, _ = chain
    calls = {
        "fit_camera": lambda: panomap.fit_camera(marks, POSITION, centre),
        "calibrate_camera": lambda: panomap.calibrate_camera(marks, POSITION, centre=centre, image_size=SIZE),
        "choose_circles": lambda: panomap.choose_circles(GOOD, centre=centre, cutoff_radius=5, outer_radius=70),
        "learn_from_images": lambda: panomap.learn_from_images([GOOD], azimuth_zero=centre),
        "fit_camera position": lambda: panomap.fit_camera(marks, centre, (80, 80)),
    }
    for name, call in calls.items():
        if centre is None and not name.startswith("fit_camera"):  # (None: not given, found or the default)
            continue
        if name == "fit_camera position" and numbers_are_good(centre, 3):
            continue
        refused(call, "centre", "azimuth_zero", "camera position")


def test_the_centre_as_text_names_what_it_must_be(chain) -> None:
    marks, _, _ = chain
    message = refused(lambda: panomap.fit_camera(marks, POSITION, "517 503"))
    assert message == "the image centre (u0, v0) must be 2 numbers, not a str ('517 503')"


@pytest.mark.parametrize(
    "landmarks",
    [[(1.0, 2.0, 3.0, 4.0, 5.0)] * 6, "marks.csv", Path("marks.csv"), {"a": 1}, None, np.zeros((6, 5))],
    ids=["list", "str", "path", "dict", "None", "array"],
)
def test_landmarks_that_are_no_landmarks_are_a_type_error(landmarks: Any) -> None:
    calls = [
        lambda: panomap.fit_camera(landmarks, POSITION, (80, 80)),
        lambda: panomap.calibrate_camera(landmarks, POSITION, centre=(80, 80), image_size=SIZE),
    ]
    for call in calls:
        with pytest.raises(TypeError, match=r"landmarks must be a Landmarks.*read_landmarks"):
            call()


@pytest.mark.parametrize("images", ["x.png", Path("x.png"), b"x", ["x.png"], [GOOD, "y.png"], 7, {"a": GOOD}])
def test_pictures_as_file_names_are_a_type_error(images: Any) -> None:
    with pytest.raises(TypeError, match=r"read_image|images"):
        panomap.learn_from_images(images)


JSON_LEAVES = st.one_of(st.none(), st.booleans(), st.integers(-(10**6), 10**6), st.floats(), st.text(max_size=5))
BAD_LEAVES = st.sampled_from(
    [math.nan, math.inf, -math.inf, 10**400, object(), {1, 2}, np.float32(1.5), np.arange(3), b"x", Path("p")]
)


def with_one_bad_leaf(draw: st.DrawFn) -> dict[str, Any]:
    values = st.recursive(JSON_LEAVES, lambda inner: st.lists(inner, max_size=3))
    base = draw(st.dictionaries(st.text(max_size=5), values))
    bad = draw(BAD_LEAVES)
    nest = draw(st.sampled_from(["flat", "list", "dict", "key"]))
    if nest == "key":
        return base | {"k": {draw(st.sampled_from([1, 2.5, None, (1, 2)])): 1}}
    leaf = {"flat": bad, "list": [1, bad], "dict": {"inner": {"deeper": bad}}}[nest]
    return base | {"bad": leaf}


BAD_INFO = st.composite(with_one_bad_leaf)()


def info_calls(chain: tuple[Any, Any, Any], tmp_path: Path, info: Any) -> dict[str, Callable[[], Any]]:
    marks, fit, table = chain
    return {
        "save_table": lambda: panomap.save_table(dataclasses.replace(table, info=info), tmp_path / "t.npz"),
        "create_table": lambda: panomap.create_table(fit, size=(64, 48), image_size=SIZE, info=info),
        "calibrate_camera": lambda: panomap.calibrate_camera(
            marks, POSITION, centre=(80.4, 79.1), image_size=SIZE, info=info
        ),
        "learn_from_images": lambda: panomap.learn_from_images([GOOD], info=info),
    }


@FUZZ
@given(info=BAD_INFO)
def test_info_json_cannot_hold_is_refused_naming_where(chain, tmp_path: Path, info: dict[str, Any]) -> None:
    for call in info_calls(chain, tmp_path, info).values():
        message = refused(call)
        assert "info" in message, message  # (refused at the boundary, not by the fit on the black picture)
    assert not (tmp_path / "t.npz").exists()


def test_nan_in_a_tables_info_names_its_key(chain, tmp_path: Path) -> None:
    _, _, table = chain
    bad = dataclasses.replace(table, info={**table.info, "mine": {"gain": [1.0, math.nan]}})
    with pytest.raises(panomap.PanomapError, match=r"info\['mine'\]\['gain'\]\[1\] is nan, not a finite number"):
        panomap.save_table(bad, tmp_path / "t.npz")
    with pytest.raises(TypeError, match=r"info\['x'\] is a float32.*float\(x\)"):
        panomap.save_table(dataclasses.replace(table, info={"x": np.float32(1)}), tmp_path / "t.npz")
    assert not (tmp_path / "t.npz").exists()


def test_good_inputs_still_pass(chain, tmp_path: Path) -> None:
    # The checks take what the API documents: lists and arrays for pairs, NumPy numbers, 16-bit and grey images.
    marks, fit, table = chain
    again = panomap.fit_camera(marks, list(POSITION), np.array(fit.model.centre), model=fit.model.radial.kind)
    assert math.dist(again.model.centre, fit.model.centre) < 1e-6
    panomap.save_table(
        dataclasses.replace(table, info={**table.info, "note": [1, 2.5, None, "x", True]}), tmp_path / "t.npz"
    )
    assert panomap.load_table(tmp_path / "t.npz").info["note"] == [1, 2.5, None, "x", True]
    remapper = panomap.GenericPanorama(size=(32, 8)).remapper(table)
    for image in (GOOD.astype(np.uint16), GOOD[..., 0], GOOD[..., :1], GOOD.astype(np.float32)):
        assert remapper(image).shape[:2] == (8, 32)
    panomap.write_image(tmp_path / "grey.png", GOOD[..., 0].astype(np.uint16))
