"""Point-by-point evaluation of the postfix programs of :mod:`geoproc.wos.expression`,
compiled with numba for use inside the walks."""

from __future__ import annotations

import math

import numba
import numpy as np

from geoproc.wos.expression import (
    MAX_STACK,
    OP_ABS,
    OP_ADD,
    OP_ATAN2,
    OP_CONST,
    OP_COS,
    OP_DIV,
    OP_EXP,
    OP_LOG,
    OP_MUL,
    OP_NEG,
    OP_NX,
    OP_NY,
    OP_POW,
    OP_SIN,
    OP_SINH,
    OP_SQRT,
    OP_SUB,
    OP_TAN,
    OP_X,
    OP_Y,
)


@numba.njit(cache=True, nogil=True)
def eval_program(code, consts, x, y, nx, ny):
    """Evaluate a compiled program at the point ``(x, y)``, where the boundary's
    outward unit normal is ``(nx, ny)`` (read by a flux; pass 0.0 elsewhere)
    (numba; used inside walks).

    One slot more than a parsed program may use: a domain far from the origin
    adds its shift to x and y (:func:`geoproc.wos.expression.translated`)."""
    stack = np.empty(MAX_STACK + 1)
    sp = 0
    for i in range(code.shape[0]):
        op = code[i]
        if op == OP_CONST:
            stack[sp] = consts[i]
            sp += 1
        elif op == OP_X:
            stack[sp] = x
            sp += 1
        elif op == OP_Y:
            stack[sp] = y
            sp += 1
        elif op == OP_NX or op == OP_NY:
            stack[sp] = nx if op == OP_NX else ny
            sp += 1
        elif op <= OP_POW or op == OP_ATAN2:
            b = stack[sp - 1]
            a = stack[sp - 2]
            sp -= 1
            if op == OP_ADD:
                r = a + b
            elif op == OP_SUB:
                r = a - b
            elif op == OP_MUL:
                r = a * b
            elif op == OP_DIV:
                r = a / b if b != 0.0 else _over_zero(a, b)
            elif op == OP_POW:
                r = _pow(a, b)
            else:
                r = math.atan2(a, b)
            stack[sp - 1] = r
        else:
            a = stack[sp - 1]
            if op == OP_NEG:
                r = -a
            elif op == OP_SIN:
                r = math.sin(a)
            elif op == OP_COS:
                r = math.cos(a)
            elif op == OP_TAN:
                r = math.tan(a)
            elif op == OP_EXP:
                r = math.exp(a)  # inf past 709.78 (compiled: no OverflowError)
            elif op == OP_LOG:
                r = math.log(a) if a > 0.0 else (-np.inf if a == 0.0 else np.nan)
            elif op == OP_SQRT:
                r = math.sqrt(a) if a >= 0.0 else np.nan
            elif op == OP_ABS:
                r = abs(a)
            elif op == OP_SINH:
                r = math.sinh(a)
            else:
                r = math.cosh(a)
            stack[sp - 1] = r
    return stack[0]


@numba.njit(cache=True, nogil=True)
def _over_zero(a, b):
    """``a / b`` for ``b`` = ±0 as IEEE division gives it (and numpy): ±inf by
    the signs of ``a`` and the zero, nan for 0 / 0 and nan / 0 (numba raises
    ZeroDivisionError for ``a / 0.0``; this had given nan for every ``a``)."""
    if a == 0.0 or a != a:
        return np.nan
    return math.copysign(np.inf, a) * math.copysign(1.0, b)


@numba.njit(cache=True, nogil=True)
def _pow(a, b):
    """``a ** b`` as C's ``pow`` (and numpy) give it where numba's would raise
    or differ: nan for a finite negative base and a non-integer power, ±inf
    for a zero base and a negative power (-inf for -0 and an odd integer
    power), inf or 0 for -inf and a non-integer power and for an infinite
    power. (np.floor: numba's math.floor returns an int64, which wrapped past
    2**63 and made (-1)**1e19 nan.)"""
    odd = b == np.floor(b) and not math.isinf(b) and b - 2.0 * np.floor(b / 2.0) != 0.0
    if math.isinf(b) and a == a:
        m = abs(a)
        return 1.0 if m == 1.0 else (np.inf if (m > 1.0) == (b > 0.0) else 0.0)
    if a == -np.inf and b == b and b != np.floor(b):
        return np.inf if b > 0.0 else 0.0
    if a < 0.0 and b != np.floor(b):
        return np.nan
    if a == 0.0 and b < 0.0:
        return math.copysign(np.inf, a) if odd else np.inf
    return a**b
