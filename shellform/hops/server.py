"""An HTTP server for Grasshopper's Hops component (``shellform serve``).

``GET /`` lists the components, ``GET /<name>`` describes one, ``POST
/solve`` (or ``POST /<name>``) solves one (:mod:`shellform.hops.protocol`).
Every reply is JSON. A request whose inputs the component refuses gets a
reply with status 200 whose ``errors`` name the input, the scene key and the
problem (Grasshopper shows them on the component); an unknown component gets
404, a body that is not JSON 400, and a fault of the server 500 with one line
of text: never a traceback.

Runs go one at a time (the mesher is not thread-safe) into folders the server
makes under its own temporary folder (in memory where the system has
``/dev/shm``), deleted once the reply is built; the files a component's
scene reads (a mesh given as a net) are written there by the server too. A repeated request with the
same inputs is answered from a cache of the last replies. A run stops at its
next progress report once the client has closed the connection (Hops gives
up after its HTTP timeout) or after ``timeout`` seconds.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import select
import shutil
import socket
import sys
import tempfile
import threading
import time
import traceback
from collections import OrderedDict
from collections.abc import Callable
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

from ..errors import MechanismError, SceneError, ShellformError
from .components import COMPONENTS, Component
from .protocol import InputError, decode_tree, encode_tree

#: replies kept for repeated requests
CACHE_SIZE = 64
#: largest request body read [bytes]
MAX_BODY = 512 * 2**20
#: seconds between two looks at the client's connection during a run
_POLL = 0.05


class RunStopped(Exception):
    """A run stopped on the server's request (the client left, or the time ran out)."""


def _fast_tmp() -> str | None:
    shm = Path("/dev/shm")
    return str(shm) if shm.is_dir() and os.access(shm, os.W_OK) else None


class HopsApp:
    """The components, the run folders and the cache of replies; independent of HTTP.

    Parameters
    ----------
    components : dict name -> Component
    timeout : float, optional
        Stop a run after this many seconds.
    cache_size : int
        Replies kept for repeated requests.
    """

    def __init__(self, components: dict | None = None, timeout: float | None = None, cache_size: int = CACHE_SIZE):
        self.components: dict[str, Component] = dict(components or COMPONENTS)
        self.timeout = timeout
        self.cache_size = cache_size
        self.cache: OrderedDict[str, dict] = OrderedDict()
        self.root = Path(tempfile.mkdtemp(prefix="shellform-hops-", dir=_fast_tmp()))
        self._run_lock = threading.Lock()
        self._cache_lock = threading.Lock()
        self.counts = {"runs": 0, "cache_hits": 0}

    def close(self) -> None:
        shutil.rmtree(self.root, ignore_errors=True)

    def listing(self) -> list[dict]:
        return [c.describe() for c in self.components.values()]

    def description(self, name: str) -> dict | None:
        c = self.components.get(name.strip("/"))
        return None if c is None else c.describe()

    def solve(self, body: bytes, name: str | None = None, stop: Callable[[], bool] = lambda: False
              ) -> tuple[int, dict]:
        """The status and reply of a solve request (``name``: of ``POST /<name>``, else the body's pointer)."""
        try:
            request = json.loads(body)
            if not isinstance(request, dict):
                raise ValueError("not a JSON object")
        except ValueError as exc:
            return 400, _errors(f"the request is not a Hops solve request: {exc}")
        pointer = str(name or request.get("pointer") or "")
        component = self.components.get(pointer.rstrip("/").rsplit("/", 1)[-1])
        if component is None:
            return 404, _errors(f"no component {pointer[:80]!r}; components: {', '.join(self.components)}")
        trees = request.get("values") or []
        if not isinstance(trees, list) or not all(isinstance(t, dict) for t in trees):
            return 400, _errors("values: expected a list of data trees")
        key = hashlib.sha256(json.dumps([component.name, sorted(
            (str(t.get("ParamName")), json.dumps(t.get("InnerTree"), sort_keys=True)) for t in trees)]).encode()
        ).hexdigest()
        with self._cache_lock:
            if key in self.cache:
                self.cache.move_to_end(key)
                self.counts["cache_hits"] += 1
                return 200, self.cache[key]
        try:
            reply = self._run(component, trees, stop)
        except InputError as exc:
            return 200, _errors(str(exc))
        except RunStopped as exc:
            return 200, _errors(f"{component.name}: {exc}")
        except ShellformError as exc:
            return 200, _errors(f"{component.name}: {exc}")
        except Exception as exc:  # noqa: BLE001 (a fault of the server: logged here, one line to the client)
            traceback.print_exc(file=sys.stderr)
            return 500, _errors(f"{component.name}: internal error ({type(exc).__name__}: {exc})")
        with self._cache_lock:
            self.cache[key] = reply
            while len(self.cache) > self.cache_size:
                self.cache.popitem(last=False)
        return 200, reply

    def _run(self, component: Component, trees: list, stop) -> dict:
        from ..api import run

        given = {str(t.get("ParamName")): t for t in trees}
        known = {p.name: p for p in component.inputs}
        unknown = [n for n in given if n not in known]
        if unknown:
            raise InputError(unknown[0][:60], f"{component.name} has no such input; inputs: {', '.join(known)}")
        values = {}
        for p in component.inputs:
            value = decode_tree(p, given[p.name]) if p.name in given else None
            values[p.name] = p.default if value is None else value
        built = component.build(values)
        folder = Path(tempfile.mkdtemp(prefix=f"{component.name}-", dir=self.root))
        try:
            scene = _parse(built, folder / "input", component.name)
            with self._run_lock:
                try:
                    result = run(scene, out=folder / "run", progress=self._watch(stop))
                except (SceneError, MechanismError) as exc:
                    # found while building or solving the model: name the input it comes from, as a check would
                    key = getattr(exc, "key", "supports")
                    raise InputError(_input_of(key, built.inputs) or component.name, str(exc)) from None
                self.counts["runs"] += 1
                outputs = component.reply(result, values, built.context)
        finally:
            shutil.rmtree(folder, ignore_errors=True)
        reply = {"values": [encode_tree(p, outputs[p.name]) for p in component.outputs if p.name in outputs],
                 "errors": [], "warnings": list(result.warnings)}
        if not result.converged:
            reply["warnings"].insert(0, f"not converged: {result.message}")
        return reply

    def _watch(self, stop: Callable[[], bool]) -> Callable[[str], None]:
        """A progress callable that stops the run when the client has gone or the time is up."""
        start = last = time.monotonic()

        def progress(message: str) -> None:
            nonlocal last
            now = time.monotonic()
            if now - last < _POLL:
                return
            last = now
            if self.timeout is not None and now - start > self.timeout:
                raise RunStopped(f"stopped after {self.timeout:g} s (the server's --timeout)")
            if stop():
                raise RunStopped("stopped: the client closed the connection")

        return progress


