"""Safe boundary-data expressions in ``x`` and ``y``.

An expression such as ``'exp(x)*cos(y)'`` is parsed with :mod:`ast`, checked
against a whitelist (numbers, ``+ - * / **``, unary minus, parentheses, the
functions in :data:`FUNCTIONS`, the constants ``pi`` and ``e``, the variables
``x`` and ``y``, and for a flux the outward unit normal ``nx``, ``ny`` of the
boundary) and compiled to a small postfix program. The program is
evaluated either on numpy arrays (:func:`evaluate`) or, point by point, inside
numba-compiled walks (:func:`geoproc.wos.program.eval_program`, a module of its
own so that parsing needs no numba). Nothing is ever passed to ``eval``.
"""

from __future__ import annotations

import ast
import math
from dataclasses import dataclass

import numpy as np

from geoproc.errors import UsageError

# opcodes of the postfix program
OP_CONST, OP_X, OP_Y, OP_ADD, OP_SUB, OP_MUL, OP_DIV, OP_POW, OP_NEG = range(9)
OP_SIN, OP_COS, OP_TAN, OP_EXP, OP_LOG, OP_SQRT, OP_ABS, OP_SINH, OP_COSH, OP_ATAN2 = range(9, 19)
OP_NX, OP_NY = 19, 20

FUNCTIONS = {
    "sin": OP_SIN, "cos": OP_COS, "tan": OP_TAN, "exp": OP_EXP, "log": OP_LOG,
    "sqrt": OP_SQRT, "abs": OP_ABS, "sinh": OP_SINH, "cosh": OP_COSH, "atan2": OP_ATAN2,
}
CONSTANTS = {"pi": math.pi, "e": math.e}
VARIABLES = {"x": OP_X, "y": OP_Y}
NORMAL_VARIABLES = {"nx": OP_NX, "ny": OP_NY}
"""The outward unit normal of the boundary where a flux is evaluated (``--neumann`` only)."""
PUSHES = (OP_CONST, OP_X, OP_Y, OP_NX, OP_NY)
"""Opcodes that push a value and pop none."""
_BINARY = {ast.Add: OP_ADD, ast.Sub: OP_SUB, ast.Mult: OP_MUL, ast.Div: OP_DIV, ast.Pow: OP_POW}
MAX_STACK = 32


@dataclass(frozen=True)
class Expression:
    """A compiled expression: ``code`` (k,) int64 opcodes, ``consts`` (k,) float64.

    ``consts[i]`` is the number pushed by an ``OP_CONST`` at position ``i``.
    """

    text: str
    code: np.ndarray
    consts: np.ndarray


def _integer_size(value: int) -> str:
    """``'a 401-digit'``, or ``'a 16000-bit'`` past Python's 4300 digits for writing one out."""
    try:
        return f"a {len(str(abs(value)))}-digit"
    except ValueError:
        return f"a {value.bit_length()}-bit"


def parse_expression(text: str, option: str = "--boundary", normals: bool = False) -> Expression:
    """Parse and compile ``text``; raise :class:`UsageError` naming what is wrong.

    Parameters
    ----------
    text : str
        The expression, e.g. ``'x**3 - 3*x*y**2'``.
    option : str
        Option name used in error messages.
    normals : bool
        Whether ``nx`` and ``ny``, the outward unit normal of the boundary
        segment where the expression is evaluated, may appear (a flux).
    """
    shown = f"{option} '{_shorten(text)}'"  # how every error names the expression
    too_deep = UsageError(f"{shown}: expression nested too deeply")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        raise UsageError(f"{shown}: not a valid expression ({exc.msg}"
                         + (f" at character {exc.offset}" if exc.offset else "") + ")") from None
    except (RecursionError, MemoryError):  # the parser's own nesting limit
        raise too_deep from None
    variables = VARIABLES | (NORMAL_VARIABLES if normals else {})
    names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
    unknown = sorted(names - set(FUNCTIONS) - set(CONSTANTS) - set(VARIABLES) - set(NORMAL_VARIABLES))
    normal = sorted(names & set(NORMAL_VARIABLES)) if not normals else []
    if normal and not unknown:
        raise UsageError(f"{shown}: {', '.join(normal)}, the boundary's outward normal, is for a flux "
                         "(--neumann) only")
    if unknown:
        also = f"; {', '.join(normal)}, the boundary's outward normal, is for --neumann only" if normal else ""
        raise UsageError(f"{shown}: unknown name{'s' if len(unknown) > 1 else ''} "
                         f"{', '.join(repr(u) for u in unknown)} (allowed: x, y, {'nx, ny, ' * normals}pi, e, "
                         f"{', '.join(sorted(FUNCTIONS))}){also}")
    code: list[int] = []
    consts: list[float] = []

    def emit(op: int, value: float = 0.0) -> None:
        code.append(op)
        consts.append(value)

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.Expression):
            visit(node.body)
        elif isinstance(node, ast.Constant) and type(node.value) in (int, float):
            try:
                emit(OP_CONST, float(node.value))
            except OverflowError:  # an integer literal past the float range
                raise UsageError(f"{shown}: {_integer_size(node.value)} integer is beyond the "
                                 f"floating-point range") from None
        elif isinstance(node, ast.Name):
            if node.id in variables:
                emit(variables[node.id])
            elif node.id in CONSTANTS:
                emit(OP_CONST, CONSTANTS[node.id])
            else:
                raise UsageError(f"{shown}: '{node.id}' is a function, call it with ()")
        elif isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            visit(node.left)
            visit(node.right)
            emit(_BINARY[type(node.op)])
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd):
            visit(node.operand)
            if isinstance(node.op, ast.USub):
                emit(OP_NEG)
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in variables:
            raise UsageError(f"{shown}: '{node.func.id}' is a variable, not a function")
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in CONSTANTS:
            raise UsageError(f"{shown}: '{node.func.id}' is a constant, not a function")
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in FUNCTIONS:
            name = node.func.id
            want = 2 if name == "atan2" else 1
            if node.keywords or len(node.args) != want:
                raise UsageError(f"{shown}: {name}() takes {want} argument{'s' * (want > 1)}")
            for a in node.args:
                visit(a)
            emit(FUNCTIONS[name])
        else:
            what = type(node).__name__
            if isinstance(node, ast.BinOp | ast.UnaryOp):
                what = type(node.op).__name__
            raise UsageError(f"{shown}: '{what}' is not allowed "
                             f"(numbers, x, y, {'nx, ny, ' * normals}+ - * / **, and the listed functions only)")

    try:
        visit(tree)
    except RecursionError:
        raise too_deep from None
    code_a = np.asarray(code, dtype=np.int64)
    if _stack_depth(code_a) > MAX_STACK:
        raise too_deep
    return Expression(text, code_a, np.asarray(consts, dtype=np.float64))


