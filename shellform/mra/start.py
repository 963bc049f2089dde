"""Start states for form finding: flat, on a B-spline surface, or from a coarser hanging net.

The MRA paper starts large nets from a NURBS surface built in a preliminary
phase, near the hanging shape, instead of from the flat planform, and reports
that the relaxation then costs much less. :func:`surface_start` places the
free nodes of a net on a height-field B-spline (planform ``x, y`` kept,
``z`` from the surface); :func:`fit_height_field` builds such a surface by
least squares from scattered points (for example a coarse hanging net).
:func:`transferred_force_densities` takes the force densities of a coarser
hanging net instead: the shape in balance with them
(:func:`~shellform.solvers.relaxation.force_density_shape`) has ropes close
to their rest lengths, where a surface through the coarse nodes stretches
them. :func:`coarse_shape_start` carries the coarse net's positions over, all
three coordinates, so the ropes keep the lengths the coarse net gave them;
it is the start :func:`~shellform.mra.formfind.form_find` uses on large nets.
"""

from __future__ import annotations

import warnings

import numpy as np

from ..errors import ModelError
from ..geometry.bspline import HeightField, basis_functions, height_field
from ..solvers.relaxation import force_density_shape
from .coarsen import coarsened_net, structured_lines
from .formfind import FormFindingResult, HypostaticWarning, OverstretchWarning, form_find, rope_state
from .net import HangingNet

#: Factor on the force densities a coarse net passes to a finer one (see :func:`coarse_force_density_start`).
DENSITY_SCALE = 0.9

#: Median rope strain a coarse net's shape is lowered to before a finer net starts from it
#: (see :func:`coarse_shape_start`): a few times the elastic strain of nearly inextensible ropes.
START_STRAIN = 3e-4

#: Most a coarse net's sag is deepened by (a fraction of itself) to reach :data:`START_STRAIN`.
MAX_DEEPENING = 0.5


def surface_start(net: HangingNet, surface: HeightField) -> np.ndarray:
    """Start state with every free node lowered/raised onto ``surface``.

    Suspension points keep their positions; the surface is added to the
    nodes' planform height, so a surface that is zero on the rim leaves
    lifted frames where they are.
    """
    s = net.structure
    x = s.nodes.copy()
    free = np.ones(s.n_nodes, dtype=bool)
    free[net.supports] = False
    x[free, 2] += surface.z(x[free, 0], x[free, 1])
    return x.ravel()


def fit_height_field(points, x_range, y_range, n_ctrl=(6, 6), degree: int = 3,
                     smoothing: float = 1e-6) -> HeightField:
    """Least-squares height-field B-spline through scattered points ``(x, y, z)``.

    A small second-difference penalty on the control heights (``smoothing``
    relative to the data term) keeps the fit well posed where data are sparse.
    """
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) < 4:
        raise ModelError(f"surface fit: expected at least 4 points of shape (n, 3), got {p.shape}")
    nu, nv = (int(n_ctrl), int(n_ctrl)) if np.ndim(n_ctrl) == 0 else (int(n_ctrl[0]), int(n_ctrl[1]))
    hf = height_field(np.zeros((nu, nv)), x_range, y_range, degree)
    srf = hf.surface
    (x0, x1), (y0, y1) = hf.x_range, hf.y_range
    (u0, u1), (v0, v1) = srf.domain
    u = u0 + (u1 - u0) * np.clip((p[:, 0] - x0) / (x1 - x0), 0, 1)
    v = v0 + (v1 - v0) * np.clip((p[:, 1] - y0) / (y1 - y0), 0, 1)
    Nu = basis_functions(srf.knots_u, srf.degree_u, u)
    Nv = basis_functions(srf.knots_v, srf.degree_v, v)
    A = (Nu[:, :, None] * Nv[:, None, :]).reshape(len(p), nu * nv)
    D = []
    I = np.eye(nu * nv).reshape(nu, nv, nu * nv)
    if nu >= 3:
        D.append((I[:-2] - 2 * I[1:-1] + I[2:]).reshape(-1, nu * nv))
    if nv >= 3:
        D.append((I[:, :-2] - 2 * I[:, 1:-1] + I[:, 2:]).reshape(-1, nu * nv))
    lhs = A.T @ A
    if D:
        D = np.concatenate(D)
        lhs = lhs + smoothing * np.trace(lhs) / len(lhs) * (D.T @ D)
    z = np.linalg.solve(lhs, A.T @ p[:, 2])
    srf.control_points[..., 2] = z.reshape(nu, nv)
    return hf


