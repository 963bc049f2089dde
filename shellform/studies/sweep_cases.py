"""The cases of a sweep: key paths into a scene, ``key=v1,v2`` values, and the scenes they make.

A case is the base scene with one value set at each swept key path (the
Cartesian product of the values). Its :attr:`Case.fingerprint` names what
it computes, so a finished case folder is reused only for the same case.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import re
import sys
from dataclasses import dataclass

from ..errors import SceneError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

_TOKEN = re.compile(r"([^.\[\]]+)|\[(\d+)\]")
_PATH_HELP = "not a valid key path (use dotted names and [index], e.g. members[0].EA)"


def parse_path(key: str) -> list:
    """``"members[0].EA"`` -> ``["members", 0, "EA"]``."""
    parts, pos = [], 0
    key = key.strip()
    for m in _TOKEN.finditer(key):
        if m.start() != pos and key[pos:m.start()] != ".":
            raise SceneError(key, _PATH_HELP)
        parts.append(m.group(1) if m.group(1) is not None else int(m.group(2)))
        pos = m.end()
    if not parts or pos != len(key):
        raise SceneError(key, _PATH_HELP)
    return parts


def parse_param(spec: str) -> tuple[str, list]:
    """``"key=v1,v2,..."`` -> (key, [values]); values are read as TOML values."""
    if "=" not in spec:
        raise SceneError(spec, "a sweep parameter is written key=v1,v2,...")
    key, text = spec.split("=", 1)
    parse_path(key)
    values = []
    for item in text.split(","):
        try:
            values.append(tomllib.loads(f"v = {item.strip()}")["v"])
        except tomllib.TOMLDecodeError:
            values.append(item.strip())  # a bare word is a string
    if not values or values == [""]:
        raise SceneError(key, "needs at least one value")
    return key.strip(), values


def set_value(data: dict, key: str, value) -> None:
    """Set ``value`` at the key path ``key`` of a raw scene dictionary."""
    parts = parse_path(key)
    node = data
    for i, p in enumerate(parts[:-1]):
        try:
            node = node[p]
        except (KeyError, IndexError, TypeError):
            where = "".join(f"[{q}]" if isinstance(q, int) else f".{q}" for q in parts[: i + 1]).lstrip(".")
            raise SceneError(key, f"the scene has no {where!r} to set a value in") from None
    try:
        node[parts[-1]] = value
    except (IndexError, TypeError):
        raise SceneError(key, "the scene has no such entry") from None


@dataclass(frozen=True)
class Case:
    """One scene of a sweep."""

    index: int
    #: the swept keys and this case's values, in the order given
    assignment: dict
    #: the raw scene (TOML as a dictionary) with the values set
    data: dict
    #: the folder relative file names of the scene are relative to
    base_dir: str

    @property
    def name(self) -> str:
        """The case's folder name in the sweep's output folder."""
        return f"case_{self.index:03d}"

    @property
    def fingerprint(self) -> str:
        """A digest of the scene and its base folder: equal digests compute the same case."""
        text = json.dumps({"scene": self.data, "base_dir": self.base_dir}, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()


def expand(raw: dict, params: list[tuple[str, list]], base_dir=None) -> list[Case]:
    """All combinations of the values as cases; each case's scene is validated now.

    ``base_dir`` is the folder relative file names of the scene are relative to.
    A bad value is refused here, before any case runs, naming the case.
    """
    from ..scene import parse_scene

    out = []
    keys = [k for k, _ in params]
    for i, combo in enumerate(itertools.product(*(v for _, v in params))):
        data = copy.deepcopy(raw)
        for k, v in zip(keys, combo):
            set_value(data, k, v)
        assignment = dict(zip(keys, combo))
        try:
            parse_scene(data, base_dir)
        except SceneError as exc:
            raise SceneError(exc.key, f"{exc.problem} (in the sweep case {assignment})") from None
        out.append(Case(i, assignment, data, str(base_dir)))
    return out
