"""Arc-length continuation against closed-form equilibrium paths.

The von Mises truss is traced through both limit points to the inverted
configuration under load control and under displacement control of the apex;
a truss loaded through a soft spring snaps back in load and displacement; a
braced truss bifurcates out of plane before its limit point.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import all_finite
from test_continuation_models import (
    ALPHA, EA, H, L, LS, P_CR, braced_critical, braced_truss, load_of_deflection,
    spring_truss, spring_truss_w_extrema, truss_load, von_mises,
)

from shellform.solvers.continuation import trace_path


def dense_negative_count(system, q):
    return int(np.sum(np.linalg.eigvalsh(system.tangent_free(q).toarray()) < 0.0))


def metric_steps(res, system, c2):
    """Arc-length distance between consecutive points in the solver's metric."""
    S = np.array(res.states)[:, system.free]
    p = res["parameter"]
    return np.sqrt(np.sum(np.diff(S, axis=0) ** 2, axis=1) + c2 * np.diff(p) ** 2)


# ---------------------------------------------------------------------------
# von Mises truss, load control
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def vm_load():
    system = von_mises("load")
    stop = lambda pt: pt.displacement > 2.2 * H  # noqa: E731  (apex well below the inverted position)
    res = trace_path(system, "load", initial_increment=P_CR / 20, ds_max=0.03, max_steps=400, callback=stop)
    return system, res


def test_von_mises_load_control_follows_analytic_curve(vm_load):
    system, res = vm_load
    assert res.status == "callback", res.message
    z = np.array(res.states)[:, 5]
    theta = np.arctan2(z, L)
    P = truss_load(theta)
    # every converged point lies on the closed-form curve
    assert np.max(np.abs(res["lam"] - P)) < 1e-8 * P_CR
    # the displacement column is the apex deflection in the load direction
    assert np.allclose(res["displacement"], H - z, atol=1e-14)
    # through the snap to the inverted configuration, with enough points to see the curve
    assert z.min() < -H and res.n_points > 40
    assert all_finite(res["lam"])


def test_von_mises_load_control_limit_points(vm_load):
    system, res = vm_load
    limits = res.events_of("limit")
    assert [e.kind for e in res.events] == ["limit", "limit"]
    upper, lower = limits
    # the von Mises truss in closed form: P_cr = 2 EA sin(q0)^3, within 0.5 % (we get far closer)
    assert abs(upper.parameter - P_CR) / P_CR < 5e-3
    assert abs(upper.parameter - P_CR) / P_CR < 1e-9
    assert abs(lower.parameter + P_CR) / P_CR < 1e-9
    assert upper.located and lower.located
    # apex heights at the limits: +-L tan(q0)
    theta_cr = np.arccos(np.cos(ALPHA) ** (1 / 3))
    assert abs(upper.q[5] - L * np.tan(theta_cr)) < 1e-4 * H
    assert abs(lower.q[5] + L * np.tan(theta_cr)) < 1e-4 * H
    # the critical mode is the apex moving vertically; the tangent is singular there
    assert abs(abs(upper.mode[5]) - 1.0) < 1e-12
    assert abs(upper.eigenvalue) < 1e-5 * EA / L
    assert upper.load == upper.parameter and upper.lam == upper.parameter


def test_von_mises_load_control_stability(vm_load):
    system, res = vm_load
    n = res["n_negative"]
    dense = [dense_negative_count(system, q) for q in res.states]
    assert list(n) == dense
    lam = res["lam"]
    z = np.array(res.states)[:, 5]
    theta_cr = np.arccos(np.cos(ALPHA) ** (1 / 3))
    zc = L * np.tan(theta_cr)
    # unstable exactly between the two limit points
    assert np.all(n[np.abs(z) < zc * (1 - 1e-3)] == 1)
    assert np.all(n[np.abs(z) > zc * (1 + 1e-3)] == 0)
    assert lam[z > -zc].max() <= P_CR * (1 + 1e-12)


def test_von_mises_cylindrical_constraint_and_lu_solver():
    system = von_mises("load")
    stop = lambda pt: pt.displacement > 2.2 * H  # noqa: E731
    for opts in ({"constraint": "cylindrical"}, {"linear_solver": "lu"}):
        res = trace_path(system, "load", initial_increment=P_CR / 10, max_steps=200, callback=stop, **opts)
        z = np.array(res.states)[:, 5]
        assert np.max(np.abs(res["lam"] - truss_load(np.arctan2(z, L)))) < 1e-8 * P_CR
        lim = res.events_of("limit")
        assert len(lim) == 2 and abs(lim[0].parameter - P_CR) < 1e-9 * P_CR


