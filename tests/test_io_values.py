"""The one converter of numbers to file values (hierplan_opt.io.values.plain, issue 31)."""

from __future__ import annotations

import json
import math
from enum import Enum

import numpy as np
import pytest
import yaml

from hierplan_opt.io.values import plain
from hierplan_opt.io.yaml import read_yaml


class Colour(Enum):
    RED = "red"


@pytest.mark.parametrize(
    "bad", [math.inf, -math.inf, math.nan, np.float64("inf"), np.float32("nan")]
)
def test_non_finite_floats_become_null_everywhere(bad: float) -> None:
    for kw in ({}, {"digits": 3}, {"significant": 6}, {"digits": 9, "integral": True}):
        assert plain(bad, **kw) is None
        assert plain({"x": [bad, (1.0, bad)]}, **kw) == {
            "x": [None, [1, None] if kw.get("integral") else [1.0, None]]
        }


def test_numpy_types_become_python_types() -> None:
    out = plain(
        {
            np.int64(3): np.int32(4),
            "f": np.float32(0.5),
            "b": np.bool_(False),
            "a": np.array([[1, 2], [3, 4]], dtype=np.int16),
            "z": np.array(2.5),
            "e": Colour.RED,
            "t": (np.uint8(1), None, "s", True),
        }
    )
    assert out == {
        "3": 4,
        "f": 0.5,
        "b": False,
        "a": [[1, 2], [3, 4]],
        "z": 2.5,
        "e": "red",
        "t": [1, None, "s", True],
    }
    kinds = {k: type(v) for k, v in out.items()}
    assert kinds["3"] is int and kinds["f"] is float and kinds["b"] is bool and kinds["z"] is float
    assert type(out["a"][0][0]) is int and type(out["t"][0]) is int
    # a bool stays a bool (it is an int subclass), never 0/1
    assert plain(True) is True and plain(np.bool_(True)) is True


def test_rounding_options() -> None:
    assert plain(0.1234567, digits=3) == 0.123
    assert plain(123456.789, significant=6) == 123457.0
    assert plain(2.0000000001, digits=9, integral=True) == 2
    assert type(plain(2.0000000001, digits=9, integral=True)) is int
    assert type(plain(2.0)) is float  # integral only when asked
    assert plain(1e20, integral=True) == 1e20 and type(plain(1e20, integral=True)) is float


def test_strict_refuses_objects_and_deep_nesting() -> None:
    assert plain(object, strict=False) is object
    with pytest.raises(TypeError):
        plain({"x": object()}, strict=True)
    # the number in [[[1]]] lies three levels down
    assert plain([[[1]]], strict=True, max_depth=3) == [[[1]]]
    with pytest.raises(TypeError):
        plain([[[1]]], strict=True, max_depth=2)


def test_output_is_safe_for_yaml_and_strict_json(tmp_path) -> None:
    tree = plain({"m": np.float64(1.5), "bad": np.inf, "v": np.arange(3), "n": math.nan})
    text = json.dumps(tree, allow_nan=False)  # would raise on inf / nan
    assert json.loads(text) == tree
    f = tmp_path / "s.yaml"
    f.write_text(yaml.safe_dump(tree))  # safe_dump refuses numpy objects
    assert read_yaml(f) == tree


def test_line_tracking_mappings_become_plain_dicts(tmp_path) -> None:
    f = tmp_path / "a.yaml"
    f.write_text("a: {b: [1, 2.5, .inf]}\n")
    data = read_yaml(f)
    out = plain(data)
    assert out == {"a": {"b": [1, 2.5, None]}}
    assert type(out) is dict and type(out["a"]) is dict and type(out["a"]["b"]) is list
