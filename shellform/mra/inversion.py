"""Hooke's inversion: the hanging net, mirrored, is a shell in pure compression.

If the ropes of the hanging net carry tensions ``T_e`` in equilibrium with
the nodal loads ``p_i``, then with the mirror ``S = diag(1, 1, -1)`` about a
horizontal plane,

    sum_e T_e S e_ij + S p_i = 0   =>   sum_e (-T_e) S e_ij + (-S p_i) = 0,

so the mirrored shape carries the load ``-S p`` (for gravity: the same
weight, downwards) with member forces ``-T_e``: compression of the same
magnitude. :func:`invert` builds that shell as its own
:class:`~shellform.model.Structure` of bars (rest lengths chosen so the bars
carry exactly ``-T_e`` in the mirrored shape), with the hanging net's masses
as point masses and the same supports, and checks its equilibrium with the
core assembly.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..assembly import System, build_system
from ..effects.curve_sliding import curve_sliding_effects
from ..effects.sliding import plane_and_line_effects
from ..errors import ModelError
from ..model import Structure
from .formfind import FormFindingResult

MIRROR = np.array([1.0, 1.0, -1.0])


@dataclass
class InvertedShell:
    """The inverted (dome) shape with its compression forces.

    Attributes
    ----------
    structure : Structure
        Bars on the mirrored nodes, point masses, supports, gravity.
    system : System
    q : ndarray
        The mirrored state (the structure's reference state).
    force : ndarray, shape (m,)
        Bar forces [N], negative in compression, in the net's rope order.
    reactions : ndarray, shape (n_supports, 3)
    equilibrium_residual : float
        Out-of-balance force of the shell at its free DOFs over the weight;
        round-off small when the hanging net was in equilibrium.
    plane_z : float
        Height of the mirror plane.
    """

    structure: Structure
    system: System
    q: np.ndarray
    force: np.ndarray
    reactions: np.ndarray
    equilibrium_residual: float
    plane_z: float

    @property
    def positions(self) -> np.ndarray:
        return self.q.reshape(-1, 3)

    def summary(self) -> dict:
        comp = -self.force
        return {
            "max_compression": float(comp.max()) if len(comp) else 0.0,
            "n_compressed_members": int(np.sum(self.force < 0)),
            "n_unloaded_members": int(np.sum(self.force == 0)),
            "max_tension": float(max(self.force.max(), 0.0)) if len(comp) else 0.0,
            "equilibrium_residual_over_weight": float(self.equilibrium_residual),
            "mirror_plane_z": float(self.plane_z),
            "rise": float(self.positions[:, 2].max() - self.plane_z),
        }


def invert(result: FormFindingResult, plane_z: float | None = None) -> InvertedShell:
    """Mirror the hanging shape and build the compression shell of Hooke's theorem.

    Parameters
    ----------
    result : FormFindingResult
        A converged hanging shape.
    plane_z : float, optional
        Height of the mirror plane; default the highest suspension point, so
        the dome rises above its supports.
    """
    net = result.net
    hang = net.structure
    x = result.positions
    if plane_z is None:
        plane_z = float(x[net.supports, 2].max())
    xi = x * MIRROR
    xi[:, 2] += 2.0 * plane_z
    shell = Structure(xi)
    shell.add_point_mass(np.arange(hang.n_nodes), hang.nodal_mass())
    g = hang.gravity if hang.gravity is not None else np.array([0.0, 0.0, -9.81])
    shell.set_gravity(-(MIRROR * g))
    for case in hang.load_cases:
        shell.add_load(np.arange(hang.n_nodes), -(MIRROR * case.forces), scaled=case.scaled)
    # bars that carry -T in the mirrored shape: EA (l - L0) / L0 = -T
    tension, length = result.tension, result.length
    EA = net.EA
    bad = np.flatnonzero(tension >= EA)
    if bad.size:
        k = int(bad[0])
        raise ModelError(
            f"inversion: rope {k} carries {tension[k]:.4g} N >= EA = {EA[k]:.4g} N (strain over 100 %); no bar can "
            "carry that compression - the hanging state is not a converged net of nearly inextensible ropes"
        )
    rest = length / (1.0 - tension / EA)
    shell.add_bars(net.rope_edges, EA=EA, rest_length=rest, name="members")
    mask = hang.constrained_mask[: 3 * hang.n_nodes]
    shell.fix_dofs(np.flatnonzero(mask))
    _mirror_sliding_supports(hang, shell, x, plane_z)
    system = build_system(shell)
    q = shell.reference_state()
    force = system.member_results(q)["members"]["axial_force"]
    R = system.reactions(q)[: 3 * hang.n_nodes].reshape(-1, 3)[net.supports]
    weight = net.total_weight()
    resid = float(np.linalg.norm(system.residual(q)[system.free]) / max(weight, 1e-300))
    return InvertedShell(structure=shell, system=system, q=q, force=force, reactions=R,
                         equilibrium_residual=resid, plane_z=plane_z)


def _mirror_sliding_supports(hang, shell, x, plane_z) -> None:
    """The net's sliding supports mirrored into the shell, each carrying the mirrored reaction.

    The plane, line or curve is mirrored with the net; the shell pushes on it where the net pulled, so
    its spring (the net's, whatever the shell's members) is stretched the other way: the plane's or
    line's point is the hanging one reflected through the node, and a curve's shift per node moves it
    across the node by twice the net's offset ``r`` (``x - s - c = -r`` mirrored).
    """
    springs = plane_and_line_effects(hang)
    at = 0
    for slider in hang.sliders:
        hung = hang.nodes[slider.nodes] if slider.origin is None else slider.origin
        origin = (2.0 * x[slider.nodes] - hung) * MIRROR
        origin[:, 2] += 2.0 * plane_z
        k = springs[0].k[at: at + len(slider.nodes)]
        at += len(slider.nodes)
        shell.sliders.append(replace(slider, held=MIRROR[:, None] * slider.held * MIRROR[None, :], origin=origin,
                                     stiffness=k))
    q = np.zeros(hang.n_dof)
    q[: 3 * hang.n_nodes] = x.ravel()
    lift = np.array([0.0, 0.0, 2.0 * plane_z])
    for slider, spring in zip(hang.curve_sliders, curve_sliding_effects(hang)):
        r = spring.nearest(q)[2]
        shell.curve_sliders.append(replace(slider, curve=slider.curve.transformed(np.diag(MIRROR), lift),
                                           shift=(spring.shift + 2.0 * r) * MIRROR, stiffness=spring.k))
