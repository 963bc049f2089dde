"""Outputs encoded in bulk are the text the item-by-item encoding gives."""

import json

import numpy as np
import pytest

from shellform.hops.protocol import Param, _encode, encode_tree


def _numbers(kind, text):
    d = json.loads(text)
    if kind == "Number":
        return [d]
    if kind == "Line":
        return [d[end][c] for end in ("From", "To") for c in "XYZ"]
    return [d[c] for c in "XYZ"]


def _one_by_one(param, value):
    return [_encode(param.kind, v) for v in value]


@pytest.mark.parametrize("kind, shape", [("Number", (7,)), ("Point", (7, 3)), ("Vector", (7, 3)), ("Line", (7, 2, 3))])
def test_bulk_text_is_the_item_by_item_text(kind, shape):
    rng = np.random.default_rng(3)
    value = rng.standard_normal(shape) * 10.0 ** rng.integers(-300, 300, size=shape)
    value.flat[0], value.flat[1], value.flat[-1] = -0.0, 1.0, 0.1  # signed zero, whole and short decimals
    param = Param("Out", kind, "", many=True)
    tree = encode_tree(param, value)
    texts = [item["data"] for item in tree["InnerTree"]["{0}"]]
    assert texts == _one_by_one(param, value)
    # and from a list of rows, as the components built them before
    assert [item["data"] for item in encode_tree(param, list(value))["InnerTree"]["{0}"]] == texts
    decoded = np.array([_numbers(kind, t) for t in texts])
    assert np.array_equal(decoded.reshape(shape), value)  # round trip, exactly


def test_values_that_are_not_finite_numbers_are_encoded_one_by_one():
    param = Param("Out", "Number", "", many=True)
    value = [1.5, float("nan"), 2]
    assert [i["data"] for i in encode_tree(param, value)["InnerTree"]["{0}"]] == ["1.5", "NaN", "2.0"]
    lines = Param("L", "Line", "", many=True)
    assert encode_tree(lines, [])["InnerTree"] == {"{0}": []}
    branches = encode_tree(lines, {0: np.zeros((1, 2, 3)), 1: np.ones((2, 2, 3))})["InnerTree"]
    assert [len(branches[k]) for k in ("{0}", "{1}")] == [1, 2]
