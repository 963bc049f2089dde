"""Apex indentation of the hemispherical gridshell: stability tools, the mode I and II paths on a coarse model."""

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from shellform.errors import ModelError
from shellform.gridshell.hemisphere import HemisphereSpec, build_hemisphere, prestress_on_net
from shellform.gridshell.configurations import classify_configuration
from shellform.gridshell.indentation import indentation_system, trace_indentation
from shellform.solvers.stability import count_negative, smallest_eigenpair

# the gridshell paper's thresholds, modes I and II (shellform.gridshell.study.PUBLISHED)
MODE_I = [1.1, 1.7, 1.9]
MODE_II = [1.50, 1.75]
TOL = 0.1
DL = 4.0e-3  # coarse Voronoi length: the whole path in a few seconds


@pytest.fixture(scope="module")
def model():
    m = build_hemisphere(HemisphereSpec(5, voronoi_length=DL))
    return m, prestress_on_net(m)


@pytest.fixture(scope="module")
def mode_one(model):
    m, pre = model
    setup = indentation_system(m, pre, mode="I")
    return setup, trace_indentation(setup)


def test_inertia_and_smallest_eigenpair_match_dense_eigenvalues():
    rng = np.random.default_rng(3)
    # a rod-like spectrum: stiff and very soft directions, a few negative ones
    n = 120
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    w = np.concatenate([[-3.0, -0.02], 10.0 ** rng.uniform(-1.5, 4, n - 2)])
    K = sp.csr_matrix((Q * w) @ Q.T)
    K = (K + K.T) * 0.5
    assert count_negative(K) == 2
    lam, v = smallest_eigenpair(K)
    ref = sla.eigh(K.toarray())
    assert lam == pytest.approx(ref[0][0], rel=1e-8)
    assert abs(v @ ref[1][:, 0]) == pytest.approx(1.0, abs=1e-8)
    # positive definite: the eigenvalue closest to zero
    K2 = sp.csr_matrix((Q * np.abs(w)) @ Q.T)
    K2 = (K2 + K2.T) * 0.5
    assert count_negative(K2) == 0
    assert smallest_eigenpair(K2)[0] == pytest.approx(0.02, rel=1e-8)


def test_prescribed_apex_nodes(model):
    m, pre = model
    one = indentation_system(m, pre, mode="I")
    two = indentation_system(m, pre, mode="II")
    assert len(one.nodes) == 2 and len(two.nodes) == 6
    assert np.array_equal(one.system.prescribed, np.sort(m.structure.node_dofs(one.nodes).ravel()))
    # the state at dD is the pre-stressed state with the apex lowered by dD
    q = one.system.state(pre.q[one.system.free], mu=0.01)
    assert np.allclose(q[one.z_dofs], pre.q[one.z_dofs] - 0.01)
    # the model itself is not changed: both modes run on it
    assert m.structure.prescribed_dofs.size == 0
    with pytest.raises(ModelError, match="mode"):
        indentation_system(m, pre, mode="III")


def test_force_is_the_reaction_at_the_apex(mode_one):
    setup, res = mode_one
    q = setup.system.state(setup.system.q_ref[setup.system.free], mu=0.0)
    r = setup.system.reactions(q)
    assert setup.force(q) == pytest.approx(-r[setup.z_dofs].sum())
    assert res.y[0] == pytest.approx(0.0, abs=1e-6 * np.abs(res.y).max())


def test_mode_one_snaps_at_the_published_thresholds(mode_one):
    _, res = mode_one
    assert res.success, res.message
    assert res.x[-1] == pytest.approx(2.0)
    assert len(res.snaps) == 3
    for computed, published in zip(res.thresholds, MODE_I):
        assert abs(computed - published) <= TOL, (res.thresholds, MODE_I)
    assert all(s.located for s in res.snaps)


