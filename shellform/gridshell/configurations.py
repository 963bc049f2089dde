"""Which configuration a hemisphere state is in: the U, O, W and S patterns of the gridshell paper.

The labels read the side views of the two central rods (their bulges from the
chords, and where the apex is), as the paper names the patterns it reports
along the indentation (W. Huang, L. Qin, Q. Chen, "Numerical Exploration on
Snap Buckling of a Pre-Stressed Hemispherical Gridshell", J. Appl. Mech.
89(1), 011005, 2022, DOI 10.1115/1.4052289).
"""

from __future__ import annotations

import numpy as np

from .hemisphere import HemisphereModel


def central_profiles(model: HemisphereModel, q: np.ndarray) -> list[np.ndarray]:
    """Side views ``(xi, z)`` of the two central rods (u0 along x, v0 along y)."""
    x = model.positions(q)
    out = []
    for family, axis in (("u", 0), ("v", 1)):
        nodes = model.rod_nodes[model.rod_index(family, 0)]
        out.append(np.stack([x[nodes, axis], x[nodes, 2]], axis=1))
    return out


def _half_bulge(prof: np.ndarray, apex: int, side: int) -> float:
    """Signed largest offset of one half of a side view from its chord (end to apex), up positive."""
    half = prof[: apex + 1] if side < 0 else prof[apex:][::-1]
    end, top = half[0], half[-1]
    chord = top - end
    normal = np.array([-chord[1], chord[0]]) * (-side)  # points up for a horizontal chord
    normal /= max(np.linalg.norm(normal), 1e-300)
    offset = (half - end) @ normal
    return float(offset[np.argmax(np.abs(offset))])


def configuration_features(model: HemisphereModel, q: np.ndarray) -> dict[str, float]:
    """Shape measures of a state (lengths relative to ``R``).

    ``bulges``: signed bulge of the four half central rods (u0 left, u0
    right, v0 left, v0 right) from their chords, up positive;
    ``apex_height``, ``top`` and ``bottom``: heights of the apex and of the
    highest and lowest points of the central rods; ``shear``: mean sideways
    deflection of the central rods, odd along each rod and of opposite sense
    on the two rods (the scissor mode of the net, closing the angle between
    the rods at the apex towards a diagonal); ``twist``: the same with equal
    senses (a rotation of the net about the vertical axis); ``lateral``: the
    largest sideways deflection of a central rod; ``asymmetry``: the largest
    distance of a node from its place in the state mirrored about the x-z
    and the y-z plane (zero for the symmetric states).
    """
    R = model.radius
    x = model.positions(q)
    bulges, tops, bottoms, odd, lateral = [], [], [], [], 0.0
    apex_z = float(x[model.apex_nodes, 2].mean() / R)
    for family, along, across in (("u", 0, 1), ("v", 1, 0)):
        k = model.rod_index(family, 0)
        nodes = model.rod_nodes[k]
        prof = np.stack([x[nodes, along], x[nodes, 2]], axis=1) / R
        apex = int(np.argmin(np.abs(np.asarray(model.rod_stations[k]))))
        bulges += [_half_bulge(prof, apex, -1), _half_bulge(prof, apex, 1)]
        tops.append(prof[:, 1].max())
        bottoms.append(prof[:, 1].min())
        side = x[nodes, across] / R
        odd.append(float(np.mean(np.sign(x[nodes, along]) * side)))
        lateral = max(lateral, float(np.abs(side).max()))
    asym = []
    for axis in (0, 1):
        y = x[model.mirror_map(axis)].copy()
        y[:, axis] *= -1.0
        asym.append(float(np.linalg.norm(x - y, axis=1).max() / R))
    return {
        "bulges": bulges,
        "asymmetry": asym,
        "apex_height": apex_z,
        "top": float(max(tops)),
        "bottom": float(min(bottoms)),
        "shear": 0.5 * (odd[0] + odd[1]),
        "twist": 0.5 * (odd[0] - odd[1]),
        "lateral": lateral,
    }


def classify_configuration(model: HemisphereModel, q: np.ndarray, tol: float = 0.03, apex_tol: float = 0.005) -> str:
    """Name the configuration of the gridshell (the paper's U+, O+, W, S, O-, U-).

    The paper names the shapes only in its figures; this is our reading,
    in terms of :func:`configuration_features` (lengths relative to ``R``):

    * ``S``: one half of a central rod bulges up and the other half of the
      same rod bulges down, by more than ``tol`` (the asymmetric pattern);
    * ``W``: otherwise, when the state has lost its mirror symmetry about the
      vertical planes through the central rods (``asymmetry > tol``): in mode I
      the net shears, the central rods turning towards one diagonal; in
      mode II (apex clamped) the rods wave sideways in a pinwheel. Both come in
      mirror images;
    * otherwise symmetric: ``U+`` when the apex is the highest point of the
      central rods (within ``apex_tol``: a dome), ``O+`` when the halves bulge
      up around a dimpled apex (a ring-shaped crest), ``U-`` when the apex is
      the lowest point (the inverted dome), ``O-`` when the halves bulge down
      around a raised apex (a ring-shaped trough).
    """
    f = configuration_features(model, q)
    b = f["bulges"]
    for left, right in ((b[0], b[1]), (b[2], b[3])):
        if (left > tol and right < -tol) or (left < -tol and right > tol):
            return "S"
    if max(f["asymmetry"]) > tol:
        return "W"
    up = float(np.mean(b)) > 0
    if up:
        return "U+" if f["apex_height"] >= f["top"] - apex_tol else "O+"
    return "U-" if f["apex_height"] <= f["bottom"] + apex_tol else "O-"
