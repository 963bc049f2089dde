"""Small checks shared by the tests."""

import math

import numpy as np


def all_finite(*objs) -> bool:
    """Whether every number in the arguments is finite.

    Accepts numbers, arrays, and dicts, lists and tuples of them (a JSON
    summary, a path table); anything else (strings, None, booleans) counts as
    finite.
    """
    for obj in objs:
        if isinstance(obj, dict):
            ok = all_finite(*obj.values())
        elif isinstance(obj, (list, tuple)):
            ok = all_finite(*obj)
        elif isinstance(obj, np.ndarray):
            ok = obj.dtype.kind not in "fc" or bool(np.all(np.isfinite(obj)))
        elif isinstance(obj, (float, np.floating)):
            ok = math.isfinite(obj)
        else:
            ok = True
        if not ok:
            return False
    return True