def test_mode_one_curve_shape(mode_one):
    _, res = mode_one
    x, y, seg = res.x, res.y, res.segment
    first = res.snaps[0]
    # stiff rise, the largest force just before the first snap, a drop at every snap
    before = seg == 0
    assert np.all(np.diff(y[before][: 5]) > 0)
    assert res.max_force == pytest.approx(y[before].max())
    assert y[before][np.argmax(x[before])] > 0.9 * res.max_force
    for s in res.snaps:
        assert abs(s.force_after) < abs(s.force_before)  # the structure lets go of the indenter
        assert s.jump > 0.1
    assert first.force_after < 0.8 * first.force_before
    # the gridshell pulls back on the indenter late in the path, and lets go at dD = 2R
    assert y.min() < -0.2 * res.max_force
    assert abs(y[-1]) < 0.1 * res.max_force
    # dD never decreases along the recorded stable path
    assert np.all(np.diff(x) >= -1e-12)


def test_mode_one_configurations(mode_one):
    _, res = mode_one
    labels = res.labels
    assert labels[0] == "U+" and labels[-1] == "U-"
    order = [lab for i, lab in enumerate(labels) if i == 0 or lab != labels[i - 1]]
    for a, b in (("U+", "O+"), ("O+", "W"), ("W", "S"), ("S", "U-")):
        assert order.index(a) < order.index(b), order
    assert res.snaps[1].label_after == "S"


def test_mode_two_first_threshold(model):
    m, pre = model
    res = trace_indentation(indentation_system(m, pre, mode="II"))
    assert res.success, res.message
    assert len(res.snaps) == 2
    for computed, published in zip(res.thresholds, MODE_II):
        assert abs(computed - published) <= TOL, (res.thresholds, MODE_II)


def test_a_dome_and_its_mirror_image_are_labelled(model):
    m, pre = model
    assert classify_configuration(m, pre.q) == "U+"
    q = pre.q.copy()
    x = q[: 3 * m.structure.n_nodes].reshape(-1, 3)
    x[:, 2] *= -1.0
    assert classify_configuration(m, q) == "U-"


@pytest.mark.slow
@pytest.mark.parametrize("mode, published", [("I", MODE_I), ("II", MODE_II)])
def test_paper_resolution_n11(mode, published):
    """n = 11 at the paper's Voronoi length of 1 mm (about a minute per mode)."""
    m = build_hemisphere(HemisphereSpec(11, voronoi_length=1.0e-3))
    res = trace_indentation(indentation_system(m, prestress_on_net(m), mode=mode))
    assert res.success, res.message
    for computed, ref in zip(res.thresholds, published):
        assert abs(computed - ref) <= TOL, (res.thresholds, published)


def test_fig7_validation_case_scores_the_trends(tmp_path, monkeypatch):
    """The Fig. 7 case: a first snap per size and mode against the published level, its spread over
    the dense nets, and the linearity of the maximum force (runs stubbed: the real ones take minutes)."""
    import shellform.validation.cases_hemisphere as ch

    first = {"I": {5: 1.01, 11: 1.16, 19: 1.193, 29: 1.198}, "II": {5: 1.43, 11: 1.49, 19: 1.508, 29: 1.516}}

    def fake(case):
        return {"thresholds": [first[case.mode][case.n]], "max_force": 11.0 * case.n + 6.0, "n_dof": 100 * case.n,
                "total_s": 1.0}

    monkeypatch.setattr(ch, "indentation_case", fake)
    res = ch.case_hemisphere_fig7(tmp_path, ns=(5, 11, 19, 29))
    by_name = {c.quantity: c for c in res.checks}
    assert len(res.checks) == 2 * (4 + 2)
    assert by_name["mode I, n = 19: first snap dD/R"].passed
    assert by_name["mode II: spread of the first snap over n >= 19"].computed == pytest.approx(0.008)
    assert by_name["mode I: maximum force linear in n, R^2"].computed == pytest.approx(1.0)
    assert all((tmp_path / f).exists() for f in res.figures) and len(res.figures) == 4