# ---------------------------------------------------------------------------
# von Mises truss, displacement control of the apex
# ---------------------------------------------------------------------------
def test_von_mises_displacement_control():
    system = von_mises("displacement")
    res = trace_path(system, "displacement", initial_increment=H / 20, ds_max=H / 20, parameter_bounds=(None, 2.2 * H))
    assert res.success and res.status == "parameter_bound"
    mu = res["mu"]
    assert mu[-1] == pytest.approx(2.2 * H, rel=1e-14)
    # reaction conjugate to the prescribed descent equals the analytic apex load
    assert np.max(np.abs(res["load"] - load_of_deflection(mu))) < 1e-8 * P_CR
    assert np.allclose(res["displacement"], mu)
    # the apex stays on the symmetry axis and the path is stable throughout
    assert np.max(np.abs(np.array(res.states)[:, 3])) < 1e-12
    assert np.all(res["n_negative"] == 0)
    assert res.events == []
    # the load passes both extremes +-P_cr (sampled, so slightly inside)
    assert len(set(mu)) == len(mu)  # the last point lands on the bound without repeating a point
    upper = res["load"][mu < H]
    assert upper.max() < P_CR and upper.max() > 0.99 * P_CR
    assert res["load"].min() > -P_CR and res["load"].min() < -0.99 * P_CR


# ---------------------------------------------------------------------------
# snap-back: truss loaded through a soft spring
# ---------------------------------------------------------------------------
def _check_on_snap_back_path(res, ks, P):
    S = np.array(res.states)
    v = H - S[:, 5]  # apex deflection
    w = H + LS - S[:, 11]  # load-point deflection
    # every point on the closed-form path: truss law and spring in series
    assert np.max(np.abs(P - load_of_deflection(v))) < 1e-8 * P_CR
    assert np.max(np.abs(w - (v + P / ks))) < 1e-10 * H
    return v, w


@pytest.mark.parametrize("control", ["load", "displacement"])
def test_snap_back_traced_continuously(control):
    system, ks = spring_truss(0.05, control)
    stop = lambda pt: pt.q[5] < -1.2 * H  # noqa: E731
    kw = dict(initial_increment=(P_CR if control == "load" else H) / 20, ds_max=0.04, max_steps=600, callback=stop)
    res = trace_path(system, control, **kw)
    assert res.status == "callback", res.message
    v, w = _check_on_snap_back_path(res, ks, res["load"])
    P = res["load"]
    # no branch jump: the apex deflection parametrises the path and grows monotonically in small steps
    assert np.all(np.diff(v) > 0) and np.max(np.diff(v)) < 0.1 * H
    # both load and displacement turn back (twice each): a true snap-back
    sign_changes = lambda x: int(np.sum(np.diff(np.sign(np.diff(x))) != 0))  # noqa: E731
    assert sign_changes(P) == 2 and sign_changes(w) == 2
    assert all_finite(P, w)
    limits = res.events_of("limit")
    assert len(limits) == 2 and all(e.located for e in limits)
    if control == "load":
        assert abs(limits[0].parameter - P_CR) < 1e-9 * P_CR
        assert abs(limits[1].parameter + P_CR) < 1e-9 * P_CR
    else:
        wmax, wmin = spring_truss_w_extrema(ks)
        assert abs(limits[0].parameter - wmax) < 1e-8 * H
        assert abs(limits[1].parameter - wmin) < 1e-8 * H
        # unstable under displacement control exactly between the snap-back points
        n = res["n_negative"]
        i_max, i_min = np.argmax(w[: np.argmin(w)]), np.argmin(w)
        assert np.all(n[1:i_max] == 0) and np.all(n[i_max + 1 : i_min] == 1) and np.all(n[i_min + 1 :] == 0)
    # each point lies at the prescribed arc length from the previous one (no point skipped along the path)
    steps = metric_steps(res, system, res.parameter_scale**2)
    assert np.allclose(steps, res["ds"][1:], rtol=1e-8)


# ---------------------------------------------------------------------------
# bifurcation before the limit point
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def braced_primary_run():
    system = braced_truss()
    (Pb, zb), (Pl, zl) = braced_critical()
    res = trace_path(system, "load", initial_increment=Pl / 10, max_steps=100, max_displacement=2.2 * H)
    return system, res


