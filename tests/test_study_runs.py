"""Imperfection studies end to end: files and units, resume, failures as rows, bad keys, random shapes, Dask, kill."""

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from shellform.cli import main
from shellform.errors import SceneError
from shellform.io.table import read_csv
from shellform.studies import StudyOptions, run_imperfection_study
from shellform.studies.link_models import critical_load, exact_knockdown, link_scene

STUDY = 'shapes = "modes"\nmodes = 1\nsigns = "positive"\nrelative_to = "absolute"\namplitudes = [1e-4, 1e-3]\n'


@pytest.fixture
def link(tmp_path):
    scene = tmp_path / "link.toml"
    scene.write_text(link_scene("symmetric", max_steps=150, study=STUDY))
    return scene


def test_a_study_writes_its_table_plot_and_the_worst_path(link, tmp_path, capsys):
    out = tmp_path / "s"
    assert main(["study", "imperfection", str(link), "--out", str(out), "--workers", "1"]) == 0
    header = (out / "study.csv").read_text().splitlines()[0]
    for column in ("amplitude [-]", "movement [m]", "lam_cr [-]", "knockdown [-]", "wall_time_s [s]"):
        assert column in header
    table = read_csv(out / "study.csv")
    exact = [exact_knockdown("symmetric", a) for a in table["amplitude"]]
    np.testing.assert_allclose(table["knockdown"], exact, atol=1e-6)
    summary = json.loads((out / "study.json").read_text())
    assert summary["perfect"]["kind"] == "bifurcation"
    assert summary["perfect"]["post_buckling"] == {"+": "falls", "-": "falls", "class": "unstable-symmetric"}
    assert summary["perfect"]["lam_cr"] == pytest.approx(critical_load("symmetric"), rel=2e-6)
    assert summary["worst"]["amplitude"] == 1e-3 and summary["failed"] == 0
    for name in ("knockdown.png", "mode_1.vtu", "perfect.json", "worst/path.csv", "worst/summary.json",
                 "worst/path.xdmf", "samples/sample_00001.json"):
        assert (out / name).is_file(), name
    first = json.loads((out / "worst" / "path_events.json").read_text())["events"][0]
    assert first["kind"] == "limit" and first["lam"] == pytest.approx(summary["worst"]["lam_cr"], rel=1e-6)
    assert "sample_00001" in capsys.readouterr().err


def test_a_second_run_keeps_finished_samples_and_a_changed_study_runs_again(link, tmp_path):
    out = tmp_path / "s"
    first = run_imperfection_study(link, out, StudyOptions(workers=1))
    again = run_imperfection_study(link, out, StudyOptions(workers=1))
    assert (first["kept"], again["kept"]) == (0, 2)
    link.write_text(link_scene("symmetric", max_steps=150, study=STUDY.replace("[1e-4, 1e-3]", "[1e-4, 1e-3, 1e-2]")))
    more = run_imperfection_study(link, out, StudyOptions(workers=1))
    assert more["kept"] == 2 and more["samples"] == 3
    link.write_text(link_scene("symmetric", max_steps=150, study=STUDY + "max_step_angle = 2.0\n"))
    assert run_imperfection_study(link, out, StudyOptions(workers=1))["kept"] == 0


def test_a_failing_sample_is_a_row_and_the_others_go_on(link, tmp_path, monkeypatch):
    import shellform.studies.sample as sample

    real = sample.imperfect_model

    def imperfect_model(scene, delta):
        if delta is not None and np.abs(delta).max() > 5e-4:
            raise RuntimeError("the solver broke down")
        return real(scene, delta)

    monkeypatch.setattr(sample, "imperfect_model", imperfect_model)
    out = tmp_path / "s"
    assert main(["study", "imperfection", str(link), "--out", str(out), "--workers", "1", "--quiet"]) == 1
    table = read_csv(out / "study.csv")
    assert list(table["status"]) == ["finished", "failed"]
    assert table["message"][1] == "RuntimeError: the solver broke down"
    assert json.loads((out / "study.json").read_text())["failed"] == 1
    # a failed sample is run again by the next study into the folder, a finished one kept
    monkeypatch.setattr(sample, "imperfect_model", real)
    summary = run_imperfection_study(link, out, StudyOptions(workers=1))
    assert summary["kept"] == 1 and summary["failed"] == 0


