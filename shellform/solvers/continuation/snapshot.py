"""The checkpoint of a continuation run: what a resume needs to go on exactly as the run would have.

The tracer's scalars, its path table, events and states, the history of effects
that carry one (rod reference frames) and a fingerprint of the model and the
settings that change the answer. The solver never touches a file: it hands
the arrays to the checkpoint it is given (a :class:`Checkpoint`, for example
:class:`shellform.io.checkpoint.CheckpointFile`), and reads them back from it.
"""

from __future__ import annotations

import json
from typing import Protocol

import numpy as np

from ...assembly import stack_histories, unstack_histories
from ...errors import CheckpointMismatch
from ...fingerprint import check_fingerprint, fingerprint_record, model_fingerprint
from .results import PathEvent

CHECKPOINT_VERSION = 2  # 2: the states' rod frames are kept with them


class Checkpoint(Protocol):
    """Where a continuation run saves what it needs to go on (:class:`shellform.io.checkpoint.CheckpointFile`).

    ``every``: accepted steps between two saves (0: only at the end);
    ``resume``: continue from a saved state when there is one; ``exists()``:
    whether there is; ``write(**arrays)``: save named arrays; ``read()``: the
    saved arrays, as a context manager with ``files`` and item access.
    """

    every: int
    resume: bool

    def exists(self) -> bool: ...

    def write(self, **arrays) -> None: ...

    def read(self): ...


def save(tr, checkpoint: Checkpoint):
    """Save the tracer's state, its path so far and a fingerprint of the model and the settings."""
    meta = {
        "version": CHECKPOINT_VERSION, "control": tr.control, "n_dof": int(tr.system.n_dof),
        "n_free": int(tr.free.size), "step": int(tr.step), "branch": int(tr.branch),
        "s": float(tr.s), "p": float(tr.p), "t_dp": float(tr.t_dp), "ds": float(tr.ds),
        "ds_min": float(tr.ds_min), "ds_max": float(tr.ds_max), "c2": float(tr.c2),
        "kbar": float(tr.kbar), "round_floor": float(tr.round_floor), "n_neg": int(tr.n_neg), "rejected": int(tr.rejected),
        "newton_total": int(tr.newton_total), "switches": int(tr.switches),
        "events": [e.to_dict() for e in tr.events], "monitors": list(tr.monitors),
        "finished": tr.finished,
    }
    arrays = {f"table_{k}": np.asarray(v, dtype=float) for k, v in tr.table.items()}
    n_ev = len(tr.events)
    n, nt = tr.system.n_dof, tr.free.size + 1
    arrays["event_modes"] = np.array([e.mode for e in tr.events]).reshape(n_ev, n)
    arrays["event_states"] = np.array([e.q for e in tr.events]).reshape(n_ev, n)
    arrays["event_reactions"] = np.array([e.reactions for e in tr.events]).reshape(n_ev, n)
    arrays["event_tangents"] = np.array([e.tangent for e in tr.events]).reshape(n_ev, nt)
    for k, obj in enumerate(tr.history_objects()):
        for name, value in obj.state().items():
            arrays[f"history{k}_{name}"] = np.asarray(value)
    meta["history_objects"] = len(tr.history_objects())
    # the states of the points so far: a resumed run then has all of them, as an uninterrupted one
    arrays["states"] = np.array(tr.states, dtype=float).reshape(len(tr.states), n)
    arrays["state_steps"] = np.asarray(tr.state_steps, dtype=np.int64)
    # with the rod frames each was found with (and those of the events' states)
    arrays.update(stack_histories("state_history", tr.state_histories))
    arrays.update(stack_histories("event_history", [e.history for e in tr.events]))

    # what the path depends on, so that a resume of another model or other settings is
    # refused: every option but the step budget and what is kept in memory
    settings = tr.o.settings()
    settings.update(control=tr.control, monitors=sorted(tr.monitors))
    meta["fingerprint"] = json.loads(fingerprint_record(model_fingerprint(tr.system), settings))
    checkpoint.write(meta=np.array(json.dumps(meta)), q=tr.q, t_du=tr.t_du, **arrays)


def load(tr, checkpoint: Checkpoint):
    """Restore the tracer from a checkpoint written by :func:`save`; a checkpoint of another model or
    other settings is refused, naming what differs."""
    path = getattr(checkpoint, "path", "checkpoint")
    with checkpoint.read() as z:
        meta = json.loads(str(z["meta"]))
        if meta.get("version") != CHECKPOINT_VERSION:
            raise CheckpointMismatch(f"checkpoint {path}: unsupported version {meta.get('version')}")
        if meta["control"] != tr.control or meta["n_dof"] != tr.system.n_dof or meta["n_free"] != tr.free.size:
            raise CheckpointMismatch(
                f"checkpoint {path} belongs to a different problem (control {meta['control']}, "
                f"{meta['n_dof']} DOFs, {meta['n_free']} free; this run: control {tr.control}, "
                f"{tr.system.n_dof} DOFs, {tr.free.size} free)"
            )
        if meta["monitors"] != list(tr.monitors):
            raise CheckpointMismatch(f"checkpoint {path}: monitors {meta['monitors']} differ from {list(tr.monitors)}")

        settings = tr.o.settings()
        settings.update(control=tr.control, monitors=sorted(tr.monitors))
        check_fingerprint(path, meta.get("fingerprint"), model_fingerprint(tr.system), settings)
        for k in tr.table:
            col = z[f"table_{k}"]
            tr.table[k] = [int(x) for x in col] if k in ("step", "branch", "n_negative", "iterations") else list(col)
        tr.q = z["q"].copy()
        tr.t_du = z["t_du"].copy()
        if "states" in z.files:
            tr.states = list(z["states"])
            tr.state_steps = [int(k) for k in z["state_steps"]]
            tr.state_histories = unstack_histories(z, "state_history", len(tr.states), path)
        modes, states, reacts, tans = z["event_modes"], z["event_states"], z["event_reactions"], z["event_tangents"]
        histories = unstack_histories(z, "event_history", len(meta["events"]), path)
        objs = tr.history_objects()
        if meta.get("history_objects", 0) != len(objs):
            raise CheckpointMismatch(
                f"checkpoint {path} holds history for {meta.get('history_objects', 0)} objects, "
                f"this system has {len(objs)}"
            )
        for k, obj in enumerate(objs):
            prefix = f"history{k}_"
            obj.restore({key[len(prefix):]: z[key].copy() for key in z.files if key.startswith(prefix)})
    for k in ("step", "branch", "s", "p", "t_dp", "ds", "ds_min", "ds_max", "c2", "kbar", "round_floor", "n_neg", "rejected",
              "newton_total", "switches"):
        setattr(tr, k, meta[k])
    tr.u = tr.q[tr.free].copy()
    tr.finished = tuple(meta["finished"]) if meta.get("finished") else None
    tr.events = [
        PathEvent(**ev, mode=modes[i], q=states[i], reactions=reacts[i], tangent=tans[i], history=histories[i])
        for i, ev in enumerate(meta["events"])
    ]
