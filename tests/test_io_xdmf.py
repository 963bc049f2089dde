"""XDMF time series with HDF5 heavy data: what is written, read back by meshio and h5py."""

import json

import h5py
import meshio
import numpy as np
import pytest
from test_continuation_models import H, P_CR, von_mises

from shellform.analyses.continuation import write_path_series
from shellform.errors import ShellformError
from shellform.io import write_series
from shellform.io.units import FIELD_UNITS
from shellform.solvers.continuation import trace_path
from shellform.solvers.newton import solve_static


def test_states_round_trip_with_positions_fields_times_and_units(tmp_path):
    system = von_mises("load")
    states = []
    for lam in (0.2, 0.5, 0.8):
        res = solve_static(system, lam=lam * P_CR)
        assert res.success
        states.append((lam, res.q, lam * P_CR))
    path = write_series(tmp_path / "s.xdmf", system, states, time_name="load factor")
    assert (tmp_path / "s.h5").exists() and not list(tmp_path.glob(".*"))
    n = system.structure.n_nodes
    with meshio.xdmf.TimeSeriesReader(path) as reader:
        points, cells = reader.read_points_cells()
        assert reader.num_steps == 3 and cells[0].type == "line"
        for k, (t, q, _) in enumerate(states):
            time, point_data, cell_data = reader.read_data(k)
            assert time == t
            assert np.allclose(point_data["displacement"], (q - system.q_ref).reshape(n, 3))
            assert np.all(np.isfinite(cell_data["axial_force"][0]))
    with h5py.File(tmp_path / "s.h5") as h5:
        assert h5.attrs["time_name"] == "load factor"
        units = json.loads(h5.attrs["units"])
        assert units["axial_force"] == FIELD_UNITS["axial_force"] == "N" and units["displacement"] == "m"
        for k, (t, q, lam) in enumerate(states):
            g = h5[f"states/{k}"]
            # each state's geometry is its deformed shape
            assert np.allclose(g["points"][()], q[: 3 * n].reshape(n, 3))
            assert g.attrs["time"] == t and g.attrs["load_factor"] == lam
            assert set(g["cell"]) == {"group", "axial_force", "strain"}


def test_times_that_do_not_increase_are_refused(tmp_path):
    system = von_mises("load")
    q = system.q_ref
    with pytest.raises(ShellformError, match="does not exceed"):
        write_series(tmp_path / "s.xdmf", system, [(0.0, q, 0.0), (1.0, q, 1.0), (1.0, q, 1.0)])
    assert not (tmp_path / "s.xdmf").exists()


def test_a_path_through_limit_points_is_timed_by_its_arc_length(tmp_path):
    system = von_mises("load")
    res = trace_path(system, "load", initial_increment=P_CR / 10, max_steps=200, max_displacement=2.2 * H)
    assert len(res.events_of("limit")) == 2
    assert write_path_series(tmp_path / "p.xdmf", system, res, 0.0) == "arc length"
    with meshio.xdmf.TimeSeriesReader(tmp_path / "p.xdmf") as reader:
        reader.read_points_cells()
        times = [reader.read_data(k)[0] for k in range(reader.num_steps)]
    assert np.all(np.diff(times) > 0)
    # up to the first limit point the load factor itself would do: a path that stops there uses it
    before = trace_path(system, "load", initial_increment=P_CR / 10, max_steps=5)
    assert write_path_series(tmp_path / "q.xdmf", system, before, 0.0) == "path parameter"


def test_heavy_data_stay_out_of_the_xml(tmp_path):
    system = von_mises("load")
    res = trace_path(system, "load", initial_increment=P_CR / 10, max_steps=40, max_displacement=2.2 * H)
    write_path_series(tmp_path / "p.xdmf", system, res, 0.0)
    import xml.etree.ElementTree as ET

    items = ET.parse(tmp_path / "p.xdmf").getroot().iter("DataItem")
    assert all(item.get("Format") == "HDF" and item.text.startswith("p.h5:/") for item in items)
