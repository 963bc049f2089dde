"""Pictures of an imperfection study: knock-down curves and the distribution of the critical load factor."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .table import _figure, plain_title, save_figure


@dataclass(frozen=True)
class KnockdownCurve:
    """One curve of a knock-down plot: ``kappa = lam_cr / lam_cr,perfect`` against the amplitude."""

    label: str
    amplitude: Sequence[float]
    knockdown: Sequence[float]
    #: a reference curve drawn underneath (an exact solution), same amplitudes or its own
    reference: tuple[Sequence[float], Sequence[float]] | None = None


def plot_knockdown(path, curves: Sequence[KnockdownCurve], xlabel: str, perfect: str, title: str = "") -> Path:
    """Knock-down curves; the perfect structure (``kappa = 1``, described by ``perfect``) as a line.

    The amplitude axis is logarithmic when the amplitudes span more than a
    factor of ten.
    """
    fig = _figure()
    ax = fig.add_subplot(1, 1, 1)
    amps = np.concatenate([np.asarray(c.amplitude, dtype=float) for c in curves]) if curves else np.zeros(0)
    amps = amps[np.isfinite(amps) & (amps > 0)]
    if amps.size and amps.max() > 10 * amps.min():
        ax.set_xscale("log")
    ax.axhline(1.0, color="k", lw=1.0, ls=":", label=perfect)
    for k, c in enumerate(curves):
        if c.reference is not None:
            ax.plot(c.reference[0], c.reference[1], color="0.6", lw=3, alpha=0.6, zorder=1,
                    label="exact" if k == 0 else None)
        ax.plot(c.amplitude, c.knockdown, "o-", ms=4, lw=1.2, color=f"C{k % 10}", label=c.label, zorder=2)
    ax.set_xlabel(xlabel, parse_math=False)
    ax.set_ylabel("knock-down lam_cr / lam_cr,perfect [-]", parse_math=False)
    if title:
        plain_title(ax, title, fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    return save_figure(fig, Path(path), bbox_inches="tight")


def plot_distribution(path, knockdown: Sequence[float], censored: int, marks: dict, title: str = "") -> Path:
    """The empirical distribution of the knock-down factors of random samples, with a fractile marked.

    ``marks`` holds ``p``, ``estimate``, ``lower``, ``upper``, ``confidence``
    (knock-down factors or None); ``censored`` samples kept their stability
    over the traced range and sit above every drawn value.
    """
    x = np.sort(np.asarray(knockdown, dtype=float))
    n = len(x) + censored
    fig = _figure((9.0, 4.0))
    hist, cdf = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    if len(x):
        hist.hist(x, bins=max(5, min(40, len(x) // 5)), color="C0", alpha=0.8)
        cdf.step(x, np.arange(1, len(x) + 1) / n, where="post", color="C0", label=f"{n} samples")
    for ax in (hist, cdf):
        if marks.get("estimate") is not None:
            ax.axvline(marks["estimate"], color="C3", lw=1.2,
                       label=f"{marks['p']:g}-fractile {marks['estimate']:.4g}")
        if marks.get("lower") is not None and marks.get("upper") is not None:
            ax.axvspan(marks["lower"], marks["upper"], color="C3", alpha=0.15,
                       label=f"{marks['confidence']:g} confidence interval")
        ax.set_xlabel("knock-down lam_cr / lam_cr,perfect [-]", parse_math=False)
        ax.grid(True, alpha=0.3)
    hist.set_ylabel("samples")
    cdf.set_ylabel("fraction of samples below [-]")
    if censored:
        cdf.set_title(f"{censored} sample(s) stable over the traced range: above the plot", fontsize=8)
    cdf.legend(fontsize=7, loc="lower right")
    if title:
        plain_title(hist, title, width=50, fontsize=9)
    fig.tight_layout()
    return save_figure(fig, Path(path), bbox_inches="tight")
