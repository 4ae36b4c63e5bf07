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
    with _discarding(1):
        yield


@contextmanager
def c_stderr_silenced() -> Iterator[None]:
    """Discard what is written on file descriptor 2 inside the block (libpng
    prints its own ``libpng error: ...`` line before OpenImageIO reports a
    damaged PNG, and the command reports the error in its one line). With no
    descriptor 2 (standard error closed at start) the block runs as it is."""
    try:
        os.fstat(2)
    except OSError:
        yield
        return
    with _discarding(2):
        yield


@contextmanager
def _discarding(fd: int) -> Iterator[None]:
    """Descriptor ``fd`` (1 or 2) sent to the null device inside the block."""
    try:
        from wurlitzer import pipes
    except ImportError:  # pragma: no cover - POSIX only
        yield
        return
    stream = sys.stdout if fd == 1 else sys.stderr
    _flush(stream)
    with open(os.devnull, "w") as null, pipes(stdout=null if fd == 1 else None, stderr=null if fd == 2 else None):
        try:
            yield
        finally:
            _flush(stream)  # what Python buffered in the block is dropped with the rest


def _flush(stream) -> None:
    if stream is not None:
        stream.flush()