def test_bifurcation_detected_and_located(braced_primary_run):
    system, res = braced_primary_run
    (Pb, zb), (Pl, zl) = braced_critical()
    kinds = [e.kind for e in res.events]
    assert kinds[:3] == ["bifurcation", "limit", "limit"], kinds
    bif, lim = res.events[0], res.events[1]
    assert bif.located and lim.located
    assert bif.parameter < lim.parameter  # bifurcation before the limit point
    assert abs(bif.parameter - Pb) / Pb < 1e-6
    assert abs(bif.q[5] - zb) < 1e-6 * H
    assert abs(lim.parameter - Pl) / Pl < 1e-9
    # critical modes: out of plane at the bifurcation, vertical at the limit point
    assert abs(abs(bif.mode[4]) - 1.0) < 1e-9
    assert abs(abs(lim.mode[5]) - 1.0) < 1e-6
    assert (bif.n_negative_before, bif.n_negative_after) == (0, 1)
    # the located bracket is tight in the parameter
    assert bif.bracket < 1e-5 * Pb


def test_primary_branch_is_kept_through_bifurcation(braced_primary_run):
    system, res = braced_primary_run
    S = np.array(res.states)
    # the primary path stays exactly in plane past the bifurcation: no silent branch jump
    assert np.max(np.abs(S[:, 4])) < 1e-10
    assert np.all(res["branch"] == 0)
    assert list(res["n_negative"]) == [dense_negative_count(system, q) for q in res.states]


@pytest.fixture(scope="module")
def braced_switch_runs():
    system = braced_truss()
    (Pb, _), (Pl, _) = braced_critical()
    runs = {}
    for side in (1, -1):
        runs[side] = trace_path(
            system, "load", initial_increment=Pl / 20, ds_max=0.04, max_steps=45, on_bifurcation="switch",
            branch_side=side,
        )
    return system, runs


def test_secondary_branch_followed(braced_switch_runs):
    system, runs = braced_switch_runs
    (Pb, zb), _ = braced_critical()
    res = runs[1]
    assert res.success, res.message
    bif = res.events[0]
    assert bif.kind == "bifurcation" and bif.switched
    br = res["branch"]
    assert set(br) == {0, 1}
    S = np.array(res.states)
    y = S[:, 4]
    on_secondary = br == 1
    # the secondary branch leaves the plane on the requested side, starting next to the bifurcation point
    first = np.flatnonzero(on_secondary)[0]
    assert y[first] > 0 and np.linalg.norm(S[first] - bif.q) < 0.1
    # the primary branch ends exactly at the located bifurcation point
    assert np.array_equal(S[first - 1], bif.q) and res["lam"][first - 1] == bif.parameter
    assert np.all(y[on_secondary][: 10] > 1e-3)
    # the load drops after the bifurcation on this branch (unstable-symmetric)
    assert np.all(res["lam"][on_secondary][:5] < Pb)
    # every point is an equilibrium and finite
    for q, lam in zip(res.states, res["lam"]):
        assert np.linalg.norm(system.residual(q, lam)[system.free]) < 1e-6 * Pb


def test_secondary_branch_sides_are_mirror_images(braced_switch_runs):
    system, runs = braced_switch_runs
    a, b = runs[1], runs[-1]
    Sa, Sb = np.array(a.states), np.array(b.states)
    n = min(len(Sa), len(Sb))
    assert np.allclose(a["lam"][:n], b["lam"][:n], rtol=1e-8, atol=1e-8 * P_CR)
    assert np.allclose(Sa[:n, 4], -Sb[:n, 4], atol=1e-9)
    assert np.allclose(Sa[:n, 5], Sb[:n, 5], atol=1e-9)


def test_switch_branch_from_a_stored_event(braced_primary_run):
    from shellform.solvers.continuation import switch_branch

    system, res = braced_primary_run
    bif = res.events[0]
    (Pb, _), (Pl, _) = braced_critical()
    sec = switch_branch(system, bif, side=-1, initial_increment=Pl / 20, ds_max=0.04, max_steps=6)
    assert sec.success, sec.message
    S = np.array(sec.states)
    assert np.all(S[1:, 4] < -1e-3) and np.all(sec["branch"][1:] == 1)
    with pytest.raises(Exception, match="entries"):
        switch_branch(system, bif, direction=np.ones(3), initial_increment=1.0)


