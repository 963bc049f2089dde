"""Typed solver options given as an object, field by field, or both."""

from __future__ import annotations

import dataclasses
from typing import TypeVar

T = TypeVar("T")


def with_overrides(cls: type[T], options: T | None, overrides: dict, what: str) -> T:
    """``options`` (default: ``cls()``) with the fields named in ``overrides`` replaced.

    A name that is not a field of ``cls`` is a TypeError naming the ``what`` options, so
    that a misspelt keyword never passes silently.
    """
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = set(overrides) - names
    if unknown:
        raise TypeError(f"unknown {what} option(s): {sorted(unknown)}")
    base = options if options is not None else cls()
    return dataclasses.replace(base, **overrides) if overrides else base
