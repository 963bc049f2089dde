"""Result files: written whole or not at all, with the umask's mode, never through a symlink,
never outside the output folder, one run per folder, and a summary that says how far a run got."""

import json
import os
import subprocess
import sys
import textwrap
import time
from importlib import resources
from pathlib import Path

import meshio
import numpy as np
import pytest

from shellform.cli import main
from shellform.io import write_json
from shellform.io.checkpoint import save_checkpoint
from shellform.io.files import LOCK_NAME, OutputError, atomic_target, open_atomic, output_lock, safe_name, write_text
from shellform.io.mesh import write_mesh
from shellform.io.table import plot_curve, write_csv
from shellform.analyses import PathFiles, run_continuation_case, run_scene
from shellform.scene import parse_scene

from test_continuation_models import von_mises

# the built-in scene: the von Mises truss traced through both limit points
VON_MISES = (resources.files("shellform") / "scenes" / "von_mises.toml").read_text()


def _mesh():
    return meshio.Mesh(np.eye(3), [("line", np.array([[0, 1], [1, 2]]))])


WRITERS = {
    "json": lambda p: write_json(p, {"a": 1}),
    "csv": lambda p: write_csv(p, {"x": [1.0, 2.0]}),
    "npz": lambda p: save_checkpoint(p, q=np.arange(3.0)),
    "vtu": lambda p: write_mesh(p, _mesh()),
    "png": lambda p: plot_curve(p, [0, 1], [0, 1], "x", "y", "t"),
    "md": lambda p: write_text(p, "# report\n"),
}


@pytest.fixture
def umask():
    """Set the process umask for one test."""
    old = os.umask(0o022)
    yield lambda mask: os.umask(mask)
    os.umask(old)


@pytest.mark.parametrize("suffix", sorted(WRITERS))
@pytest.mark.parametrize("mask", [0o022, 0o027, 0o002])
def test_every_writer_gives_the_umask_mode(tmp_path, umask, suffix, mask):
    umask(mask)
    path = tmp_path / f"result.{suffix}"
    WRITERS[suffix](path)
    assert path.stat().st_mode & 0o777 == 0o666 & ~mask
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no temporary left behind


@pytest.mark.parametrize("suffix", sorted(WRITERS))
def test_a_symlink_at_the_target_is_replaced_not_written_through(tmp_path, suffix):
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    target = tmp_path / "out" / f"result.{suffix}"
    target.parent.mkdir()
    target.symlink_to(victim)
    WRITERS[suffix](target)
    assert victim.read_text() == "keep me"
    assert not target.is_symlink() and target.stat().st_size > 0


