"""Exceptions raised by shellform.

Every error a user can provoke with bad input is a :class:`ModelError` (or a
subclass) whose message names the offending item and what is wrong with it.
"""


class ShellformError(Exception):
    """Base class of all shellform errors."""


class ModelError(ShellformError, ValueError):
    """The structural model is invalid (bad geometry, indices, properties)."""


class MechanismError(ModelError):
    """The structure can move as a rigid body: supports do not restrain it."""


class CheckpointMismatch(ModelError):
    """A checkpoint that cannot be resumed from: of another model or other settings, or unreadable."""


class SceneError(ShellformError, ValueError):
    """A scene file is malformed; the message names the key and the problem."""

    def __init__(self, key: str, problem: str):
        self.key = key
        self.problem = problem
        super().__init__(f"scene key '{key}': {problem}")