def transferred_force_densities(coarse: FormFindingResult, net: HangingNet) -> np.ndarray:
    """Force densities for the ropes of ``net`` from a hanging coarser net on the same kind of grid.

    The force densities ``N / l`` of the coarse ropes form one field per
    family of grid lines, known at the rope midpoints in the structured
    coordinates ``(i / (n_i - 1), j / (n_j - 1))`` that both grids share.
    Every rope of ``net`` takes the bilinear interpolation of its family's
    field at its own midpoint (the field's edge values beyond the coarse
    midpoints); coarse grid edges that are not ropes (between two supports)
    are left out of the interpolation. A rope's tension grows with the load
    per area times the rope spacing and its length with the spacing, so the
    force density scales with the load per area: the field is multiplied by
    the ratio of the two nets' weights. Ropes slack in the coarse net would
    get no force density and leave nodes unheld, so every rope gets at least
    1 % of the median.

    Returns
    -------
    ndarray, shape (len(net.rope_edges),)
        Force densities [N/m], in the order of ``net.rope_edges``.
    """
    cnet = coarse.net
    density = np.where(coarse.length > 0, coarse.tension / np.maximum(coarse.length, 1e-300), 0.0)
    c_ij, f_mid = _rope_lattice(cnet), _structured_midpoints(net)
    out = np.zeros(len(net.rope_edges))
    ni, nj = cnet.grid.shape
    cu, cv = structured_lines(cnet)
    for fam in (0, 1):
        into = net.family == fam
        if not into.any():
            continue
        have = cnet.family == fam
        if not have.any():
            raise ModelError(f"force-density transfer: the coarse net has no ropes of family {fam} to take from")
        # the lattice of this family's rope midpoints: halfway between lines along the ropes
        shape = (ni - 1, nj) if fam == 0 else (ni, nj - 1)
        u = 0.5 * (cu[:-1] + cu[1:]) if fam == 0 else cu
        v = 0.5 * (cv[:-1] + cv[1:]) if fam == 1 else cv
        value, present = np.zeros(shape), np.zeros(shape, dtype=bool)
        value[c_ij[have, 0], c_ij[have, 1]] = density[have]
        present[c_ij[have, 0], c_ij[have, 1]] = True
        field, weight = _present_bilinear(u, v, value, present, f_mid[into])
        out[into] = np.where(weight > 1e-12, field, float(np.median(density[have])))
    out = np.maximum(out, 0.01 * float(np.median(out[out > 0]))) if np.any(out > 0) else out
    return out * net.total_weight() / cnet.total_weight()


def coarse_force_density_start(coarse: FormFindingResult, net: HangingNet,
                               density_scale: float = DENSITY_SCALE) -> np.ndarray | None:
    """Start state of ``net``: the shape in balance with the force densities of the hanging ``coarse`` net.

    :func:`transferred_force_densities`, times ``density_scale``, followed by
    :func:`~shellform.solvers.relaxation.force_density_shape` (the net's ropes
    are its System's axial members, in the same order). None when those
    force densities do not hold every free node.

    Why lower the densities (by 10 % by default): the transferred field is
    within a few per cent of the final one, yet its shape leaves many ropes
    short of their rest length by more than their elastic strain (on a
    100 x 100 net 60 % of them, the median by 2.5e-4 against a strain of
    4e-5), and the relaxation spends its steps pulling them taut. Lower
    densities hang the start deeper, so most ropes start taut and the
    relaxation only has to let it rise. Steps to rest from ``start="coarse_net"``
    as transferred and lowered by 10 %: 29 and 25 on the 100 x 100 square net of
    ``benchmarks/bench_mra.py``, 72 and 46 on its 316 x 316 net; 51 and 30,
    43 and 26 on the circle scenes with slack 0.02 and 0.10 at 100 x 100 nodes;
    81 and 73 on ``large_frames``. Lowered by 20 % the large-frames net took 77.
    """
    if not density_scale > 0:
        raise ModelError(f"coarse start: density_scale must be positive, got {density_scale!r}")
    return force_density_shape(net.system(), density_scale * transferred_force_densities(coarse, net))


