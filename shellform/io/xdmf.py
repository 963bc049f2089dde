"""Time series as XDMF with the heavy data in HDF5 (ParaView opens the ``.xdmf``).

``name.xdmf`` is a small XML file; the arrays are in ``name.h5`` beside it:

* ``/cells``: the line cells (members, then joints), written once;
* ``/states/<k>/points``: node positions of state ``k`` (the deformed shape:
  ParaView needs no "Warp By Vector");
* ``/states/<k>/point/<field>`` and ``/states/<k>/cell/<field>``: the fields
  of :func:`~shellform.io.mesh.state_mesh`;
* attributes of ``/states/<k>``: ``time`` and ``load_factor``; of the root:
  ``time_name`` (what the time axis is) and ``units`` of every field (JSON).

The time of a state is the quantity the caller names (a load factor, a
prescribed displacement, an arc length or a physical time); it must increase
from state to state, because readers order states by it.

meshio's own XDMF writer puts the HDF5 file in the working folder rather than
beside the XDMF file, and writes it under the name of a temporary file: both
are wrong for files renamed into place, hence this writer. The two files are
written to temporary names and renamed, the HDF5 file first, so the XDMF file
never names an HDF5 file that is not complete.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from ..errors import ShellformError
from .files import atomic_target, write_bytes
from .mesh import state_mesh
from .units import FIELD_UNITS


def _item(parent, h5_name: str, dataset: str, data: np.ndarray) -> None:
    kind = "Int" if np.issubdtype(data.dtype, np.integer) else "Float"
    item = ET.SubElement(parent, "DataItem", Format="HDF", NumberType=kind, Precision=str(data.dtype.itemsize),
                         Dimensions=" ".join(str(d) for d in data.shape))
    item.text = f"{h5_name}:{dataset}"


def _attribute(grid, h5_name, dataset, name, data, center) -> None:
    kind = "Scalar" if data.ndim == 1 else "Vector"
    attr = ET.SubElement(grid, "Attribute", Name=name, AttributeType=kind, Center=center)
    _item(attr, h5_name, dataset, data)


def write_series(path, system, states: Iterable[tuple], time_name: str = "step") -> Path:
    """Write a sequence of states as ``path`` (XDMF) and ``path`` with suffix ``.h5``.

    Parameters
    ----------
    path : path-like
        Target ``.xdmf`` file.
    states : iterable of (time, q, load_factor) or (time, q, load_factor, history)
        ``history``: the path history the state was found with
        (:func:`~shellform.io.mesh.state_mesh`), for rod models.
    time_name : str
        What ``time`` is (stored in the HDF5 file), for example ``"load factor"``.

    Raises
    ------
    ShellformError
        When the times do not increase.
    """
    import h5py

    path = Path(path)
    h5_path = path.with_suffix(".h5")
    root = ET.Element("Xdmf", Version="3.0")
    collection = ET.SubElement(ET.SubElement(root, "Domain"), "Grid", Name="states", GridType="Collection",
                               CollectionType="Temporal")
    last = -np.inf
    with atomic_target(h5_path) as tmp, h5py.File(tmp, "w") as h5:
        h5.attrs["time_name"] = time_name
        for k, (t, q, lam, *history) in enumerate(states):
            t = float(t)
            if not t > last:
                raise ShellformError(f"{path.name}: the {time_name} of state {k} ({t:g}) does not exceed the one "
                                     f"before ({last:g}); a time series needs increasing times")
            last = t
            mesh = state_mesh(system, q, lam, history[0] if history else None)
            lines = mesh.cells[0].data
            if k == 0:
                h5["cells"] = lines
                h5.attrs["units"] = json.dumps({n: FIELD_UNITS.get(n, "") for n in [*mesh.point_data, *mesh.cell_data]})
            group = h5.create_group(f"states/{k}")
            group.attrs.update(time=t, load_factor=float(lam))
            grid = ET.SubElement(collection, "Grid", Name=f"state {k}", GridType="Uniform")
            ET.SubElement(grid, "Time", Value=repr(t))
            topology = ET.SubElement(grid, "Topology", TopologyType="Polyline", NodesPerElement="2",
                                     NumberOfElements=str(len(lines)))
            _item(topology, h5_path.name, "/cells", lines)
            group["points"] = mesh.points
            _item(ET.SubElement(grid, "Geometry", GeometryType="XYZ"), h5_path.name, f"/states/{k}/points",
                  mesh.points)
            for name, data in mesh.point_data.items():
                group[f"point/{name}"] = data
                _attribute(grid, h5_path.name, f"/states/{k}/point/{name}", name, np.asarray(data), "Node")
            for name, blocks in mesh.cell_data.items():
                group[f"cell/{name}"] = blocks[0]
                _attribute(grid, h5_path.name, f"/states/{k}/cell/{name}", name, np.asarray(blocks[0]), "Cell")
    ET.indent(root)
    write_bytes(path, ET.tostring(root, xml_declaration=True, encoding="utf-8"))
    return path
