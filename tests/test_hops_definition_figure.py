"""The schematic of the Grasshopper definition is drawn from the server's own descriptions."""

import importlib.util
import time
from pathlib import Path

import pytest

pytest.importorskip("rhino3dm")

SCRIPT = Path(__file__).resolve().parents[1] / "docs" / "figures" / "grasshopper_definition.py"


def test_the_picture_names_exactly_the_served_components_inputs_and_outputs(tmp_path):
    from shellform.hops import HopsApp

    spec = importlib.util.spec_from_file_location("grasshopper_definition", SCRIPT)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    t0 = time.perf_counter()
    fig, path = script.main(["--out", str(tmp_path / "definition.png")])
    assert time.perf_counter() - t0 < 5.0
    assert path.stat().st_size > 10_000 and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    app = HopsApp()
    try:
        served = app.listing()
    finally:
        app.close()
    expected = {f"component:{c['Name']}" for c in served}
    expected |= {f"input:{c['Name']}:{p['Name']}" for c in served for p in c["Inputs"]}
    expected |= {f"output:{c['Name']}:{p['Name']}" for c in served for p in c["Outputs"]}
    drawn = script.drawn_names(fig)
    assert drawn == expected
    # and the text shown is the name the gid gives
    for t in fig.findobj(lambda a: hasattr(a, "get_gid") and hasattr(a, "get_text") and a.get_gid()):
        assert t.get_text() == t.get_gid().rsplit(":", 1)[-1]
