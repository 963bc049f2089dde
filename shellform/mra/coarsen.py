"""A coarser version of a hanging net, for a cheap first look at its shape.

The coarse net keeps every ``factor``-th grid line of both families (and the
first and last lines), plus whatever lines are needed to keep the suspension
points: a point is kept when it is a crossing of kept lines, or when it lies
on a kept line between two crossings that are suspension points together with
every node between them (a frame, a supported side). Each coarse rope stands
for the chain of fine ropes it replaces: its rest length is their sum (the
slack is kept), its axial stiffness is theirs in series times the number of
fine lines it carries the load of, so its strain stays that of the fine
ropes. The weight and loads of every fine node are shared between the four
crossings around it with bilinear weights, so the coarse net carries the same
load, distributed the same way.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..errors import ModelError
from .net import HangingNet, hanging_net


def coarsened_net(net: HangingNet, factor: int = 3) -> HangingNet:
    """The net on every ``factor``-th grid line, with the same supports and the same load.

    Parameters
    ----------
    net : HangingNet
    factor : int
        Kept grid lines are ``factor`` fine lines apart (closer where a line
        is kept for a suspension point).

    Returns
    -------
    HangingNet
        ``info["lattice"]`` holds the kept lines' structured coordinates in
        ``net``'s own (see :func:`structured_lines`), ``info["source"]`` the
        fine node of every coarse node.

    Raises
    ------
    ModelError
        When ``factor`` is below 2, when the suspension points lie on so
        many lines that the coarse net would keep more than half the nodes,
        or when the coarse net has nothing left to hang.
    """
    if int(factor) != factor or factor < 2:
        raise ModelError(f"coarse net: the coarsening factor must be an integer of at least 2, got {factor}")
    reason = coarsening_obstacle(net)
    if reason:
        raise ModelError(f"coarse net: {reason}")
    grid, s = net.grid, net.structure
    ni, nj = grid.shape
    is_support = np.zeros((ni, nj), dtype=bool)
    is_support[grid.ij[net.supports, 0], grid.ij[net.supports, 1]] = True
    lines = [_every(ni, factor), _every(nj, factor)]
    for _ in range(max(ni, nj)):  # each pass adds lines; it stops long before this
        lost = _unkept_supports(is_support, *lines)
        if not lost.any():
            break
        lines = [np.union1d(lines[0], np.flatnonzero(lost.any(axis=1))),
                 np.union1d(lines[1], np.flatnonzero(lost.any(axis=0)))]
    if len(lines[0]) * len(lines[1]) > 0.5 * ni * nj:
        raise ModelError(f"coarse net: the suspension points lie on {len(lines[0])} x {len(lines[1])} of the "
                         f"{ni} x {nj} grid lines; a coarse net would not be coarse")
    coarse, source = grid.lattice(*lines)

    rest, compliance = _chains(net, lines)
    e = coarse.edges
    lo = coarse.ij[e[:, 0]]  # edges run from the lower crossing
    fam = coarse.edge_direction()
    # a coarse rope carries the load of several fine lines: stiffer by as much, it strains as they do
    width = [_widths(lines[1]), _widths(lines[0])]
    chain_rest, chain_comp, w = np.empty(len(e)), np.empty(len(e)), np.empty(len(e))
    for f in (0, 1):
        k = fam == f
        chain_rest[k] = rest[f][lo[k, 0], lo[k, 1]]
        chain_comp[k] = compliance[f][lo[k, 0], lo[k, 1]]
        w[k] = width[f][lo[k, 1 - f]]
    # supports keep their lifted positions: the coarse grid is the net's present geometry
    coarse.nodes = s.nodes[source].copy()
    span = np.linalg.norm(coarse.nodes[e[:, 1]] - coarse.nodes[e[:, 0]], axis=1)
    if np.any(span <= 0):
        raise ModelError("coarse net: two kept crossings coincide")
    gravity = s.gravity if s.gravity is not None else np.zeros(3)
    loads = sum((c.forces for c in s.load_cases), np.zeros((grid.n_nodes, 3)))
    share = _bilinear_shares(grid.ij, lines, coarse.shape)
    sup = np.flatnonzero(is_support[lines[0]][:, lines[1]].ravel())
    try:
        out = hanging_net(coarse, {"nodes": sup.tolist(), "dofs": net.info.get("support_dofs", "xyz")},
                          slack=chain_rest / span - 1.0, EA=w * chain_rest / chain_comp, mass_per_length=0.0,
                          node_mass=share.T @ s.nodal_mass(), gravity=gravity,
                          loads=share.T @ loads if s.load_cases else None)
    except ModelError as exc:
        # e.g. a net so small that every kept crossing is a suspension point
        raise ModelError(f"coarse net ({len(lines[0])} x {len(lines[1])} of the {ni} x {nj} grid lines): {exc}") from None
    u, v = structured_lines(net)
    out.info["lattice"] = (u[lines[0]], v[lines[1]])
    out.info["source"] = source
    return out


def coarsening_obstacle(net: HangingNet) -> str | None:
    """Why ``net`` has no coarse net, or None when it has one (when its suspension points allow)."""
    if not net.grid.structured:
        return ("the net is unstructured: a coarse net keeps every k-th grid line of a structured grid, and an "
                "unstructured net has no grid lines")
    if net.info.get("n_cable_ropes"):
        return "the net has edge cables, which a coarse net of grid lines does not carry over"
    if net.info.get("support_dofs") is None:
        return "its suspension points hold different components, which a coarse net does not carry over"
    return None


def structured_lines(net: HangingNet) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates in ``[0, 1]`` of the net's ``i`` and ``j`` grid lines.

    Evenly spaced, ``k / (n - 1)``, for a net built on a grid; for a
    :func:`coarsened_net`, those of its kept lines in the finer net's
    coordinates, so a coarse net and its source share one frame.
    """
    if "lattice" in net.info:
        return net.info["lattice"]
    ni, nj = net.grid.shape
    return np.linspace(0.0, 1.0, ni), np.linspace(0.0, 1.0, nj)