def _shorten(text: str, limit: int = 60) -> str:
    """``text`` cut to ``limit`` characters for a one-line message."""
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _stack_depth(code: np.ndarray) -> int:
    depth = best = 0
    for op in code:
        if op in PUSHES:
            depth += 1
        elif op in (OP_ADD, OP_SUB, OP_MUL, OP_DIV, OP_POW, OP_ATAN2):
            depth -= 1
        best = max(best, depth)
    return best


def translated(expr: Expression, dx: float, dy: float) -> Expression:
    """``expr`` as a function of coordinates relative to ``(dx, dy)``: every ``x``
    becomes ``(x + dx)`` and every ``y`` ``(y + dy)``, one stack slot deeper
    than ``expr`` (the compiled evaluator keeps one past :data:`MAX_STACK`)."""
    code: list[int] = []
    consts: list[float] = []
    for op, c in zip(expr.code.tolist(), expr.consts.tolist(), strict=True):
        code.append(op)
        consts.append(c)
        if op in (OP_X, OP_Y):
            code += [OP_CONST, OP_ADD]
            consts += [dx if op == OP_X else dy, 0.0]
    return Expression(expr.text, np.array(code, dtype=np.int64), np.array(consts, dtype=np.float64))


def is_constant(expr: Expression) -> bool:
    """Whether ``expr`` reads none of x, y, nx and ny: one value everywhere."""
    return not np.isin(expr.code, (OP_X, OP_Y, OP_NX, OP_NY)).any()


def is_zero(expr: Expression) -> bool:
    """Whether ``expr`` is the constant 0 (:func:`is_constant`, and it evaluates
    to +0 or -0): ``--neumann 0`` is then the zero flux the option's absence means."""
    return is_constant(expr) and bool(evaluate(expr, np.zeros(1), np.zeros(1))[0] == 0.0)


def uses_normal(expr: Expression) -> bool:
    """Whether ``expr`` reads the outward normal ``nx`` or ``ny``."""
    return bool(np.isin(expr.code, (OP_NX, OP_NY)).any())


def evaluate(expr: Expression, x: np.ndarray, y: np.ndarray, nx: np.ndarray | None = None,
             ny: np.ndarray | None = None) -> np.ndarray:
    """Evaluate ``expr`` elementwise on arrays ``x``, ``y`` (same shape), and the
    outward unit normal ``nx``, ``ny`` there (same shape; needed when ``expr``
    reads it, see :func:`uses_normal`); float64 result."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if (nx is None or ny is None) and uses_normal(expr):
        raise ValueError(f"{expr.text!r} reads the boundary normal: give nx and ny")
    normal = {OP_NX: nx, OP_NY: ny}
    unary = {OP_NEG: np.negative, OP_SIN: np.sin, OP_COS: np.cos, OP_TAN: np.tan, OP_EXP: np.exp,
             OP_LOG: np.log, OP_SQRT: np.sqrt, OP_ABS: np.abs, OP_SINH: np.sinh, OP_COSH: np.cosh}
    binary = {OP_ADD: np.add, OP_SUB: np.subtract, OP_MUL: np.multiply, OP_DIV: np.divide,
              OP_POW: np.power, OP_ATAN2: np.arctan2}
    stack: list[np.ndarray] = []
    with np.errstate(all="ignore"):
        for op, c in zip(expr.code.tolist(), expr.consts.tolist(), strict=True):
            if op == OP_CONST:
                stack.append(np.full(x.shape, c))
            elif op == OP_X:
                stack.append(x)
            elif op == OP_Y:
                stack.append(y)
            elif op in normal:
                stack.append(np.broadcast_to(np.asarray(normal[op], dtype=np.float64), x.shape))
            elif op in unary:
                stack.append(unary[op](stack.pop()))
            else:
                b = stack.pop()
                a = stack.pop()
                stack.append(binary[op](a, b))
    return np.broadcast_to(stack[-1], x.shape).astype(np.float64)