def test_switching_with_an_imperfection_shape():
    system = braced_truss()
    (Pb, _), (Pl, _) = braced_critical()
    shape = np.zeros(system.n_dof)
    shape[4] = -1.0  # out of plane, towards -y
    res = trace_path(system, "load", initial_increment=Pl / 20, ds_max=0.04, max_steps=20, on_bifurcation="switch",
                     switch_direction=shape)
    S = np.array(res.states)
    assert np.all(S[res["branch"] == 1, 4] < 0)


def test_stop_at_bifurcation():
    system = braced_truss()
    (Pb, _), (Pl, _) = braced_critical()
    res = trace_path(system, "load", initial_increment=Pl / 10, on_bifurcation="stop", max_steps=50)
    assert res.status == "event" and res.success
    assert len(res.events) == 1 and res.events[0].kind == "bifurcation"


@pytest.mark.parametrize("rtol", [1e-3, 1e-6, 1e-9])
def test_critical_loads_located_to_the_requested_tolerance(rtol):
    """Both limit points of the von Mises truss and the braced truss's bifurcation point are located
    to ``critical_rtol`` on the critical load (the limit loads here in closed form; the corrector
    converges to 1e-10 of the forces, which bounds what can be asked)."""
    system = von_mises("load")
    res = trace_path(system, "load", initial_increment=P_CR / 7, max_steps=200, critical_rtol=rtol,
                     callback=lambda pt: pt.q[5] < -1.2 * H)
    upper, lower = res.events_of("limit")
    assert upper.located and lower.located
    assert abs(upper.parameter - P_CR) <= rtol * P_CR
    assert abs(lower.parameter + P_CR) <= rtol * P_CR
    (Pb, _), _ = braced_critical()
    res = trace_path(braced_truss(), "load", initial_increment=Pb / 7, max_steps=100, max_displacement=2.2 * H,
                     critical_rtol=rtol)
    bif = res.events_of("bifurcation")[0]
    assert bif.located and abs(bif.parameter - Pb) <= rtol * Pb
    if rtol >= 1e-6:  # tighter, the bracket ends at locate_tol (1e-8 of the step) first
        assert bif.bracket <= rtol * Pb * 1.0001


def test_critical_point_located_in_fewer_trials_than_bisection():
    """A bisection to 1e-8 of the step takes 27 corrected points per event; the secant a handful."""
    import shellform.solvers.continuation.events as events

    trials = []
    probe = events._probe

    def counted(*args):
        trials.append(1)
        return probe(*args)

    events._probe = counted
    try:
        (Pb, _), _ = braced_critical()
        res = trace_path(braced_truss(), "load", initial_increment=Pb / 7, max_steps=100,
                         max_displacement=2.2 * H)
    finally:
        events._probe = probe
    n_events = len(res.events)
    assert n_events >= 3 and all(e.located for e in res.events)
    assert len(trials) <= 8 * n_events


def test_a_branch_known_stable_is_factorised_by_cholesky_first(monkeypatch):
    """Without stability counting the tracer takes the caller's word that its branch is stable
    (``definite_branch``): the same path, its tangents factorised by Cholesky first."""
    import shellform.solvers.continuation.problem as problem
    from test_continuation_models import P_CR, von_mises

    from shellform.solvers.continuation import trace_path

    calls = []
    original = problem.CholeskyFactor
    monkeypatch.setattr(problem, "CholeskyFactor", lambda *a, **k: calls.append(1) or original(*a, **k))
    options = dict(initial_increment=P_CR / 10, parameter_bounds=(0.0, 0.9 * P_CR), stability=False, max_steps=50)
    plain = trace_path(von_mises("load"), "load", **options)
    assert not calls
    stable = trace_path(von_mises("load"), "load", definite_branch=True, **options)
    assert calls and plain.success and stable.success
    np.testing.assert_allclose(stable["lam"], plain["lam"], rtol=1e-12)
    np.testing.assert_allclose(stable["displacement"], plain["displacement"], rtol=1e-9, atol=1e-14)