def _every(n: int, factor: int) -> np.ndarray:
    return np.union1d(np.arange(0, n, int(factor)), [n - 1])


def _widths(lines: np.ndarray) -> np.ndarray:
    """How many fine lines' load each kept line carries.

    An inner line carries half the gaps on its two sides, a side line half
    the gap next to it; a fine line carries one spacing inside and half a
    spacing on a side, so the ratio is the mean gap inside and the gap on a side.
    """
    gaps = np.diff(lines).astype(float)
    return 0.5 * (np.concatenate([gaps[:1], gaps]) + np.concatenate([gaps, gaps[-1:]]))


def _unkept_supports(is_support: np.ndarray, i_lines: np.ndarray, j_lines: np.ndarray) -> np.ndarray:
    """Mask of the suspension points a lattice on these lines would lose."""
    ni, nj = is_support.shape
    on_i = np.isin(np.arange(ni), i_lines)[:, None]
    on_j = np.isin(np.arange(nj), j_lines)[None, :]
    lost = is_support & ~(on_i & on_j)
    # on a kept j line (a chain along i): kept when every node from crossing to crossing is a support
    along_i = _whole_chains(is_support, i_lines) & on_j
    along_j = _whole_chains(is_support.T, j_lines).T & on_i
    return lost & ~along_i & ~along_j


def _whole_chains(mask: np.ndarray, lines: np.ndarray) -> np.ndarray:
    """Nodes whose stretch of axis 0 between kept lines holds only masked nodes."""
    seg = _segment(lines, np.arange(mask.shape[0]))
    a, b = lines[seg], lines[seg + 1]
    count = np.vstack([np.zeros((1, mask.shape[1])), np.cumsum(mask, axis=0)])
    return (count[b + 1] - count[a]) == (b - a + 1)[:, None]