def test_a_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path):
    path = tmp_path / "summary.json"
    write_json(path, {"run": 1})
    with pytest.raises(RuntimeError):
        with open_atomic(path, "w") as fh:
            fh.write('{"run": 2, "half')
            raise RuntimeError("killed half-way")
    with pytest.raises(TypeError):
        write_json(path, {"run": 3, "bad": object()})  # not JSON: nothing is touched
    with pytest.raises(RuntimeError):
        with atomic_target(path):
            raise RuntimeError
    assert json.loads(path.read_text()) == {"run": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["summary.json"]


def test_the_continuation_checkpoint_does_not_write_through_a_planted_symlink(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    out = tmp_path / "out"
    out.mkdir()
    # the fixed temporary name an earlier version used
    (out / "path_checkpoint.npz.tmp.npz").symlink_to(victim)
    (out / "path_checkpoint.npz").symlink_to(victim)
    res, _ = run_continuation_case(von_mises("load"), out, "load", PathFiles(plot=None, checkpoint_every=1, resume=False),
                                   initial_increment=3.0, max_steps=5)
    assert victim.read_text() == "keep me"
    assert not (out / "path_checkpoint.npz").is_symlink()
    assert int(json.loads(str(np.load(out / "path_checkpoint.npz")["meta"]))["step"]) == res.steps


def test_out_naming_a_file_is_a_clean_error(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text(VON_MISES)
    taken = tmp_path / "taken"
    taken.write_text("not a folder")
    assert main(["run", str(scene), "--out", str(taken), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "taken" in err and "a file of that name exists" in err and "Traceback" not in err
    assert main(["run", str(scene), "--out", str(taken / "below"), "--quiet"]) == 2
    assert taken.read_text() == "not a folder"


def test_temporaries_of_a_killed_writer_are_removed_by_the_next_run(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    leftovers = [".path-ab12cd_9.tmp.xdmf", ".summary-k2j4h5g6.tmp.json", ".state-aaaaaaaa.tmp.vtu"]
    kept = [".hidden", ".notes-x.tmp", "path.csv.tmp", "mine-abcdefgh.tmp.csv"]
    for name in leftovers + kept:
        (out / name).write_text("x")
    assert run_scene(parse_scene(_toml(VON_MISES)), out)["converged"]
    names = {p.name for p in out.iterdir()}
    assert not names & set(leftovers) and set(kept) <= names


def test_a_second_run_into_a_busy_folder_is_refused_naming_folder_and_pid(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text(VON_MISES)
    out = tmp_path / "busy"
    holder = subprocess.Popen([sys.executable, "-c", textwrap.dedent(f"""
        import sys, time
        from shellform.io.files import output_lock
        with output_lock({str(out)!r}):
            print("locked", flush=True)
            time.sleep(60)
        """)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        assert main(["run", str(scene), "--out", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err
        assert str(out.resolve()) in err and f"pid {holder.pid}" in err and "in use" in err
        assert not (out / "summary.json").exists()  # the other run's folder is left alone
    finally:
        holder.kill()
        holder.wait()
    # the holder died without cleaning up: its lock file is stale and does not block
    assert (out / LOCK_NAME).read_text().strip() == str(holder.pid)
    assert main(["run", str(scene), "--out", str(out), "--quiet"]) == 0
    assert not (out / LOCK_NAME).exists()  # a run that ends removes its lock file


def test_the_lock_is_held_for_the_run_and_refuses_in_process_too(tmp_path):
    with output_lock(tmp_path):
        with pytest.raises(OutputError, match=f"pid {os.getpid()}"):
            run_scene(parse_scene(_toml(VON_MISES)), tmp_path)
    summary = run_scene(parse_scene(_toml(VON_MISES)), tmp_path)
    assert summary["converged"]


def test_lock_file_that_is_a_symlink_is_refused(tmp_path):
    victim = tmp_path / "victim"
    victim.write_text("keep")
    out = tmp_path / "out"
    out.mkdir()
    (out / LOCK_NAME).symlink_to(victim)
    with pytest.raises(OutputError, match="symlink"):
        with output_lock(out):
            pass
    assert victim.read_text() == "keep"


def _toml(text):
    import tomllib

    return tomllib.loads(text)


@pytest.mark.parametrize("name", ["../../escape", "/etc/passwd", "a/../../b", "..x", "ok_name-1.2"])
def test_names_from_scene_content_stay_in_their_folder(tmp_path, name):
    folder = tmp_path / "results"
    made = safe_name(name)
    assert (folder / made).resolve().parent == folder.resolve()
    assert "/" not in made and ".." not in made and not made.startswith(".")
    assert safe_name("ok_name-1.2") == "ok_name-1.2"
    for hopeless in ("..", "../", "", "///"):
        with pytest.raises(OutputError):
            safe_name(hopeless)


def test_mra_case_named_to_escape_its_results_folder_stays_inside(tmp_path):
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "run_cases", Path(__file__).parents[1] / "validation" / "mra" / "run_cases.py")
    run_cases = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(run_cases)
    case = tmp_path / "case.toml"
    case.write_text(textwrap.dedent("""
        name = "../../escaped"
        [geometry]
        type = "rectangle"
        length_x = 2.0
        length_y = 2.0
        n_i = 3
        n_j = 3
        [supports]
        positions = [[0, 0], [-1, 0], [0, -1], [-1, -1]]
        """))
    results = tmp_path / "a" / "b" / "results"
    folder = run_cases.case_folder(results, {"name": "../../escaped"}, case)
    assert folder.parent == results and ".." not in folder.name
    run_cases.main([case], results=results)
    assert (folder / "summary.json").exists()
    assert not (tmp_path / "escaped").exists() and not (tmp_path / "a" / "escaped").exists()


def test_bad_tex_in_the_title_loses_nothing(tmp_path):
    raw = _toml(VON_MISES)
    raw["title"] = r"snap-through of $\bad$ at $x^{$"  # unknown symbol, unclosed group: mathtext raises
    summary = run_scene(parse_scene(raw), tmp_path)
    assert summary["converged"] and "warnings" not in summary
    assert json.loads((tmp_path / "summary.json").read_text())["converged"] is True
    assert (tmp_path / "load_displacement.png").stat().st_size > 1000


def test_labels_with_bad_tex_are_drawn_as_typed(tmp_path):
    png = plot_curve(tmp_path / "c.png", [0, 1], [0, 1], r"members[0].EA $\bad$", "rise $x^{$", r"$\bad$")
    assert png.stat().st_size > 1000


def test_a_long_title_is_cut_and_quick_to_plot(tmp_path):
    t0 = time.perf_counter()
    plot_curve(tmp_path / "c.png", [0, 1], [0, 1], "x", "y", "very long title " * 65_536)  # 1 MB
    assert time.perf_counter() - t0 < 5.0


def test_a_plot_that_fails_is_reported_and_the_results_stay(tmp_path, monkeypatch):
    import shellform.analyses.continuation as runner

    def broken(*args, **kwargs):
        raise ValueError("drawing failed")

    monkeypatch.setattr(runner, "plot_path", broken)
    summary = run_scene(parse_scene(_toml(VON_MISES)), tmp_path)
    assert summary["converged"]
    assert any("load_displacement.png" in w and "drawing failed" in w for w in summary["warnings"])
    for name in ("summary.json", "path.csv", "path_events.json", "path.xdmf"):
        assert (tmp_path / name).exists(), name


# -- the summary of a run in stages -------------------------------------------------------------

FORM_AND_BUCKLE = "default"


def _default_scene():
    from shellform.cli import _scene_path
    from shellform.scene import load_scene

    return load_scene(_scene_path(FORM_AND_BUCKLE))


def test_a_run_stopped_while_buckling_does_not_claim_success(tmp_path):
    def stop_in_buckling(message):
        if message.startswith("step "):
            raise KeyboardInterrupt  # Ctrl-C at the first buckling step

    with pytest.raises(KeyboardInterrupt):
        run_scene(_default_scene(), tmp_path, progress=stop_in_buckling)
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["converged"] is False and s["run_status"] == "interrupted"
    assert s["stages"]["form_finding"] == {"status": "finished", "converged": True,
                                           "message": s["stages"]["form_finding"]["message"]}
    assert s["stages"]["buckling"]["status"] == "interrupted"
    assert "buckling" not in s


def test_the_summary_says_running_while_a_stage_runs(tmp_path):
    seen = {}

    def look(message):
        if message.startswith("buckling of the inverted shell") and not seen:
            seen.update(json.loads((tmp_path / "summary.json").read_text()))

    summary = run_scene(_default_scene(), tmp_path, progress=look)
    assert seen["run_status"] == "running" and seen["converged"] is False
    assert seen["stages"]["form_finding"]["status"] == "finished"
    assert seen["stages"]["buckling"] == {"status": "running"}
    assert summary["converged"] and summary["stages"]["buckling"]["status"] == "finished"
    on_disk = json.loads((tmp_path / "summary.json").read_text())
    assert on_disk["converged"] is True and on_disk["run_status"] == "finished"
    assert on_disk["buckling"]["critical_load_factor"] > 0


def test_exit_code_follows_the_last_stage(tmp_path):
    from shellform.cli import _scene_path

    text = _scene_path(FORM_AND_BUCKLE).read_text()
    scene = tmp_path / "short.toml"
    # one continuation step cannot reach the critical point: the buckling stage ends unconverged
    scene.write_text(text.replace("load_factor_max = 1000.0", "load_factor_max = 1000.0\nmax_steps = 1"))
    code = main(["run", str(scene), "--out", str(tmp_path / "o"), "--quiet"])
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["stages"]["form_finding"]["converged"] is True
    assert s["stages"]["buckling"]["status"] == "finished"
    assert code == (0 if s["converged"] else 1)
    assert s["converged"] == s["stages"]["buckling"]["converged"]


def test_a_failing_stage_is_recorded_as_failed(tmp_path, monkeypatch):
    import shellform.analyses.continuation as runner

    def broken(*args, **kwargs):
        raise RuntimeError("solver crashed")

    monkeypatch.setattr(runner, "run_continuation_case", broken)
    with pytest.raises(RuntimeError):
        run_scene(_default_scene(), tmp_path)
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["run_status"] == "failed" and s["converged"] is False
    assert s["stages"]["buckling"] == {"status": "failed", "message": "RuntimeError: solver crashed"}
