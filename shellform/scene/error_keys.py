"""Errors that name the scene key they are about."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from ..errors import ModelError, SceneError


def support_key(scene: dict, i: int, key: str = "") -> str:
    """The scene key of supports entry ``i`` as the file wrote it ([supports] or [[supports]])."""
    base = "supports" if scene.get("single_support") else f"supports[{i}]"
    return f"{base}.{key}" if key else base


@contextmanager
def scene_error_at(where: str) -> Iterator[None]:
    """Report a :class:`ModelError` raised inside as a :class:`SceneError` of the key ``where``.

    The model checks values it is given without knowing where in the scene they came
    from; this names the key for the user.
    """
    try:
        yield
    except ModelError as exc:
        raise SceneError(where, str(exc)) from None
