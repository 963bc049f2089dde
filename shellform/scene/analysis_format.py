"""The scene format's tables of the analyses: form finding with its start and length control,
buckling, indentation, time stepping and imperfection studies (parts of
:data:`shellform.scene.format.SCENE`)."""

from __future__ import annotations

from ..mra.formfind import COARSE_START_NODES
from ..solvers.continuation.options import ContinuationOptions
from ..solvers.relaxation.options import Refinements, RelaxationOptions
from .schema import NONNEGATIVE as _NONNEG
from .schema import POSITIVE as _POS
from .schema import Key, Table

# the relaxation's defaults are the solver's own, written once in its options
_RELAX, _REFINE = RelaxationOptions(), Refinements()

RELAXATION = Table(
    fill_defaults=True,
    doc="MRA form finding by dynamic relaxation (analysis 'mra' and 'form_and_buckle'). Also read from a "
        "top-level [solver] table.",
    keys={
        "scheme": Key("str", "Relaxation scheme: pseudo-transient Newton (fast), the paper's explicit RK4, or "
                      "leapfrog with kinetic damping.", default=_RELAX.scheme, choices=("implicit", "rk4", "kinetic")),
        "rtol": Key("float", "Rest: every nodal acceleration <= rtol g and velocity <= rtol sqrt(g L).",
                    default=_RELAX.rtol, **_POS),
        "velocity_tol": Key("float", "Explicit velocity tolerance (default from rtol).", default=_RELAX.velocity_tol, unit="m/s",
                            **_POS),
        "acceleration_tol": Key("float", "Explicit acceleration tolerance (default from rtol).", default=_RELAX.acceleration_tol,
                                unit="m/s^2", **_POS),
        "max_iterations": Key("int", "Give up after this many steps (default 500 implicit, 2,000,000 explicit).",
                              default=_RELAX.max_iterations, minimum=1),
        "max_wall_time": Key("float", "Give up after this many seconds (default: no limit).", default=_RELAX.max_wall_time, unit="s", **_POS),
        "damping": Key("float", "Viscous damping per unit mass (default 2 sqrt(g / L)).", default=_RELAX.damping, unit="1/s",
                       **_NONNEG),
        "linear_solver": Key("str", "Linear solver of the implicit scheme: 'auto' is 'cholesky' (supernodal "
                             "CHOLMOD); 'ldl' (QDLDL), 'nd' (SuperLU in nested-dissection order), 'amg' (soft nets "
                             "only) or 'direct'.", default=_RELAX.linear_solver,
                             choices=("auto", "cholesky", "ldl", "nd", "amg", "direct")),
        "slack_active_set": Key("bool", "Implicit scheme: solve each step again with the slack ropes it would "
                                "stretch modelled as taut: about half the steps, each up to three solves.", default=_REFINE.slack_active_set),
        "front_sweeps": Key("bool", "Implicit scheme: after a step that leaves only a few nodes out of balance "
                            "(along the fronts between taut and slack regions), take up to three Newton steps on the "
                            "nodes within four ropes of them, the rest of the net held.", default=_REFINE.front_sweeps),
        "factor_correction": Key("bool", "Implicit scheme: before refactorising the tangent, try conjugate gradients "
                                 "with the kept factorisation corrected by an exact solve on the nodes whose tangent "
                                 "entries changed (ropes pulled taut or gone slack).", default=_REFINE.factor_correction),
        "slack_settling": Key("bool", "Implicit scheme: when a step gets ropes' slack state wrong (slack ropes it "
                              "stretches outside its active set, taut ones it shortens below their rest length), "
                              "settle them by Newton steps on the step's model over the nodes within three ropes of "
                              "them (needs slack_active_set).", default=_REFINE.slack_settling),
        "step_repair": Key("bool", "Implicit scheme: when a few ropes make a step of the whole net overshoot, keep "
                           "the full step and relax the nodes within three ropes of them from there instead of "
                           "shortening the whole step (needs slack_active_set).", default=_REFINE.step_repair),
        "start": Key("str", "Start of a relaxation without a [start] surface: 'auto' is, for the implicit "
                     f"scheme, the coarse net's start on nets of {COARSE_START_NODES:,} nodes or more and the force-density shape "
                     "below, and the flat planform for the explicit ones (as in the paper); 'reference' forces the "
                     "planform, 'force_density' the force-density shape, 'coarse_net' the shape of the net with "
                     "every third grid line, hung first, interpolated and hung a little deeper.", default="auto",
                     choices=("auto", "reference", "force_density", "coarse_net")),
        "dt": Key("float", "Explicit time step (default 90 % of the stability bound) or first pseudo time step.",
                  default=_RELAX.dt, unit="s", **_POS),
        "checkpoint_interval": Key("float", "Save the relaxation state to DIR/relaxation_checkpoint.npz at most "
                                   "this often (and when it stops unconverged); `--resume` restarts from it.",
                                   default=5.0, unit="s", **_NONNEG),
    },
)

