"""How far a continuation step may go without passing a critical point unseen.

A critical point inside a step is seen when the step's ends differ: the sign of
``dp/ds`` (a limit point) or the inertia of the tangent (a bifurcation). A step
long enough to pass *two* critical points can land on a state that looks like
its start: over both limit points of a snap-through, from one stable branch
to the next. Two bounds keep steps shorter than the structure's own scale:

* **before the first step**, a linearised estimate of the nearest critical
  point. Along the path tangent ``(du/dp, 1)`` the tangent changes at the
  rate ``D = dK/ds`` (a finite difference of two assemblies); the smallest
  ``mu > 0`` with ``K + mu D`` singular is the parameter increment at which
  a linear change of ``K`` reaches a critical point. It is the smallest root
  of the generalised problem ``D phi = theta K phi``, ``mu = -1 / theta``
  for the most negative ``theta``. For a shallow arch it is a third of the
  rise where the exact fold lies at 42 % of it.
* **after every step**, the extrapolation of ``dp/ds`` to zero: where it
  falls along the path, the next fold lies about ``t_B ds / (t_A - t_B)``
  ahead, and the next step goes at most twice that far (so it may pass the
  fold and bracket it, but cannot reach far beyond).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse.linalg as spla

from .linear import SingularMatrixError
from .stability import DENSE_LIMIT, eigsh_short_first, start_vector

#: a step goes at most this many times the predicted distance to the next fold
FOLD_OVERSHOOT = 2.0


def linearised_critical_increment(jacobian, u: np.ndarray, p: float, K, F, du_dp: np.ndarray,
                                  direction: float, q_scale: float) -> float | None:
    """Parameter increment to the nearest critical point along the path, by linearising the tangent.

    Parameters
    ----------
    jacobian : callable
        ``jacobian(u, p) -> (K, g)``: the free tangent at a state.
    u, p : ndarray, float
        The (stable) starting point.
    K, F
        The free tangent at the start and its factorisation (``F.solve``).
    du_dp : ndarray
        The path tangent ``K^{-1} (-dG/dp)``.
    direction : {1, -1}
        Direction of travel of the parameter.
    q_scale : float
        Size of the coordinates (for the finite-difference step).

    Returns
    -------
    float or None
        The estimated increment ``mu > 0``, or None where the tangent does not
        move towards singularity or the estimate cannot be made (an unstable
        start, a failed eigensolve).
    """
    b = direction * du_dp
    b_max = float(np.max(np.abs(b), initial=0.0))
    if b_max == 0.0 or not np.isfinite(b_max):
        return None
    h = 1e-7 * max(q_scale, 1e-12) / b_max
    K_h, _ = jacobian(u + h * b, p + direction * h)
    D = ((K_h - K) / h).tocsr()
    D = 0.5 * (D + D.T)
    n = K.shape[0]
    try:
        if n <= DENSE_LIMIT:
            theta = float(sla.eigh(D.toarray(), K.toarray(), eigvals_only=True, subset_by_index=[0, 0])[0])
        else:
            Kinv = spla.LinearOperator(K.shape, matvec=F.solve, dtype=float)
            theta = float(eigsh_short_first(D, k=1, M=K, Minv=Kinv, which="SA", tol=1e-3, maxiter=200,
                                            v0=start_vector(n), return_eigenvectors=False)[0])
    except (sla.LinAlgError, spla.ArpackError, spla.ArpackNoConvergence, SingularMatrixError, ValueError):
        return None
    if not (np.isfinite(theta) and theta < 0.0):
        return None
    return -1.0 / theta


def fold_distance(t_dp_a: float, t_dp_b: float, ds: float) -> float | None:
    """Arc length from B to the fold that ``dp/ds`` falling from A to B points at (None if not falling)."""
    if t_dp_a * t_dp_b <= 0.0 or abs(t_dp_b) >= abs(t_dp_a):
        return None
    return abs(t_dp_b) * ds / (abs(t_dp_a) - abs(t_dp_b))
