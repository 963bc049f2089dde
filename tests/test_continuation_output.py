"""Files of a continuation run: CSV table, PNG plot, event summary, resuming."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
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
    # every status states the point's residual against its tolerance, and the residual meets it
    for line in lines[:-1]:
        residual, tolerance = map(float, re.search(r"residual (\S+) \(tolerance (\S+)\)", line).groups())
        assert 0.0 <= residual <= tolerance, line
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


def test_the_eigenvalue_column_follows_the_tangent_through_its_critical_points(tmp_path):
    """At the unloaded von Mises truss the tangent's eigenvalue nearest zero is the vertical
    stiffness 2 EA sin^2(alpha) / L0; it is negative exactly where a negative eigenvalue is
    counted, and the CSV carries it."""
    system = von_mises("load")
    res = trace_path(system, "load", initial_increment=P_CR / 10, max_steps=200, max_displacement=2.2 * H,
                     eigenvalue_column=True)
    eig = res.table["eigenvalue"]
    L0 = np.hypot(L, H)
    assert abs(eig[0] - 2.0 * 1.0e6 * (H / L0) ** 2 / L0) < 1e-9 * eig[0]
    assert np.array_equal(eig < 0, res.table["n_negative"] > 0)
    table = read_path_csv(write_path_csv(res, tmp_path / "p.csv"))
    assert np.array_equal(table["eigenvalue"], eig)


def test_the_eigenvalue_column_of_a_large_model_is_the_lanczos_value_nearest_zero():
    """797 free DOFs (Lanczos on the point's own factor, past the dense limit): after Euler's
    load the pinned column's double buckling eigenvalue is negative and nearest zero."""
    import scipy.sparse.linalg as spla

    from shellform.solvers.newton import solve_static
    from shellform.validation.cases_rods import euler_column

    s, system = euler_column("pinned-pinned", n=200)
    res = trace_path(system, "load", initial_increment=2.0, parameter_bounds=(0.0, 1.3 * np.pi**2), max_steps=60,
                     eigenvalue_column=True)
    assert system.n_free > 400 and np.all(np.isfinite(res.table["eigenvalue"]))
    k = int(np.argmax(res.table["n_negative"] > 0))
    static = solve_static(system, lam=float(res.table["lam"][k]), q0=res.states[k])
    w = spla.eigsh(system.tangent_free(static.q), k=3, sigma=0.0, which="LM", return_eigenvectors=False)
    assert res.table["eigenvalue"][k] == pytest.approx(w[np.argmin(np.abs(w))], rel=1e-6)
    assert res.table["eigenvalue"][k] < 0
