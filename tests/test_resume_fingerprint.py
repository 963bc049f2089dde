"""A resume continues only the run that was started: checkpoints carry a fingerprint of the model
and of the settings that change the answer; a run killed at any moment and resumed writes what an
uninterrupted run writes."""

from __future__ import annotations

import copy
import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from test_continuation_models import P_CR, von_mises

import shellform as sf
from shellform.cli import main
from shellform.errors import ModelError, SceneError
from shellform.errors import CheckpointMismatch
from shellform.fingerprint import model_fingerprint
from shellform.analyses import run_scene
from shellform.scene import parse_scene
from shellform.io.checkpoint import CheckpointFile
from shellform.solvers.continuation import trace_path

ROOT = Path(__file__).parents[1]


def truss(EA=1.0e4, apex=0.2, fix_y=True, load=-1.0):
    s = sf.Structure([[-1, 0, 0], [0, 0, apex], [1, 0, 0]])
    s.add_bars([[0, 1], [1, 2]], EA=EA)
    s.fix([0, 2])
    if fix_y:
        s.fix([1], "y")
    else:
        s.fix([1], "x")
    s.add_load([1], [0, 0, load])
    return sf.build_system(s)


def changed_parts(a, b):
    fa, fb = model_fingerprint(a), model_fingerprint(b)
    return sorted(k for k in fa if fa[k] != fb[k])


def test_each_part_of_the_model_has_its_own_hash():
    base = truss()
    assert model_fingerprint(truss()) == model_fingerprint(base)  # the same model, built again
    assert changed_parts(base, truss(EA=2.0e4)) == ["member properties"]
    assert changed_parts(base, truss(apex=0.25)) == ["member properties", "nodes"]  # rest lengths too
    assert changed_parts(base, truss(fix_y=False)) == ["supports"]
    assert changed_parts(base, truss(load=-2.0)) == ["loads"]


def test_the_fingerprint_of_rods_does_not_change_along_the_path(tmp_path):
    # the rods' reference frames move along the path: history the checkpoint restores, not the model
    assert main(["run", "--out", str(tmp_path), "--quiet"]) == 0
    first = (tmp_path / "buckling_path.csv").read_bytes()
    assert main(["run", "--out", str(tmp_path), "--quiet", "--resume"]) == 0
    assert (tmp_path / "buckling_path.csv").read_bytes() == first


OPTS = dict(initial_increment=P_CR / 20, max_displacement=1.1, max_steps=40)


def _interrupted_path(tmp_path, **opts):
    """A path of the von Mises truss stopped after 12 steps, its checkpoint written at step 10."""
    ck = tmp_path / "path.npz"

    class Crash(Exception):
        pass

    def crash(pt):
        if pt.step == 12:
            raise Crash

    with pytest.raises(Crash):
        trace_path(von_mises("load"), "load", checkpoint=CheckpointFile(ck, every=5), callback=crash, **{**OPTS, **opts})
    return ck


def test_continuation_refuses_a_checkpoint_of_a_stiffer_structure(tmp_path):
    ck = _interrupted_path(tmp_path)
    stiffer = von_mises("load")
    for e in stiffer.effects:
        if hasattr(e, "EA"):
            e.EA = 2.0 * e.EA  # EA doubled: the same sizes, another structure
    with pytest.raises(CheckpointMismatch, match="member properties differ") as info:
        trace_path(stiffer, "load", checkpoint=CheckpointFile(ck, resume=True), **OPTS)
    assert isinstance(info.value, ModelError) and "nodes" not in str(info.value)


def test_continuation_refuses_other_settings_and_names_them(tmp_path):
    ck = _interrupted_path(tmp_path)
    with pytest.raises(CheckpointMismatch, match="analysis option rtol differs: 1e-10 in the checkpoint, 1e-08 now"):
        trace_path(von_mises("load"), "load", checkpoint=CheckpointFile(ck, resume=True), rtol=1e-8, **OPTS)
    with pytest.raises(CheckpointMismatch, match="analysis option max_displacement differs"):
        trace_path(von_mises("load"), "load", checkpoint=CheckpointFile(ck, resume=True), **{**OPTS, "max_displacement": 0.9})
    # a larger step budget is what a resume is for
    full = trace_path(von_mises("load"), "load", **{**OPTS, "max_steps": 60})
    res = trace_path(von_mises("load"), "load", checkpoint=CheckpointFile(ck, resume=True), **{**OPTS, "max_steps": 60})
    assert res.success and np.array_equal(res["lam"], full["lam"])
    assert res.state_steps == full.state_steps
    assert np.array_equal(np.array(res.states), np.array(full.states))


