"""Fixtures shared by the tests; plain helper functions are in helpers.py (``from helpers import ...``).

Test modules import each other's helpers only through this file and helpers.py.
"""

from __future__ import annotations

import pytest

from panomap.simulate.example import Example, make_example


@pytest.fixture(scope="module")
def example(request: pytest.FixtureRequest) -> Example:
    """The simulated camera to learn (:mod:`panomap.simulate.example`): 8 true landmarks on
    the room rendered at the requesting module's ``SIZE`` (width, height), without supersampling."""
    return make_example(request.module.SIZE, count=8, supersample=1)
