"""The ``--map`` grammar: arithmetic over header names as users write them, never eval.

The oracle for precedence and signs is Python's own parser (``ast.parse``, which parses and
runs nothing), walked by a few lines here; the grammar under test shares no code with it.
"""

from __future__ import annotations

import ast
import operator
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gms_comp.errors import TraceError
from gms_comp.measured import trace_map

COLUMNS = {"a": np.array([2.0, -3.0]), "b": np.array([0.5, 4.0])}
_BINARY = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv}  # fmt: skip


def _oracle(node: ast.AST) -> np.ndarray | float:
    """Python's reading of an expression of a, b, numbers, + - * / and signs."""
    if isinstance(node, ast.Expression):
        return _oracle(node.body)
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        with np.errstate(all="ignore"):
            return _BINARY[type(node.op)](_oracle(node.left), _oracle(node.right))
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd):
        value = _oracle(node.operand)
        return -value if isinstance(node.op, ast.USub) else value
    if isinstance(node, ast.Constant) and isinstance(node.value, int | float):
        return np.float64(node.value)
    if isinstance(node, ast.Name) and node.id in COLUMNS:
        return COLUMNS[node.id]
    raise ValueError("outside the grammar")


LEAVES = st.sampled_from(["a", "b", "2", "0.5", "1e-3", ".25", "3.", "7E2"])
EXPRESSIONS = st.recursive(
    LEAVES,
    lambda inner: st.one_of(
        st.tuples(inner, st.sampled_from(["+", "-", "*", "/", " * ", "- -"]), inner).map("".join),
        inner.map(lambda e: f"({e})"),
        inner.map(lambda e: f"-{e}"),
    ),
    max_leaves=8,
)


@settings(max_examples=400, deadline=None)
@given(st.one_of(EXPRESSIONS, st.text("ab0123456789.e+-*/() ", max_size=24)))
def test_any_text_parses_as_python_reads_it_or_is_refused_in_one_line(text: str) -> None:
    try:
        node = trace_map.parse(text, COLUMNS, "--map force_N=...")
    except TraceError as err:
        assert "\n" not in str(err)
        return
    expected = _oracle(ast.parse(text.strip(), mode="eval"))  # whatever we read, Python reads
    got = trace_map.evaluate(node, COLUMNS)
    np.testing.assert_array_equal(np.broadcast_to(got, (2,)), np.broadcast_to(expected, (2,)))


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("a+b*2", [3.0, 5.0]),
        ("-(a-b)/2", [-0.75, 3.5]),
        ("((((a))))*1e-3", [2e-3, -3e-3]),
        ("a--b", [2.5, 1.0]),
        ('"a"-"b"', [1.5, -7.0]),
    ],
)
def test_precedence_signs_and_quotes(text: str, expected: list[float]) -> None:
    node = trace_map.parse(text, COLUMNS, "--map")
    np.testing.assert_allclose(trace_map.evaluate(node, COLUMNS), expected)


def test_header_names_with_operators_are_read_whole_and_quoted_ones_split() -> None:
    columns = {"a-b": np.array([1.0]), "a": np.array([10.0]), "b": np.array([3.0]),
               "t[ms]": np.array([5.0]), "0/": np.array([7.0]), 'q"x': np.array([2.0])}  # fmt: skip
    for text, value in (
        ("a-b", 1.0),  # the longest name wins over the operator inside it
        ('"a"-"b"', 7.0),
        ("t[ms]*0.001", 0.005),
        ("0/*2", 14.0),  # a name that starts with a number
        ('"q""x"*3', 6.0),  # a doubled quote stands for one
        ("2*a", 20.0),
    ):
        node = trace_map.parse(text, columns, "--map")
        assert trace_map.evaluate(node, columns) == pytest.approx(value), text


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ('__import__("os").system("true")', "'__import__' is neither a column name"),
        ("a % 2", "is neither a column name nor a number, nor one of"),
        ("a*", "ends where a name or a number is expected"),
        ("(" * 20 + "a" + ")" * 20, "nested more than 16 deep"),
        ("a*" * 130 + "a", "characters, more than 256"),
        ('"a', "is not closed"),
        ("a/0", "division by zero"),
        ("1+2", "names no column"),
        ("01*a", "has leading zeros"),  # as Python refuses it
    ],
)
def test_refusals(text: str, says: str) -> None:
    with pytest.raises(TraceError, match=f"^--map: .*{re.escape(says)}"):
        trace_map.parse(text, COLUMNS, "--map")


def test_suggested_scalings_parse_back() -> None:
    for expr in ("pos", '"pos (um)"', "t[ms]", "a+b"):
        text = trace_map.scaled(expr, 1e-3)
        names = {"pos": 0, "pos (um)": 0, "t[ms]": 0, "a": 0, "b": 0}
        node = trace_map.parse(text, names, "--map")
        assert isinstance(node, trace_map.Binary) and node.op == "*"
        assert node.right == trace_map.Number(1e-3)
