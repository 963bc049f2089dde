"""Reading a scene file: a bounded regular file of UTF-8 TOML, with errors that name the file."""

from __future__ import annotations

import stat
import sys
from pathlib import Path

from ..errors import SceneError
from .schema import LIMITS

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

#: size of a scene file: a scene of two million nodes given one by one stays well below it
MAX_SCENE_BYTES = LIMITS["scene_bytes"]


def shown_path(path: Path) -> str:
    """A file name for a message (its last 200 characters)."""
    text = str(path)
    return text if len(text) <= 200 else "..." + text[-197:]


def read_scene_text(path) -> str:
    """The text of a scene file: a regular file of at most ``MAX_SCENE_BYTES``, UTF-8 encoded."""
    path = Path(path)
    where = shown_path(path)
    try:
        info = path.stat()
    except (OSError, ValueError) as exc:
        raise SceneError(where, f"cannot read the scene file ({getattr(exc, 'strerror', None) or exc})") from None
    if not stat.S_ISREG(info.st_mode):
        raise SceneError(where, "not a regular file (a directory, device or pipe cannot be a scene)")
    if info.st_size > MAX_SCENE_BYTES:
        raise SceneError(where, f"the file has {info.st_size:,} bytes; a scene may have at most "
                         f"{MAX_SCENE_BYTES:,}")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise SceneError(where, f"cannot read the scene file ({exc.strerror})") from None
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        column = exc.start - (raw.rfind(b"\n", 0, exc.start) + 1) + 1
        raise SceneError(where, f"not UTF-8 text: byte 0x{raw[exc.start]:02x} at line {line}, column {column} "
                         "(save the scene as UTF-8)") from None


def parse_toml(text: str, where: str = "scene") -> dict:
    """A TOML text as a dictionary; errors name the line and what is wrong there."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(where, f"not valid TOML: {exc}") from None
    except RecursionError:  # the parser recurses into nested arrays and inline tables
        raise SceneError(where, "not valid TOML for a scene: arrays or tables nested hundreds of levels deep "
                         "(a scene nests at most four)") from None
    except ValueError:  # an integer of thousands of digits
        raise SceneError(where, "not valid TOML for a scene: an integer of thousands of digits") from None
