"""Rope-length statistics and length control (Section 3 of the MRA paper).

A gridshell is cheaper to build when many of its members share one length.
:func:`length_statistics` reports the lengths at equilibrium (range, mean,
how many lie within a tolerance of a target, and the natural length classes);
:func:`control_lengths` drives the ropes towards a small set of length
classes: it clusters the equilibrium lengths, gives every rope the rest
length of its class, lets the net hang again from where it is, and repeats,
reporting after each round how many ropes conform (length within the
tolerance of their class).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import ModelError
from ..model import MemberGroup
from .formfind import FormFindingResult, form_find


def tolerance_classes(lengths: np.ndarray, tol: float) -> np.ndarray:
    """Greedy 1-D grouping: sorted lengths go into one class while they stay within
    ``2 tol`` (relative) of the class's shortest member. Returns the class of every length."""
    lengths = np.asarray(lengths, dtype=float)
    order = np.argsort(lengths)
    label = np.empty(len(lengths), dtype=np.int64)
    k, start = 0, None
    for idx in order:  # a one-off sort of member lengths, not a solver loop
        if start is None or lengths[idx] > start * (1.0 + 2.0 * tol):
            if start is not None:
                k += 1
            start = lengths[idx]
        label[idx] = k
    return label


def kmeans_1d(lengths: np.ndarray, k: int, iterations: int = 100) -> tuple[np.ndarray, np.ndarray]:
    """Lloyd's algorithm in one dimension; returns sorted ``(centres, labels)``.

    The start splits the sorted lengths at their ``k - 1`` widest gaps (the
    natural breaks between length classes); a class that empties is reseeded
    at the length farthest from its centre.
    """
    x = np.asarray(lengths, dtype=float)
    k = int(max(1, min(k, len(np.unique(x)))))
    xs = np.sort(x)
    cuts = np.sort(np.argsort(np.diff(xs))[::-1][: k - 1]) + 1
    c = np.array([part.mean() for part in np.split(xs, cuts)])
    for _ in range(iterations):
        lab = np.argmin(np.abs(x[:, None] - c[None, :]), axis=1)
        counts = np.bincount(lab, minlength=k)
        new = np.bincount(lab, x, minlength=k) / np.maximum(counts, 1)
        for j in np.flatnonzero(counts == 0):  # at most k reseeds per sweep
            far = np.argmax(np.abs(x - c[lab]))
            new[j] = x[far]
        if np.allclose(new, c, rtol=0, atol=1e-15 * max(float(np.abs(x).max()), 1.0)):
            c = new
            break
        c = new
    c = np.sort(c)
    lab = np.argmin(np.abs(x[:, None] - c[None, :]), axis=1)
    return c, lab


def length_statistics(lengths, tol: float = 0.01, target: float | None = None, centres=None) -> dict:
    """Statistics of member lengths.

    Parameters
    ----------
    lengths : array_like
    tol : float
        Relative tolerance for "the same length".
    target : float, optional
        Report how many members are within ``tol`` of this length.
    centres : array_like, optional
        Given length classes: report how many members are within ``tol`` of
        their nearest class. Without them, classes are formed greedily
        (:func:`tolerance_classes`).
    """
    x = np.asarray(lengths, dtype=float)
    if x.size == 0:
        raise ModelError("length statistics: no lengths given")
    out = {
        "n": int(x.size), "min": float(x.min()), "max": float(x.max()), "mean": float(x.mean()),
        "std": float(x.std()), "tolerance": float(tol),
    }
    if target is not None:
        out["target"] = float(target)
        out["n_within_target"] = int(np.sum(np.abs(x - target) <= tol * target))
    if centres is None:
        lab = tolerance_classes(x, tol)
        centres = np.array([x[lab == j].mean() for j in range(lab.max() + 1)])
        counts = np.bincount(lab)
        big = np.argsort(-counts)[:10]
        out["n_classes"] = int(len(centres))
        out["largest_classes"] = [{"length": float(centres[j]), "count": int(counts[j])} for j in big]
        out["n_in_largest_class"] = int(counts.max())
    else:
        c = np.asarray(centres, dtype=float)
        lab = np.argmin(np.abs(x[:, None] - c[None, :]), axis=1)
        ok = np.abs(x - c[lab]) <= tol * c[lab]
        out["n_classes"] = int(len(c))
        out["classes"] = [{"length": float(c[j]), "count": int(np.sum(lab == j)),
                           "conforming": int(np.sum(ok & (lab == j)))} for j in range(len(c))]
        out["n_conforming"] = int(ok.sum())
    return out