START_SHAPE = Table(
    fill_defaults=True,
    doc="Start shape of the form finding. Also read from a top-level [start] table.",
    keys={
        "type": Key("str", "No start surface ('flat': the [solver] start decides, the planform for the explicit "
                    "schemes), a B-spline dish, a B-spline fitted to a coarser hanging net, or the shape in balance "
                    "with the force densities of a coarser hanging net.",
                    default="flat", choices=("flat", "nurbs", "coarse_nurbs", "coarse_force_density")),
        "depth": Key("float", "nurbs: depth of the dish.", default=None, unit="m"),
        "control_heights": Key("grid", "nurbs: control heights over the planform box (instead of depth).",
                               default=None, unit="m"),
        "coarsening": Key("int", "coarse_nurbs, coarse_force_density: the coarse net has this many times fewer "
                          "quads per side.",
                          default=4, minimum=1),
        "n_ctrl": Key("int", "coarse_nurbs: control points per direction of the fitted surface.", default=6,
                      minimum=2),
        "compare_flat": Key("bool", "Also relax from the flat start and report the iterations and time saved.",
                            default=False),
    },
)

LENGTHS = Table(
    fill_defaults=True,
    doc="Rope length statistics and control (analysis 'mra'). Also read from a top-level [lengths] table.",
    keys={
        "tolerance": Key("float", "Relative tolerance for 'the same length'.", default=0.01, **_POS),
        "target": Key("float", "Count the ropes within tolerance of this length (default: no count).", default=None, unit="m", **_POS),
        "control": Key("bool", "Drive the ropes towards n_classes lengths.", default=False),
        "n_classes": Key("int", "Length classes of the control.", default=3, minimum=1),
        "rounds": Key("int", "Rounds of the control.", default=4, minimum=1),
    },
)

BUCKLING = Table(
    fill_defaults=True,
    doc="Buckling of the rod gridshell built on the found form (analysis 'form_and_buckle'): the inverted net's "
        "grid lines (an unstructured quad net's straight edge chains) become rods ([rods]), pinned at the suspension points, loaded by the net's weight times a "
        "load factor traced by arc-length continuation to the first critical point. Also read from a top-level "
        "[buckling] table (which may hold the [rods] keys E, G, radius, density and rest_shape too).",
    keys={
        "load_factor_max": Key("float", "Stop when the load factor exceeds this.", default=100.0, **_POS),
        "max_steps": Key("int", "Continuation steps before stopping.", default=60, minimum=1),
        "initial_increment": Key("float", "First load-factor increment (default 1/20 of load_factor_max).",
                                 default=None, **_POS),
        "checkpoint_every": Key("int", "Checkpoint of the path every this many steps.", default=10, minimum=1),
    },
)

INDENTATION = Table(
    fill_defaults=True,
    doc="Apex indentation of the hemisphere (analysis 'indentation'): pre-stress on the net, push the apex down "
        "by dD in displacement control through every snap (gridshell paper). The imperfection is random dead "
        "forces ([imperfection] type 'forces'; default 1e-4 EI/R^2, seed 0).",
    keys={
        "mode": Key("str", "I: apex node(s) prescribed, rods rotate freely; II: apex and its neighbours on the "
                    "central rods move together (clamped-like).", default="I", choices=("I", "II")),
        "max_displacement": Key("float", "Final apex displacement dD / R.", default=2.0, **_POS),
        "increment": Key("float", "First continuation step, as dD / R.", default=0.01, **_POS),
        "snap_method": Key("str", "How the stable state after a snap is found: damped implicit Euler dynamics, "
                           "energy descent, or descent first.", default="dynamic",
                           choices=("dynamic", "energy", "auto")),
        "max_snaps": Key("int", "Stop after this many losses of stability.", default=12, minimum=1),
        "max_steps": Key("int", "Continuation steps before stopping.", default=3000, minimum=1),
    },
)

