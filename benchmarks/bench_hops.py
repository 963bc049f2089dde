"""Latency of the Hops server: a FormFind round trip as Grasshopper's Hops component makes it.

A server runs in this process on a free port (warmed by one untimed request);
each timed request is a full HTTP round trip: encode the inputs as Hops does
(the boundary a rhino3dm polyline curve), POST /solve, receive the reply and
decode every output (lines, the shell mesh, numbers). The nets are square
grids on a 10 m square hung from their boundary, slack 0.05, of about 1e2,
1e3 and 1e4 nodes. Each size is timed ``--rounds`` times with a new slack
each round (a new request, so a run), then once more with the last request
repeated (answered from the server's cache). The table gives the median
round trip, the server's run (the analysis with its files, ``wall_time_s`` of
the report), the rest of the round trip (decoding the inputs, building the
scene, reading the run's meshes back, encoding the outputs, HTTP and the
client's decoding; median of the per-round differences), the cached round
trip and the machine's load average before the size's first round.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_hops.py [--rounds 5] [--sizes 9 31 99]

Writes benchmarks/results/bench_hops.md.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
import urllib.request
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import rhino3dm  # noqa: E402

from shellform.hops import COMPONENTS, start  # noqa: E402
from shellform.hops.protocol import encode_input  # noqa: E402

OUT = Path(__file__).parent / "results" / "bench_hops.md"


def boundary():
    pl = rhino3dm.Polyline(5)
    for x, y in [(0, 0), (10, 0), (10, 10), (0, 10), (0, 0)]:
        pl.Add(float(x), float(y), 0.0)
    return rhino3dm.PolylineCurve(pl)


def body(n: int, slack: float) -> bytes:
    p = {q.name: q for q in COMPONENTS["FormFind"].inputs}
    values = [encode_input(p["Boundary"], boundary()), encode_input(p["Divisions"], n),
              encode_input(p["Slack"], slack)]
    return json.dumps({"pointer": "FormFind", "values": values}).encode()


def round_trip(url: str, data: bytes) -> tuple[float, dict]:
    t0 = time.perf_counter()
    req = urllib.request.Request(url + "/solve", data=data, headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(req, timeout=600) as r:
        reply = json.loads(r.read())
    decoded = {}
    for tree in reply["values"]:
        items = tree["InnerTree"]["{0}"]
        if tree["ParamName"] == "Shell":
            decoded["Shell"] = rhino3dm.CommonObject.Decode(json.loads(items[0]["data"]))
        else:
            decoded[tree["ParamName"]] = [json.loads(it["data"]) for it in items]
    elapsed = time.perf_counter() - t0
    if reply["errors"]:
        raise RuntimeError(reply["errors"])
    return elapsed, decoded


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--sizes", type=int, nargs="+", default=[9, 31, 99], help="quads per side (nodes: (n+1)^2)")
    args = ap.parse_args()
    server, _ = start(port=0)
    rows = []
    try:
        round_trip(server.url, body(8, 0.01))  # warm: imports, the mesher, the first factorisation
        for n in args.sizes:
            times, runs, load = [], [], os.getloadavg()[0]
            for k in range(args.rounds):
                data = body(n, 0.05 + 1e-4 * k)
                t, out = round_trip(server.url, data)
                report = json.loads(out["Report"][0])
                times.append(t)
                runs.append(report["wall_time_s"])
                print(f"n = {(n + 1) ** 2:>6} nodes: {t:.3f} s round trip, run {report['wall_time_s']:.3f} s, "
                      f"{len(out['HangingNet'])} ropes", flush=True)
            cached, _ = round_trip(server.url, data)
            rest = statistics.median(t - r for t, r in zip(times, runs))
            rows.append(((n + 1) ** 2, len(out["HangingNet"]), statistics.median(times), min(times), max(times),
                         statistics.median(runs), rest, cached, load))
            print(f"  cached: {cached * 1e3:.1f} ms", flush=True)
    finally:
        server.shutdown()
        server.server_close()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    lines = [
        "# Hops server latency: FormFind round trips",
        "",
        f"`OPENBLAS_NUM_THREADS=1 python benchmarks/bench_hops.py --rounds {args.rounds}` on {platform.machine()}, "
        f"{os.cpu_count()} cores (load average {load:.2f} at the end), Python {platform.python_version()}.",
        "",
        "A warm server in the same process; one round trip is encoding the inputs as Hops does, POST /solve, "
        "the run, and decoding every output (lines, shell mesh, numbers). Nets: a 10 m square hung from its "
        "boundary, slack 0.05 (changed by 1e-4 each round, so every round is a new run). Run: the server's "
        "`wall_time_s` of the analysis (relaxation, inversion, files). Rest: the round trip less the run "
        "(inputs, scene, reading the meshes back, encoding the outputs, HTTP, the client's decoding).",
        "",
        "| nodes | ropes | round trip median [s] | min [s] | max [s] | of which the run [s] | rest [s] "
        "| repeated request (cache) [ms] | load average before |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for nodes, ropes, med, lo, hi, run, rest, cached, load in rows:
        lines.append(f"| {nodes:,} | {ropes:,} | {med:.3f} | {lo:.3f} | {hi:.3f} | {run:.3f} | {rest:.3f} "
                     f"| {cached * 1e3:.1f} | {load:.2f} |")
    lines += ["", "Target: under 0.3 s for 1e3 nodes, so that a slider feels live.", ""]
    OUT.write_text("\n".join(lines))
    print(f"written {OUT}")


if __name__ == "__main__":
    main()
