"""A state as a COMPAS graph: compas reads it back with positions and member results."""

import numpy as np
import pytest
from test_continuation_models import P_CR, von_mises

from shellform.io.compas_graph import write_compas_graph
from shellform.solvers.newton import solve_static


def test_compas_reads_the_graph_with_positions_and_forces(tmp_path):
    import compas.data as compas_data  # in the test extra
    system = von_mises("load")
    res = solve_static(system, lam=0.5 * P_CR)
    assert res.success
    path = write_compas_graph(tmp_path / "g.compas.json", system, res.q, 0.5 * P_CR)
    graph = compas_data.json_load(str(path))
    assert type(graph).__name__ == "Graph"
    x = res.q[: 3 * system.structure.n_nodes].reshape(-1, 3)
    for node in graph.nodes():
        assert np.allclose(graph.node_coordinates(node), x[node])
    forces = system.member_results(res.q)
    (name, fields), = ((k, v) for k, v in forces.items() if "axial_force" in v)
    for k, (a, b) in enumerate(system.structure.groups[0].connectivity):
        assert graph.edge_attribute((int(a), int(b)), "axial_force") == pytest.approx(fields["axial_force"][k])
        # bars are never slack: the attribute is absent, not 0
        assert graph.edge_attribute((int(a), int(b)), "slack") is None
    assert graph.attributes["load_factor"] == 0.5 * P_CR
