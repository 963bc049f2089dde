"""The figures of a study: a fractile with its distribution-free confidence interval, and Koiter's exponent.

Fractile. Of ``n`` independent samples sorted ``x_(1) <= ... <= x_(n)``, the
``p``-fractile ``xi_p`` of their (any continuous) distribution lies below
``x_(r)`` exactly when at least ``r`` samples do, so

    P(x_(r) <= xi_p <= x_(s)) = B(s - 1; n, p) - B(r - 1; n, p)

with ``B`` the binomial distribution function: an interval of order
statistics with a known coverage and no assumption on the distribution.
The estimate is ``x_(ceil(n p))``; the one-sided lower confidence bound is
the largest ``x_(r)`` with ``P(Bin(n, p) >= r) >= confidence`` (the
"characteristic value" of design codes). Samples that kept their stability
over the whole traced range are right-censored: their critical load is
above the range, which is all a lower fractile needs while fewer than
``n (1 - p)`` of them are censored.

Exponent. Koiter's asymptotic laws say ``1 - lam_cr / lam_c ~ C a^e`` for
small amplitudes ``a``: ``e = 2/3`` at an unstable-symmetric bifurcation,
``1/2`` at an asymmetric one and ``e = 1`` (a shifted limit point) at a
limit point. The slope of ``log(1 - kappa)`` against ``log a`` measures it.
"""

from __future__ import annotations

import math

import numpy as np


def fractile(values, p: float, confidence: float) -> dict:
    """The ``p``-fractile of ``values`` (``inf``: censored above) and its distribution-free confidence bounds.

    Returns
    -------
    dict
        ``n``; ``estimate`` (``x_(ceil(n p))``); ``lower``, ``upper``: the
        two-sided interval ``[x_(r), x_(s)]`` of coverage at least
        ``confidence`` (None where ``n`` is too small for a bound) and its
        ``coverage``, ``r``, ``s``; ``lower_bound``: the one-sided lower
        ``confidence`` bound and its rank (None when ``n`` is too small).
        None stands for a value that does not exist, never for a number.
    """
    from scipy.stats import binom

    x = np.sort(np.asarray(values, dtype=float))
    n = len(x)
    out = {"n": n, "p": p, "confidence": confidence, "estimate": None, "lower": None, "upper": None,
           "coverage": None, "r": None, "s": None, "lower_bound": None, "lower_bound_rank": None}
    if n == 0:
        return out
    value = lambda rank: float(x[rank - 1]) if np.isfinite(x[rank - 1]) else None  # noqa: E731
    out["estimate"] = value(max(1, math.ceil(n * p)))
    alpha = 1.0 - confidence
    # the widest ranks a two-sided interval may start and end at, symmetric in probability
    r = int(binom.ppf(alpha / 2.0, n, p))
    s = int(binom.ppf(1.0 - alpha / 2.0, n, p)) + 1
    while r >= 1 and binom.cdf(s - 1, n, p) - binom.cdf(r - 1, n, p) < confidence:
        r -= 1
    if r >= 1 and s <= n:
        out.update(lower=value(r), upper=value(s), r=r, s=s,
                   coverage=float(binom.cdf(s - 1, n, p) - binom.cdf(r - 1, n, p)))
    # one-sided: P(x_(k) <= xi_p) = P(Bin(n, p) >= k) decreases with k
    ranks = [k for k in range(1, n + 1) if binom.sf(k - 1, n, p) >= confidence]
    if ranks:
        out.update(lower_bound=value(ranks[-1]), lower_bound_rank=ranks[-1])
    return out


def moments(values) -> dict:
    """Mean, standard deviation (n - 1), smallest and largest of the finite values."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return {"mean": None, "std": None, "min": None, "max": None, "count": 0}
    return {"mean": float(x.mean()), "std": float(x.std(ddof=1)) if x.size > 1 else None,
            "min": float(x.min()), "max": float(x.max()), "count": int(x.size)}


def knockdown_exponent(amplitudes, knockdown) -> dict | None:
    """Fit ``1 - kappa = C a^e`` by least squares in log-log; None with fewer than two usable points.

    Points with ``kappa >= 1`` (no reduction) are left out.
    """
    a = np.asarray(amplitudes, dtype=float)
    k = np.asarray(knockdown, dtype=float)
    ok = np.isfinite(a) & np.isfinite(k) & (a > 0) & (k < 1)
    if ok.sum() < 2 or np.ptp(np.log(a[ok])) == 0:
        return None
    e, logc = np.polyfit(np.log(a[ok]), np.log(1.0 - k[ok]), 1)
    return {"exponent": float(e), "coefficient": float(np.exp(logc)), "points": int(ok.sum())}
