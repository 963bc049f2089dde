"""The Hops server driven over HTTP as Grasshopper's Hops component drives it.

The server runs on a free port in a thread; the tests list and describe the
components, solve each one with inputs encoded as Hops encodes them (rhino3dm
geometry in the data trees), decode the outputs and compare them with the same
analysis run from a scene.
"""

from __future__ import annotations

import json
import socket
import time
import urllib.error
import urllib.request

import numpy as np
import pytest

rhino3dm = pytest.importorskip("rhino3dm")

import shellform as sf  # noqa: E402
from shellform.errors import SceneError  # noqa: E402
from shellform.hops import COMPONENTS, start  # noqa: E402
from shellform.hops.protocol import encode_input  # noqa: E402
from shellform.scene import parse_scene  # noqa: E402


def get(server, path):
    try:
        with urllib.request.urlopen(server.url + path, timeout=60) as r:
            return r.status, r.headers["Content-Type"], json.load(r)
    except urllib.error.HTTPError as err:
        return err.code, err.headers["Content-Type"], json.loads(err.read())


def post(server, body, path="/solve"):
    data = body if isinstance(body, bytes) else json.dumps(body).encode()
    req = urllib.request.Request(server.url + path, data=data, headers={"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(req, timeout=300) as r:
            return r.status, r.read().decode()
    except urllib.error.HTTPError as err:
        return err.code, err.read().decode()


def request(component, **values):
    """A solve request as Hops sends it: the pointer and one data tree per connected input."""
    params = {p.name: p for p in COMPONENTS[component].inputs}
    return {"absolutetolerance": 0.001, "modelunits": "Meters", "dataversion": 7, "pointer": component,
            "cachesolve": False, "values": [encode_input(params[k], v) for k, v in values.items()]}


def outputs(text):
    """The reply's data trees decoded: name -> list of items (one branch) or dict of branches."""
    reply = json.loads(text)
    out = {}
    for tree in reply["values"]:
        branches = {}
        for path, items in tree["InnerTree"].items():
            branches[path] = [_decode(it) for it in items]
        out[tree["ParamName"]] = branches["{0}"] if list(branches) == ["{0}"] else branches
    return reply, out


def _decode(item):
    data = item["data"]
    kind = item["type"]
    if kind in ("System.Double", "System.Int32", "System.Boolean", "System.String"):
        return json.loads(data)
    value = json.loads(data)
    if kind in ("Rhino.Geometry.Point3d", "Rhino.Geometry.Vector3d"):
        return [value["X"], value["Y"], value["Z"]]
    if kind == "Rhino.Geometry.Line":
        return [[value["From"][c] for c in "XYZ"], [value["To"][c] for c in "XYZ"]]
    return rhino3dm.CommonObject.Decode(value)


def rectangle(x0, y0, lx, ly, z=0.0):
    pl = rhino3dm.Polyline(5)
    for p in [(x0, y0), (x0 + lx, y0), (x0 + lx, y0 + ly), (x0, y0 + ly), (x0, y0)]:
        pl.Add(p[0], p[1], z)
    return rhino3dm.PolylineCurve(pl)


def lines_of(mesh):
    """The line cells of a meshio mesh as [[a, b], ...] point pairs."""
    lines = mesh.cells_dict["line"]
    return np.stack([mesh.points[lines[:, 0]], mesh.points[lines[:, 1]]], axis=1)


# -- listing and describing ---------------------------------------------------------------------


def test_list_and_describe(server):
    status, ctype, listing = get(server, "/")
    assert status == 200 and "json" in ctype
    assert [c["Name"] for c in listing] == ["FormFind", "Lengths", "Gridshell", "Trace"]
    for c in listing:
        status, ctype, one = get(server, f"/{c['Name']}")
        assert status == 200 and "json" in ctype and one == c
        assert one["Uri"] == f"/{c['Name']}"
        for p in one["Inputs"]:
            assert {"Name", "Nickname", "Description", "ParamType", "AtLeast", "AtMost"} <= set(p)
            assert p["ParamType"] in ("Number", "Integer", "Boolean", "Text", "Point", "Vector", "Line", "Curve",
                                      "Mesh")
        assert all(o["Name"] and o["ParamType"] for o in one["Outputs"])
    # units are stated in the descriptions
    ff = listing[0]
    assert "[N]" in next(o["Description"] for o in ff["Outputs"] if o["Name"] == "RopeForces")
    assert "(scene key ropes.slack)" in next(i["Description"] for i in ff["Inputs"] if i["Name"] == "Slack")
    status, _, err = get(server, "/NoSuch")
    assert status == 404 and "FormFind" in err["errors"][0]


# -- solving each component, against the same scene ----------------------------------------------


FORM = dict(Boundary=rectangle(1.0, 2.0, 6.0, 4.0), Divisions=6, DivisionsY=4, Slack=0.05, MassPerLength=2.0)
FORM_SCENE = {
    "geometry": {"type": "rectangle", "length_x": 6.0, "length_y": 4.0, "origin": [1.0, 2.0, 0.0], "n_i": 6,
                 "n_j": 4},
    "supports": [{"groups": ["boundary"]}],
    "ropes": {"slack": 0.05, "mass_per_length": 2.0},
    "analysis": {"type": "mra"},
}


def test_formfind_matches_the_scene(server):
    status, text = post(server, request("FormFind", **FORM))
    assert status == 200
    reply, out = outputs(text)
    assert reply["errors"] == []
    ref = sf.run(parse_scene(FORM_SCENE))
    hang = ref.mesh("hanging.vtu")
    span = 6.0
    np.testing.assert_allclose(np.array(out["HangingNet"]), lines_of(hang), rtol=0, atol=1e-12 * span)
    np.testing.assert_allclose(out["RopeForces"], hang.cell_data["tension"][0], rtol=1e-12, atol=1e-9)
    assert out["Slack"] == [bool(s > 0.5) for s in hang.cell_data["slack"][0]]
    shell = ref.mesh("inverted_shell.vtu")
    mesh = out["Shell"][0]
    verts = np.array([[p.X, p.Y, p.Z] for p in (mesh.Vertices.Point3dAt(i) for i in range(len(mesh.Vertices)))])
    np.testing.assert_allclose(verts, shell.points, rtol=0, atol=1e-12 * span)
    assert mesh.Faces.Count == len(shell.cells_dict["quad"])
    # the reactions carry the whole weight (checked against the summary's weight, not the same numbers)
    R = np.array(out["Reactions"])
    assert len(R) == len(out["SupportPoints"]) == ref.summary["n_supports"]
    np.testing.assert_allclose(R.sum(axis=0), [0.0, 0.0, ref.summary["total_weight"]], atol=1e-6 * ref.summary[
        "total_weight"])
    report = json.loads(out["Report"][0])
    assert out["Converged"] == [True] and report["converged"] and report["iterations"] == ref.summary["iterations"]


def test_formfind_circle_and_support_points(server):
    circle = rhino3dm.Circle(rhino3dm.Point3d(0.0, 0.0, 1.0), 3.0).ToNurbsCurve()
    body = request("FormFind", Boundary=circle, Divisions=8, Supports="",
                   SupportPoints=[[3.0, 0.0, 1.0], [-3.0, 0.0, 1.0], [0.0, 3.0, 1.0], [0.0, -3.0, 1.0]])
    status, text = post(server, body)
    reply, out = outputs(text)
    assert status == 200 and reply["errors"] == []
    np.testing.assert_allclose(sorted(map(tuple, np.round(out["SupportPoints"], 9))),
                               sorted([(-3.0, 0.0, 1.0), (0.0, -3.0, 1.0), (0.0, 3.0, 1.0), (3.0, 0.0, 1.0)]),
                               atol=1e-9)
    from shellform.geometry.grids import disk_grid

    grid = disk_grid(3.0, 8, (0.0, 0.0, 1.0))
    held = [int(np.argmin(np.linalg.norm(grid.nodes - p, axis=1)))
            for p in ([3.0, 0.0, 1.0], [-3.0, 0.0, 1.0], [0.0, 3.0, 1.0], [0.0, -3.0, 1.0])]
    ref = sf.run(parse_scene({"geometry": {"type": "disk", "radius": 3.0, "n": 8, "center": [0.0, 0.0, 1.0]},
                              "supports": [{"nodes": held}], "analysis": {"type": "mra"}}))
    hang = ref.mesh("hanging.vtu")
    np.testing.assert_allclose(np.array(out["HangingNet"]), lines_of(hang), rtol=0, atol=1e-12 * 6.0)
    assert json.loads(out["Report"][0])["rise"] == pytest.approx(ref.summary["rise"], rel=1e-10)
    assert len(out["HangingNet"]) == len(hang.cells_dict["line"])


def polyline(points, z=0.0):
    pl = rhino3dm.Polyline(len(points) + 1)
    for x, y in list(points) + [points[0]]:
        pl.Add(x, y, z)
    return rhino3dm.PolylineCurve(pl)


L_SHAPE = [(0.0, 0.0), (6.0, 0.0), (6.0, 3.0), (3.0, 3.0), (3.0, 6.0), (0.0, 6.0)]
COURT = [(0.8, 0.8), (2.0, 0.8), (2.0, 2.0), (0.8, 2.0)]


def test_formfind_of_any_outline_with_a_hole_matches_the_scene(server):
    """An L-shaped polyline with a square hole: meshed by gmsh at the edge length, hung from its outer
    corners and the hole's rim, exactly as the scene of the same outline."""
    body = request("FormFind", Boundary=polyline(L_SHAPE), Holes=[polyline(COURT)], EdgeLength=0.5,
                   Supports="corners, hole_1", Slack=0.05)
    status, text = post(server, body)
    reply, out = outputs(text)
    assert status == 200 and reply["errors"] == []
    ref = sf.run(parse_scene({
        "geometry": {"type": "polygon", "boundary": [[x, y, 0.0] for x, y in L_SHAPE],
                     "holes": [{"points": [[x, y, 0.0] for x, y in COURT]}], "edge_length": 0.5},
        "supports": [{"groups": ["corners", "hole_1"]}], "ropes": {"slack": 0.05}, "analysis": {"type": "mra"}}))
    hang = ref.mesh("hanging.vtu")
    np.testing.assert_allclose(np.array(out["HangingNet"]), lines_of(hang), rtol=0, atol=1e-12 * 6.0)
    assert out["Converged"] == [True] and ref.summary["converged"]
    shell = ref.mesh("inverted_shell.vtu")
    assert out["Shell"][0].Faces.Count == sum(len(c) for c in shell.cells_dict.values()) > 0
    assert "quad" in shell.cells_dict  # gmsh's quads, with the triangles recombination leaves


def test_lengths_with_control_matches_the_scene(server):
    status, text = post(server, request("Lengths", **FORM, Control=True, Classes=2, LengthTolerance=0.002))
    reply, out = outputs(text)
    assert status == 200 and reply["errors"] == []
    scene = json.loads(json.dumps(FORM_SCENE))
    scene["analysis"]["lengths"] = {"tolerance": 0.002, "control": True, "n_classes": 2}
    ref = sf.run(parse_scene(scene))
    lc = ref.summary["length_control"]
    np.testing.assert_allclose(out["ClassLengths"], lc["centres"], rtol=1e-12)
    assert out["ConformingCount"] == [lc["statistics"]["n_conforming"]]
    assert sum(out["Conforming"]) == lc["statistics"]["n_conforming"]
    hang = ref.mesh("hanging_length_control.vtu")
    np.testing.assert_allclose(out["RopeLengths"], hang.cell_data["length"][0], rtol=1e-12)
    assert set(out["LengthClass"]) <= {0, 1}


GRIDSHELL = dict(Boundary=rectangle(0.0, 0.0, 6.0, 6.0), Divisions=6, Slack=0.05, Radius=0.004, MaxSteps=40)


@pytest.mark.parametrize("section, rods", [
    ({}, {"radius": 0.004}),
    ({"Section": "rectangle", "Depth": 0.006, "Width": 0.01}, {"section": "rectangle", "depth": 0.006, "width": 0.01}),
], ids=["circle", "lath"])
def test_gridshell_matches_the_scene(server, section, rods):
    status, text = post(server, request("Gridshell", **{**GRIDSHELL, **section}))
    reply, out = outputs(text)
    assert status == 200 and reply["errors"] == [], reply["errors"]
    ref = sf.run(parse_scene({
        "geometry": {"type": "rectangle", "length_x": 6.0, "length_y": 6.0, "n_i": 6, "n_j": 6},
        "supports": [{"groups": ["boundary"]}], "ropes": {"slack": 0.05}, "rods": rods,
        "analysis": {"type": "form_and_buckle", "buckling": {"max_steps": 40}}}))
    b = ref.summary["buckling"]
    assert b["critical_load_factor"] is not None
    assert out["CriticalLoadFactor"] == [pytest.approx(b["critical_load_factor"], rel=1e-12)]
    assert out["CriticalKind"] == [b["critical_kind"]]
    crit = ref.mesh(ref.events[0]["file"])
    np.testing.assert_allclose(np.array(out["Rods"]), lines_of(crit), atol=1e-12)
    moved = np.array(out["BucklingMode"]) - np.array(out["Rods"])
    # the mode drawn at ModeScale (default 0.1 m): the largest nodal displacement is 0.1 m
    assert np.linalg.norm(moved, axis=2).max() == pytest.approx(0.1, rel=1e-9)
    np.testing.assert_allclose(out["AxialForce"], crit.cell_data["axial_force"][0], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(out["BendingMoment"], crit.cell_data["bending_moment"][0], rtol=1e-12, atol=1e-12)


VON_MISES = dict(Members=[[[-1.0, 0.0, 0.0], [0.0, 0.0, 0.2]], [[0.0, 0.0, 0.2], [1.0, 0.0, 0.0]]], EA=1.0e4,
                 Supports=[[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.2]], SupportDofs=["xyz", "xyz", "y"],
                 LoadPoints=[[0.0, 0.0, 0.2]], Force=[0.0, 0.0, -1.0], ParameterMax=40.0, MaxDisplacement=0.5,
                 States=[10.0, 25.0])


def test_trace_matches_the_builtin_von_mises_truss(server):
    status, text = post(server, request("Trace", **VON_MISES))
    reply, out = outputs(text)
    assert status == 200 and reply["errors"] == []
    ref = sf.run("von_mises")  # the same truss from its scene file
    path = ref.table()
    np.testing.assert_allclose(out["Load"], path["load"], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(out["Parameter"], path["parameter"], rtol=1e-12, atol=1e-12)
    assert out["Stable"] == [bool(n == 0) for n in path["n_negative"]]
    assert out["EventLoads"][0] == pytest.approx(ref.events[0]["load"], rel=1e-12)
    assert out["EventLoads"][0] == pytest.approx(29.605, abs=0.01)  # the analytic limit load
    assert out["Events"][0].startswith("limit point")
    states = out["DeformedStates"]
    assert set(states) == {"{0}", "{1}"} and len(out["StateParameters"]) == 2
    positions = ref.states().positions
    for k, p in enumerate(out["StateParameters"]):
        j = int(np.flatnonzero(path["parameter"] == p)[0])
        np.testing.assert_allclose(np.array(states[f"{{{k}}}"])[1, 0], positions[j][1], atol=1e-12)


# -- bad inputs -----------------------------------------------------------------------------------


def _error(server, body):
    status, text = post(server, body)
    assert status == 200, text
    assert "Traceback" not in text
    reply = json.loads(text)
    assert reply["values"] == [] and len(reply["errors"]) == 1
    return reply["errors"][0]


def test_bad_inputs_name_the_input_and_the_scene_key(server):
    # the message is the scene's own about the key it fills
    bad = json.loads(json.dumps(FORM_SCENE))
    bad["ropes"]["slack"] = -2.0
    with pytest.raises(SceneError) as scene_error:
        parse_scene(bad)
    assert _error(server, request("FormFind", **{**FORM, "Slack": -2.0})) == f"Slack: {scene_error.value}"
    assert _error(server, request("FormFind", **{**FORM, "Scheme": "fast"})).startswith(
        "Scheme: scene key 'analysis.relaxation.scheme': got 'fast'")
    assert _error(server, request("FormFind", **{**FORM, "Supports": "../../etc/passwd"})).startswith(
        "Supports: scene key 'supports[0].groups': a planform grid has no node set '../../etc/passwd'")
    assert _error(server, request("FormFind", **{**FORM, "Divisions": 0})).startswith(
        "Divisions: scene key 'geometry.n_i'")
    line = rhino3dm.LineCurve(rhino3dm.Point3d(0, 0, 0), rhino3dm.Point3d(1, 0, 0))
    assert _error(server, request("FormFind", **{**FORM, "Boundary": line})).startswith("Boundary: is an open curve")
    tilted = rhino3dm.Circle(3.0).ToNurbsCurve()
    tilted.Rotate(0.3, rhino3dm.Vector3d(1, 0, 0), rhino3dm.Point3d(0, 0, 0))
    assert "horizontal plane" in _error(server, request("FormFind", **{**FORM, "Boundary": tilted}))
    trace = {k: v for k, v in VON_MISES.items() if k != "EA"}
    assert _error(server, request("Trace", **trace)) == "EA: scene key 'members[0].EA': this key is required"
    assert _error(server, request("Trace", **{**VON_MISES, "Supports": [[5.0, 5.0, 5.0]]})).startswith(
        "Supports: item 0 at (5, 5, 5) m is no node of the structure")
    assert _error(server, request("Trace", **{**VON_MISES, "Kind": "cable"})).startswith("Kind: scene key "
                                                                                        "'members[0].kind'")
    body = request("FormFind", **FORM)
    body["values"].append({"ParamName": "Path", "InnerTree": {"{0}": [{"type": "System.String", "data": "\"/etc\""}]}})
    assert _error(server, body).startswith("Path: FormFind has no such input")
    body = request("FormFind", **FORM)
    body["values"][0]["InnerTree"]["{0}"][0]["data"] = "{\"version\": 1}"
    assert _error(server, body).startswith("Boundary: cannot decode")


def test_bad_requests_get_json_replies(server):
    status, text = post(server, b"not json")
    assert status == 400 and json.loads(text)["errors"]
    status, text = post(server, {"pointer": "Nope", "values": []})
    assert status == 404 and "FormFind" in json.loads(text)["errors"][0]
    status, text = post(server, request("Trace", **VON_MISES), path="/Trace")  # POST /<name> solves too
    assert status == 200 and json.loads(text)["errors"] == []


# -- cache, folders, stopping ---------------------------------------------------------------------


def test_a_repeated_request_is_answered_from_the_cache(server):
    body = request("FormFind", **{**FORM, "Slack": 0.07})
    runs, hits = server.app.counts["runs"], server.app.counts["cache_hits"]
    first = post(server, body)
    second = post(server, body)
    assert first == second
    assert server.app.counts["runs"] == runs + 1 and server.app.counts["cache_hits"] == hits + 1
    # run folders live under the server's own folder and are gone after the reply
    assert server.app.root.is_dir() and list(server.app.root.iterdir()) == []


def test_a_run_stops_after_the_timeout():
    srv, thread = start(port=0, timeout=0.01)
    try:
        body = request("FormFind", **{**FORM, "Divisions": 40, "DivisionsY": 40})
        status, text = post(srv, body)
        assert status == 200
        assert json.loads(text)["errors"] == ["FormFind: stopped after 0.01 s (the server's --timeout)"]
        assert list(srv.app.root.iterdir()) == []
    finally:
        srv.shutdown()
        srv.server_close()


def test_a_run_stops_when_the_client_goes(server):
    body = json.dumps(request("FormFind", **{**FORM, "Divisions": 99, "DivisionsY": 99})).encode()
    host, port = server.server_address[:2]
    with socket.create_connection((host, port)) as s:
        s.sendall(b"POST /solve HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: "
                  + str(len(body)).encode() + b"\r\n\r\n" + body)
        time.sleep(0.5)
    # the next request waits for the server's one run at a time: it comes soon, not after the ~5 s net
    t0 = time.perf_counter()
    status, _ = post(server, request("Trace", **{**VON_MISES, "MaxSteps": 3}))
    assert status == 200
    assert time.perf_counter() - t0 < 2.0
