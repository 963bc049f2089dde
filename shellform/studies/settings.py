"""The settings of an imperfection study: the scene's ``[study]`` table checked against its scene."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SceneError
from ..solvers.continuation.options import ContinuationOptions


@dataclass(frozen=True)
class StudySettings:
    """What an imperfection study computes (the keys of ``[study]``, see ``shellform.scene.format.STUDY``)."""

    shapes: str
    #: amplitudes as multiples of the reference length, in increasing order
    amplitudes: tuple[float, ...]
    relative_to: str
    modes: int = 3
    signs: tuple[int, ...] = (1, -1)
    samples: int = 100
    seed: int = 0
    correlation_length: float | None = None
    fractile: float = 0.05
    confidence: float = 0.95
    max_step_angle: float = ContinuationOptions.max_angle_deg

    @property
    def random(self) -> bool:
        """Random shapes (a distribution), not the modes one by one."""
        return self.shapes != "modes"


def _amplitudes(study: dict) -> tuple[float, ...]:
    given = study["amplitudes"]
    low, high, count = study["amplitude_min"], study["amplitude_max"], study["amplitude_count"]
    if given is not None:
        if low is not None or high is not None:
            raise SceneError("study.amplitudes", "give either amplitudes or amplitude_min and amplitude_max, "
                             "not both")
        values = np.atleast_1d(np.asarray(given, dtype=float))
        if values.size == 0:
            raise SceneError("study.amplitudes", "got an empty list; expected at least one amplitude > 0")
        if np.any(values <= 0):
            raise SceneError("study.amplitudes", f"got {values[values <= 0][0]!r}; every amplitude must be > 0 "
                             "(the sign of a mode is set by study.signs)")
        if len(set(values.tolist())) != values.size:
            raise SceneError("study.amplitudes", "an amplitude is given twice")
        return tuple(sorted(values.tolist()))
    if low is None or high is None:
        raise SceneError("study.amplitudes", "the study needs its amplitudes: amplitudes = [...], or "
                         "amplitude_min and amplitude_max (with amplitude_count)")
    if high < low:
        raise SceneError("study.amplitude_max", f"got {high!r}; expected at least amplitude_min = {low!r}")
    if count == 1 or high == low:
        return (float(low),)
    space = np.geomspace if study["amplitude_spacing"] == "log" else np.linspace
    return tuple(float(v) for v in space(low, high, count))


def study_settings(scene: dict) -> StudySettings:
    """The study a checked scene asks for; raises :class:`SceneError` naming the key that does not fit.

    The scene must trace a load-controlled continuation of a bar, rope or rod
    structure without an ``[imperfection]`` of its own (the study sets one
    per sample). A scene without ``[study]`` gets the defaults, which need
    amplitudes, so it is refused with the key to add.
    """
    a = scene["analysis"]
    if a["type"] != "continuation":
        raise SceneError("analysis.type", f"got {a['type']!r}; an imperfection study traces a 'continuation' "
                         "(load control) of the perfect and of each imperfect structure")
    if a["continuation"]["control"] != "load":
        raise SceneError("analysis.continuation.control", "got 'displacement'; an imperfection study finds "
                         "the critical load factor, under load control ('load')")
    if scene["imperfection"] is not None:
        raise SceneError("imperfection", "the scene has an imperfection of its own; a study sets the "
                         "imperfection of every sample itself: remove [imperfection]")
    study = scene.get("study")
    if study is None:
        raise SceneError("study", "the scene has no [study] table; add one with at least the amplitudes "
                         "(see docs/imperfections.md)")
    shapes = study["shapes"]
    signs = {"both": (1, -1), "positive": (1,), "negative": (-1,)}[study["signs"] or "both"]
    return StudySettings(
        shapes=shapes, amplitudes=_amplitudes(study), relative_to=study["relative_to"],
        modes=study["modes"] if study["modes"] is not None else 3,
        signs=signs if shapes == "modes" else (1,),
        samples=study["samples"] if study["samples"] is not None else 1,
        seed=study["seed"] or 0, correlation_length=study["correlation_length"],
        fractile=study["fractile"], confidence=study["confidence"], max_step_angle=study["max_step_angle"])
