"""Assembly of effects into one global residual and sparse tangent.

The :class:`System` owns the DOF partition (free, fixed, prescribed) and the
sparsity pattern, both computed once. Each call to :meth:`System.tangent`
only evaluates the effects' Hessian values and scatters them into the CSR data
array (one ``np.bincount``, one product by a constant 0/1 matrix, or the
effect's own compiled loop): no Python loop over members.

Sign conventions
----------------
Total potential ``Pi(q, lam) = sum(E_internal) + sum(E_dead) + lam * sum(E_scaled)``.
The residual is its gradient, ``r = f_int - f_ext``; equilibrium is
``r[free] = 0`` and the reactions (forces the supports exert on the
structure) are ``r[constrained]``.
"""

from __future__ import annotations

from collections.abc import Sequence
from contextlib import contextmanager

import numpy as np
import scipy.sparse as sp

from .effects import AxialBar, Effect, Rope, gravity_effect, nodal_load_effects
from .effects.sliding import sliding_effects
from .errors import CheckpointMismatch, ModelError
from .model import Structure
from .sparse_pattern import Pattern, same_pattern
from .upper_tangent import UpperTangent


class System:
    """The global equilibrium problem of a structure with a chosen set of effects.

    Parameters
    ----------
    structure : Structure
        Nodes, supports and prescribed motion (members and loads enter only
        through ``effects``).
    effects : sequence of Effect
        The energy terms to sum; nothing else is evaluated.
    check : bool
        Check that every connected part is restrained against rigid translation.
    """

    def __init__(self, structure: Structure, effects: Sequence[Effect], check: bool = True):
        self.structure = structure
        self.effects = tuple(effects)
        self.n_dof = structure.n_dof
        for e in self.effects:
            if e.n_dof != self.n_dof:
                raise ModelError(f"effect {e.name!r} was built for {e.n_dof} DOFs, the structure has {self.n_dof}")
        if check:
            structure.check_supports()
        self.q_ref = structure.reference_state()
        constrained = structure.constrained_mask
        self.free = np.flatnonzero(~constrained)
        self.constrained = np.flatnonzero(constrained)
        self.prescribed = structure.prescribed_dofs
        self.direction = structure.prescribed_direction
        if self.free.size == 0:
            raise ModelError("every DOF is constrained: there is nothing to solve for")

        rows, cols = self._pattern_triplets()
        self._full = Pattern(rows, cols, (self.n_dof, self.n_dof))
        free_index = np.full(self.n_dof, -1, dtype=np.int64)
        free_index[self.free] = np.arange(self.free.size)
        # the free pattern: the full one's entries in free rows and columns, in the same order (renumbering
        # the free DOFs keeps their order), and the slot there of every triplet
        self._ff, self._ff_slot = self._full.restricted(free_index)
        self._full.rows = None
        # effects that give the upper triangles of their element blocks: the tangents from those
        self._upper = UpperTangent.of(self.effects, self._ranges)
        if self._upper is not None:
            self._upper_free = self._upper.scatter(self.effects, free_index, self._ff, self._ff_slot)
            self._upper_full = None  # built on first use
        self._measures = None  # pattern of the held measures' Jacobian, built on first use

    # -- construction --------------------------------------------------------------
    def _pattern_triplets(self):
        """Triplets of every effect's pattern, once per distinct pattern.

        Effects whose patterns are equal (the bending and twisting of the
        same rod hinges) share their triplets: their values are summed before
        the one scatter. ``self._ranges[k]`` is the slice of the triplets that
        effect ``k``'s values fill, ``self._groups`` the effects sharing each
        slice, in the order of the triplets.
        """
        rows, cols = [], []
        self._ranges = []
        self._groups = []
        count = 0
        for k, e in enumerate(self.effects):
            r, c = e.hessian_pattern()
            shared = next((g for g in self._groups if len(r) and self._ranges[g[0]][1] - self._ranges[g[0]][0] == len(r)
                           and same_pattern(self.effects[g[0]].hessian_pattern(), (r, c))), None)
            if shared is not None:
                shared.append(k)
                self._ranges.append(self._ranges[shared[0]])
                continue
            rows.append(r)
            cols.append(c)
            self._ranges.append((count, count + len(r)))
            self._groups.append([k])
            count += len(r)
        self._n_triplets = count
        # the diagonal is always in the pattern so that a regularising shift
        # never changes the structure of the matrix
        diag = np.arange(self.n_dof, dtype=np.int64)
        rows.append(diag)
        cols.append(diag)
        return np.concatenate(rows), np.concatenate(cols)

    def _group_values(self, values: dict) -> np.ndarray:
        """The values of all triplets from values by effect index (summed over effects sharing a pattern; zero
        for effects left out)."""
        parts = []
        for g in self._groups:
            present = [values[k] for k in g if k in values]
            if not present:
                start, end = self._ranges[g[0]]
                parts.append(np.zeros(end - start))
            elif len(present) == 1:
                parts.append(present[0])
            else:
                total = present[0] + present[1]
                for v in present[2:]:
                    total += v
                parts.append(total)
        return np.concatenate(parts) if parts else np.zeros(0)

    # -- states ---------------------------------------------------------------------
    @property
    def n_free(self) -> int:
        return self.free.size

    def state(self, u_free: np.ndarray | None = None, mu: float = 0.0, base: np.ndarray | None = None) -> np.ndarray:
        """Full DOF vector from free values and the prescribed-displacement parameter ``mu``.

        Constrained DOFs take ``q_ref + mu * direction``; free DOFs take
        ``u_free`` or, when it is None, their value in ``base`` (default ``q_ref``).
        """
        q = np.array(self.q_ref if base is None else base, dtype=float, copy=True)
        q[self.constrained] = self.q_ref[self.constrained] + mu * self.direction[self.constrained]
        if u_free is not None:
            q[self.free] = u_free
        return q

    # -- evaluation -----------------------------------------------------------------------
    def _factor(self, e: Effect, lam: float) -> float:
        return lam if e.scales_with_load else 1.0

    def energy(self, q: np.ndarray, lam: float = 1.0) -> float:
        """Total potential ``Pi(q, lam)``."""
        return float(sum(self._factor(e, lam) * e.energy(q) for e in self.effects))

    def residual(self, q: np.ndarray, lam: float = 1.0) -> np.ndarray:
        """Gradient of the total potential: ``f_int(q) - f_ext(lam)``, all DOFs."""
        r = np.zeros(self.n_dof)
        for e in self.effects:
            r += self._factor(e, lam) * e.gradient(q)
        return r

    def external_force(self, lam: float = 1.0) -> np.ndarray:
        """Applied forces at load factor ``lam`` (dead loads in full, scaled loads times ``lam``)."""
        f = np.zeros(self.n_dof)
        for e in self.effects:
            if e.is_external:
                f -= self._factor(e, lam) * e.gradient(self.q_ref)
        return f

    def forces_in_play(self, q: np.ndarray, lam: float = 1.0) -> np.ndarray:
        """Per DOF, the summed magnitudes of every member force and applied force acting there.

        The scale of an equilibrium test (:mod:`shellform.solvers.equilibrium`):
        unlike the residual, the members' forces do not cancel in it, and
        unlike a tangent it does not grow with a member's stiffness.
        """
        f = np.zeros(self.n_dof)
        for e in self.effects:
            f += abs(self._factor(e, lam)) * e.force_magnitudes(q)
        return f

    def load_vector(self) -> np.ndarray:
        """Reference load ``f_ref`` (``-d residual / d lam``): the sum of the scaled loads."""
        f = np.zeros(self.n_dof)
        for e in self.effects:
            if e.scales_with_load:
                f -= e.gradient(self.q_ref)
        return f

    def tangent(self, q: np.ndarray) -> sp.csr_matrix:
        """Hessian of the total potential over all DOFs (CSR).

        Loads are conservative and constant, so the tangent does not depend on
        the load factor.
        """
        if self._upper is not None:
            if self._upper_full is None:
                self._upper_full = self._upper.scatter(self.effects, np.arange(self.n_dof), self._full,
                                                       self._full.slot)
            data = self._upper.data(self.effects, q, self._upper_full)
            return sp.csr_matrix((data, self._full.indices, self._full.indptr), shape=self._full.shape)
        vals = self._group_values({k: e.hessian_values(q) for k, e in enumerate(self.effects)})
        return self._full.matrix(np.concatenate([vals, np.zeros(self.n_dof)]))

    def tangent_free(self, q: np.ndarray) -> sp.csr_matrix:
        """Tangent restricted to the free DOFs (CSR), assembled directly.

        Effects that give the upper triangles of their element blocks
        (:meth:`Effect.hessian_upper_pattern`) compute and scatter only those;
        the scatter fills the free pattern's data with one product by a
        constant 0/1 matrix, or the effects add their values to it themselves
        (:class:`~shellform.upper_tangent.UpperTangent`); :meth:`tangent` alike.
        """
        if self._upper is not None:
            data = self._upper.data(self.effects, q, self._upper_free)
            return sp.csr_matrix((data, self._ff.indices, self._ff.indptr), shape=self._ff.shape)
        return self._free_matrix({k: e.hessian_values(q) for k, e in enumerate(self.effects)
                                  if self._ranges[k][1] > self._ranges[k][0]})

    def assemble_free(self, values: dict) -> sp.csr_matrix:
        """A matrix on the pattern of :meth:`tangent_free` from some effects' Hessian-shaped values.

        ``values`` maps an effect (one of ``self.effects``) to values in the
        order of its ``hessian_pattern``; the other effects contribute zero.
        The result has exactly the tangent's sparsity structure, so its
        ``data`` can be added to a tangent's entry by entry.
        """
        return self._free_matrix({self._index(e): np.asarray(v, dtype=float) for e, v in values.items()})

    def _index(self, effect: Effect) -> int:
        """Position of ``effect`` in ``self.effects`` (by identity: two effects may compare equal)."""
        k = next((i for i, e in enumerate(self.effects) if e is effect), None)
        if k is None:
            raise ModelError(f"effect {effect.name!r} is not one of this system's effects")
        return k

    def _free_matrix(self, values: dict) -> sp.csr_matrix:
        """The free pattern's matrix from Hessian values by effect index (the other effects give zero)."""
        nnz = self._ff.nnz
        for k, v in values.items():
            start, end = self._ranges[k]
            if v.shape != (end - start,):
                raise ModelError(f"effect {self.effects[k].name!r}: {v.shape} Hessian values for "
                                 f"{end - start} pattern entries")
        if len(values) == 1:
            # the usual case (one kind of member): its values scatter as they are, without a copy
            (k, weights), = values.items()
            slot = self._ff_slot[slice(*self._ranges[k])]
        else:
            # one scatter in the order of the entries, so that every sum is added in a fixed order
            weights = self._group_values(values)
            slot = self._ff_slot[:self._n_triplets]
        data = np.bincount(slot, weights=weights, minlength=nnz + 1)[:nnz]
        return sp.csr_matrix((data, self._ff.indices, self._ff.indptr), shape=self._ff.shape)

    def add_free_entries(self, A: sp.csr_matrix, effect: Effect, entries: np.ndarray, values: np.ndarray) -> None:
        """Add values of some of an effect's Hessian entries to a matrix of :meth:`tangent_free`'s pattern.

        ``A.data`` is changed in place at the entries' positions, without
        assembling a whole matrix: updating a tangent for a few members then
        costs what they cost (a whole assembly moves about 7e7 entries on a
        net of 10^6 nodes). Entries in a row or column of a constrained DOF
        are left out, as in :meth:`tangent_free`.

        Parameters
        ----------
        A : scipy.sparse.csr_matrix
            A matrix with exactly the pattern of :meth:`tangent_free`.
        effect : Effect
            One of ``self.effects``.
        entries : ndarray of int
            Indices into the effect's :meth:`~Effect.hessian_pattern`.
        values : ndarray
            One value per entry.
        """
        n_f = self.free.size
        if A.shape != (n_f, n_f) or A.nnz != self._ff.nnz:
            raise ModelError(f"add_free_entries: the matrix ({A.shape[0]} x {A.shape[1]}, {A.nnz} entries) does not "
                             f"have the pattern of the free tangent ({n_f} x {n_f}, {self._ff.nnz} entries)")
        k = self._index(effect)
        slots = self._ff_slot[slice(*self._ranges[k])][entries]
        free = slots < self._ff.nnz
        np.add.at(A.data, slots[free], np.asarray(values, dtype=float)[free])

    def held_measures(self, q: np.ndarray) -> tuple[np.ndarray, sp.csr_matrix] | None:
        """Values of the effects' held measures (:meth:`Effect.held_measures`) and their Jacobian on the free DOFs.

        Returns ``(values (m,), J (m, n_free))`` or None when no effect has any.
        Measures that depend on constrained DOFs only are left out (nothing
        can change them).
        """
        parts = [m for m in (e.held_measures(q) for e in self.effects) if m is not None]
        if not parts:
            return None
        if self._measures is None:  # the pattern is fixed: built once
            free_index = np.full(self.n_dof, -1, dtype=np.int64)
            free_index[self.free] = np.arange(self.free.size)
            rows, cols, count = [], [], 0
            for _, dofs, _ in parts:
                m, k = dofs.shape
                rows.append(np.repeat(np.arange(count, count + m), k))
                cols.append(free_index[dofs.ravel()])
                count += m
            rows, cols = np.concatenate(rows), np.concatenate(cols)
            keep = cols >= 0
            active = np.unique(rows[keep])
            renumber = np.full(count, -1, dtype=np.int64)
            renumber[active] = np.arange(active.size)
            pattern = Pattern(renumber[rows[keep]], cols[keep], (active.size, self.free.size))
            self._measures = (active, keep, pattern)
        active, keep, pattern = self._measures
        values = np.concatenate([m[0] for m in parts])[active]
        grads = np.concatenate([m[2].ravel() for m in parts])[keep]
        return values, pattern.matrix(grads)

    def reactions(self, q: np.ndarray, lam: float = 1.0) -> np.ndarray:
        """Forces the supports exert on the structure, all DOFs (zero where free): the residual at the
        constrained DOFs, and the springs of sliding supports."""
        r = self.residual(q, lam)
        out = np.zeros(self.n_dof)
        out[self.constrained] = r[self.constrained]
        for e in self.effects:
            if getattr(e, "is_support", False):
                out -= e.gradient(q)
        return out

    def accept(self, q: np.ndarray) -> None:
        """Tell the effects that keep history that ``q`` is an accepted state.

        Discrete elastic rods carry their reference frames from the last
        accepted configuration by parallel transport; other effects have no
        history and are not called. Solvers call this after each converged
        load, continuation or time step. The energy at ``q`` is unchanged.
        """
        for e in self.effects:
            hook = getattr(e, "accept", None)
            if hook is not None:
                hook(q)

    # -- path history ---------------------------------------------------------------------
    def history_objects(self) -> list:
        """The objects that carry the path's history (the rods' reference frames), each once.

        A rod's twist angles are measured from reference frames carried along
        the accepted states, so a state vector means a configuration only
        together with the frames it was found with.
        """
        objs, seen = [], set()
        for e in self.effects:
            f = getattr(e, "frames", None)
            if f is not None and hasattr(f, "state") and hasattr(f, "restore") and id(f) not in seen:
                seen.add(id(f))
                objs.append(f)
        return objs

    def history(self):
        """A copy of the path's history as accepted so far (None when no effect keeps one)."""
        objs = self.history_objects()
        return tuple(o.state() for o in objs) if objs else None

    def restore_history(self, saved) -> None:
        """Return to a history saved by :meth:`history` (None: nothing to restore)."""
        if saved is None:
            return
        objs = self.history_objects()
        if len(saved) != len(objs):
            raise ModelError(f"a saved path history of {len(saved)} objects cannot be restored on a system "
                             f"with {len(objs)}")
        for o, state in zip(objs, saved):
            o.restore(state)

    @contextmanager
    def evaluated_with(self, saved):
        """Evaluate states with the path history ``saved`` (from :meth:`history`), then put the current one back.

        What a stored state of a rod model is (its twists, torques, reactions)
        depends on the frames it was found with, not on those of the end of
        the run.
        """
        if saved is None:
            yield self
            return
        now = self.history()
        self.restore_history(saved)
        try:
            yield self
        finally:
            self.restore_history(now)

    def member_results(self, q: np.ndarray) -> dict[str, dict[str, np.ndarray]]:
        """Per-member output of every effect that reports any, keyed by effect label."""
        out = {}
        for e in self.effects:
            res = e.member_results(q)
            if res:
                out[getattr(e, "label", e.name)] = res
        return out


