"""``panomap.learn_from_images``: what it refuses before any work (the fit itself is tested through the
command, tests/test_line_fit.py and tests/test_learn_lines.py, and the manual's script, tests/test_docs.py)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import panomap
from panomap.errors import PanomapError


def test_no_image_is_refused() -> None:
    with pytest.raises(PanomapError, match="no image to learn the camera from"):
        panomap.learn_from_images([])


def test_images_of_two_sizes_are_refused_naming_the_one_that_differs() -> None:
    images = [np.zeros((48, 64, 3), np.uint8), np.zeros((48, 64, 3), np.uint8), np.zeros((40, 64, 3), np.uint8)]
    with pytest.raises(PanomapError) as error:
        panomap.learn_from_images(images, names=["a.png", "b.png", "c.png"])
    assert str(error.value) == "c.png: is 64 x 40, but a.png is 64 x 48: the images of one camera have one size"
    with pytest.raises(PanomapError, match=r"^image 2: is 64 x 40, but the first image is 64 x 48"):
        panomap.learn_from_images(images[1:])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"model": "paper"}, "the paper model takes the centre as given"),
        ({"names": ["a.png", "b.png"]}, "2 names for 1 images: give one name per image"),
    ],
)
def test_what_cannot_be_learned_is_refused(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(PanomapError, match=message):
        panomap.learn_from_images(np.zeros((48, 64), np.uint8), **kwargs)
