"""The robust spread against the normal distribution's closed form."""

from __future__ import annotations

from statistics import NormalDist

import numpy as np
import pytest

from panomap.robust import mad_sigma


def test_normal_values_give_their_standard_deviation_unmoved_by_outliers() -> None:
    rng = np.random.default_rng(7)
    values = rng.normal(0.0, 2.5, 200_000)
    assert mad_sigma(values) == pytest.approx(2.5, rel=0.01)
    # 30% of the values thrown far away: the median absolute deviation widens by less than the sample's spread would.
    spoiled = values.copy()
    spoiled[:60_000] = rng.uniform(1e3, 1e4, 60_000)
    assert mad_sigma(spoiled[60_000:]) == pytest.approx(2.5, rel=0.01)
    # The outliers' share moves the median, not their size: the median |value| is now the normal's 5/7 quantile of
    # |x| (0.7 P(|x| < q) = 1/2), 2.5 x 1.0676, so the sigma read is 1.58 times the truth (closed form).
    share_quantile = NormalDist().inv_cdf(0.5 + 0.5 * (0.5 / 0.7))
    assert mad_sigma(spoiled) == pytest.approx(2.5 * share_quantile / NormalDist().inv_cdf(0.75), rel=0.01)
    assert float(np.std(spoiled)) > 1000


def test_about_the_median_and_along_an_axis() -> None:
    rng = np.random.default_rng(8)
    columns = rng.normal([100.0, -3.0], [1.0, 4.0], (100_000, 2))
    assert mad_sigma(columns[:, 0], centre="median") == pytest.approx(1.0, rel=0.02)
    assert mad_sigma(columns[:, 0], centre=100.0) == pytest.approx(1.0, rel=0.02)
    assert mad_sigma(columns[:, 0]) > 99  # about 0, as residuals are: the level is not the spread
    spread = mad_sigma(columns, centre="median", axis=0)
    assert spread.shape == (2,)
    np.testing.assert_allclose(spread, [1.0, 4.0], rtol=0.02)
    # The exact value on a small set: deviations 0, 1, 1, 2, 3 about the median 3 have median 1.
    assert mad_sigma(np.array([3.0, 2.0, 4.0, 1.0, 6.0]), centre="median") == pytest.approx(1.4826)
