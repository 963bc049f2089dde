"""What a saved state belongs to: hashes of a model's parts and of the settings of an analysis.

A checkpoint stores them (:func:`fingerprint_record`), and a resume compares
them with the run's own (:func:`check_fingerprint`), so that a state is never
continued on another model or with other settings. Nothing here reads or
writes a file: :mod:`shellform.io.checkpoint` does.
"""

from __future__ import annotations

import hashlib
import json

import numpy as np

from .errors import CheckpointMismatch

def digest(*items) -> str:
    """A short hash of arrays, numbers and strings (arrays by dtype, shape and bytes)."""
    h = hashlib.sha256()
    for item in items:
        if isinstance(item, np.ndarray) or (isinstance(item, (list, tuple)) and item and
                                            isinstance(item[0], np.ndarray)):
            arrays = [item] if isinstance(item, np.ndarray) else list(item)
            for a in arrays:
                a = np.ascontiguousarray(a)
                h.update(f"{a.dtype.str}{a.shape}".encode())
                h.update(a.tobytes())
        else:
            h.update(json.dumps(item, sort_keys=True, default=str).encode())
        h.update(b"|")
    return h.hexdigest()[:16]


def _effect_data(effect) -> tuple[list, list]:
    """An effect's integer arrays (which DOFs it couples) and its numbers (stiffness, rest shape)."""
    ints, values = [], []
    for name, v in sorted(vars(effect).items()):
        # leading underscore: caches and patterns derived from the rest
        if name.startswith("_"):
            continue
        if isinstance(v, np.ndarray) and v.dtype != object:
            (ints if np.issubdtype(v.dtype, np.integer) or v.dtype == bool else values).append((name, v))
        elif isinstance(v, (bool, int, float, str, np.generic)):
            values.append((name, v))
    return ints, values


def model_fingerprint(system, mass: np.ndarray | None = None) -> dict[str, str]:
    """Hashes of the parts of a model a saved state depends on, one per part.

    Parts: ``nodes``, ``members`` (connectivity of the member groups and of
    every effect), ``member properties`` (stiffness, rest lengths, rest
    curvature, masses per length), ``supports`` (fixed and prescribed DOFs),
    ``loads`` (load cases, gravity and every applied-load effect), ``effects``
    (which energy terms) and, when given, ``masses`` (the mass of every DOF).
    Two models agree on a part exactly when its hash agrees.
    """
    s = system.structure
    groups = s.groups
    internal = [e for e in system.effects if not getattr(e, "is_external", False)]
    external = [e for e in system.effects if getattr(e, "is_external", False)]

    def described(effects, part):
        out = []
        for e in effects:
            ints, values = _effect_data(e)
            out.append(type(e).__name__)
            out += [x for kv in (ints if part == "ints" else values) for x in (kv[0], kv[1])]
        return out

    def flat(items):
        return digest(*[x if isinstance(x, np.ndarray) else (x.item() if isinstance(x, np.generic) else x)
                        for x in items])

    parts = {
        "nodes": digest(s.nodes, int(s.n_twist)),
        "members": flat([x for g in groups for x in (g.name, g.kind, g.connectivity)] + described(internal, "ints")),
        "member properties": flat([x for g in groups for x in (g.EA, g.rest_length, g.mass_per_length)]
                                  + described(internal, "values")),
        "supports": digest(np.asarray(system.constrained), np.asarray(system.prescribed),
                           np.asarray(system.direction, dtype=float)),
        "loads": flat([x for c in s.load_cases for x in (c.forces, bool(c.scaled))]
                      + [s.gravity if s.gravity is not None else "no gravity", s.point_mass]
                      + described(external, "ints") + described(external, "values")),
        "effects": digest([type(e).__name__ for e in system.effects]),
    }
    if mass is not None:
        parts["masses"] = digest(np.asarray(mass, dtype=float))
    return parts


def plain_settings(settings: dict) -> dict:
    """Analysis settings as JSON values (arrays by their hash), as a checkpoint keeps them."""
    out = {}
    for k, v in settings.items():
        if isinstance(v, np.ndarray):
            v = "array " + digest(v)
        elif callable(v):
            v = "function"
        out[k] = json.loads(json.dumps(v, default=str))
    return out


def differences(saved_model: dict, model: dict, saved_settings: dict, settings: dict) -> list[str]:
    """What differs between a checkpoint and this run, in words."""
    found = [f"{part} differ" if part.endswith("s") else f"{part} differs"
             for part in model if saved_model.get(part) != model[part]]
    found += [f"model part {part} is not in this run" for part in saved_model if part not in model]
    settings = plain_settings(settings)
    for k in sorted(set(settings) | set(saved_settings)):
        a, b = saved_settings.get(k, "unset"), settings.get(k, "unset")
        if a != b:
            found.append(f"analysis option {k} differs: {a} in the checkpoint, {b} now")
    return found


def check_fingerprint(path, saved: dict | None, model: dict, settings: dict) -> None:
    """Refuse a checkpoint whose model or settings differ from this run's.

    ``saved`` is ``{"model": ..., "settings": ...}`` as written by
    :func:`fingerprint_record` (None: a checkpoint written without one).

    Raises
    ------
    CheckpointMismatch
        Naming every part and option that differs.
    """
    if not saved:
        raise CheckpointMismatch(f"checkpoint {path} does not say which model it belongs to (written by an "
                                 "older shellform): delete it or run without --resume")
    found = differences(saved.get("model", {}), model, saved.get("settings", {}), settings)
    if found:
        raise CheckpointMismatch(f"checkpoint {path} belongs to a different run: " + "; ".join(found)
                                 + ". Delete it or run without --resume")


def fingerprint_record(model: dict, settings: dict) -> str:
    """The JSON text a checkpoint stores to be checked by :func:`check_fingerprint`."""
    return json.dumps({"model": model, "settings": plain_settings(settings)}, sort_keys=True)
