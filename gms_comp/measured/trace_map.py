"""The column mapping of a trace: a canonical column as arithmetic over the file's columns.

``--map position_m=pos_mm*0.001`` names, for one canonical column, an expression over the
source file's columns (CSV header names, MATLAB variable names) and numbers. Nothing is
evaluated by Python: a small grammar is parsed here and applied to the arrays.

Grammar (``+ - * /``, parentheses, unary signs; usual precedence)::

    expr   := term (("+" | "-") term)*
    term   := unary (("*" | "/") unary)*
    unary  := ("+" | "-") unary | atom
    atom   := NUMBER | NAME | "(" expr ")"

A NUMBER is a decimal number (``0.001``, ``1e-6``). A NAME is a double-quoted name
(``"t[ms]"``; a quote inside is doubled, as in CSV), a header name written as it is
(``t[ms]``, ``pos (um)``, ``F/N``: the longest header name that starts there and ends
before an operator, a space or the end), or an identifier (``[A-Za-z_][A-Za-z0-9_]*``).
The longest token wins: a header name over the operators inside it (with a column
``a-b`` the expression ``a-b`` is that column; write ``"a"-"b"`` for the difference) and
over a number it starts with (``0/``); a number over a header name as long (a column
named ``1`` must be quoted). Expressions are bounded in length and nesting; a division
by the number zero is refused when parsed, one by a column that holds a zero gives a
non-finite value that the loader then refuses with its row.
"""

from __future__ import annotations

import math
import re
from collections.abc import Collection, Mapping
from dataclasses import dataclass

import numpy as np

from gms_comp.arrays import FloatArray
from gms_comp.errors import TraceError

#: Characters of one mapping expression (a product of a few names and scales needs tens).
MAX_MAP_CHARS = 256
#: Nesting of parentheses and unary signs in a mapping expression (the parser recurses
#: once per level).
MAX_MAP_DEPTH = 16

