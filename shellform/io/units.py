"""Units of the quantities shellform writes: SI throughout (m, N, s, rad).

Every CSV header names its column's unit (``load [N]``); mesh fields, whose
names ParaView shows bare, have theirs in :data:`FIELD_UNITS`, which the run
summary and the HDF5 file of a time series repeat. ``-`` marks a number
without unit (a factor, a count, a flag).
"""

from __future__ import annotations

#: point and cell data of the written meshes
FIELD_UNITS = {
    "displacement": "m", "reaction": "N", "group": "-", "mode": "-",
    "axial_force": "N", "strain": "-", "slack": "-",
    "bending_moment": "N m", "bending_moment_1": "N m", "bending_moment_2": "N m",
    "curvature_1": "1/m", "curvature_2": "1/m", "torque": "N m", "twist_rate": "rad/m", "max_stress": "Pa",
    "joint_force": "N", "joint_gap": "m",
}


def units_block() -> dict:
    """The ``units`` entry of a run summary: the system of units and the unit of every mesh field."""
    return {"system": "SI: lengths m, forces N, moments N m, time s, angles rad; load factors and counts have none",
            "fields": dict(FIELD_UNITS), "tables": "each CSV header gives its column's unit in brackets"}


def path_units(control: str, monitors=()) -> dict[str, str]:
    """Units of the columns of a traced path's table.

    Under load control the parameter is the load factor ``lam`` (a multiple
    of the scene's loads, no unit); under displacement control it is the
    magnitude ``mu`` of the prescribed displacements [m] and the generalised
    load is the reaction conjugate to it [N]. Monitors are displacements; the
    tangent's eigenvalue (``eigenvalue``) has none.
    """
    load = "-" if control == "load" else "N"
    units = {
        "step": "-", "branch": "-", "arc_length": "-", "lam": "-", "mu": "m",
        "parameter": "-" if control == "load" else "m", "load": load, "displacement": "m",
        "n_negative": "-", "iterations": "-", "ds": "-",
    }
    # the tangent's eigenvalue mixes N/m (translations) and N m (twist angles): no one unit
    units.update({m: "m" for m in monitors if m != "eigenvalue"})
    return units


def header(name: str, units: dict[str, str] | None) -> str:
    """A column header: the name with its unit in brackets when the unit is known."""
    unit = (units or {}).get(name)
    return f"{name} [{unit}]" if unit else name


def bare_name(text: str) -> str:
    """The column name of a header written by :func:`header`."""
    text = text.strip()
    if text.endswith("]") and " [" in text:
        return text[: text.rindex(" [")]
    return text
