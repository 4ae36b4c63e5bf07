"""Exact polyhedral geodesic distance (the MMP algorithm, via libigl)."""

from __future__ import annotations

import multiprocessing
import os
import signal

import numpy as np


def exact_geodesic_distance(V: np.ndarray, F: np.ndarray, sources: np.ndarray) -> np.ndarray:
    """(n,) exact geodesic distance on the polyhedral surface to the nearest source.

    ``igl.exact_geodesic`` (Mitchell-Mount-Papadimitriou, Kirsanov's
    implementation). Vertices it cannot reach come back as +inf. The mesh is
    solved at unit bounding-box diagonal and the distances scaled back, since
    the implementation's tolerances are absolute (at a diagonal of 1e-30 it
    does not finish). The call runs in a child process
    (:func:`call_in_child`) so that a signal handler of the caller that raises
    stops it at once.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
        Edge-manifold triangles.
    sources : (k,) int array
        Source vertex indices.
    """
    from geoproc.mesh.topology import vertex_components

    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)  # libigl takes native int64 (not big-endian)
    VS = np.atleast_1d(np.ascontiguousarray(sources, dtype=np.int64))
    VT = np.arange(len(V), dtype=np.int64)
    lo = V.min(axis=0)
    scale = float(np.linalg.norm(V.max(axis=0) - lo)) or 1.0
    U = np.ascontiguousarray((V - lo) / scale)
    d = np.asarray(call_in_child(_igl_exact_geodesic, U, np.ascontiguousarray(F), VS, VT), dtype=np.float64)
    d[~np.isfinite(d) | (d > 1e99)] = np.inf
    # libigl leaves the vertices of components without a source at 0
    _, comp = vertex_components(F, len(V))  # -1: a vertex no face uses
    reached = np.isin(comp, comp[VS][comp[VS] >= 0])
    reached[VS] = True
    d[~reached] = np.inf
    return d * scale


def _igl_exact_geodesic(U, F, VS, VT):
    import igl

    empty = np.zeros(0, dtype=np.int64)
    return np.asarray(igl.exact_geodesic(U, F, VS, empty, VT, empty))


def call_in_child(fn, *args):
    """``fn(*args)`` computed in a forked child process; its result, or its
    exception (a MemoryError stays one, anything else becomes a RuntimeError
    with its message). A child killed by SIGKILL, as the system's
    out-of-memory killer kills, is a MemoryError too.

    For long calls into compiled code that never return to the interpreter:
    while the child works, this process waits in a system call, so a signal
    handler that raises (Ctrl-C, SIGTERM) runs at once, and the child is killed
    on the way out. The child dies with this process (Linux) and on the
    signals itself. Where fork is not available, or in a daemonic process (a
    ``multiprocessing.Pool`` worker, which may not start children), ``fn``
    runs here.
    """
    if "fork" not in multiprocessing.get_all_start_methods() or multiprocessing.current_process().daemon:
        return fn(*args)  # (a daemonic process, as a Pool worker, may not start children)
    ctx = multiprocessing.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    child = ctx.Process(target=_child_main, args=(send, os.getpid(), fn, args), daemon=True)
    child.start()
    send.close()
    try:
        try:
            kind, value = recv.recv()
        except EOFError:
            child.join()
            code = child.exitcode
            if code == -signal.SIGKILL:  # what the system's out-of-memory killer sends
                raise MemoryError("the computation's process was killed by SIGKILL without a result, as the "
                                  "system kills a process when memory runs out") from None
            how = (f"was killed by {signal.Signals(-code).name}" if code is not None and code < 0
                   else f"exited with code {code}")
            raise RuntimeError(f"the computation's process {how} without a result") from None
    finally:
        if child.is_alive():
            child.kill()
        child.join()
        recv.close()
    if kind == "ok":
        return value
    raise MemoryError(value) if kind == "memory" else RuntimeError(value)


def _child_main(send, parent, fn, args):
    for sig in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None)):
        if sig is not None and signal.getsignal(sig) not in (signal.SIG_IGN, None):
            signal.signal(sig, signal.SIG_DFL)
    _die_with_parent(parent)
    try:
        out = ("ok", fn(*args))
    except MemoryError as exc:
        out = ("memory", str(exc) or "out of memory")
    except Exception as exc:  # noqa: BLE001 - passed back to the caller as its message
        out = ("error", f"{type(exc).__name__}: {exc}")
    send.send(out)
    send.close()


def _die_with_parent(parent: int) -> None:
    """Ask Linux to kill this process when its parent exits (prctl
    PR_SET_PDEATHSIG); exit now if the parent is already gone."""
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL))  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if os.getppid() != parent:
        os._exit(1)
