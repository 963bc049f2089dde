"""Local process pools: how their processes start, and what a worker that dies becomes."""

import os
import subprocess
import sys
import threading

import pytest

from shellform.errors import SceneError
from shellform.studies import runner
from shellform.studies.runner import Runner

linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="fork and forkserver are chosen on Linux")


def _died(why):
    return f"died: {why}"


@pytest.fixture
def no_override(monkeypatch):
    monkeypatch.delenv(runner.START_METHOD_VARIABLE, raising=False)


@linux
def test_a_process_with_no_other_thread_forks(no_override):
    if not runner.only_blas_threads():
        pytest.skip("this test process runs threads of its own")
    assert runner.start_method() == "fork"


@linux
def test_a_live_thread_makes_the_pool_start_from_a_fork_server(no_override):
    stop = threading.Event()
    thread = threading.Thread(target=stop.wait)
    thread.start()
    try:
        assert not runner.only_blas_threads()
        assert runner.start_method() == "forkserver"
    finally:
        stop.set()
        thread.join()


def test_the_environment_variable_chooses_and_a_bad_value_is_refused(monkeypatch):
    monkeypatch.setenv(runner.START_METHOD_VARIABLE, "spawn")
    assert runner.start_method() == "spawn"
    monkeypatch.setenv(runner.START_METHOD_VARIABLE, "teleport")
    with pytest.raises(SceneError, match="teleport"):
        runner.start_method()


@pytest.mark.parametrize("method", ["fork", "forkserver", "spawn"])
def test_every_start_method_runs_the_tasks_and_reports_a_worker_that_dies(method, monkeypatch):
    import multiprocessing

    if method not in multiprocessing.get_all_start_methods():
        pytest.skip(f"no {method} here")
    monkeypatch.setenv(runner.START_METHOD_VARIABLE, method)
    results = dict(Runner(workers=2).run(os.getpid, [(k, ()) for k in range(4)], _died))
    assert sorted(results) == [0, 1, 2, 3]
    assert os.getpid() not in results.values()
    # a worker that exits under its task breaks the pool: its task and those not done become died(...)
    results = dict(Runner(workers=2).run(os._exit, [("a", (3,)), ("b", (3,))], _died))
    assert all(str(v).startswith("died: BrokenProcessPool") for v in results.values())


@linux
def test_a_forked_worker_imports_nothing_a_case_needs(tmp_path):
    """After the preload a chain case (time stepping, its plot, its XDMF) imports no package of its own."""
    scene = os.path.join(os.path.dirname(__file__), "..", "scenes", "chain_dynamics.toml")
    code = f"""
import sys, tomllib
from shellform.studies import runner
from shellform.studies.sweep import run_case
runner.preload()
before = {{m.split(".")[0] for m in sys.modules}}
data = tomllib.loads(open({scene!r}).read())
data["analysis"]["dynamics"]["duration"] = 0.2
summary = run_case(data, {str(tmp_path / 'case')!r}, {os.path.dirname(scene)!r})
assert summary["run_status"] == "finished", summary
new = sorted({{m.split(".")[0] for m in sys.modules}} - before)
print(" ".join(new))
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split() == []