def interpolated_shape(coarse: FormFindingResult, net: HangingNet) -> np.ndarray | None:
    """The hanging coarse net's node positions, interpolated at every node of ``net``.

    Both nets share the structured coordinates ``(i / (n_i - 1), j / (n_j - 1))``
    (:func:`~shellform.mra.coarsen.structured_lines`); each coordinate of the
    coarse nodes is a field on the coarse lattice, interpolated bilinearly at
    the fine nodes. Lattice points without a coarse node are skipped by
    interpolating their presence alike.

    Returns
    -------
    ndarray, shape (n_nodes, 3), or None
        None when a node of ``net`` has no coarse node around it.
    """
    cnet = coarse.net
    ni, nj = cnet.grid.shape
    ij = cnet.grid.ij
    value, present = np.zeros((ni, nj, 3)), np.zeros((ni, nj), dtype=bool)
    value[ij[:, 0], ij[:, 1]] = coarse.positions
    present[ij[:, 0], ij[:, 1]] = True
    fu, fv = structured_lines(net)
    points = np.column_stack([fu[net.grid.ij[:, 0]], fv[net.grid.ij[:, 1]]])
    x, weight = _present_bilinear(*structured_lines(cnet), value, present, points)
    return None if np.any(weight <= 1e-12) else x


def coarse_shape_start(coarse: FormFindingResult, net: HangingNet, median_strain: float = START_STRAIN,
                       system=None) -> np.ndarray | None:
    """Start state of ``net``: the hanging ``coarse`` net's shape, interpolated and hung a little deeper.

    :func:`interpolated_shape` puts every node where the coarse net hangs.
    The ropes on the coarse net's grid lines then have nearly their rest
    length, but the ropes in between cut across the coarse cells and come
    out slightly short: on the 100 x 100 square benchmark net, 27 % of the
    ropes that end taut start short, the median one by 9e-5 of its length,
    against an elastic strain of 4e-5. A short rope has no stiffness, so the
    relaxation would spend its steps pulling them taut one front of nodes at
    a time. The sag (the displacement from the planform along the load) is
    therefore deepened by the factor ``1 + d``, with ``d`` the value
    (found by bisection, at most :data:`MAX_DEEPENING`) that gives the
    ropes a median strain of ``median_strain``: most ropes start taut and
    the relaxation lets a taut net rise.

    ``system`` is ``net.system()`` when the caller has built it already
    (building it costs seconds on a net of 10^5 nodes).

    Returns
    -------
    ndarray, shape (3 n_nodes,), or None
        None when the coarse net does not reach every node of ``net``.
    """
    if not (np.isfinite(median_strain) and median_strain >= 0):
        raise ModelError(f"coarse start: median_strain must be a finite number >= 0, got {median_strain!r}")
    x = interpolated_shape(coarse, net)
    if x is None:
        return None
    system = net.system() if system is None else system
    ref = system.q_ref.reshape(-1, 3)
    x = system.state(base=x.ravel()).reshape(-1, 3)  # held coordinates where they are held
    load = system.external_force(1.0).reshape(-1, 3).sum(axis=0)
    if not np.linalg.norm(load) > 0:
        return x.ravel()
    down = load / np.linalg.norm(load)
    sag = np.outer((x - ref) @ down, down)

    def strain(d):
        return float(np.median(rope_state(net, (x + d * sag).ravel())[1] / net.rest_length - 1.0))

    if strain(0.0) >= median_strain:
        d = 0.0
    elif strain(MAX_DEEPENING) < median_strain:
        d = MAX_DEEPENING
    else:
        lo, d = 0.0, MAX_DEEPENING
        for _ in range(30):  # to 5e-10 of the sag
            mid = 0.5 * (lo + d)
            lo, d = (mid, d) if strain(mid) < median_strain else (lo, mid)
    return system.state(base=(x + d * sag).ravel())


