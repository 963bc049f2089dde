"""Published and analytic reference values used by the validation cases.

They follow the project's reference table (``published.toml``) and name
their sources, so that the installed package validates without it.
"""

# symmetric two-bar truss, engineering strain: cos(q0) = cos(alpha)^(1/3), P_cr = 2 EA sin(q0)^3
VON_MISES_SOURCE = "analytic (von Mises truss, engineering strain)"

# catenary: S_len = 2 a sinh(S / 2a), sag f = a (cosh(S / 2a) - 1)
CATENARY_SOURCE = "analytic catenary"
CATENARY_TOLERANCE = 5e-3