@pytest.mark.parametrize("study, key", [
    ("", "study"),
    (STUDY + "amplitude_min = 1e-3\namplitude_max = 1e-2\n", "study.amplitudes"),
    (STUDY.replace("[1e-4, 1e-3]", "[-1e-4]"), "study.amplitudes"),
    ('shapes = "random_field"\namplitudes = [1e-3]\n', "study.correlation_length"),
    ('shapes = "random_field"\ncorrelation_length = 0.5\nsigns = "both"\namplitudes = [1e-3]\n', "study.signs"),
    (STUDY + "colour = 1\n", "study.colour"),
    (STUDY + "fractile = 0.9\n", "study.fractile"),
])
def test_bad_study_keys_are_refused_naming_the_key(tmp_path, study, key):
    scene = tmp_path / "bad.toml"
    scene.write_text(link_scene("symmetric", max_steps=150, study=study) if study else link_scene("symmetric"))
    with pytest.raises(SceneError) as err:
        run_imperfection_study(scene, tmp_path / "out", StudyOptions(workers=1))
    assert err.value.key == key
    assert not (tmp_path / "out" / "study.csv").exists()


def test_a_scene_that_is_not_a_load_controlled_path_is_refused(tmp_path):
    scene = tmp_path / "bad.toml"
    scene.write_text(link_scene("symmetric", max_steps=150, study=STUDY).replace('[analysis.continuation]',
                                                             '[analysis.continuation]\ncontrol = "displacement"'))
    with pytest.raises(SceneError) as err:
        run_imperfection_study(scene, tmp_path / "out")
    assert err.value.key in ("analysis.continuation.control", "prescribed")


def test_random_fields_are_reproducible_zero_at_supports_and_smoother_for_longer_correlation():
    from shellform.scene import load_scene
    from shellform.studies.settings import StudySettings
    from shellform.studies.shapes import field_factor, free_node_mask, random_shape
    from shellform.studies.sample import imperfect_model

    from pathlib import Path

    scene = load_scene(Path(__file__).parents[1] / "scenes" / "lattice_dome.toml")
    structure = imperfect_model(scene, None).structure
    free = free_node_mask(structure)
    roughness = {}
    for length in (0.2, 2.0):
        s = StudySettings("random_field", (1e-3,), "span", correlation_length=length, seed=4)
        factor = field_factor(structure.nodes, length)
        shapes = [random_shape(s, j, None, factor, free) for j in range(40)]
        assert np.array_equal(shapes[3], random_shape(s, 3, None, factor, free))
        assert not np.allclose(shapes[0], shapes[1])
        for x in shapes:
            assert np.linalg.norm(x, axis=1).max() == pytest.approx(1.0)
            assert np.all(x[~free] == 0.0)
        # mean difference between the two ends of each bar between free nodes (a supported end does not move)
        conn = structure.groups[0].connectivity
        conn = conn[free[conn[:, 0]].all(axis=1) & free[conn[:, 1]].all(axis=1)]
        roughness[length] = np.mean([np.linalg.norm(x[conn[:, 0]] - x[conn[:, 1]], axis=1).mean() for x in shapes])
    assert roughness[2.0] < 0.5 * roughness[0.2]