def _parse(built, folder: Path, name: str) -> dict:
    """The checked scene of a built component: its files written into ``folder``, which it is read from."""
    from ..scene import parse_scene

    if built.files:
        folder.mkdir()
        for file, write in built.files.items():
            write(folder / file)
    try:
        return parse_scene(_given(built.scene), base_dir=folder)
    except SceneError as exc:
        raise InputError(_input_of(exc.key, built.inputs) or name, str(exc)) from None


def _given(data):
    """A scene without the keys of unconnected inputs (None): absent, so the scene's defaults and checks apply."""
    if isinstance(data, dict):
        return {k: _given(v) for k, v in data.items() if v is not None}
    if isinstance(data, list):
        return [_given(v) for v in data]
    return data


def _input_of(key: str, inputs: dict) -> str | None:
    """The input that fills a scene key (the longest matching prefix), if any."""
    bare = re.sub(r"\[\d+\]", "", key)
    hits = [k for k in inputs if bare == k or bare.startswith(k + ".")]
    return inputs[max(hits, key=len)] if hits else None


def _errors(message: str) -> dict:
    return {"values": [], "errors": [message], "warnings": []}


def _peer_closed(sock) -> bool:
    """Whether the other end of a connection has closed it (its request was read in full)."""
    try:
        readable, _, _ = select.select([sock], [], [], 0)
        return bool(readable) and sock.recv(1, socket.MSG_PEEK) == b""
    except (OSError, ValueError):
        return True


class _Handler(BaseHTTPRequestHandler):
    app: HopsApp
    verbose = False
    protocol_version = "HTTP/1.1"

    def log_message(self, format, *args):  # noqa: A002 (the base class's name)
        if self.verbose:
            sys.stderr.write(f"{self.address_string()} {format % args}\n")

    def _send(self, status: int, payload) -> None:
        data = json.dumps(payload).encode()
        self.log_request(status, len(data))
        reason = self.responses.get(status, ("",))[0]
        head = (f"{self.protocol_version} {status} {reason}\r\nServer: shellform\r\nContent-Type: application/json\r\n"
                f"Content-Length: {len(data)}\r\n\r\n").encode()
        # MSG_NOSIGNAL: a client that has gone is an error here, never a SIGPIPE (the mesher's library may
        # have set SIGPIPE back to its default, which ends the process)
        self.connection.sendall(head + data, socket.MSG_NOSIGNAL)

    def do_GET(self):  # noqa: N802 (http.server's name)
        path = self.path.split("?", 1)[0]
        if path in ("/", ""):
            return self._send(200, self.app.listing())
        described = self.app.description(path)
        if described is None:
            return self._send(404, _errors(f"no component {path[:80]!r}; components: "
                                           f"{', '.join(self.app.components)}"))
        return self._send(200, described)

    def do_POST(self):  # noqa: N802
        path = self.path.split("?", 1)[0].rstrip("/")
        try:
            length = int(self.headers.get("Content-Length", "0"))
        except ValueError:
            length = -1
        if not 0 <= length <= MAX_BODY:
            self.close_connection = True
            return self._send(400, _errors(f"the request needs a Content-Length of at most {MAX_BODY} bytes"))
        body = self.rfile.read(length)
        name = None if path in ("/solve", "") else path
        status, reply = self.app.solve(body, name, stop=lambda: _peer_closed(self.connection))
        try:
            self._send(status, reply)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the client has gone


class HopsServer(ThreadingHTTPServer):
    """A threading HTTP server of a :class:`HopsApp` (``server_address`` port 0: a free port)."""

    daemon_threads = True

    def __init__(self, address: tuple[str, int], app: HopsApp | None = None, verbose: bool = False):
        self.app = app or HopsApp()
        handler = type("Handler", (_Handler,), {"app": self.app, "verbose": verbose})
        super().__init__(address, handler)

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
        return f"http://{host}:{port}"

    def server_close(self) -> None:
        super().server_close()
        self.app.close()


def start(host: str = "127.0.0.1", port: int = 0, **app_options) -> tuple[HopsServer, threading.Thread]:
    """A server serving in a background thread (``port`` 0: a free port); stop it with ``shutdown()``."""
    server = HopsServer((host, port), HopsApp(**app_options))
    thread = threading.Thread(target=server.serve_forever, name="shellform-hops", daemon=True)
    thread.start()
    return server, thread