DYNAMICS = Table(
    fill_defaults=True,
    doc="Time stepping by implicit Euler (analysis 'dynamics'; gridshell paper, Eq. 2): lumped masses from "
        "mass_per_length and [masses], damping C = c M, the loads times the load factor (ramped over ramp_time).",
    keys={
        "time_step": Key("float", "Time step h (halved where Newton fails, grown back after). Required for "
                         "analysis 'dynamics'.", default=None,
                         unit="s", **_POS),
        "duration": Key("float", "Simulated time. Required for analysis 'dynamics'.", default=None, unit="s", **_POS),
        "damping": Key("float", "Mass-proportional damping coefficient c.", default=0.0, unit="1/s", **_NONNEG),
        "ramp_time": Key("float", "The load factor rises linearly from 0 over this time (0: applied at once).",
                         default=0.0, unit="s", **_NONNEG),
        "output_every": Key("int", "Write every k-th step to the XDMF time series.", default=1, minimum=1),
        "monitor_node": Key("int", "Node whose displacement is tabulated and plotted (default: none; the "
                            "largest node displacement is tabulated and plotted in any case).", default=None,
                            minimum=0),
        "monitor_component": Key("str", "Component of monitor_node.", default="z", choices=("x", "y", "z")),
        "checkpoint_interval": Key("float", "Save the state to DIR/dynamics_checkpoint.npz at most this often; "
                                   "`--resume` continues from it.", default=5.0, unit="s", **_NONNEG),
    },
)

#: kinds of imperfection shape of a study (shellform.studies.shapes)
STUDY_SHAPES = ("modes", "mode_combinations", "random_field")

STUDY = Table(
    discriminator="shapes",
    doc="An imperfection-sensitivity study (`shellform study imperfection SCENE`; see imperfections.md): the "
        "scene's load-controlled continuation traced for many imperfect structures, each to the load at which it "
        "first loses stability. The imperfection moves the stress-free nodes (free DOFs only) by a shape scaled to "
        "a largest node movement of amplitude x the reference length. `shellform run` ignores this table.",
    keys={
        "shapes": Key("str", "modes: each of the lowest buckling modes of the perfect structure (at its first "
                      "critical point) on its own; mode_combinations: random combinations of them (independent "
                      "standard normal weights); random_field: Gaussian random fields over the nodes.",
                      default="modes", choices=STUDY_SHAPES),
        "modes": Key("int", "How many of the lowest buckling modes (modes, mode_combinations).", default=3,
                     minimum=1, maximum=100, only=("modes", "mode_combinations")),
        "amplitudes": Key("float_or_list", "Imperfection amplitudes, as multiples of the reference length "
                          "(relative_to); instead of amplitude_min/max/count.", default=None),
        "amplitude_min": Key("float", "Smallest amplitude of a range (with amplitude_max, amplitude_count).",
                             default=None, **_POS),
        "amplitude_max": Key("float", "Largest amplitude of a range.", default=None, **_POS),
        "amplitude_count": Key("int", "Amplitudes in the range.", default=5, minimum=1, maximum=1000),
        "amplitude_spacing": Key("str", "Spacing of the range.", default="log", choices=("log", "linear")),
        "relative_to": Key("str", "Reference length of the amplitudes: span (the largest distance between two "
                           "nodes in plan), member_length (the mean rest length of the members) or absolute "
                           "(amplitudes in m).", default="span", choices=("span", "member_length", "absolute")),
        "signs": Key("str", "modes: the sign of each mode (a mode's largest component is positive).",
                     default="both", choices=("both", "positive", "negative"), only=("modes",)),
        "samples": Key("int", "Random shapes per amplitude (mode_combinations, random_field).", default=100,
                       minimum=1, maximum=100_000, only=("mode_combinations", "random_field")),
        "seed": Key("int", "Seed of the random shapes.", default=0, minimum=0,
                    only=("mode_combinations", "random_field")),
        "correlation_length": Key("float", "random_field: correlation length of the squared-exponential "
                                  "covariance exp(-d^2 / (2 l^2)) between nodes a distance d apart.", default=None,
                                  unit="m", only=("random_field",), required_for=("random_field",), **_POS),
        "fractile": Key("float", "Fractile of the critical load factor reported for random shapes.", default=0.05,
                        minimum=0.0, exclusive_minimum=True, maximum=0.5),
        "confidence": Key("float", "Confidence level of the fractile's distribution-free interval.", default=0.95,
                          minimum=0.5, maximum=0.9999),
        "max_step_angle": Key("float", "Largest angle between a continuation step's prediction and its converged "
                              "point (degrees); a step turned further is taken again, shorter.",
                              default=ContinuationOptions.max_angle_deg, minimum=0.01, maximum=90.0),
    },
)
