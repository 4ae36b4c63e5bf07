"""A boundary-value problem ready for walks: segments, acceleration grids, data.

:class:`WalkProblem` bundles what the numba walks need and exposes one call,
:meth:`WalkProblem.estimate`, that runs Walk on Spheres (Dirichlet only) or
Walk on Stars (mixed) with an optional control variate.
"""

from __future__ import annotations

import numba
import numpy as np

from geoproc.errors import InputError, UsageError
from geoproc.wos.closest import build_segment_grid, closest_points
from geoproc.wos.domain import Domain
from geoproc.wos.expression import Expression, evaluate, is_constant, is_zero
from geoproc.wos.kernels import KernelSet
from geoproc.wos.rng import stream_state
from geoproc.wos.walk import wos_dirichlet, wos_dirichlet_serial
from geoproc.wos.wost import neumann_index, silhouette_candidates, wost_mixed, wost_mixed_serial

MAX_STEPS = 10_000
SERIAL_WALKS = 1024
CHUNK_WALKS = 1 << 18
"""Walks per call of the compiled walk kernels in :meth:`WalkProblem.estimate_chunked`
(about a third of a second on two cores on the fixtures): Ctrl-C and the progress bar
are answered between calls, and a point's walks are not split. A call takes at least
two points per thread, so that every thread has work when the points have many walks
each (with one point per call, as 400,000 walks per point gave, one core did all)."""
CHUNK_POINTS = 4096
"""At most this many points per call."""
_EMPTY2 = np.zeros((0, 2))
_EMPTY1 = np.zeros(0)
_NO_CODE = np.zeros(0, dtype=np.int64)
_NO_ARCS = np.zeros((0, 2), dtype=np.int64)
_NO_BOXES = np.zeros((0, 4))
_NO_CONTROL_VARIATE = (0, _EMPTY2, _EMPTY2, _EMPTY1, _NO_ARCS, _NO_BOXES)
"""The walk kernels' control-variate arguments (kind, KP, KQ, W, ARC, BOX) for none."""


def require_finite_boundary_data(domain: Domain, boundary: Expression | None,
                                 flux: Expression | None, samples: int = 9) -> None:
    """UsageError naming the first point where the Dirichlet expression (on the
    Dirichlet segments) or the flux (on the Neumann ones) is not finite, over
    ``samples`` evenly spaced points of every segment, ends included."""
    for expr, mask, option in ((boundary, ~domain.neumann, "--boundary"), (flux, domain.neumann, "--neumann")):
        if expr is None or not mask.any():
            continue
        P, v = segment_values(domain, expr, mask, samples)
        bad = ~np.isfinite(v)
        if bad.any():
            x, y = P[np.flatnonzero(bad)[0]] + domain.offset  # where the input has it
            raise UsageError(f"{option} is not finite on the boundary of {domain.source} "
                             f"(first at x = {x:.6g}, y = {y:.6g})")


def segment_samples(domain: Domain, mask: np.ndarray, samples: int) -> np.ndarray:
    """(k samples, 2) ``samples`` evenly spaced points, ends included, of each
    segment of ``domain`` that ``mask`` (S,) selects."""
    t = np.linspace(0.0, 1.0, samples)
    A, B = domain.A[mask], domain.B[mask]
    return (A[:, None, :] + t[None, :, None] * (B - A)[:, None, :]).reshape(-1, 2)