def test_a_point_the_tracer_proved_stable_is_not_counted_again(model, monkeypatch):
    """A path point whose tangent the tracer factorised by Cholesky is stable: the trace takes that
    proof instead of counting again after the rod frames follow the point. The same path, snap and
    threshold as when every point is counted after its frames are accepted."""
    import shellform.gridshell.indentation as indentation
    import shellform.solvers.continuation.tracer as tracer

    m, pre = model
    counted = []
    count = indentation.negative_count
    monkeypatch.setattr(indentation, "negative_count", lambda *a: counted.append(1) or count(*a))

    def trace():
        counted.clear()
        res = trace_indentation(indentation_system(m, pre, mode="I"), dD_max=1.3 * m.radius, classify=False)
        return res, len(counted)

    proved, calls = trace()
    uncounted = tracer.Tracer.count
    monkeypatch.setattr(tracer.Tracer, "count",
                        lambda self, K, F=None, signed=False: -1 if not self.o.stability else uncounted(self, K, F, signed))
    recounted, all_calls = trace()
    assert proved.success and recounted.success and len(proved.snaps) == len(recounted.snaps) == 1
    assert calls < all_calls / 3, (calls, all_calls)
    assert all_calls >= len(recounted.x)
    np.testing.assert_array_equal(proved.x, recounted.x)
    np.testing.assert_array_equal(proved.y, recounted.y)
    assert proved.thresholds == recounted.thresholds


def test_the_snap_dynamics_take_as_many_newton_iterations_as_a_step_through_a_snap_needs(model, monkeypatch):
    """A time step through a snap is nearly an energy descent of its own (up to 48 Newton iterations
    at 1 mm): the snap dynamics allow 60 before a step is rejected and halved, which would
    discretise the snap differently and move where it lands."""
    import shellform.solvers.implicit_euler as ie

    m, pre = model
    caps = []
    integrate = ie.implicit_euler
    monkeypatch.setattr(ie, "implicit_euler", lambda *a, **k: caps.append(k["max_newton"]) or integrate(*a, **k))
    res = trace_indentation(indentation_system(m, pre, mode="I"), dD_max=1.3 * m.radius, classify=False)
    assert res.success and len(res.snaps) == 1
    assert caps and set(caps) == {60}


def test_the_force_before_a_snap_is_read_at_the_critical_state_with_its_own_rod_frames(model, monkeypatch):
    """The rods' twist angles are measured from the frames of the last accepted state: after a snap has
    turned them, the critical state's vector describes other twists and another force."""
    import shellform.gridshell.indentation as indentation

    m, pre = model
    setup = indentation_system(m, pre, mode="I")
    expected = []
    critical_point = indentation._Trace.critical_point

    def recorded(self, res, last):
        out = critical_point(self, res, last)
        with setup.system.evaluated_with(out[5]):  # the frames the critical state was found with
            expected.append((out[0], setup.force(out[1]) / setup.force_scale))
        return out

    monkeypatch.setattr(indentation._Trace, "critical_point", recorded)
    res = trace_indentation(setup, dD_max=1.8 * m.radius, classify=False)
    events = {e.dD: e for e in res.snaps + res.exchanges}
    assert res.success and len(res.snaps) == 2 and len(events) == len(expected)
    for dD, f_c in expected:
        assert events[dD].force_before == pytest.approx(f_c, rel=1e-12)