_NUMBER = re.compile(r"(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
# An integer written with leading zeros (``01``): Python refuses it (an old octal form);
# so does this reader, rather than guess what was meant. ``00``, ``01.5``, ``01e3`` are fine.
_LEADING_ZEROS = re.compile(r"0+[1-9]\d*")
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_OPERATORS = "+-*/()"
_ENDS_NAME = frozenset(" \t*/+-)")


@dataclass(frozen=True)
class Number:
    """A constant."""

    value: float


@dataclass(frozen=True)
class Column:
    """A source column (or MATLAB variable) by its name."""

    name: str


@dataclass(frozen=True)
class Negated:
    """``-operand``."""

    operand: Node


@dataclass(frozen=True)
class Binary:
    """``left op right`` for op in ``+ - * /``."""

    op: str
    left: Node
    right: Node


Node = Number | Column | Negated | Binary


def parse(text: str, names: Collection[str], where: str) -> Node:
    """The expression ``text`` over the source columns ``names``.

    Raises
    ------
    TraceError
        One line naming ``where`` (e.g. ``--map force_N=...``) and what is wrong.
    """
    if len(text) > MAX_MAP_CHARS:
        raise TraceError(where, "", f"{len(text)} characters, more than {MAX_MAP_CHARS}")
    tokens = _tokens(text, sorted(names, key=len, reverse=True), where)
    if not tokens:
        raise TraceError(where, "", "empty expression")
    node, at = _Parser(tokens, where).expression(0, 0)
    if at != len(tokens):
        raise TraceError(where, "", f"unexpected {_shown(tokens[at])} after a complete term")
    if not sources(node):
        raise TraceError(where, "", "names no column of the file (only numbers)")
    return node


def sources(node: Node) -> set[str]:
    """The source columns an expression reads."""
    if isinstance(node, Column):
        return {node.name}
    if isinstance(node, Negated):
        return sources(node.operand)
    if isinstance(node, Binary):
        return sources(node.left) | sources(node.right)
    return set()


def evaluate(node: Node, columns: Mapping[str, FloatArray]) -> FloatArray | float:
    """The expression's value: an array for a column (a 1-element one, such as EMPS's
    ``gtau``, is a scalar), numpy arithmetic for the operators."""
    if isinstance(node, Number):
        return node.value
    if isinstance(node, Column):
        data = columns[node.name]
        return float(data[0]) if data.size == 1 else data
    if isinstance(node, Negated):
        return -evaluate(node.operand, columns)
    left, right = evaluate(node.left, columns), evaluate(node.right, columns)
    with np.errstate(all="ignore"):  # a non-finite result is refused with its row
        if node.op == "+":
            return left + right
        if node.op == "-":
            return left - right
        if node.op == "*":
            return left * right
        return np.true_divide(left, right)


def scaled(text: str, factor: float) -> str:
    """``text`` times ``factor``, as a mapping to suggest (``pos*0.001``)."""
    simple = _IDENTIFIER.fullmatch(text) or (text.startswith('"') and text.count('"') == 2)
    return f"{text if simple else f'({text})'}*{factor:g}"


def quoted(name: str) -> str:
    """``name`` as the expression that reads it: bare if an identifier, else quoted."""
    return name if _IDENTIFIER.fullmatch(name) else '"' + name.replace('"', '""') + '"'


# --- tokens and parser -------------------------------------------------------------------

Token = tuple[str, object]  # ("num", float) | ("name", str) | ("op", str)


def _tokens(text: str, names: list[str], where: str) -> list[Token]:
    out: list[Token] = []
    i = 0
    while i < len(text):
        ch = text[i]
        if ch in " \t":
            i += 1
        elif ch == '"':
            i = _quoted(text, i, where, out)
        elif (token := _longest(text, i, names)) is not None:
            kind, value, i = token
            if kind == "num" and not math.isfinite(float(value)):
                raise TraceError(where, "", f"number {value} is not finite")
            if kind == "num" and _LEADING_ZEROS.fullmatch(value):
                raise TraceError(where, "", f"number {value} has leading zeros: write "
                                 f"{value.lstrip('0')}")  # fmt: skip
            out.append((kind, float(value) if kind == "num" else value))
        elif ch in _OPERATORS:
            out.append(("op", ch))
            i += 1
        elif identifier := _IDENTIFIER.match(text, i):
            name = identifier.group()
            if names and name not in names:
                raise TraceError(where, "", _not_a_column(name, names))
            out.append(("name", name))
            i = identifier.end()
        else:
            rest = text[i:]
            raise TraceError(
                where, "", f"{rest[:20]!r} is neither a column name nor a number, nor one of "
                f"+ - * / ( ){_header_hint(names)}",
            )  # fmt: skip
    return out


def _quoted(text: str, start: int, where: str, out: list[Token]) -> int:
    """Read the quoted name at ``start``; return the index after it."""
    name, i = [], start + 1
    while True:
        end = text.find('"', i)
        if end < 0:
            raise TraceError(where, "", f"quote opened at character {start + 1} is not closed")
        name.append(text[i:end])
        if text.startswith('"', end + 1):  # a doubled quote stands for one
            name.append('"')
            i = end + 2
            continue
        out.append(("name", "".join(name)))
        return end + 1


def _longest(text: str, i: int, names: list[str]) -> tuple[str, str, int] | None:
    """The number or the header name written at ``text[i:]``, whichever is longer (a
    number on a tie): ``0/`` is the column ``0/``, ``1e-6`` the number even beside a
    column ``1e``. Returns (kind, text, end) or None."""
    number = _NUMBER.match(text, i)
    header = _header_name(text, i, names)
    if number is not None and (header is None or number.end() - i >= len(header)):
        return "num", number.group(), number.end()
    if header is not None:
        return "name", header, i + len(header)
    return None


def _header_name(text: str, i: int, names: list[str]) -> str | None:
    """The longest of ``names`` written at ``text[i:]`` and ending at an operator, a
    space or the end (so ``a`` is not read out of ``ab``)."""
    for name in names:  # longest first
        end = i + len(name)
        if name and text.startswith(name, i) and (end == len(text) or text[end] in _ENDS_NAME):
            return name
    return None


def _not_a_column(name: str, names: Collection[str]) -> str:
    return f"{name!r} is neither a column name nor a number{_header_hint(names)}"


def _header_hint(names: Collection[str]) -> str:
    if not names:
        return ""
    shown = ", ".join(list(names)[:12]) + (", ..." if len(names) > 12 else "")
    return f' (the file\'s columns: {shown}; names may be quoted: "pos (um)")'


def _shown(token: Token) -> str:
    kind, value = token
    return f"{value!r}" if kind != "num" else f"number {value:g}"


class _Parser:
    """Recursive descent over the tokens; ``depth`` bounds the recursion."""

    def __init__(self, tokens: list[Token], where: str) -> None:
        self.tokens = tokens
        self.where = where

    def expression(self, at: int, depth: int) -> tuple[Node, int]:
        node, at = self.term(at, depth)
        while self._op(at) in ("+", "-"):
            op = str(self.tokens[at][1])
            right, at = self.term(at + 1, depth)
            node = Binary(op, node, right)
        return node, at

    def term(self, at: int, depth: int) -> tuple[Node, int]:
        node, at = self.unary(at, depth)
        while self._op(at) in ("*", "/"):
            op = str(self.tokens[at][1])
            right, at = self.unary(at + 1, depth)
            if op == "/" and right == Number(0.0):
                raise TraceError(self.where, "", "division by zero")
            node = Binary(op, node, right)
        return node, at

    def unary(self, at: int, depth: int) -> tuple[Node, int]:
        if depth > MAX_MAP_DEPTH:
            raise TraceError(self.where, "", f"nested more than {MAX_MAP_DEPTH} deep")
        if self._op(at) in ("+", "-"):
            operand, end = self.unary(at + 1, depth + 1)
            return (Negated(operand) if self.tokens[at][1] == "-" else operand), end
        return self.atom(at, depth)

    def atom(self, at: int, depth: int) -> tuple[Node, int]:
        if at >= len(self.tokens):
            raise TraceError(self.where, "", "ends where a name or a number is expected")
        kind, value = self.tokens[at]
        if kind == "num":
            return Number(float(value)), at + 1  # type: ignore[arg-type]
        if kind == "name":
            return Column(str(value)), at + 1
        if value == "(":
            node, end = self.expression(at + 1, depth + 1)
            if self._op(end) != ")":
                raise TraceError(self.where, "", "a parenthesis is not closed")
            return node, end + 1
        raise TraceError(self.where, "", f"{value!r} where a name or a number is expected")

    def _op(self, at: int) -> str | None:
        if at < len(self.tokens) and self.tokens[at][0] == "op":
            return str(self.tokens[at][1])
        return None
