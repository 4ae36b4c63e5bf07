"""Keeping compiled libraries' own prints off standard output.

A command may write its result to standard output (``-o -``), so nothing else
may reach it: not even a C library's ``printf``, which bypasses Python's
``sys.stdout``.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def c_stdout_silenced() -> Iterator[None]:
    """Discard what is written on file descriptor 1 inside the block, by
    compiled code or by Python (wurlitzer's redirect to the null device);
    standard error is left alone. Where wurlitzer does not run (Windows), the
    block runs as it is."""
    try:
        from wurlitzer import pipes
    except ImportError:  # pragma: no cover - POSIX only
        yield
        return
    _flush_stdout()
    with open(os.devnull, "w") as null, pipes(stdout=null, stderr=None):
        try:
            yield
        finally:
            _flush_stdout()  # what Python buffered in the block is dropped with the rest


def _flush_stdout() -> None:
    if sys.stdout is not None:
        sys.stdout.flush()