def test_a_checkpoint_without_fingerprint_or_not_a_checkpoint_is_refused(tmp_path):
    ck = _interrupted_path(tmp_path)
    with np.load(ck) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays["meta"]))
    del meta["fingerprint"]
    arrays["meta"] = np.array(json.dumps(meta))
    np.savez(ck, **arrays)
    with pytest.raises(CheckpointMismatch, match="does not say which model"):
        trace_path(von_mises("load"), "load", checkpoint=CheckpointFile(ck, resume=True), **OPTS)
    ck.write_text("not a checkpoint")
    with pytest.raises(CheckpointMismatch, match="cannot be read"):
        trace_path(von_mises("load"), "load", checkpoint=CheckpointFile(ck, resume=True), **OPTS)


SPRING = {
    "title": "mass on a spring",
    "nodes": {"coordinates": [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]},
    "members": [{"kind": "bar", "connectivity": [[0, 1]], "EA": 100.0}],
    "supports": [{"nodes": [0]}, {"nodes": [1], "dofs": "yz"}],
    "masses": {"node_mass": 1.0},
    "loads": [{"nodes": [1], "force": [1.0, 0.0, 0.0]}],
    "analysis": {"type": "dynamics",
                 "dynamics": {"time_step": 0.01, "duration": 0.2, "monitor_node": 1, "monitor_component": "x",
                              "checkpoint_interval": 0.0}},
}


def test_time_stepping_refuses_a_checkpoint_of_another_structure_or_damping(tmp_path):
    run_scene(parse_scene(copy.deepcopy(SPRING)), tmp_path)
    stiffer = copy.deepcopy(SPRING)
    stiffer["members"][0]["EA"] = 200.0
    with pytest.raises(ModelError, match="member properties differ"):
        run_scene(parse_scene(stiffer), tmp_path, resume=True)
    damped = copy.deepcopy(SPRING)
    damped["analysis"]["dynamics"]["damping"] = 1.0
    with pytest.raises(ModelError, match="analysis option damping differs: 0.0 in the checkpoint, 1.0 now"):
        run_scene(parse_scene(damped), tmp_path, resume=True)
    heavier = copy.deepcopy(SPRING)
    heavier["masses"]["node_mass"] = 2.0
    with pytest.raises(ModelError, match="masses differ"):
        run_scene(parse_scene(heavier), tmp_path, resume=True)
    longer = copy.deepcopy(SPRING)
    longer["analysis"]["dynamics"]["duration"] = 0.3  # going on further is allowed
    assert run_scene(parse_scene(longer), tmp_path, resume=True)["time"] == pytest.approx(0.3)


def test_relaxation_refuses_another_net_naming_the_part(tmp_path):
    from test_analyses import NET

    run_scene(parse_scene(copy.deepcopy(NET)), tmp_path)
    other = copy.deepcopy(NET)
    other["ropes"]["slack"] = 0.1
    with pytest.raises(SceneError, match=r"different net \(ropes differ\)") as info:
        run_scene(parse_scene(other), tmp_path, resume=True)
    assert isinstance(info.value, CheckpointMismatch)


def test_a_refused_resume_into_a_folder_without_summary_says_it_failed(tmp_path):
    ck = _interrupted_path(tmp_path)  # a checkpoint and no summary, as a run killed early leaves
    (tmp_path / "path.npz").rename(tmp_path / "path_checkpoint.npz")
    scene = (ROOT / "shellform" / "scenes" / "von_mises.toml").read_text().replace("EA = 1.0e4", "EA = 3.0e4")
    assert ck.parent == tmp_path
    with pytest.raises(CheckpointMismatch):
        run_scene(parse_scene(_toml(scene)), tmp_path, resume=True)
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["run_status"] == "failed" and s["converged"] is False
    assert "differ" in s["stages"]["continuation"]["message"]


def _toml(text):
    import tomllib

    return tomllib.loads(text)