def _segment(lines: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Index of the gap between kept lines that holds each fine line ``x`` (the last gap holds the last line)."""
    return np.clip(np.searchsorted(lines, x, side="right") - 1, 0, len(lines) - 2)


def _chains(net: HangingNet, lines) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Rest length and compliance (sum of ``L / EA``) of every chain of fine edges between kept crossings.

    Returned per family on the coarse lattice: ``[0]`` has shape
    ``(len(i_lines) - 1, len(j_lines))`` (chains along ``i``), ``[1]`` the
    transpose pattern. Fine edges that are not ropes (between two held
    supports) count with their present length and the median compliance.
    """
    grid, s = net.grid, net.structure
    ni, nj = grid.shape
    length = {0: np.zeros((ni - 1, nj)), 1: np.zeros((ni, nj - 1))}
    comp = {0: np.zeros((ni - 1, nj)), 1: np.zeros((ni, nj - 1))}
    e = net.rope_edges
    lo = grid.ij[e].min(axis=1)
    c = net.rest_length / net.EA
    for fam in (0, 1):
        k = net.family == fam
        length[fam][lo[k, 0], lo[k, 1]] = net.rest_length[k]
        comp[fam][lo[k, 0], lo[k, 1]] = c[k]
    held = net.info.get("held_ropes", np.zeros((0, 2), dtype=np.int64))
    if len(held):
        h_ij = grid.ij[held]
        h_lo = h_ij.min(axis=1)
        h_fam = (h_ij[:, 1, 0] == h_ij[:, 0, 0]).astype(np.int8)
        h_len = np.linalg.norm(s.nodes[held[:, 1]] - s.nodes[held[:, 0]], axis=1)
        h_comp = h_len / float(np.median(net.EA))
        for fam in (0, 1):
            k = h_fam == fam
            length[fam][h_lo[k, 0], h_lo[k, 1]] = h_len[k]
            comp[fam][h_lo[k, 0], h_lo[k, 1]] = h_comp[k]
    i_lines, j_lines = lines
    rest, compliance = [], []
    for fam, axis, kept, other in ((0, 0, i_lines, j_lines), (1, 1, j_lines, i_lines)):
        # prefix sums along the chains' direction, read between consecutive kept lines
        pad = [(1, 0), (0, 0)] if axis == 0 else [(0, 0), (1, 0)]
        csum_l = np.pad(np.cumsum(length[fam], axis=axis), pad)
        csum_c = np.pad(np.cumsum(comp[fam], axis=axis), pad)
        if axis == 0:
            rest.append((csum_l[kept[1:]] - csum_l[kept[:-1]])[:, other])
            compliance.append((csum_c[kept[1:]] - csum_c[kept[:-1]])[:, other])
        else:
            rest.append((csum_l[:, kept[1:]] - csum_l[:, kept[:-1]])[other, :])
            compliance.append((csum_c[:, kept[1:]] - csum_c[:, kept[:-1]])[other, :])
    return rest, compliance


def _bilinear_shares(ij: np.ndarray, lines, shape) -> np.ndarray:
    """Sparse ``(n_fine, n_coarse)`` matrix sharing each fine node among the four crossings around it."""
    idx, frac = [], []
    for axis in (0, 1):
        kept = lines[axis]
        x = ij[:, axis]
        seg = _segment(kept, x)
        idx.append(seg)
        frac.append((x - kept[seg]) / (kept[seg + 1] - kept[seg]))
    (a, b), (s, t) = idx, frac
    n = len(ij)
    rows = np.tile(np.arange(n), 4)
    cols = np.concatenate([a * shape[1] + b, (a + 1) * shape[1] + b, a * shape[1] + b + 1, (a + 1) * shape[1] + b + 1])
    vals = np.concatenate([(1 - s) * (1 - t), s * (1 - t), (1 - s) * t, s * t])
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, shape[0] * shape[1]))
