"""The tangents assembled from the upper triangles of element blocks against the full Hessian values."""

import numpy as np
import pytest
import scipy.sparse as sp
from test_rod_effects import network_from, random_lines

from shellform.assembly import System, build_system
from shellform.effects.base import Effect
from shellform.effects.rod_hinge import UPPER_PAIRS, HingeEffect
from shellform.model import Structure
from shellform.rods import build_rod_system


def dense(e, q, values=None):
    rows, cols = e.hessian_pattern()
    vals = e.hessian_values(q) if values is None else values
    return sp.coo_matrix((vals, (rows, cols)), shape=(q.size, q.size)).toarray()


def dense_upper(e, q, values=None):
    """``S + S^T`` with the mirrored entries of the upper pattern counted in both places."""
    rows, cols, mirrored = e.hessian_upper_pattern()
    vals = e.hessian_upper_values(q) if values is None else values
    S = sp.coo_matrix((vals, (rows, cols)), shape=(q.size, q.size)).toarray()
    M = sp.coo_matrix((vals[mirrored], (cols[mirrored], rows[mirrored])), shape=(q.size, q.size)).toarray()
    return S + M


def rod_case(seed, ratio):
    rng = np.random.default_rng(seed)
    s, net = network_from(random_lines(rng, (3, 6, 9)), closed=(2,), natural=["rest", "straight", "rest"],
                          twist=[0.3, 0.0, -0.2], seed=seed, ratio=ratio)
    q1 = s.reference_state() + 0.2 * rng.normal(size=s.n_dof)
    net.frames.update(q1)
    return s, net, q1 + 0.3 * rng.normal(size=s.n_dof)


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("ratio", [None, "random"])
def test_upper_values_of_rod_effects_are_their_full_values(seed, ratio):
    """Curved, twisted, closed, anisotropic rods: every upper value is the full Hessian's entry, and the
    bending and twisting summed in one pass are the sum of the two."""
    s, net, q = rod_case(seed, ratio)
    effects = net.effects()
    for e in effects:
        if e.hessian_upper_pattern() is None:
            continue
        A, B = dense(e, q), dense_upper(e, q)
        assert np.allclose(B, A, rtol=0, atol=1e-12 * np.abs(A).max()), e.name
    hinges = [e for e in effects if isinstance(e, HingeEffect)]
    assert len(hinges) == 2
    summed = type(hinges[0]).summed_hessian_upper_values(hinges, q)
    parts = sum(e.hessian_upper_values(q) for e in hinges)
    assert np.allclose(summed, parts, rtol=0, atol=1e-12 * np.abs(parts).max())
    # the values are those of the full stencil Hessian at the listed entries
    h = len(hinges[0].stencil)
    full = hinges[0].hessian_values(q).reshape(11, 11, h)
    upper = hinges[0].hessian_upper_values(q).reshape(66, h)
    expected = full[UPPER_PAIRS[:, 0], UPPER_PAIRS[:, 1]]
    assert np.allclose(upper, expected, rtol=0, atol=1e-13 * np.abs(expected).max())


def test_tangents_of_a_clamped_rod_network_are_the_sum_of_the_effects():
    rng = np.random.default_rng(11)
    s, net = network_from(random_lines(rng, (5, 8, 6)), natural=["rest", "straight", "rest"], twist=[0.2, 0.0, 0.1],
                          ratio="random")
    net.clamp(0, "start")
    net.clamp(1, "end")
    net.clamp(2, "start")
    system = build_rod_system(net)
    assert system._upper is not None
    q = s.reference_state() + 0.05 * rng.normal(size=s.n_dof)
    total = sum(dense(e, q) for e in system.effects)
    free = system.free
    K = system.tangent_free(q)
    assert np.allclose(K.toarray(), total[np.ix_(free, free)], rtol=0, atol=1e-13 * np.abs(total).max())
    # the same pattern as the other assembly paths
    A = system.assemble_free({e: e.hessian_values(q) for e in system.effects})
    assert np.array_equal(K.indptr, A.indptr) and np.array_equal(K.indices, A.indices)
    assert np.allclose(K.data, A.data, rtol=0, atol=1e-13 * np.abs(total).max())
    assert np.allclose(K.toarray(), K.toarray().T, rtol=0, atol=0)
    # the full tangent alike, on the pattern of the other path
    Kfull = system.tangent(q)
    assert np.allclose(Kfull.toarray(), total, rtol=0, atol=1e-13 * np.abs(total).max())
    assert Kfull.nnz == system._full.nnz


class BlockEffect(Effect):
    """Constant symmetric element blocks on given DOFs (repeats allowed), by full and by upper patterns."""

    name = "blocks"

    def __init__(self, n_dof, dofs, blocks, upper=True):
        super().__init__(n_dof)
        self.dofs, self.blocks, self.upper = dofs, blocks, upper
        m, k = dofs.shape
        self.pairs = np.array([(a, b) for a in range(k) for b in range(a, k)])

    def energy(self, q):
        return 0.5 * float(np.einsum("mi,mij,mj->", q[self.dofs], self.blocks, q[self.dofs]))

    def gradient(self, q):
        return np.bincount(self.dofs.ravel(), weights=np.einsum("mij,mj->mi", self.blocks, q[self.dofs]).ravel(),
                           minlength=self.n_dof)

    def hessian_pattern(self):
        m, k = self.dofs.shape
        return (np.repeat(self.dofs, k, axis=1).ravel(), np.tile(self.dofs, (1, k)).ravel())

    def hessian_values(self, q):
        return self.blocks.ravel()

    def hessian_upper_pattern(self):
        if not self.upper:
            return None
        a, b = self.pairs.T
        return self.dofs[:, a].ravel(), self.dofs[:, b].ravel(), np.tile(a != b, len(self.dofs))

    def hessian_upper_values(self, q, out=None):
        a, b = self.pairs.T
        v = self.blocks[:, a, b].ravel()
        if out is None:
            return v
        out[...] = v
        return out