def segment_values(domain: Domain, expr: Expression, mask: np.ndarray,
                   samples: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`segment_samples` of the segments ``mask`` selects, (k, 2), and
    ``expr`` there, (k,), each sample with its segment's outward normal (which
    a flux may read)."""
    P = segment_samples(domain, mask, samples)
    N = np.repeat(domain.outward_normals[mask], samples, axis=0)
    return P, evaluate(expr, P[:, 0], P[:, 1], N[:, 0], N[:, 1])


def dirichlet_data_bound(domain: Domain, boundary: Expression | None, samples: int = 9) -> float:
    """The largest magnitude of the Dirichlet data: ``boundary`` at ``samples``
    evenly spaced points of every Dirichlet segment (as
    :func:`require_finite_boundary_data` reads it), or the domain's per-vertex
    values on those segments when there is no expression; 0 without either.
    Non-finite samples are left out (that function refuses them)."""
    mask = ~domain.neumann
    if not mask.any():
        return 0.0
    if boundary is not None:
        with np.errstate(all="ignore"):
            v = np.abs(segment_values(domain, boundary, mask, samples)[1])
    elif domain.values is not None:
        v = np.abs(domain.values[mask]).ravel()
    else:
        return 0.0
    v = v[np.isfinite(v)]
    return float(v.max()) if v.size else 0.0


def constant_dirichlet_data(domain: Domain, boundary: Expression | None) -> bool:
    """Whether the Dirichlet data take one value: ``boundary`` reads neither x
    nor y (sampled points could all fall where ``1e6 + sin(8*pi*x)`` is 1e6),
    or, with no expression, the domain's per-vertex values on the Dirichlet
    segments are all equal."""
    mask = ~domain.neumann
    if not mask.any():
        return False
    if boundary is not None:
        return is_constant(boundary)
    if domain.values is None:
        return False
    v = np.asarray(domain.values[mask], dtype=np.float64).ravel()
    return bool(v.size and np.isfinite(v).all() and (v == v[0]).all())


def neumann_data_bound(domain: Domain, flux: Expression | None, samples: int = 9) -> float:
    """The largest magnitude of the Neumann data: ``flux`` at ``samples`` evenly
    spaced points of every Neumann segment, with that segment's outward normal
    (as :func:`require_finite_boundary_data` reads it); 0 without Neumann
    segments or data. Non-finite samples are left out (that function refuses them)."""
    mask = domain.neumann
    if flux is None or not mask.any():
        return 0.0
    with np.errstate(all="ignore"):
        v = np.abs(segment_values(domain, flux, mask, samples)[1])
    v = v[np.isfinite(v)]
    return float(v.max()) if v.size else 0.0


def require_dirichlet_in_every_part(domain: Domain) -> None:
    """InputError naming a connected part of the domain whose whole boundary is
    Neumann: u is not unique there, and its walks would never stop (they ran to
    the step cap and scored a Dirichlet segment of another part). A domain
    with no Dirichlet segment at all is named as such."""
    if domain.neumann.all():
        raise InputError(domain.source, "every boundary segment is Neumann; at least one "
                         "Dirichlet segment is needed for a unique solution")
    part = domain.part_of[domain.loop_of]
    for p in np.unique(part):
        if domain.neumann[part == p].all():
            loops = np.flatnonzero(domain.part_of == p).tolist()
            which = f"loop {loops[0]}" if len(loops) == 1 else "loops " + ", ".join(map(str, loops))
            raise InputError(domain.source, f"the part of the domain bounded by {which} has only Neumann "
                             "segments; each connected part needs a Dirichlet segment for a unique solution")


def pass_seed(seed: int, tag: int) -> np.uint64:
    """Seed of the random streams of one pass (``tag``) of a run seeded with ``seed``."""
    # int(): a numpy integer's remainder by 2^64 does not fit its own type
    return np.uint64(stream_state(np.uint64(int(seed) % (1 << 64)), np.uint64(int(tag))))


class WalkProblem:
    """Walk-ready form of a Laplace problem on a :class:`Domain`.

    Parameters
    ----------
    domain : Domain
    boundary : Expression or None
        Dirichlet data; None uses the domain's per-vertex values.
    flux : Expression or None
        Neumann data ``du/dn`` (outward normal) on the Neumann segments; None is zero
        flux, and so is a constant 0 (the walks then draw the same random numbers).
    eps : float
        Stopping distance (length units).
    """

    def __init__(self, domain: Domain, boundary: Expression | None, flux: Expression | None,
                 eps: float):
        if boundary is None and domain.values is None:
            raise UsageError(f"{domain.source}: give --boundary 'EXPR' (a mask carries no boundary values)"
                             if domain.traced else
                             f"{domain.source}: give --boundary 'EXPR' or per-vertex 'values' in the domain JSON")
        if flux is not None and not domain.has_neumann:
            raise UsageError(f"--neumann given but {domain.source} marks no Neumann loops "
                             "(add \"neumann\": [loop indices] to the JSON)")
        require_dirichlet_in_every_part(domain)
        require_finite_boundary_data(domain, boundary, flux)
        self.domain = domain
        self.eps = float(eps)
        lo, hi = domain.bbox
        self.tiny = 1e-12 * float(np.linalg.norm(np.asarray(hi) - np.asarray(lo)))  # see wost_mixed
        self.A = np.ascontiguousarray(domain.A)
        self.B = np.ascontiguousarray(domain.B)
        self.grid_all = build_segment_grid(self.A, self.B)
        self.mixed = domain.has_neumann
        if boundary is not None:
            self.bkind, self.code, self.consts = 0, boundary.code, boundary.consts
            self.V = _EMPTY2
        else:
            self.bkind, self.code, self.consts = 1, _NO_CODE, _EMPTY1
            self.V = np.ascontiguousarray(domain.values)
        if self.mixed:
            dir_ids = np.flatnonzero(~domain.neumann)
            self.grid_dir = build_segment_grid(self.A, self.B, dir_ids)
            self.nseg = np.flatnonzero(domain.neumann).astype(np.int64)
            self.U, self.Vs, self.Wn = silhouette_candidates(self.A, self.B, domain.neumann,
                                                             domain.loop_of)
            self.neumann_index = neumann_index(self.A, self.B, self.nseg, self.Vs)
            if flux is not None and not is_zero(flux):  # a zero flux needs no flux samples
                self.hkind, self.hcode, self.hconsts = 0, flux.code, flux.consts
            else:
                self.hkind, self.hcode, self.hconsts = 1, _NO_CODE, _EMPTY1

    def distance(self, P: np.ndarray, dirichlet_only: bool = False) -> np.ndarray:
        """(n,) distance from points P (n, 2) to the boundary (or its Dirichlet part)."""
        grid = self.grid_dir if (dirichlet_only and self.mixed) else self.grid_all
        d, _, _ = closest_points(np.ascontiguousarray(P, dtype=np.float64), self.A, self.B, grid)
        return d

    def estimate_chunked(self, X: np.ndarray, walks: int, stream_seed, kernels: KernelSet | None = None,
                         sigma: np.ndarray | None = None, progress=None):
        """:meth:`estimate` over X in slices of about :data:`CHUNK_WALKS` walks
        (at most :data:`CHUNK_POINTS` points, at least two per thread), with the same
        numbers (each point keeps its random stream); ``progress(fraction_done)``
        after each slice. Ctrl-C is answered between slices."""
        n = len(X)
        step = int(min(CHUNK_POINTS, max(CHUNK_WALKS // walks, 2 * numba.get_num_threads())))
        mean, var, steps = np.empty(n), np.empty(n), np.empty(n, dtype=np.int64)
        for i in range(0, n, step):
            sl = slice(i, i + step)
            mean[sl], var[sl], steps[sl] = self.estimate(X[sl], walks, stream_seed, i, kernels, sigma)
            if progress is not None:
                progress(min(1.0, (i + step) / n))
        return mean, var, steps

    def estimate(self, X: np.ndarray, walks: int, stream_seed, index0: int = 0,
                 kernels: KernelSet | None = None, sigma: np.ndarray | None = None):
        """Estimate u at X (n, 2): (mean (n,), var (n,), steps (n,) int64).

        Every point of X must lie in the domain (or on its Dirichlet boundary):
        a walk started outside does not estimate anything. ``solve_laplace``
        keeps the grid points that :meth:`Domain.contains` accepts.

        With ``kernels`` and ``sigma`` the control variate ``sum sigma_j phi_j`` is used.
        """
        X = np.ascontiguousarray(X, dtype=np.float64)
        if kernels is None:
            ckind, KP, KQ, W, ARC, BOX = _NO_CONTROL_VARIATE
        else:
            ckind, KP, KQ, W = kernels.kind, kernels.P, kernels.Q, kernels.weights(sigma)
            ARC, BOX = kernels.arcs, kernels.boxes
        if len(X) == 0:
            return np.zeros(0), np.zeros(0), np.zeros(0, dtype=np.int64)
        # small batches (npass steps) run on one thread: thread start-up would dominate;
        # the numbers are the same either way (per-point random streams)
        return self._run(X, walks, stream_seed, index0, ckind, KP, KQ, W, ARC, BOX,
                         serial=len(X) * walks <= SERIAL_WALKS)

    def load_kernels(self, X: np.ndarray) -> None:
        """Compile, or load from numba's cache, both the one-thread and the
        parallel walk kernel, with one walk from the first point of X (n, 2),
        so that neither is loaded inside a timed pass (the parallel one had
        been, and the first run's steps per second read 3.0M for 11.7M)."""
        X = np.ascontiguousarray(X[:1], dtype=np.float64)
        for serial in (True, False):
            self._run(X, 1, pass_seed(0, 0), 0, *_NO_CONTROL_VARIATE, serial=serial)

    def _run(self, X, walks, stream_seed, index0, ckind, KP, KQ, W, ARC, BOX, serial):
        """The walk kernel on X: the one-thread version when ``serial``, else the parallel one."""
        dirichlet = wos_dirichlet_serial if serial else wos_dirichlet
        mixed = wost_mixed_serial if serial else wost_mixed
        old = numba.get_parallel_chunksize()
        # blocks of 16 points per thread, smaller when there are few points (long walks)
        numba.set_parallel_chunksize(max(1, min(16, len(X) // (2 * numba.get_num_threads()))))
        try:
            if not self.mixed:
                return dirichlet(X, index0, int(walks), self.eps, MAX_STEPS, stream_seed,
                                     self.A, self.B, self.grid_all, self.bkind, self.code,
                                     self.consts, self.V, ckind, KP, KQ, W, ARC, BOX)
            return mixed(X, index0, int(walks), self.eps, self.tiny, MAX_STEPS, stream_seed, self.A,
                              self.B, self.grid_dir, self.nseg, self.U, self.Vs, self.Wn, self.neumann_index,
                              self.bkind, self.code, self.consts, self.V, self.hkind, self.hcode,
                              self.hconsts, ckind, KP, KQ, W, ARC, BOX)
        finally:
            numba.set_parallel_chunksize(old)
