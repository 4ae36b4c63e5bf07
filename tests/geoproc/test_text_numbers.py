"""Block reading of whitespace-separated numbers (geoproc.mesh.text_numbers)
against Python's own line-by-line reading."""

from __future__ import annotations

import numpy as np
import pytest

from geoproc.mesh.text_numbers import numbers_on_lines, uniform_rows


def _by_line(lines, integer):
    cast = int if integer else float
    rows = [[cast(t) for t in ln.split()] for ln in lines]
    return np.array([v for r in rows for v in r]), np.array([len(r) for r in rows])


def test_integers_on_lines_of_any_length_read_as_python_reads_them():
    rng = np.random.default_rng(0)
    lines = [b" ".join(str(v).encode() for v in rng.integers(-10**12, 10**12, rng.integers(0, 7)))
             for _ in range(500)]
    lines[3] = b"  +5\t-0  7 \x0b8\x0c "  # signs and every separator bytes.split() splits at
    values, counts = numbers_on_lines(lines, integer=True)
    want_values, want_counts = _by_line(lines, integer=True)
    assert np.array_equal(counts, want_counts) and np.array_equal(values, want_values)
    assert values.dtype == np.int64


def test_floats_read_as_python_reads_them():
    rng = np.random.default_rng(1)
    lines = [b" ".join(repr(float(v)).encode() for v in rng.normal(size=3) * 10.0 ** rng.integers(-300, 300, 3))
             for _ in range(500)]
    lines += [b"nan -inf Infinity", b".5 5. -1E-3", b"1e308 4.9e-324 -0"]
    rows = uniform_rows(lines, integer=False)
    want = np.array([[float(t) for t in ln.split()] for ln in lines])
    assert rows.shape == (503, 3) and np.array_equal(rows, want, equal_nan=True)
    assert np.array_equal(np.signbit(rows), np.signbit(want))  # -0 stays negative


@pytest.mark.parametrize("line,integer", [
    (b"1 2 1.0", True), (b"1 2 1e3", True), (b"1 1_0 2", True),
    (b"99999999999999999999 1", True), (b"-99999999999999999999 1", True),  # beyond int64
    (b"1 0x1p3", False), (b"1,5 2", False), (b"1 nan(2)", False), (b"1 - 2", False), (b"1 2e", False),
    (b"1 \x1c2", False),
    # a sign alone: numpy read it as 0 when it ended the data ("3 0 1 +" became the face 0 1 0)
    (b"3 0 1 +", True), (b"3 0 1 -", True), (b"1 + 2", True), (b"1 2 +", False),
])
def test_other_spellings_are_left_to_the_line_readers(line, integer):
    assert numbers_on_lines([b"1 2 3", line], integer) is None


def test_uniform_rows_needs_one_count_per_line():
    assert uniform_rows([b"1 2 3", b"4 5"], integer=True) is None
    assert uniform_rows([], integer=True) is None
    assert np.array_equal(uniform_rows([b"1 2", b"3 4"], integer=True), [[1, 2], [3, 4]])
    values, counts = numbers_on_lines([b"", b"1", b"  "], integer=True)
    assert list(counts) == [0, 1, 0] and list(values) == [1]