def test_a_stored_state_is_written_with_the_rod_frames_it_was_found_with(model, monkeypatch):
    """A rod state's twist angles are measured from the frames of the state accepted before it: the
    torques, moments and reactions of every stored state are written as they were when it was found,
    not with the frames the end of the run left (which gave reactions off by a factor of up to 7)."""
    import shellform.gridshell.indentation as indentation
    from shellform.io import state_mesh

    m, pre = model
    setup = indentation_system(m, pre, mode="I")
    found = []
    add_point = indentation._Trace.add_point

    def recorded(self, q, mu, n_neg):
        found.append(state_mesh(self.system, q))
        return add_point(self, q, mu, n_neg)

    monkeypatch.setattr(indentation._Trace, "add_point", recorded)
    res = trace_indentation(setup, dD_max=1.3 * m.radius, classify=False, store_states=True)
    assert res.success and len(res.snaps) == 1 and len(found) == len(res.path_states) == len(res.path_histories)
    stale = 0.0
    for mesh, q, history in zip(found, res.path_states, res.path_histories):
        written = state_mesh(setup.system, q, history=history)
        for name in ("torque", "bending_moment_1", "bending_moment_2", "twist_rate"):
            np.testing.assert_array_equal(written.cell_data[name][0], mesh.cell_data[name][0])
        np.testing.assert_array_equal(written.point_data["reaction"], mesh.point_data["reaction"])
        now = state_mesh(setup.system, q).point_data["reaction"]
        stale = max(stale, float(np.abs(now - mesh.point_data["reaction"]).max()))
    assert stale > 1e-3 * max(float(np.abs(f.point_data["reaction"]).max()) for f in found)
    # the selected states too, each with its own frames; the run's own frames are left as they were
    end = setup.system.history()
    assert set(res.state_histories) == set(res.states)
    for x, q in res.states.items():
        state_mesh(setup.system, q, history=res.state_histories[x])
    for a, b in zip(setup.system.history(), end):
        for key in a:
            np.testing.assert_array_equal(a[key], b[key])


def test_a_traced_path_keeps_each_state_with_its_rod_frames_through_a_checkpoint(model, tmp_path):
    """The continuation's stored states and its events' states come with the rod frames they were
    found with; a checkpoint carries them, so a resumed run writes what an uninterrupted one does."""
    from shellform.io import state_mesh
    from shellform.io.checkpoint import CheckpointFile
    from shellform.solvers.continuation import trace_path

    m, pre = model
    setup = indentation_system(m, pre, mode="I")
    options = dict(q0=setup.system.q_ref, initial_increment=0.02 * m.radius, parameter_bounds=(0.0, 0.3 * m.radius),
                   store_states=True, stability=False, max_steps=40)
    found = []

    def at_point(pt):
        found.append(state_mesh(setup.system, pt.q))

    m.network.frames.restore(setup.frames_state)
    res = trace_path(setup.system, "displacement", callback=at_point, **options)
    assert res.success and len(res.states) == len(res.state_histories) == len(found) > 5
    stale = 0.0
    for mesh, q, history in zip(found, res.states, res.state_histories):
        written = state_mesh(setup.system, q, history=history)
        np.testing.assert_array_equal(written.cell_data["torque"][0], mesh.cell_data["torque"][0])
        np.testing.assert_array_equal(written.point_data["reaction"], mesh.point_data["reaction"])
        stale = max(stale, float(np.abs(state_mesh(setup.system, q).point_data["reaction"]
                                        - mesh.point_data["reaction"]).max()))
    assert stale > 0.0
    # stopped at step 6 after a checkpoint at step 5, then resumed: the same states with the same frames
    m.network.frames.restore(setup.frames_state)
    ck = tmp_path / "path.npz"
    with pytest.raises(RuntimeError):
        trace_path(setup.system, "displacement", checkpoint=CheckpointFile(ck, every=5),
                   callback=lambda pt: (_ for _ in ()).throw(RuntimeError("stop")) if pt.step == 6 else None,
                   **options)
    m.network.frames.restore(setup.frames_state)
    resumed = trace_path(setup.system, "displacement", checkpoint=CheckpointFile(ck, every=5, resume=True), **options)
    assert len(resumed.states) == len(res.states)
    for mesh, q, history in zip(found, resumed.states, resumed.state_histories):
        written = state_mesh(setup.system, q, history=history)
        np.testing.assert_allclose(written.point_data["reaction"], mesh.point_data["reaction"],
                                   atol=1e-9 * float(np.abs(mesh.point_data["reaction"]).max()))
