"""Small, safe expressions over the columns of a results table: the conditions and metrics of claims.

``parse(text, key, kind)`` reads ``text`` with Python's own parser and keeps only a whitelist of
constructs, so nothing is ever executed: a ``kind="condition"`` is a filter on the design, e.g.

    perception.direction_deg <= 20
    mode == "pattern" and perception.field_deg in [30, 60]
    30 <= perception.field_deg < 90 or not patterns.enabled

and a ``kind="metric"`` a number per run, a column or arithmetic on columns, e.g.
``follow_corr_max - follow_corr_before`` or ``abs(heading_change_deg) / 180``.

Allowed: column names, dotted like preset keys (``perception.field_deg``; ``n`` means ``init.n`` as
everywhere); numbers, strings in quotes, ``true``/``false`` (also ``True``/``False``); ``+ - * /``,
unary ``-``; the functions ``abs``, ``sqrt``, ``log``, ``exp``; and in conditions the comparisons
``== != < <= > >=`` (chained too), ``in [..]`` / ``not in [..]`` with a list of constants, and
``and``, ``or``, ``not``. Anything else is a :class:`~simcore.schema.ConfigError` at ``key`` saying what
is allowed: attribute access that is not a column name (``x.__class__`` is the column ``x.__class__``,
which no table has), calls of any other function (``__import__('os')``, ``eval``, methods), ``**``
(no huge powers), subscripts, lambdas, comprehensions, f-strings, walrus. An expression is at most
:data:`MAX_LENGTH` characters and :data:`MAX_DEPTH` levels deep (3,000 nested ``not`` or 20,000 ``+``
terms are refused with that figure, never a RecursionError). Evaluation is numpy arithmetic on columns:
it reads the table and nothing else, never the file system or the network.

:class:`Expression` has ``text``, ``kind``, ``names`` (the columns it reads, in order of appearance) and
``evaluate(frame) -> numpy array`` (one value per row; a condition gives booleans, NaN compares false).
Comparing a text column with a number (or a number column with text) raises :class:`ExpressionError`
naming both, so a condition is checked against a table by evaluating it. Nothing here knows about
flocking or claims.
"""
from __future__ import annotations

import ast
import operator
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from flocksweep.simcore.params import canonical_key
from flocksweep.simcore.schema import ConfigError

MAX_LENGTH = 4000   # characters of an expression
MAX_DEPTH = 60      # levels of its syntax tree
FUNCTIONS = {"abs": np.abs, "sqrt": np.sqrt, "log": np.log, "exp": np.exp}
CONSTANTS = {"true": True, "false": False, "True": True, "False": False}
ARITHMETIC = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv}
COMPARISONS = {ast.Eq: operator.eq, ast.NotEq: operator.ne, ast.Lt: operator.lt, ast.LtE: operator.le,
               ast.Gt: operator.gt, ast.GtE: operator.ge}
ALLOWED = {
    "condition": "column names, numbers, \"text\", true/false, + - * /, abs/sqrt/log/exp, comparisons "
                 "(== != < <= > >=, in [..], not in [..]) joined by and / or / not",
    "metric": "column names, numbers, + - * / and abs/sqrt/log/exp",
}


class ExpressionError(ValueError):
    """An expression cannot be evaluated on a table (a missing column, text compared with a number)."""


@dataclass(frozen=True)
class Expression:
    text: str
    kind: str
    tree: ast.AST = field(repr=False, compare=False)
    names: tuple[str, ...] = ()

    def evaluate(self, frame: pd.DataFrame) -> np.ndarray:
        """One value per row of ``frame`` (booleans for a condition); see the module docstring."""
        value = _evaluate(self.tree, frame)
        if np.ndim(value) == 0:
            value = np.full(len(frame), value)
        value = np.asarray(value)
        if self.kind == "condition":
            if value.dtype != bool:
                raise ExpressionError(f"{self.text!r} is not a condition (true or false per run)")
            return value
        return value.astype(float)


