"""Fractiles of a study: distribution-free confidence intervals that hold their coverage, censored samples."""

import numpy as np
import pytest

from shellform.studies.statistics import fractile, knockdown_exponent, moments


def test_the_interval_covers_the_true_fractile_as_often_as_it_says():
    rng = np.random.default_rng(3)
    p, n, trials = 0.05, 200, 3000
    true = -np.log(1.0 - p)  # the 5 % fractile of the unit exponential distribution
    first = fractile(rng.exponential(size=n), p, 0.95)
    assert first["coverage"] >= 0.95
    hits, below = 0, 0
    for _ in range(trials):
        f = fractile(rng.exponential(size=n), p, 0.95)
        hits += f["lower"] <= true <= f["upper"]
        below += f["lower_bound"] <= true
    # binomial noise of 3000 trials: 3 standard deviations about 0.012
    assert hits / trials >= first["coverage"] - 0.012
    assert below / trials >= 0.95 - 0.012
    # and not far more than promised: the interval is not needlessly wide
    assert hits / trials <= first["coverage"] + 0.012


def test_order_statistics_and_censored_samples():
    values = np.arange(1.0, 201.0)  # 1 .. 200
    f = fractile(values, 0.05, 0.95)
    assert f["estimate"] == 10.0  # x_(ceil(200 * 0.05))
    assert f["r"] < 10 < f["s"] and f["lower"] == f["r"] and f["upper"] == f["s"]
    # samples above the traced range do not move a lower fractile
    censored = np.concatenate([values[:150], np.full(50, np.inf)])
    g = fractile(censored, 0.05, 0.95)
    assert (g["estimate"], g["lower"], g["upper"]) == (f["estimate"], f["lower"], f["upper"])
    # too few samples for a two-sided interval: the bounds are absent, not made up
    small = fractile(np.arange(1.0, 11.0), 0.05, 0.95)
    assert small["lower"] is None and small["lower_bound"] is None and small["estimate"] == 1.0


def test_moments_and_exponent():
    m = moments([1.0, 2.0, np.inf, 3.0])
    assert m["mean"] == 2.0 and m["std"] == pytest.approx(1.0) and m["count"] == 3
    a = np.geomspace(1e-4, 1e-2, 5)
    fit = knockdown_exponent(a, 1.0 - 1.5 * a ** (2.0 / 3.0))
    assert fit["exponent"] == pytest.approx(2.0 / 3.0, rel=1e-12) and fit["coefficient"] == pytest.approx(1.5)
    assert knockdown_exponent([1e-3], [0.9]) is None