def test_without_stability_only_a_cholesky_factor_counts_a_point():
    """Without stability counting a point's negative eigenvalues are known only where its tangent
    was factorised by Cholesky (none); past the limit point they are not counted (-1), and the
    summary does not claim a maximum over the points it did not count."""
    from test_continuation_models import H, P_CR, von_mises

    from shellform.solvers.continuation import trace_path

    from shellform.solvers.stability import count_negative

    options = dict(initial_increment=P_CR / 10, max_steps=60, max_displacement=0.8 * H)
    system = von_mises("load")
    proved = trace_path(system, "load", stability=False, definite_branch=True, store_states=True, **options)
    counts = np.array([count_negative(system.tangent_free(q)) for q in proved.states])
    assert set(counts) == {0, 1}
    np.testing.assert_array_equal(proved["n_negative"], np.where(counts == 0, 0, -1))
    counted = trace_path(von_mises("load"), "load", **options)
    assert set(counted["n_negative"]) == {0, 1}
    assert counted.summary()["max_negative_eigenvalues"] == 1
    assert proved.summary()["max_negative_eigenvalues"] == -1
    uncounted = trace_path(von_mises("load"), "load", stability=False, **options)
    assert set(uncounted["n_negative"]) == {-1}


def test_without_stability_a_point_takes_the_correctors_last_factor(monkeypatch):
    """Where nothing is counted at a converged point, its path tangent comes from the corrector's last
    tangent and factor (a last correction away) instead of a new factorisation; the limit points are
    still located to a tight tolerance on the load, and with stability counted every point is
    factorised anew."""
    import shellform.solvers.continuation.corrector as corrector
    import shellform.solvers.continuation.tracer as tracer
    from test_continuation_models import H, P_CR, von_mises

    from shellform.solvers.continuation import trace_path

    calls = []
    factor = tracer.Problem.factor
    monkeypatch.setattr(tracer.Problem, "factor", lambda self, K: calls.append(1) or factor(self, K))

    def run(reuse, stability):
        monkeypatch.setattr(corrector, "REUSE_DISTANCE", 1e-3 if reuse else -1.0)
        calls.clear()
        res = trace_path(von_mises("load"), "load", initial_increment=P_CR / 7, max_steps=200, critical_rtol=1e-9,
                         stability=stability, callback=lambda pt: pt.q[5] < -1.2 * H)
        upper, lower = res.events_of("limit")
        assert upper.located and lower.located
        assert abs(upper.parameter - P_CR) <= 1e-9 * P_CR and abs(lower.parameter + P_CR) <= 1e-9 * P_CR
        return res, len(calls)

    reused, n_reused = run(True, False)
    fresh, n_fresh = run(False, False)
    assert n_reused <= n_fresh - reused.steps + 1, (n_reused, n_fresh, reused.steps)
    n_counted = run(True, True)[1]
    assert n_counted == run(False, True)[1]


def test_cholesky_is_not_tried_again_within_a_point_after_it_failed(monkeypatch):
    """Past a limit point Cholesky fails; the same point's remaining factorisations go at once to
    the tangent with its diagonal raised (or to LDL^T where that fails too), the next point (a step,
    a trial point of the location) tries Cholesky again. The start, uncounted yet, is factorised
    by Cholesky and still bounds the first step by the linearised distance to the nearest
    critical point."""
    import importlib

    import shellform.solvers.continuation.problem as problem

    start = importlib.import_module("shellform.solvers.continuation.start")
    log = []
    chol, ldl, raised = problem.CholeskyFactor, problem.LDLFactor, problem.RaisedCholeskyFactor

    def cholesky(*a, **k):
        try:
            F = chol(*a, **k)
        except Exception:
            log.append("cholesky failed")
            raise
        log.append("cholesky")
        return F

    class LoggedLDL(ldl):  # subclasses, so that the tracer's isinstance checks still hold
        def __init__(self, *a, **k):
            log.append("ldl")
            super().__init__(*a, **k)

    class LoggedRaised(raised):
        def __init__(self, *a, **k):
            log.append("raised")
            super().__init__(*a, **k)

    monkeypatch.setattr(problem, "CholeskyFactor", cholesky)
    monkeypatch.setattr(problem, "LDLFactor", LoggedLDL)
    monkeypatch.setattr(problem, "RaisedCholeskyFactor", LoggedRaised)
    new_point = problem.Problem.new_point
    monkeypatch.setattr(problem.Problem, "new_point", lambda self: log.append("point") or new_point(self))
    estimates = []
    critical_increment = start.critical_increment
    monkeypatch.setattr(start, "critical_increment",
                        lambda *a: estimates.append(critical_increment(*a)) or estimates[-1])
    system = von_mises("load")
    res = trace_path(system, "load", stop_after_events=1, max_steps=100)
    assert res.events and res.events[0].kind == "limit" and res.events[0].located
    np.testing.assert_allclose(res.events[0].parameter, P_CR, rtol=1e-6)
    assert log[0] == "cholesky" and estimates and estimates[0] is not None and estimates[0] > 0.0
    assert "cholesky failed" in log
    points = "\n".join(log).split("point")
    for seq in points:
        steps = [s for s in seq.split("\n") if s]
        if "cholesky failed" in steps:
            after = steps[steps.index("cholesky failed") + 1:]
            assert "cholesky" not in after and "cholesky failed" not in after
            assert set(after) <= {"raised", "ldl"}
    assert any(s.count("raised") >= 2 for s in points)  # a point whose later factorisations went to the raised one
    assert "ldl" not in log  # the truss's one negative eigenvalue: the raised Cholesky serves every point past it


