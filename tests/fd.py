"""Finite-difference checks shared by the effect tests."""

import numpy as np
import scipy.sparse as sp


def fd_gradient(f, q, h=1e-6):
    """Central differences of a scalar function."""
    g = np.zeros_like(q)
    for i in range(q.size):
        e = np.zeros_like(q)
        e[i] = h
        g[i] = (f(q + e) - f(q - e)) / (2 * h)
    return g


def fd_jacobian(grad, q, h=1e-6):
    """Central differences of a vector function, as a dense matrix."""
    J = np.zeros((q.size, q.size))
    for i in range(q.size):
        e = np.zeros_like(q)
        e[i] = h
        J[:, i] = (grad(q + e) - grad(q - e)) / (2 * h)
    return J


def dense_hessian(effect, q):
    rows, cols, vals = effect.hessian(q)
    return sp.coo_matrix((vals, (rows, cols)), shape=(q.size, q.size)).toarray()


def relative_error(a, b):
    return np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300)
