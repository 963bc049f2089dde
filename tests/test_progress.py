"""Progress on a terminal and in the run log."""

import io

import pytest

from shellform.progress import Console, Status, indented, tee, time_left


class Terminal(io.StringIO):
    def isatty(self):
        return True


def test_a_terminal_keeps_the_status_on_one_line_and_lines_below_it():
    term = Terminal()
    console = Console(1, term)
    console("start")
    console(Status("step 1", 0.25))
    console(Status("step 2", 0.5))
    console("limit point")
    console(Status("step 3", 0.75))
    console.close()
    text = term.getvalue()
    assert text.startswith("start\n\r\x1b[Kstep 1  25 %")
    assert "\r\x1b[Kstep 2  50 %" in text
    # a line clears the status before it is written
    assert "\r\x1b[Klimit point\n" in text
    assert text.endswith("\n") and text.count("\n") == 3


def test_a_stream_that_is_no_terminal_gets_a_status_now_and_then():
    stream = io.StringIO()
    console = Console(1, stream, interval=3600)
    for k in range(10):
        console(Status(f"step {k}"))
    console("done")
    assert stream.getvalue() == "step 0\ndone\n"


def test_verbose_prints_every_status_and_quiet_nothing():
    loud, silent = io.StringIO(), io.StringIO()
    for console in (Console(2, loud), Console(0, silent)):
        for k in range(3):
            console(Status(f"step {k}", k / 3))
    assert loud.getvalue() == "step 0\nstep 1\nstep 2\n" and silent.getvalue() == ""


def test_time_left_is_the_linear_estimate():
    assert time_left(10.0, 0.25) == pytest.approx(30.0)
    assert time_left(10.0, None) is None and time_left(0.0, 0.5) is None


def test_indented_and_teed_statuses_stay_statuses():
    seen = []
    say = indented(tee(seen.append, seen.append))
    say(Status("step 1", 0.5))
    say("line")
    assert seen[0] == "  step 1" and isinstance(seen[0], Status) and seen[0].fraction == 0.5
    assert seen[2] == "  line" and not isinstance(seen[2], Status)


def test_a_run_writes_its_progress_to_run_log(tmp_path):
    from shellform.cli import main

    out = tmp_path / "out"
    assert main(["run", "von_mises", "--out", str(out), "-q"]) == 0
    log = (out / "run.log").read_text()
    assert log.startswith("--- ") and "step    1" in log and "limit point" in log
    assert main(["run", "von_mises", "--out", str(out), "-q"]) == 0
    assert (out / "run.log").read_text().count("--- ") == 2  # a second run appends