def test_past_limit_points_a_raised_cholesky_traces_the_path_ldl_would(monkeypatch):
    """The star dome under an apex load through limit and bifurcation points (up to seven negative
    eigenvalues): where a tangent has one to three negative eigenvalues, a Cholesky factor of it
    with the diagonal raised at the largest entries of the path tangent gives its solves and its
    inertia. The same points, the same counts and the same events as with LDL^T at every
    indefinite tangent."""
    import shellform.solvers.continuation.problem as problem
    from test_hard_cases import star_dome

    import shellform as sf

    s = star_dome(1.0)
    s.load_cases.clear()
    s.add_load([0], [0.0, 0.0, -1.0])
    counts = []
    raised = problem.RaisedCholeskyFactor

    class CountedRaised(raised):
        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            counts.append(self.n_negative_pivots)

    monkeypatch.setattr(problem, "RaisedCholeskyFactor", CountedRaised)
    with_raised = trace_path(sf.build_system(s), "load", max_steps=80, stability=True)
    monkeypatch.setattr(problem, "MAX_RAISED_ROWS", 0)  # every indefinite tangent by LDL^T
    ldl_only = trace_path(sf.build_system(s), "load", max_steps=80, stability=True)
    assert {1, 2} <= set(counts)  # past limit points with one and with two negative eigenvalues
    assert with_raised.n_points == ldl_only.n_points == 81
    assert list(with_raised["n_negative"]) == list(ldl_only["n_negative"]) and max(with_raised["n_negative"]) == 7
    scale = np.max(np.abs(ldl_only["parameter"]))
    assert np.max(np.abs(with_raised["parameter"] - ldl_only["parameter"])) < 1e-10 * scale
    assert [e.kind for e in with_raised.events] == [e.kind for e in ldl_only.events] and len(ldl_only.events) == 8
    for a, b in zip(with_raised.events, ldl_only.events):
        assert a.located and b.located
        assert abs(a.parameter - b.parameter) <= 2e-6 * abs(b.parameter)  # each located to critical_rtol = 1e-6


def test_back_on_a_stable_branch_the_tangents_go_to_plain_cholesky_again(monkeypatch):
    """The von Mises truss snaps through to its inverted, stable shape: the tangents between its two
    limit points go to the raised Cholesky, and past the second one, where the path is stable again,
    to plain Cholesky."""
    import shellform.solvers.continuation.problem as problem

    kinds = []
    raised, cholesky = problem.RaisedCholeskyFactor, problem.CholeskyFactor

    class LoggedRaised(raised):
        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            kinds.append(f"raised {self.n_negative_pivots}")

    def logged_cholesky(*a, **k):
        F = cholesky(*a, **k)
        kinds.append("cholesky")
        return F

    monkeypatch.setattr(problem, "RaisedCholeskyFactor", LoggedRaised)
    monkeypatch.setattr(problem, "CholeskyFactor", logged_cholesky)
    stop = lambda pt: pt.displacement > 2.2 * H  # noqa: E731
    res = trace_path(von_mises("load"), "load", initial_increment=P_CR / 20, ds_max=0.03, max_steps=400,
                     callback=stop)
    assert [e.kind for e in res.events] == ["limit", "limit"] and res["n_negative"][-1] == 0
    last_unstable = max(i for i, k in enumerate(kinds) if k == "raised 1")
    after = kinds[last_unstable + 1:]
    assert after.count("cholesky") >= 10 and after.count("cholesky") >= len(after) - 3
