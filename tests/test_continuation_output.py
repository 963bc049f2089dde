"""Files of a continuation run: CSV table, PNG plot, event summary, resuming."""

from __future__ import annotations

import json

import numpy as np
from test_continuation_models import H, L, P_CR, truss_load, von_mises

from shellform.io.table import plot_path, read_path_csv, write_path_csv
from shellform.analyses import PathFiles, run_continuation_case
from shellform.solvers.continuation import TABLE_COLUMNS, trace_path


def test_csv_round_trip_and_plot(tmp_path):
    system = von_mises("load")
    res = trace_path(system, "load", initial_increment=P_CR / 10, max_steps=30, max_displacement=2.2 * H,
                     monitors={"apex_z": 5})
    csv_path = write_path_csv(res, tmp_path / "path.csv")
    table = read_path_csv(csv_path)
    assert list(table) == list(TABLE_COLUMNS) + ["apex_z"]
    for k, v in res.table.items():
        assert np.array_equal(table[k], v), k  # repr round trip is exact
    z = np.linspace(H, -1.2 * H, 200)
    png = plot_path(res, tmp_path / "path.png", reference=(H - z, truss_load(np.arctan2(z, L))))
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000


def test_run_continuation_case_writes_files_and_resumes(tmp_path):
    system = von_mises("load")
    lines = []
    opts = dict(initial_increment=P_CR / 10, max_displacement=2.2 * H, max_steps=200)
    res, summary = run_continuation_case(system, tmp_path, "load", progress=lines.append, **opts)
    assert res.success
    for f in ("path.csv", "path.png", "path_events.json", "path_checkpoint.npz"):
        assert (tmp_path / f).exists(), f
    on_disk = json.loads((tmp_path / "path_events.json").read_text())
    assert on_disk["status"] == "displacement_bound"
    assert [e["kind"] for e in on_disk["events"]] == ["limit", "limit"]
    assert abs(on_disk["events"][0]["parameter"] - P_CR) < 1e-9 * P_CR
    assert len(lines) == res.n_points + 1 and "negative eigenvalues" in lines[0]
    # started again: the finished run is picked up from its checkpoint, not recomputed
    lines2 = []
    res2, _ = run_continuation_case(system, tmp_path, "load", progress=lines2.append, **opts)
    assert res2.n_points == res.n_points and len(lines2) == 1
    assert np.array_equal(res2["lam"], res["lam"])


def test_a_step_across_a_critical_point_is_drawn_stable_up_to_it(tmp_path, monkeypatch):
    """Coarse steps over the von Mises truss's first limit point: the plotted polyline gets the
    located point inserted, so the stretch before it is solid and only the part after it dashed."""
    import shellform.io.table as table
    from test_continuation_models import P_CR, von_mises

    res = trace_path(von_mises("load"), "load", initial_increment=1.2 * P_CR, max_steps=12)
    limit = res.events_of("limit")[0]
    seen = {}
    monkeypatch.setattr(table, "plot_curve", lambda path, x, y, *a: seen.update(x=x, y=y, stable=a[-1].stable))
    table.plot_path(res, tmp_path / "p.png")
    at = seen["y"].index(limit.load)
    assert seen["stable"][at] and seen["stable"][at - 1]  # solid up to the limit point
    assert not seen["stable"][at + 1]  # dashed after it
    assert len(seen["x"]) == res.n_points + len(res.events)


def test_the_written_buckling_mode_of_a_pinned_column_is_a_half_sine(tmp_path):
    """Euler's pinned column: the critical point's file holds the state there and the mode
    sin(pi x / L) (normalised to 1, sign-free; the column may buckle in any transverse
    direction, so the mode's transverse part is taken along its own direction)."""
    import meshio

    from shellform.validation.cases_rods import euler_column

    L = 1.0
    s, system = euler_column("pinned-pinned", n=40, L=L)
    res, summary = run_continuation_case(system, tmp_path, "load", PathFiles(plot=None), initial_increment=2.0,
                                         parameter_bounds=(0.0, 1.3 * np.pi**2), max_steps=60)
    first = summary["events"][0]
    assert first["kind"] == "bifurcation" and first["number"] == 1
    assert first["parameter"] == np.float64(first["parameter"])
    mesh = meshio.read(tmp_path / first["file"])
    mode = mesh.point_data["mode"]
    assert mode.shape == (s.n_nodes, 3) and np.all(np.isfinite(mode))
    transverse = mode[:, 1:]
    direction = np.linalg.svd(transverse)[2][0]
    shape = transverse @ direction
    shape /= shape[np.argmax(np.abs(shape))]
    x = s.nodes[:, 0]
    assert np.abs(shape - np.sin(np.pi * x / L)).max() < 1e-3
    assert abs(np.linalg.norm(mode, axis=1).max() - 1.0) < 1e-12  # largest nodal displacement 1
    assert first["file"] in summary["files"]