def test_repeated_dofs_and_mixed_effects():
    """An off-diagonal entry of a block on a repeated DOF counts twice; effects without upper values, sharing or
    not a pattern, add their full values; entries in held rows and columns are left out."""
    rng = np.random.default_rng(5)
    n_nodes = 6
    s = Structure(rng.normal(size=(n_nodes, 3)))
    s.fix([0], "xy")
    n = s.n_dof
    dofs = np.array([[0, 4, 4, 7], [3, 9, 12, 3], [2, 5, 8, 17], [16, 1, 16, 16]])
    blocks = rng.normal(size=(4, 4, 4))
    blocks = blocks + blocks.transpose(0, 2, 1)
    effects = [BlockEffect(n, dofs, blocks), BlockEffect(n, dofs, 2.0 * blocks),
               BlockEffect(n, dofs[::-1].copy(), blocks, upper=False), BlockEffect(n, dofs[::-1].copy(), -blocks, upper=False),
               BlockEffect(n, dofs[:2], blocks[:2], upper=False)]
    system = System(s, effects, check=False)
    assert system._upper is not None
    q = rng.normal(size=n)
    total = sum(dense(e, q) for e in effects)
    free = system.free
    assert np.allclose(system.tangent_free(q).toarray(), total[np.ix_(free, free)], rtol=0, atol=1e-13)
    assert np.allclose(system.tangent(q).toarray(), total, rtol=0, atol=1e-13)
    assert np.allclose(dense_upper(effects[0], q), dense(effects[0], q), rtol=0, atol=1e-13)


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "numpy"])
def test_a_bar_lattice_tangent_from_upper_values_is_the_sum_of_the_full_blocks(monkeypatch, compiled):
    """Bars give the upper triangles of their blocks, added by the compiled loop (from ``compiled_from``
    members, here all) or else summed by the System's constant 0/1 matrix; ropes keep their full blocks;
    the tangents, free and full, are the sum of the members' full 6 x 6 blocks, and so are the bars on a
    subset of members (``on_members``)."""
    from shellform.effects import rod_compiled
    from shellform.effects.axial import AxialBar, Rope

    monkeypatch.setattr(rod_compiled, "available", compiled and rod_compiled.available)
    monkeypatch.setattr(AxialBar, "compiled_from", 0)
    rng = np.random.default_rng(4)
    nodes = rng.normal(size=(30, 3))
    s = Structure(nodes)
    bars = np.array([(i, j) for i in range(30) for j in range(i + 1, 30) if rng.random() < 0.15])
    s.add_bars(bars[: len(bars) // 2], EA=rng.uniform(1e5, 1e6, len(bars) // 2))
    s.add_ropes(bars[len(bars) // 2:], EA=2e5, rest_length=0.9 * np.linalg.norm(
        nodes[bars[len(bars) // 2:, 1]] - nodes[bars[len(bars) // 2:, 0]], axis=1))
    s.fix([0, 1, 2])
    system = build_system(s)
    assert any(isinstance(e, AxialBar) for e in system.effects) and any(isinstance(e, Rope) for e in system.effects)
    assert system._upper is not None
    q = s.reference_state() + 0.05 * rng.normal(size=s.n_dof)
    total = sum(dense(e, q) for e in system.effects)
    tol = 1e-13 * np.abs(total).max()
    free = system.free
    assert np.allclose(system.tangent_free(q).toarray(), total[np.ix_(free, free)], rtol=0, atol=tol)
    assert np.allclose(system.tangent(q).toarray(), total, rtol=0, atol=tol)
    bar = next(e for e in system.effects if isinstance(e, AxialBar))
    g = np.zeros(s.n_dof)
    compiled_energy = bar._compiled(q, g)
    assert (compiled_energy is not None) == rod_compiled.available
    if compiled_energy is not None:  # energy and forces as the NumPy law gives them
        assert 0.5 * np.sum(compiled_energy) == pytest.approx(super(AxialBar, bar).energy(q), rel=1e-13)
        np.testing.assert_allclose(g, super(AxialBar, bar).gradient(q), rtol=0, atol=1e-12 * np.abs(g).max())
        assert np.allclose(dense_upper(bar, q), dense(bar, q), rtol=0, atol=tol)
        part = bar.on_members(np.arange(0, len(bar.conn), 2), np.arange(30), s.n_dof)
        assert len(part.hessian_upper_pattern()[0]) == 21 * len(part.conn)
        assert np.allclose(dense_upper(part, q), dense(part, q), rtol=0, atol=tol)
    monkeypatch.setattr(AxialBar, "compiled_from", 10**9)  # a small lattice: the upper triangles summed by the 0/1 matrix
    small = build_system(s)
    assert small._upper is not None and not small._upper_free.direct
    assert np.allclose(small.tangent_free(q).toarray(), total[np.ix_(free, free)], rtol=0, atol=tol)
