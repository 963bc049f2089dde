"""Two link models built of bars, with the exact maximum load of the imperfect model in closed form.

Both are a strut ``D B`` of rest length ``L`` (axial stiffness ``EA``)
loaded at its top ``D`` by a dead load ``lam`` (1 N downwards). ``D`` runs
on a vertical roller (only z free), the foot ``B`` on a horizontal one (only
x free), so the strut turns by an angle ``theta`` with ``sin theta = x_B / l``
(``l`` its current length) and the model has one degree of freedom besides
the strut's shortening. A spring bar holds ``B``:

- **symmetric**: a horizontal bar ``B C`` of length ``S`` (``C`` pinned,
  ``EA_s = k S``). ``B`` moves along the bar, so its force is exactly
  ``k (x - x0)`` (engineering strain): the classic rigid link propped by a
  linear spring, an unstable-symmetric bifurcation.
- **asymmetric**: a bar ``B C`` at 45 degrees below the roller (``C`` at
  ``(-S cos a, -S sin a)``): its length changes to second order in ``x`` with
  a sign, an asymmetric bifurcation.

Equilibrium of D (vertical) and B (horizontal) with the strut's compression
``N = EA (L' - l) / L'`` gives, with ``F(x)`` the spring's horizontal force
at B and ``L'`` the strut's rest length,

    sin theta = x / L' + F(x) / EA,      lam = F(x) cot theta,

an explicit load along the path parametrised by ``x``. An imperfection of
amplitude ``a`` (the foot moved to ``x0 = a`` in the stress-free geometry;
the perfect model's critical mode) gives ``L' = sqrt(L^2 + a^2)`` and the
spring's rest length from the moved foot. For the symmetric model the
maximum is in closed form: with ``s = a / L'`` and ``k_a = EA_s / (S + a)``,

    lam_max = k_a L' / (1 + k_a L' / EA) (1 - s^(2/3))^(3/2)

(at ``sin theta = s^(1/3)``; Koiter: ``1 - kappa ~ 3/2 s^(2/3)``). For the
asymmetric one the explicit ``lam(x)`` is maximised over ``x`` to round-off.
The perfect models bifurcate at ``lam_c = k L / (1 + k L / EA)`` with
``k = EA_s / S`` (symmetric) or ``EA_s cos^2 a / S`` (asymmetric).
"""

from __future__ import annotations

import numpy as np

#: the models' data: strut length and stiffness, spring length, stiffness per length, angle
SYMMETRIC = {"L": 1.0, "EA": 100.0, "S": 100.0, "k": 1.0, "alpha": 0.0}
ASYMMETRIC = {"L": 1.0, "EA": 100.0, "S": 1.0, "k": 1.0, "alpha": np.pi / 4}
MODELS = {"symmetric": SYMMETRIC, "asymmetric": ASYMMETRIC}


def link_scene(kind: str, study: str = "", parameter_max: float = 2.0, max_steps: int = 400) -> str:
    """The TOML scene of a link model (``kind`` symmetric or asymmetric), with ``study`` as its ``[study]`` body."""
    m = MODELS[kind]
    c = (-float(m["S"] * np.cos(m["alpha"])), 0.0, -float(m["S"] * np.sin(m["alpha"])))
    text = f"""title = "{kind} link model: a strut on rollers held by a spring bar"
[nodes]
coordinates = [[0.0, 0.0, {m['L']!r}], [0.0, 0.0, 0.0], [{c[0]!r}, 0.0, {c[2]!r}]]
[[members]]
name = "strut"
kind = "bar"
connectivity = [[0, 1]]
EA = {m['EA']!r}
[[members]]
name = "spring"
kind = "bar"
connectivity = [[1, 2]]
EA = {m['k'] * m['S']!r}
[[supports]]
nodes = [0]
dofs = "xy"
[[supports]]
nodes = [1]
dofs = "yz"
[[supports]]
nodes = [2]
dofs = "xyz"
[[loads]]
nodes = [0]
force = [0.0, 0.0, -1.0]
[analysis]
type = "continuation"
[analysis.continuation]
parameter_max = {parameter_max!r}
max_steps = {max_steps}
initial_increment = 0.01
"""
    return text + (f"[study]\n{study}\n" if study else "")


def critical_load(kind: str) -> float:
    """The perfect model's bifurcation load factor."""
    m = MODELS[kind]
    k = m["k"] * np.cos(m["alpha"]) ** 2
    return k * m["L"] / (1.0 + k * m["L"] / m["EA"])


def path_load(kind: str, x, a: float):
    """The load factor on the path of the model with imperfection ``a`` where the foot is at ``x``."""
    m = MODELS[kind]
    L1 = np.hypot(m["L"], a)
    cx, cz = m["S"] * np.cos(m["alpha"]), m["S"] * np.sin(m["alpha"])
    length = lambda x: np.hypot(x + cx, cz)  # noqa: E731 (the spring's length with the foot at x)
    rest = length(a)
    F = m["k"] * m["S"] * (length(x) - rest) / rest * (x + cx) / length(x)
    sin = x / L1 + F / m["EA"]
    return F * np.sqrt(1.0 - sin**2) / sin


def exact_knockdown(kind: str, a: float) -> float:
    """``lam_max(a) / lam_c`` of the model with imperfection ``a`` (> 0 symmetric, < 0 the unstable side asymmetric)."""
    m = MODELS[kind]
    if kind == "symmetric":
        L1 = np.hypot(m["L"], a)
        ka = m["k"] * m["S"] / (m["S"] + a)
        s = abs(a) / L1
        return ka * L1 / (1.0 + ka * L1 / m["EA"]) * (1.0 - s ** (2.0 / 3.0)) ** 1.5 / critical_load(kind)
    from scipy.optimize import minimize_scalar

    lo, hi = (-0.5 * m["L"], a) if a < 0 else (a, 0.5 * m["L"])
    best = minimize_scalar(lambda x: -path_load(kind, x, a), bounds=(lo, hi), method="bounded",
                           options={"xatol": 1e-15, "maxiter": 1000})
    return float(-best.fun / critical_load(kind))