def test_a_study_on_a_dask_cluster(link, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as c:
        summary = run_imperfection_study(link, tmp_path / "d", StudyOptions(scheduler=c.scheduler_address))
    assert summary["finished"] == 2 and summary["failed"] == 0
    table = read_csv(tmp_path / "d" / "study.csv")
    np.testing.assert_allclose(table["knockdown"], [exact_knockdown("symmetric", a) for a in (1e-4, 1e-3)],
                               atol=1e-6)


@pytest.mark.slow
def test_a_killed_study_resumes_without_recomputing_finished_samples(tmp_path):
    scene = tmp_path / "link.toml"
    amplitudes = np.geomspace(1e-5, 1e-2, 12).tolist()
    scene.write_text(link_scene("symmetric", max_steps=150, study=STUDY.replace("[1e-4, 1e-3]", str(amplitudes))))
    whole = run_imperfection_study(scene, tmp_path / "whole", StudyOptions(workers=1))
    cut = tmp_path / "cut"
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    command = [sys.executable, "-m", "shellform", "study", "imperfection", str(scene), "--out", str(cut),
               "--workers", "1", "--quiet"]
    proc = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 300
        while len(list((cut / "samples").glob("sample_*.json"))) < 4 if (cut / "samples").is_dir() else True:
            assert proc.poll() is None, "the study ended before it could be killed"
            assert time.monotonic() < deadline
            time.sleep(0.005)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait()
    done = len(list((cut / "samples").glob("sample_*.json")))
    assert 4 <= done < 12
    # the table is rewritten at most once a second: it holds finished samples only, all but those of the
    # last second before the kill (their records are kept, and the resumed study tables them)
    tabled = read_csv(cut / "study.csv")["sample"].tolist()
    assert set(tabled) <= {p.stem for p in (cut / "samples").glob("sample_*.json")}
    resumed = run_imperfection_study(scene, cut, StudyOptions(workers=1))
    assert resumed["kept"] == done and resumed["finished"] == 12
    a, b = read_csv(tmp_path / "whole" / "study.csv"), read_csv(cut / "study.csv")
    assert a["lam_cr"].tolist() == b["lam_cr"].tolist()
    assert whole["worst"] == resumed["worst"]


def test_a_rod_gridshell_study_moves_the_laths_and_knows_its_bifurcation_is_stable(tmp_path):
    """The form-found timber gridshell bifurcates at 1.83 times its weight onto secondary paths that rise on
    both sides: imperfect in its first mode, it passes that load and loses stability later (knock-down > 1),
    which the study expects of a stable bifurcation instead of calling it a branch jump."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    scene = (root / "scenes" / "form_found_gridshell.toml").read_text().replace(
        "../meshes/form_found_gridshell.obj", str(root / "meshes" / "form_found_gridshell.obj"))
    (tmp_path / "g.toml").write_text(scene + '[study]\nshapes = "modes"\nmodes = 1\nsigns = "positive"\n'
                                     'relative_to = "span"\namplitudes = [1e-3]\n')
    summary = run_imperfection_study(tmp_path / "g.toml", tmp_path / "s", StudyOptions(workers=1))
    perfect = summary["perfect"]
    assert perfect["kind"] == "bifurcation" and perfect["lam_cr"] == pytest.approx(1.8325, abs=1e-4)
    assert perfect["post_buckling"]["class"] == "stable-symmetric"
    (row,) = read_csv(tmp_path / "s" / "study.csv")["knockdown"]
    assert summary["finished"] == 1 and row > 1.0
    assert not summary["warnings"]


def test_rerun_computes_the_perfect_structure_again(link, tmp_path):
    """A kept perfect.npz is of the same scene and settings, not necessarily of the same code: --rerun must
    not take it (a study rerun after a change of the model took the old critical load)."""
    from shellform.io.checkpoint import load_checkpoint, save_checkpoint

    out = tmp_path / "s"
    first = run_imperfection_study(link, out, StudyOptions(workers=1))
    saved = dict(load_checkpoint(out / "perfect.npz"))
    save_checkpoint(out / "perfect.npz", **{**saved, "lam_cr": 2.0 * first["perfect"]["lam_cr"]})
    assert run_imperfection_study(link, out, StudyOptions(workers=1))["perfect"]["lam_cr"] == pytest.approx(
        2.0 * first["perfect"]["lam_cr"])  # kept, as a resumed study should
    again = run_imperfection_study(link, out, StudyOptions(workers=1, rerun=True))
    assert again["perfect"]["lam_cr"] == first["perfect"]["lam_cr"]