def _dotted(node) -> str | None:
    """'a.b.c' for Name/Attribute chains, else None."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name):
        parts.append(node.id)
        return ".".join(reversed(parts))
    return None


def _check(node, kind: str, key: str, names: list[str]) -> None:
    """Raise ConfigError at ``key`` for anything outside the whitelist; collect column names."""
    def refuse(what: str):
        raise ConfigError(key, f"{what} is not allowed here; allowed: {ALLOWED[kind]}")

    dotted = _dotted(node)
    if dotted is not None:
        if dotted in CONSTANTS:
            return
        name = canonical_key(dotted)
        if name not in names:
            names.append(name)
        return
    if isinstance(node, ast.Constant):
        if isinstance(node.value, bool) or isinstance(node.value, (int, float)):
            return
        if isinstance(node.value, str) and kind == "condition":
            return
        refuse(f"the constant {node.value!r}")
    elif isinstance(node, ast.BinOp) and type(node.op) in ARITHMETIC:
        _check(node.left, kind, key, names)
        _check(node.right, kind, key, names)
    elif isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        _check(node.operand, kind, key, names)
    elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in FUNCTIONS:
        if len(node.args) != 1 or node.keywords:
            refuse(f"{node.func.id}() with other than one argument")
        _check(node.args[0], kind, key, names)
    elif kind == "condition" and isinstance(node, ast.BoolOp):
        for value in node.values:
            _check(value, kind, key, names)
    elif kind == "condition" and isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
        _check(node.operand, kind, key, names)
    elif kind == "condition" and isinstance(node, ast.Compare):
        if len(node.ops) > 1 and any(isinstance(op, (ast.In, ast.NotIn)) for op in node.ops):
            refuse("'in' inside a chain of comparisons")
        _check(node.left, kind, key, names)
        for op, right in zip(node.ops, node.comparators):
            if isinstance(op, (ast.In, ast.NotIn)):
                if not isinstance(right, (ast.List, ast.Tuple)) or not all(
                        isinstance(e, ast.Constant) and not isinstance(e.value, bytes) for e in right.elts):
                    refuse("'in' with anything but a list of constants")
            elif type(op) in COMPARISONS:
                _check(right, kind, key, names)
            else:
                refuse(f"the comparison {type(op).__name__}")
    else:
        refuse(f"{ast.unparse(node)!r}")


def parse(text, key: str, kind: str) -> Expression:
    """The checked :class:`Expression` of ``text`` (``kind`` 'condition' or 'metric'); ConfigError at
    ``key`` when it is not one."""
    if kind not in ALLOWED:
        raise ValueError(f"kind: expected 'condition' or 'metric', got {kind!r}")
    if not isinstance(text, str) or not text.strip():
        raise ConfigError(key, f"got {text!r}; expected a {kind} such as "
                               + ("'perception.direction_deg <= 20'" if kind == "condition" else "'cohesion_mean'"))
    if len(text) > MAX_LENGTH:
        raise ConfigError(key, f"a {kind} of {len(text):,} characters; at most {MAX_LENGTH:,} are allowed")
    try:
        tree = ast.parse(text.strip(), mode="eval").body
    except SyntaxError as err:
        raise ConfigError(key, f"{text!r} is not a valid {kind}: {err.msg}") from None
    except (RecursionError, MemoryError, ValueError):   # nested too deeply for the parser; a huge literal
        raise ConfigError(key, f"{_short(text)} is not a valid {kind}: nested more than {MAX_DEPTH} levels deep "
                               "or a number too long") from None
    if _depth(tree) > MAX_DEPTH:
        raise ConfigError(key, f"{_short(text)}: nested more than {MAX_DEPTH} levels deep; split it into simpler "
                               f"{kind}s")
    names: list[str] = []
    _check(tree, kind, key, names)
    return Expression(text=text.strip(), kind=kind, tree=tree, names=tuple(names))


def _short(text: str) -> str:
    return repr(text if len(text) <= 60 else text[:57] + "...")


def _depth(tree: ast.AST) -> int:
    """Levels of the syntax tree (counted without recursion)."""
    deepest, todo = 0, [(tree, 1)]
    while todo:
        node, level = todo.pop()
        deepest = max(deepest, level)
        todo += [(child, level + 1) for child in ast.iter_child_nodes(node)]
    return deepest


# ------------------------------------------------------------------------------------------ evaluation

def _is_text(value) -> bool:
    array = np.asarray(value)
    return array.dtype.kind in "OUS" and array.size > 0 and isinstance(array.flat[0], str)


def _column(frame: pd.DataFrame, name: str):
    if name not in frame.columns:
        raise ExpressionError(f"no column {name!r}")
    column = frame[name]
    if pd.api.types.is_bool_dtype(column):
        return column.to_numpy(dtype=bool)
    if pd.api.types.is_numeric_dtype(column):
        return column.to_numpy(dtype=float)
    return column.astype(object).to_numpy()


def _compare(op, left, right, text: str):
    if _is_text(left) != _is_text(right):
        raise ExpressionError(f"{text}: compares text with a number")
    with np.errstate(invalid="ignore"):
        return np.asarray(COMPARISONS[type(op)](left, right), dtype=bool)


def _evaluate(node, frame: pd.DataFrame):
    dotted = _dotted(node)
    if dotted is not None:
        return CONSTANTS[dotted] if dotted in CONSTANTS else _column(frame, canonical_key(dotted))
    if isinstance(node, ast.Constant):
        return node.value
    if isinstance(node, ast.BinOp):
        left, right = _evaluate(node.left, frame), _evaluate(node.right, frame)
        if _is_text(left) or _is_text(right):
            raise ExpressionError(f"{ast.unparse(node)}: arithmetic on text")
        with np.errstate(divide="ignore", invalid="ignore"):
            return ARITHMETIC[type(node.op)](np.asarray(left, dtype=float), np.asarray(right, dtype=float))
    if isinstance(node, ast.UnaryOp):
        value = _evaluate(node.operand, frame)
        if isinstance(node.op, ast.Not):
            return ~np.asarray(value, dtype=bool)
        return -np.asarray(value, dtype=float) if isinstance(node.op, ast.USub) else np.asarray(value, dtype=float)
    if isinstance(node, ast.Call):
        with np.errstate(divide="ignore", invalid="ignore"):
            return FUNCTIONS[node.func.id](np.asarray(_evaluate(node.args[0], frame), dtype=float))
    if isinstance(node, ast.BoolOp):
        values = [np.asarray(_evaluate(v, frame), dtype=bool) for v in node.values]
        combine = np.logical_and if isinstance(node.op, ast.And) else np.logical_or
        out = values[0]
        for value in values[1:]:
            out = combine(out, value)
        return out
    if isinstance(node, ast.Compare):
        left = _evaluate(node.left, frame)
        result = np.ones(len(frame), dtype=bool)
        for op, right_node in zip(node.ops, node.comparators):
            text = ast.unparse(node)
            if isinstance(op, (ast.In, ast.NotIn)):
                choices = [e.value for e in right_node.elts]
                if choices and any(isinstance(c, str) for c in choices) != _is_text(left):
                    raise ExpressionError(f"{text}: compares text with a number")
                inside = np.isin(np.asarray(left), np.asarray(choices, dtype=object if _is_text(left) else float))
                result &= ~inside if isinstance(op, ast.NotIn) else inside
                right = None
            else:
                right = _evaluate(right_node, frame)
                result &= _compare(op, left, right, text)
            left = right
        return result
    raise ExpressionError(f"cannot evaluate {ast.unparse(node)!r}")  # parse() admits nothing else