def test_a_refused_resume_leaves_the_folder_as_it_was(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    text = (ROOT / "shellform" / "scenes" / "von_mises.toml").read_text()
    scene.write_text(text)
    out = tmp_path / "out"
    assert main(["run", str(scene), "--out", str(out), "--quiet"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    scene.write_text(text.replace("EA = 1.0e4", "EA = 2.0e4"))
    assert main(["run", str(scene), "--out", str(out), "--quiet", "--resume"]) == 2
    err = capsys.readouterr().err
    assert "member properties differ" in err and "Traceback" not in err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


# -- killed at a random moment, then resumed ------------------------------------------------------

ENV = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
VOLATILE = {"wall_time_s", "timings_s", "form_finding_wall_time_s", "relaxation_wall_time_s", "checkpoints_written",
            "steps_this_run", "start", "iterations", "message", "stages", "prestress", "wall_time"}


def _command(scene, out, *extra):
    return [sys.executable, "-m", "shellform", "run", str(scene), "--out", str(out), "--quiet", *extra]


def _run(scene, out, *extra) -> subprocess.CompletedProcess:
    return subprocess.run(_command(scene, out, *extra), env=ENV, capture_output=True, text=True, timeout=900)


def _kill_at_random(scene, out, started: str, rng: random.Random, window: float) -> bool:
    """Start a run, wait until ``started`` exists in ``out``, kill -9 it up to ``window`` s later.

    Returns whether the run was still going when it was killed.
    """
    proc = subprocess.Popen(_command(scene, out), env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 600
        while not (out / started).exists():
            assert proc.poll() is None, f"the run ended before writing {started}"
            assert time.monotonic() < deadline
            time.sleep(0.002)
        time.sleep(rng.uniform(0.0, window))
        alive = proc.poll() is None
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait()
    return alive


def _strip(d, volatile=VOLATILE):
    """A summary without what differs between any two runs (wall times) or says how this run went."""
    return {k: _strip(v, volatile) if isinstance(v, dict) else v for k, v in d.items() if k not in volatile}


def _results(folder: Path, names) -> dict:
    # JSON files hold wall times: compared without them; every other file byte for byte
    return {n: _strip(json.loads((folder / n).read_text())) if n.endswith(".json") else (folder / n).read_bytes()
            for n in names}


def _plain_summary(folder: Path, volatile=VOLATILE) -> dict:
    return _strip(json.loads((folder / "summary.json").read_text()), volatile)


def _kill_and_resume(tmp_path, scene, started, window, files, seed, rounds=1, volatile=()):
    """The files of an uninterrupted run and of a run killed ``rounds`` times and resumed: the same."""
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    # only the killed runs need a process of their own
    t0 = time.monotonic()
    code = main(["run", str(scene), "--out", str(whole), "--quiet"])
    assert code in (0, 1)
    # a kill lands within the run: the window is cut to most of what the whole run takes here
    window = min(window, 0.6 * (time.monotonic() - t0))
    rng = random.Random(seed)
    killed_alive = []
    for k in range(rounds):
        if k == 0:
            killed_alive.append(_kill_at_random(scene, cut, started, rng, window))
        else:
            proc = subprocess.Popen(_command(scene, cut, "--resume"), env=ENV, stdout=subprocess.DEVNULL,
                                    stderr=subprocess.DEVNULL)
            time.sleep(0.5 + rng.uniform(0.0, window))  # after the start-up of a new process
            killed_alive.append(proc.poll() is None)
            proc.send_signal(signal.SIGKILL)
            proc.wait()
        # a killed run never leaves a summary that claims success (unless it got to its very end:
        # still a process, its last summary written)
        if (cut / "summary.json").exists() and killed_alive[-1]:
            s = json.loads((cut / "summary.json").read_text())
            assert s["run_status"] in ("running", "finished")
            assert s["converged"] is False or s["run_status"] == "finished"
    assert main(["run", str(scene), "--out", str(cut), "--quiet", "--resume"]) == code
    a, b = _results(whole, files), _results(cut, files)
    for name in files:
        assert a[name] == b[name], f"{name} differs after kill -9 and --resume (killed while running: {killed_alive})"
    assert _plain_summary(whole, VOLATILE | set(volatile)) == _plain_summary(cut, VOLATILE | set(volatile))
    stages = [{k: (v["status"], v.get("converged")) for k, v in json.loads((f / "summary.json").read_text())
               ["stages"].items()} for f in (whole, cut)]
    assert stages[0] == stages[1] and all(status == "finished" for status, _ in stages[1].values())
    # the killed run's temporary files and its lock file are gone after the resume
    assert [p.name for p in cut.iterdir() if p.name.startswith(".")] == []
    return killed_alive


def _continuation_scene(tmp_path, steps=150, every=1) -> Path:
    text = (ROOT / "scenes" / "lattice_dome_imperfect.toml").read_text()
    text = text.replace('file = "../meshes/lattice_dome.obj"', f'file = "{ROOT / "meshes" / "lattice_dome.obj"}"')
    # small steps (at most 10 times the first): the path lasts long enough for a kill to land in it
    text = text.replace("max_steps = 150", f"max_steps = {steps}\ncheckpoint_every = {every}\ninitial_increment = 0.005")
    scene = tmp_path / "dome.toml"
    scene.write_text(text)
    return scene


CONTINUATION_FILES = ("path.csv", "path.xdmf", "path.h5", "path_events.json", "load_displacement.png", "state.vtu")


def test_continuation_killed_and_resumed_writes_the_uninterrupted_files(tmp_path, capsys):
    scene = _continuation_scene(tmp_path, steps=30, every=3)
    alive = _kill_and_resume(tmp_path, scene, "path_checkpoint.npz", 0.3, CONTINUATION_FILES, seed=1)
    assert alive == [True]
    # the same folder, the structure changed (EA doubled): the resume is refused
    scene.write_text(scene.read_text().replace("EA = 2.0e6", "EA = 4.0e6"))
    assert main(["run", str(scene), "--out", str(tmp_path / "cut"), "--quiet", "--resume"]) == 2
    err = capsys.readouterr().err
    assert "member properties differ" in err and "Traceback" not in err


@pytest.mark.slow
@pytest.mark.parametrize("seed", [3, 4, 5])
def test_continuation_killed_twice_at_random(tmp_path, seed):
    scene = _continuation_scene(tmp_path)
    alive = _kill_and_resume(tmp_path, scene, "path_checkpoint.npz", 2.0, CONTINUATION_FILES, seed=seed, rounds=2)
    assert alive[0]


@pytest.mark.slow
@pytest.mark.parametrize("seed", [6, 7])
def test_form_finding_killed_and_resumed(tmp_path, seed):
    scene = ROOT / "validation" / "mra" / "net_9x4_explicit.toml"
    files = ("hanging.vtu", "inverted.vtu", "inverted_shell.vtu")
    # a relaxation resumed from a state saved at rest reports the velocity of its own last step
    alive = _kill_and_resume(tmp_path, scene, "relaxation_checkpoint.npz", 4.0, files, seed=seed,
                             volatile={"max_velocity", "max_acceleration"})
    assert alive == [True]


@pytest.mark.slow
@pytest.mark.parametrize("seed", [8, 9])
def test_form_and_buckle_killed_while_buckling_and_resumed(tmp_path, seed):
    text = (ROOT / "shellform" / "scenes" / "default.toml").read_text()
    scene = tmp_path / "dome.toml"
    # small steps, a checkpoint at each: the buckling stage lasts long enough to be killed in
    scene.write_text(text.replace("load_factor_max = 1000.0",
                                  "load_factor_max = 1000.0\ninitial_increment = 2.0\ncheckpoint_every = 1"))
    files = ("hanging.vtu", "inverted.vtu", "inverted_shell.vtu", "buckling_path.csv", "buckling_path.xdmf",
             "buckling_path.h5",
             "buckling_path_events.json", "buckling_curve.png")
    # the form finding, resumed from its state saved at rest, reports the velocity of its own last step
    alive = _kill_and_resume(tmp_path, scene, "buckling_path_checkpoint.npz", 0.5, files, seed=seed,
                             volatile={"max_velocity", "max_acceleration"})
    assert alive == [True]


@pytest.mark.slow
def test_indentation_killed_and_run_again(tmp_path):
    # the indentation keeps no checkpoint: a resume starts over, and since every Lanczos run starts
    # from one fixed vector, the run again writes the uninterrupted run's files byte for byte
    scene = ROOT / "scenes" / "hemisphere_indentation.toml"
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    start = time.monotonic()
    code = main(["run", str(scene), "--out", str(whole), "--quiet"])
    # killed within the first half of an uninterrupted run's time (the run's own start-up included), so that
    # it is still indenting however fast this machine is
    window = 0.5 * (time.monotonic() - start)
    assert _kill_at_random(scene, cut, "summary.json", random.Random(10), window)
    s = json.loads((cut / "summary.json").read_text())
    assert s["converged"] is False and s["run_status"] == "running"
    assert main(["run", str(scene), "--out", str(cut), "--quiet", "--resume"]) == code
    a, b = (json.loads((f / "summary.json").read_text()) for f in (whole, cut))
    assert a["labels"] == b["labels"] and len(a["snaps"]) == len(b["snaps"]) > 0
    assert np.allclose([x["dD_over_R"] for x in a["snaps"]], [x["dD_over_R"] for x in b["snaps"]], atol=1e-2)
    assert b["max_force_normalised"] == pytest.approx(a["max_force_normalised"], rel=1e-2)
    assert [c["label"] for c in a["configurations"]] == [c["label"] for c in b["configurations"]]
    assert [p.name for p in cut.iterdir() if p.name.startswith(".")] == []
    for name in ("indentation.csv", "indentation.xdmf", "indentation.h5"):
        assert (cut / name).read_bytes() == (whole / name).read_bytes(), name


@pytest.mark.slow
def test_time_stepping_killed_and_resumed(tmp_path):
    text = (ROOT / "scenes" / "chain_dynamics.toml").read_text()
    scene = tmp_path / "chain.toml"
    scene.write_text(text + "checkpoint_interval = 0.0\n" if "checkpoint_interval" not in text else text)
    files = ("dynamics.csv", "dynamics.xdmf", "dynamics.h5", "dynamics.png")
    # the Newton iterations and rejected steps the summary gives are those of the last run
    _kill_and_resume(tmp_path, scene, "dynamics_checkpoint.npz", 1.0, files, seed=11,
                     volatile={"newton_iterations", "rejected_steps"})
