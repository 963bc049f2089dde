"""Which way the perfect structure goes after its bifurcation: Koiter's classes, from its secondary paths.

At a bifurcation the secondary path leaves the primary one in the critical
mode, on either side. Where it rises (the load factor grows along it, the
structure stable on it) the bifurcation is *stable*: an imperfect structure
passes the perfect critical load and loses stability later, if at all, so a
knock-down factor above 1 is expected of it. Where it falls the bifurcation
is *unstable* on that side: the imperfect structure's limit point lies below
the perfect load (Koiter's 2/3-power law when both sides fall, 1/2-power law
when one rises and the other falls).

The secondary path is followed for :data:`POINTS` points on each side with
the scene's own continuation settings, from the primary path traced again
(a fresh model: the rods' reference frames carry the history of a path).
"""

from __future__ import annotations

#: points followed on each secondary path: enough for its curvature to show
#: at the default step sizes (the first two lie on the bifurcation's tangent)
POINTS = 6

#: Koiter's class of a bifurcation from the way its two secondary paths go
CLASSES = {("rises", "rises"): "stable-symmetric", ("falls", "falls"): "unstable-symmetric",
           ("rises", "falls"): "asymmetric", ("falls", "rises"): "asymmetric"}


def secondary_path(scene: dict, max_step_angle: float, side: int) -> str:
    """``"rises"``, ``"falls"`` or ``"unknown"``: the load factor along the secondary path on ``side`` (+1, -1)."""
    from ..analyses.continuation import path_options
    from ..solvers.continuation import trace_path
    from .sample import imperfect_model

    model = imperfect_model(scene, None)
    options, _, _ = path_options(scene, model.structure, model.system)
    seen: list[tuple[float, int]] = []

    def on_point(pt):
        if pt.branch == 1:
            seen.append((pt.lam, pt.n_negative))
        return True if len(seen) >= POINTS else None

    options.update(on_bifurcation="switch", branch_side=side, max_switches=1, stop_after_events=None,
                   store_states=False, max_angle_deg=max_step_angle, callback=on_point)
    trace_path(model.system, "load", **options)
    if len(seen) < 2:
        return "unknown"
    (first, _), (last, n_negative) = seen[0], seen[-1]
    if last > first and n_negative == 0:
        return "rises"
    if last < first:
        return "falls"
    return "unknown"


def post_buckling(scene: dict, max_step_angle: float) -> dict:
    """The way of both secondary paths of the perfect structure's first bifurcation, and Koiter's class."""
    sides = {"+": secondary_path(scene, max_step_angle, 1), "-": secondary_path(scene, max_step_angle, -1)}
    return {**sides, "class": CLASSES.get((sides["+"], sides["-"]), "unknown")}
