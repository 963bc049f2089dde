"""The stiffness continuation of the implicit scheme: soft ropes first, the true EA last.

Nearly inextensible ropes make the potential so stiff that a quadratic model
is accurate only for tiny steps while the net is far from its shape; soft
ropes let the early steps be large. Each stage is ten times stiffer than the
one before and starts from its end; the last has the true EA, so the
equilibrium is the same.
"""

from __future__ import annotations

import copy

import numpy as np

from .ropes import axial_effects, is_axial, member_lengths


def with_stiffness_scale(system, scale: float):
    """A shallow copy of ``system`` whose axial members have ``scale`` times their EA.

    The springs of sliding supports, a multiple of the members' stiffness, are
    scaled with them: a spring that kept its full stiffness in a soft stage
    would hold a node that slides along a curve so tightly that each step could
    follow the curve only a little way (on a net hung from a curved wall,
    299 iterations against 108 with the springs scaled; 51 with straight rails
    at the same nodes). The copy shares the sparsity patterns (they do not
    depend on EA) and leaves the caller's System untouched.
    """
    view = copy.copy(system)
    effects = []
    for e in system.effects:
        if is_axial(e):
            e = copy.copy(e)
            e.EA = e.EA * scale
        elif getattr(e, "is_support", False):
            e = e.scaled(scale)
        effects.append(e)
    view.effects = tuple(effects)
    return view


#: an intermediate stiffness stage ends when every nodal acceleration is below this many g: it
#: only has to land near its equilibrium, and a tighter tolerance ends it with a crawl of slack fronts
STAGE_TOLERANCE = 0.3


def continuation_scales(system, st, lam) -> list[float]:
    """Stiffness scales of the EA continuation, ending at 1.

    The first stage makes the ropes soft enough to stretch about 10 % under an
    estimate of the rope tension (the largest nodal load times the number of
    ropes across the net, over four); each later stage is ten times stiffer.
    When most ropes are already taut at the start, the first stage is the one
    whose expected strain matches their median strain.
    """
    axial = axial_effects(system)
    if not axial:
        return [1.0]
    EA = np.concatenate([e.EA for e in axial])
    L = np.concatenate([e.L for e in axial])
    f = np.linalg.norm(system.external_force(lam).reshape(-1, 3), axis=1)
    tension = float(f.max()) * max(st.L_ref / float(np.mean(L)), 1.0) / 4.0
    if tension <= 0:
        return [1.0]
    s0 = 10.0 * tension / float(np.median(EA))
    # A start that already hangs (most ropes taut, e.g. on a surface close to the
    # shape) skips the stages softer than its own rope strains: a soft stage would
    # only stretch the net away from where it starts.
    strain = np.concatenate([(member_lengths(e, st.q) - e.L) / e.L for e in axial])
    taut = strain > 0
    if taut.mean() >= 0.5:
        s0 = max(s0, 0.1 * s0 / max(float(np.median(strain[taut])), 1e-12))
    if s0 >= 0.1:
        return [1.0]
    scales = []
    while s0 < 1.0:
        scales.append(s0)
        s0 *= 10.0
    return scales + [1.0]
