"""Dynamic relaxation of hanging rope nets: the multi-body rope approach (MRA).

Every node of the net is a mass; the ropes between the nodes pull only when
taut. The net falls from its start configuration under its weight and comes to
rest in the hanging (funicular) shape. At every free DOF the d'Alembert
balance of Eqs. (6)-(8) of the MRA paper reads

    m_i a_i + c_i v_i = -r_i(q),        r = f_int(q) - f_ext  (System.residual)

with lumped nodal masses ``m_i`` (``Structure.nodal_mass()`` plus optional
extra inertia) and viscous damping ``c_i = damping * m_i``. Rest is reached
when every nodal velocity and every nodal acceleration is below a tolerance.

Three schemes reach that rest state; ``RelaxationOptions.scheme`` selects one:

``"rk4"``
    The paper's scheme: explicit classical Runge-Kutta time stepping of the
    damped motion with a fixed step below the stability limit (from a
    Gershgorin bound of the rope stiffnesses over the masses).
``"kinetic"``
    Explicit leapfrog with kinetic damping (Cundall/Barnes): no viscosity;
    whenever the kinetic energy passes a peak the velocities are zeroed and
    the state moved back to the peak. One force evaluation per step instead of
    four, and no viscous drag slowing the fall.
``"implicit"``
    Pseudo-transient continuation: each step is a backward-Euler step of the
    motion from rest, ``(K + (1/dt^2 + c/dt) M) dq = -r``, with the global sparse
    tangent ``System.tangent_free``. The total potential of a hanging net is
    convex (a taut rope's energy is a convex function of the node positions,
    a slack one is zero, the weight is linear), so a step is accepted when the
    potential falls as the quadratic model predicts, and the pseudo time step
    grows; when it grows without bound the step is Newton's method and
    convergence is quadratic. The mass term keeps the matrix positive definite
    while ropes are slack (a slack rope has no stiffness). Five devices make
    it fast on nets of nearly inextensible ropes: a start from the
    force-density shape (one scalar linear solve, :mod:`.force_density`)
    instead of the flat planform, so the net does not have to fall into its
    shape; a continuation in the rope stiffness (soft ropes first, ten times
    stiffer per stage, the true EA last, :mod:`.stiffness`); a line search on the potential
    along each step (its changes summed member by member, so they stay
    accurate near equilibrium, :mod:`.line_search`); conjugate gradients preconditioned by the
    factor of an earlier step, refactorising only when they stall (CHOLMOD's
    supernodal Cholesky; LDL^T or SuperLU in nested-dissection order on
    request, :mod:`.linalg`); and, once only a few nodes along the fronts between taut and
    slack regions are far from balance, Newton steps on the patches around
    them with the rest of the net held (:func:`~.patch_steps.sweep_fronts`). A step's
    slack ropes enter its model by an active set (:func:`~.active_set.engage_slack_ropes`),
    settled on the patches where its rounds leave ropes in the wrong state
    (:func:`~.active_set.settle_slack_set`).

All three stop on the same test (nodal velocity and acceleration below the
tolerances) and reach the same equilibrium: the minimum of the potential.

Layout: :mod:`.driver` (:func:`relax`), :mod:`.options`, :mod:`.result`,
:mod:`.bounds` (masses, tolerances, the explicit step bound), :mod:`.monitor`,
:mod:`.explicit` (RK4, kinetic damping), :mod:`.implicit` (pseudo-transient
continuation), :mod:`.stiffness`, :mod:`.active_set`, :mod:`.patch` and
:mod:`.patch_steps` (front sweeps, step repair), :mod:`.line_search`,
:mod:`.linalg`, :mod:`.ordering`, :mod:`.local_correction`,
:mod:`.force_density`, and :mod:`.ropes` (what the relaxation knows of ropes).
"""

from .bounds import nodal_masses, node_stiffness_bound, stable_time_step
from .driver import relax
from .force_density import force_density_shape, force_density_start
from .line_search import energy_change
from .linalg import REFACTOR_COST, iteration_budget
from .options import SCHEMES, START_STATES, Refinements, RelaxationOptions
from .ordering import nested_dissection
from .result import RelaxationProgress, RelaxationResult

__all__ = [
    "REFACTOR_COST", "SCHEMES", "START_STATES", "Refinements", "RelaxationOptions", "RelaxationProgress",
    "RelaxationResult", "energy_change", "force_density_shape", "force_density_start", "iteration_budget",
    "nested_dissection", "nodal_masses", "node_stiffness_bound", "relax", "stable_time_step",
]
