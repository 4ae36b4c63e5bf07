"""Safe boundary expressions: parsing, whitelist, numpy and numba evaluation."""

import re

import numpy as np
import pytest

from geoproc.errors import UsageError
from geoproc.wos.expression import evaluate, parse_expression
from geoproc.wos.program import eval_program

CASES = [
    ("x**3 - 3*x*y**2", lambda x, y: x**3 - 3 * x * y**2),
    ("exp(x)*cos(y)", lambda x, y: np.exp(x) * np.cos(y)),
    ("log(sqrt((x-2)**2 + y**2))", lambda x, y: np.log(np.sqrt((x - 2) ** 2 + y**2))),
    ("-atan2(y, x) / pi + e", lambda x, y: -np.arctan2(y, x) / np.pi + np.e),
    ("sinh(x)*sin(y) + cosh(0.5)*tan(0.1) - abs(-x) + +2", lambda x, y: np.sinh(x) * np.sin(y)
     + np.cosh(0.5) * np.tan(0.1) - np.abs(-x) + 2),
    ("2**-1 * x", lambda x, y: 0.5 * x),
]


@pytest.mark.parametrize("text,ref", CASES)
def test_numpy_and_numba_evaluation_match_reference(text, ref):
    rng = np.random.default_rng(1)
    x, y = rng.uniform(-1, 1, 50), rng.uniform(-1, 1, 50)
    e = parse_expression(text)
    want = ref(x, y)
    np.testing.assert_allclose(evaluate(e, x, y), want, rtol=1e-13, atol=1e-13)
    got = np.array([eval_program(e.code, e.consts, a, b, 0.0, 0.0) for a, b in zip(x, y, strict=True)])
    np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-13)


def test_exponentials_overflow_where_the_floats_do():
    # the compiled evaluator gave inf from exp(709), sinh and cosh of +-709: exp(709.5*x)*1e-300
    # is at most 1.4e8 on the unit square, and the walks called it not finite
    x = np.array([709.5, 710.0, -710.0, 709.9, 711.0, np.nan])
    for name, ref in (("exp", np.exp), ("sinh", np.sinh), ("cosh", np.cosh)):
        e = parse_expression(f"{name}(x)")
        with np.errstate(over="ignore"):
            want = ref(x)
        got = np.array([eval_program(e.code, e.consts, a, 0.0, 0.0, 0.0) for a in x])
        np.testing.assert_allclose(got, want, rtol=1e-13)
        np.testing.assert_allclose(evaluate(e, x, 0 * x), want, rtol=1e-13)


@pytest.mark.parametrize("text", ["x / y", "x ** y", "atan2(x, y)", "log(x) + sqrt(y)", "exp(x) * sin(y)",
                                  "tan(x) - cosh(y) + abs(x) * sinh(y)"])
def test_numba_matches_numpy_on_zeros_infinities_and_nan(text):
    # the compiled evaluator gave nan for 1/0 (numpy: inf), inf for (-0)**-1 (-inf), nan for (-2)**inf (inf)
    vals = np.array([0.0, -0.0, 1.0, -1.0, 2.5, -2.5, 0.5, -0.5, 3.0, -3.0, 1e-320, 2.0**60, 2.0**53 + 2,
                     2.0**63, -2.0**63, 1e19, -1e19, 1e300, np.inf, -np.inf, np.nan])
    a, b = (g.ravel() for g in np.meshgrid(vals, vals, indexing="ij"))
    e = parse_expression(text)
    want = evaluate(e, a, b)
    got = np.array([eval_program(e.code, e.consts, p, q, 0.0, 0.0) for p, q in zip(a, b, strict=True)])
    np.testing.assert_allclose(got, want, rtol=1e-15, atol=0)
    assert np.array_equal(np.signbit(got[got == 0]), np.signbit(want[got == 0]))


def test_unknown_names_are_named():
    with pytest.raises(UsageError, match=r"unknown names 'foo', 'z'"):
        parse_expression("foo(x) + z")


@pytest.mark.parametrize("text", [
    "__import__('os').system('true')", "x.real", "x if y else 1", "x < y", "[x]", "lambda: 1",
    "'abc'", "x // 2", "x % 2", "sin(x, y)", "sin", "x; y", "",
])
def test_disallowed_constructs_are_rejected(text):
    with pytest.raises(UsageError):
        parse_expression(text)


def test_an_integer_past_the_float_range_is_a_usage_error():
    # float() of a 401-digit literal raises OverflowError, which had ended the run with exit 3
    with pytest.raises(UsageError, match="a 401-digit integer is beyond the floating-point range"):
        parse_expression("1" + "0" * 400 + " * x")


def test_syntax_errors_name_the_character_and_stay_one_short_line():
    with pytest.raises(UsageError, match=r"'x\+\*y': not a valid expression \(invalid syntax at character 3\)"):
        parse_expression("x+*y")
    long = "x+" * 200 + ")"
    with pytest.raises(UsageError) as err:
        parse_expression(long)
    assert len(str(err.value)) < 150 and "unmatched ')' at character 401" in str(err.value)


def test_a_flux_reads_the_outward_normal():
    rng = np.random.default_rng(2)
    x, y, t = rng.uniform(-1, 1, 20), rng.uniform(-1, 1, 20), rng.uniform(0, 2 * np.pi, 20)
    nx, ny = np.cos(t), np.sin(t)
    e = parse_expression("y*nx + x*ny - 2*ny**2", "--neumann", normals=True)  # grad(xy).n - 2 ny^2
    want = y * nx + x * ny - 2 * ny**2
    np.testing.assert_allclose(evaluate(e, x, y, nx, ny), want, rtol=1e-14, atol=1e-14)
    got = np.array([eval_program(e.code, e.consts, *v) for v in zip(x, y, nx, ny, strict=True)])
    np.testing.assert_allclose(got, want, rtol=1e-14, atol=1e-14)
    with pytest.raises(ValueError, match="reads the boundary normal"):
        evaluate(e, x, y)
    from geoproc.wos.expression import is_zero, uses_normal

    assert uses_normal(e) and not uses_normal(parse_expression("x*y"))
    assert not is_zero(parse_expression("0*nx", "--neumann", normals=True))


@pytest.mark.parametrize("text,message", [
    ("nx", "--boundary 'nx': nx, the boundary's outward normal, is for a flux (--neumann) only"),
    ("x + nz", "unknown name 'nz' (allowed: x, y, pi, e,"),
])
def test_the_normal_is_refused_outside_a_flux(text, message):
    with pytest.raises(UsageError, match=re.escape(message)):
        parse_expression(text)


def test_an_unknown_name_in_a_flux_lists_the_normal_among_the_allowed():
    with pytest.raises(UsageError, match=re.escape("unknown name 'nz' (allowed: x, y, nx, ny, pi, e,")):
        parse_expression("nz", "--neumann", normals=True)


@pytest.mark.parametrize("text,normals,message", [
    ("nx + nz", False, "unknown name 'nz' (allowed: x, y, pi, e,"),
    ("nx(1)", False, "nx, the boundary's outward normal, is for a flux (--neumann) only"),
    ("nx(1)", True, "'nx' is a variable, not a function"),
    ("nx + foo", False, "unknown name 'foo' (allowed: x, y, pi, e,"),
    ("nx + foo", False, "; nx, the boundary's outward normal, is for --neumann only"),
    ("pi(x)", False, "'pi' is a constant, not a function"),
])
def test_misused_normal_names_get_one_message_each(text, normals, message):
    with pytest.raises(UsageError, match=re.escape(message)):
        parse_expression(text, "--neumann" if normals else "--boundary", normals=normals)