@dataclass
class LengthControlResult:
    """Outcome of :func:`control_lengths`.

    Attributes
    ----------
    result : FormFindingResult
        The hanging shape after the last round (with the modified net).
    centres : ndarray
        Length classes [m].
    labels : ndarray
        Class of every rope.
    n_conforming : list of int
        Conforming ropes after every round (the first entry: before control).
    rounds : int
    wall_time_s : float
    """

    result: FormFindingResult
    centres: np.ndarray
    labels: np.ndarray
    n_conforming: list = field(default_factory=list)
    rounds: int = 0
    wall_time_s: float = 0.0
    tol: float = 0.01

    def summary(self) -> dict:
        stats = length_statistics(self.result.length, self.tol, centres=self.centres)
        final = self.result.summary()
        return {"n_classes": int(len(self.centres)), "centres": self.centres.tolist(),
                "n_conforming_per_round": list(self.n_conforming), "rounds": int(self.rounds),
                "converged": bool(self.result.converged), "statistics": stats,
                "strain_max": final["strain_max"], "n_overstretched_ropes": final["n_overstretched_ropes"],
                "wall_time_s": float(self.wall_time_s)}


def _with_rest_lengths(net, rest):
    """A copy of the net whose ropes have new rest lengths (same order as ``net.rope_edges``)."""
    import copy

    s = copy.copy(net.structure)
    groups, k = [], 0
    for g in net.structure.groups:
        if g.kind == "rope":
            m = g.n_members
            g = MemberGroup(g.name, g.kind, g.connectivity, g.EA, rest[k:k + m].copy(), g.mass_per_length)
            k += m
        groups.append(g)
    s.groups = groups
    return replace(net, structure=s)


def control_lengths(result: FormFindingResult, n_classes: int = 3, tol: float = 0.01, rounds: int = 5,
                    **form_options) -> LengthControlResult:
    """Drive the ropes towards ``n_classes`` lengths.

    Each round clusters the current rope lengths (1-D k-means), sets every
    rope's rest length so that, at its current strain, its length would equal
    its class length, and relaxes the net again from the current shape. The
    round with the most conforming ropes is kept.

    Ropes strained beyond the result's strain limit keep their rest length
    and take no part in the clustering: their length is set by where the
    suspension points are, not by their rest length, so a shorter rope
    would only stretch further (:attr:`FormFindingResult.overstretched`).

    Note that changing rest lengths changes the rope masses (mass per length
    is kept), so the weight changes slightly; the shape stays funicular for
    the modified net.
    """
    t0 = time.perf_counter()
    if n_classes < 1:
        raise ModelError(f"length control: n_classes must be at least 1, got {n_classes}")
    best = result
    centres, labels = _classes(result, n_classes)
    history = [int(np.sum(np.abs(result.length - centres[labels]) <= tol * centres[labels]))]
    best_count, best_centres, best_labels = history[0], centres, labels
    current = result
    for _ in range(int(rounds)):
        centres, labels = _classes(current, n_classes)
        net = current.net
        # keep each rope's current stretch (length / rest length) at its class length
        stretch = np.maximum(current.length / net.rest_length, 1.0)
        controlled = ~current.overstretched
        rest = np.where(controlled, centres[labels] / stretch, net.rest_length)
        new_net = _with_rest_lengths(net, rest)
        current = form_find(new_net, current.q, **form_options)
        conf = int(np.sum(np.abs(current.length - centres[labels]) <= tol * centres[labels]))
        history.append(conf)
        if conf > best_count and current.converged:
            best, best_count, best_centres, best_labels = current, conf, centres, labels
        if conf == len(labels):
            break
    return LengthControlResult(best, best_centres, best_labels, history, len(history) - 1,
                               time.perf_counter() - t0, tol)


def _classes(result: FormFindingResult, n_classes: int) -> tuple[np.ndarray, np.ndarray]:
    """Length classes of the ropes that are not overstretched, and the nearest class of every rope."""
    controlled = ~result.overstretched
    if not controlled.any():
        raise ModelError("length control: every rope is stretched beyond the strain limit; "
                         "no rope length is set by its rest length")
    centres, _ = kmeans_1d(result.length[controlled], n_classes)
    return centres, np.argmin(np.abs(result.length[:, None] - centres[None, :]), axis=1)