def coarse_net_start(net: HangingNet, factor: int = 3, median_strain: float = START_STRAIN, system=None,
                     **form_options) -> tuple[np.ndarray | None, FormFindingResult]:
    """Hang the :func:`~shellform.mra.coarsen.coarsened_net` of ``net`` and start ``net`` from its shape.

    Parameters
    ----------
    net : HangingNet
    factor : int
        Coarsening factor (grid lines kept).
    median_strain : float
        Median rope strain of the start (:func:`coarse_shape_start`).
    system : System, optional
        ``net.system()``, if already built.
    **form_options
        Passed to :func:`~shellform.mra.formfind.form_find` for the coarse net
        (``options``, ``progress``, ``callback``).

    Returns
    -------
    q0 : ndarray or None
        :func:`coarse_shape_start` (None when the coarse net does not reach
        every node).
    coarse : FormFindingResult
        The coarse net at rest.
    """
    cnet = coarsened_net(net, factor)
    with warnings.catch_warnings():
        # a coarse net may have too few free nodes for Eqs. (11)-(12); it only shapes the start
        warnings.simplefilter("ignore", HypostaticWarning)
        warnings.simplefilter("ignore", OverstretchWarning)
        coarse = form_find(cnet, **form_options)
    return coarse_shape_start(coarse, net, median_strain, system), coarse


def _structured_midpoints(net: HangingNet) -> np.ndarray:
    """Rope midpoints in the net's structured coordinates (:func:`~shellform.mra.coarsen.structured_lines`)."""
    u, v = structured_lines(net)
    uv = np.column_stack([u[net.grid.ij[:, 0]], v[net.grid.ij[:, 1]]])
    e = net.rope_edges
    return 0.5 * (uv[e[:, 0]] + uv[e[:, 1]])


def _rope_lattice(net: HangingNet) -> np.ndarray:
    """Lattice index of every rope: the smaller structured position of its two ends."""
    ij = net.grid.ij[net.rope_edges]
    return ij.min(axis=1)


def _present_bilinear(u, v, values: np.ndarray, present: np.ndarray, points: np.ndarray):
    """Bilinear interpolation over the lattice points where ``present`` only.

    Interpolating the values and the presence alike and dividing leaves the
    absent points out. ``values`` has the lattice's shape, optionally with
    trailing axes (interpolated one by one). Returns the interpolant at
    ``points`` (NaN-free; meaningless where the weight is zero) and the
    weight of the present points there.
    """
    weight = _bilinear(u, v, present.astype(float), points)
    flat = values.reshape(values.shape[:2] + (-1,))
    field = np.column_stack([_bilinear(u, v, flat[..., k], points) for k in range(flat.shape[2])])
    field = field / np.maximum(weight, 1e-12)[:, None]
    return field.reshape((len(points),) + values.shape[2:]), weight


def _bilinear(u: np.ndarray, v: np.ndarray, values: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Bilinear interpolation on the lattice ``u x v`` (ascending), clamped to its edges."""
    def locate(axis, x):
        if len(axis) == 1:
            return np.zeros(len(x), dtype=np.int64), np.zeros(len(x))
        x = np.clip(x, axis[0], axis[-1])
        k = np.clip(np.searchsorted(axis, x, side="right") - 1, 0, len(axis) - 2)
        return k, (x - axis[k]) / (axis[k + 1] - axis[k])

    a, s = locate(u, points[:, 0])
    b, t = locate(v, points[:, 1])
    a1 = np.minimum(a + 1, len(u) - 1)
    b1 = np.minimum(b + 1, len(v) - 1)
    return ((1 - s) * (1 - t) * values[a, b] + s * (1 - t) * values[a1, b]
            + (1 - s) * t * values[a, b1] + s * t * values[a1, b1])