def member_effects(structure: Structure) -> list[Effect]:
    """One effect per member group, of the group's kind."""
    kinds = {"bar": AxialBar, "rope": Rope}
    effects = []
    for g in structure.groups:
        if g.kind not in kinds:
            raise ModelError(f"member group {g.name!r}: unknown kind {g.kind!r}; expected one of {sorted(kinds)}")
        e = kinds[g.kind](structure.n_dof, g.connectivity, g.EA, g.rest_length)
        e.label = g.name
        effects.append(e)
    return effects


def build_system(structure: Structure, gravity_scaled: bool = False, check: bool = True) -> System:
    """A System with the effects the structure calls for.

    Members give axial or rope effects, load cases give constant forces, and
    self-weight is included only when ``structure.gravity`` is set.
    """
    effects = member_effects(structure) + sliding_effects(structure) + nodal_load_effects(structure)
    if structure.gravity is not None:
        effects.append(gravity_effect(structure, scales_with_load=gravity_scaled))
    return System(structure, effects, check=check)


def stack_histories(prefix: str, histories: list) -> dict[str, np.ndarray]:
    """Path histories (``System.history()`` of each of a run's states) as stacked arrays ``{prefix}{k}_{name}``.

    Nothing when there are none (no rods).
    """
    if not histories or histories[0] is None:
        return {}
    return {f"{prefix}{k}_{name}": np.stack([h[k][name] for h in histories])
            for k in range(len(histories[0])) for name in histories[0][k]}


def unstack_histories(arrays, prefix: str, count: int, path) -> list:
    """The histories of :func:`stack_histories` back, one per state (None each when none were saved)."""
    names = getattr(arrays, "files", None) or list(arrays)
    fields: dict[int, list[str]] = {}
    for key in names:
        if key.startswith(prefix):
            k, name = key[len(prefix):].split("_", 1)
            fields.setdefault(int(k), []).append(name)
    if not fields:
        return [None] * count
    if sorted(fields) != list(range(len(fields))):
        raise CheckpointMismatch(f"checkpoint {path}: its saved rod frames ({prefix}) miss an object")
    return [tuple({name: np.array(arrays[f"{prefix}{k}_{name}"][i]) for name in fields[k]} for k in range(len(fields)))
            for i in range(count)]
