"""Published and analytic reference values used by the validation cases.

Each value names its source: a closed form, or one of the two papers the
package implements, the MRA paper (A. Manuello Bertetto, J. Melchiorre, L. Sardone, G. C. Marano, "Multi-body rope approach for the form-finding of shape optimized grid shell structures", WCCM-APCOM 2022, DOI 10.23967/wccm-apcom.2022.075) and the gridshell paper (W. Huang, L. Qin, Q. Chen, "Numerical Exploration on Snap Buckling of a Pre-Stressed Hemispherical Gridshell", J. Appl. Mech. 89(1), 011005 (2022), DOI 10.1115/1.4052289).
"""

# symmetric two-bar truss, engineering strain: cos(q0) = cos(alpha)^(1/3), P_cr = 2 EA sin(q0)^3
VON_MISES_SOURCE = "analytic (von Mises truss, engineering strain)"

# catenary: S_len = 2 a sinh(S / 2a), sag f = a (cosh(S / 2a) - 1)
CATENARY_SOURCE = "analytic catenary"
CATENARY_TOLERANCE = 5e-3

# planar elastica under self-weight, theta'' = alpha (1 - s) cos(theta), clamped horizontally:
# tip (x/L, z/L) for alpha = rho A g L^3 / EI
CANTILEVER_SELF_WEIGHT = {1.0: (0.9912, -0.1235), 5.0: (0.8467, -0.4959), 10.0: (0.6564, -0.7002),
                          39.24: (0.2871, -0.8934)}
CANTILEVER_SOURCE = "planar elastica under self-weight, integrated to 1e-4 (CANTILEVER_SELF_WEIGHT)"
CANTILEVER_TOLERANCE = 2e-3  # of L: the reference is given to 1e-4, 40 rod edges are good to ~1e-3

# Euler buckling P_cr = pi^2 EI / (K L)^2
EULER_EFFECTIVE_LENGTH = {"pinned-pinned": 1.0, "clamped-free": 2.0, "clamped-pinned": 0.699,
                          "clamped-clamped": 0.5}
EULER_SOURCE = "Euler buckling, pi^2 EI / (K L)^2"
# Greenhill: a rod clamped at both ends buckles under the torque M_cr = 8.9868 EI / L (2 x the
# first root of tan x = x)
GREENHILL_TORQUE = 2 * 4.493409457909064
GREENHILL_SOURCE = "Greenhill twist buckling, clamped ends"
ROD_BUCKLING_TOLERANCE = 1e-2
# lateral-torsional buckling of a narrow cantilever under an end load at the centroid (Prandtl 1899,
# Michell 1899; Timoshenko and Gere, Theory of Elastic Stability, 2nd ed., section 6.3):
# P_cr = 4.013 sqrt(EI_min GJ) / L^2 when the stiff bending stiffness is far larger than both
PRANDTL_COEFFICIENT = 4.013
PRANDTL_SOURCE = "lateral-torsional buckling of a narrow cantilever (Prandtl, Michell): 4.013 sqrt(EI GJ) / L^2"

# multi-body rope approach (the MRA paper, DOI 10.23967/wccm-apcom.2022.075): rest states of hanging nets
MRA_SOURCE = "multi-body rope approach, Sec. 3 (Manuello Bertetto et al., WCCM-APCOM 2022)"
MEMBRANE_SQUARE_COEFFICIENT = 0.0736714  # w_max = c p a^2 / N, small-slope membrane on a square
MEMBRANE_SOURCE = "small-slope membrane, N laplacian(w) = -p (series solution on a square, MEMBRANE_SQUARE_COEFFICIENT)"
