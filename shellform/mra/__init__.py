"""Form finding by the multi-body rope approach (MRA): hanging nets and their inverted shells.

Typical use::

    from shellform.geometry import rectangle_grid
    from shellform.mra import hanging_net, form_find, invert, length_statistics

    net = hanging_net(rectangle_grid(9, 4, 9, 4), {"positions": [[0, 0], [-1, 0], ...]}, slack=0.05)
    res = form_find(net)                 # hypostatic check, relaxation, reports
    dome = invert(res)                   # Hooke: the mirrored shell in compression
    stats = length_statistics(res.length, tol=0.01)

:func:`solve_mra_case` does all of it for one case described by a dictionary
(:func:`shellform.analyses.form_finding.run_mra_case` also writes its files).
"""

from .case import MraCase, build_grid, build_net, solve_mra_case
from .formfind import (FormFindingOptions, FormFindingResult, HypostaticWarning, OverstretchWarning, form_find,
                       rope_state)
from .hypostatic import HypostaticReport, hypostatic_check
from .inversion import InvertedShell, invert
from .lengths import LengthControlResult, control_lengths, kmeans_1d, length_statistics
from .net import HangingNet, NetOptions, hanging_net, support_nodes
from .start import fit_height_field, surface_start

__all__ = [
    "FormFindingOptions",
    "FormFindingResult",
    "HangingNet",
    "HypostaticReport",
    "HypostaticWarning",
    "OverstretchWarning",
    "InvertedShell",
    "LengthControlResult",
    "MraCase",
    "NetOptions",
    "build_grid",
    "build_net",
    "control_lengths",
    "fit_height_field",
    "form_find",
    "hanging_net",
    "hypostatic_check",
    "invert",
    "kmeans_1d",
    "length_statistics",
    "rope_state",
    "solve_mra_case",
    "support_nodes",
    "surface_start",
]
