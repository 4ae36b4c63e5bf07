"""geoproc.geodesic against independent references: analytic distances (plane,
sphere), libigl's exact geodesics, scipy's direct sparse solve, a
high-precision Decimal solve, and the CVXPY/Clarabel convex program."""

from __future__ import annotations

from decimal import Decimal, getcontext

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

import geoproc.geodesic as gd
from geoproc.errors import InputError, UsageError
from geoproc.geodesic.log_lu import LogMMatrixSolver
from geoproc.geodesic.log_ode import LogODESolver, LogStepSystem, log_ode_step, log_ode_steps
from geoproc.mesh import load_mesh


def _exact(V, F, s):
    return gd.exact_geodesic_distance(V, F, np.atleast_1d(s))


# ---- exact geodesics against analytic distances -------------------------------------------

@pytest.mark.parametrize("source", [0, 220, 440])
def test_exact_on_flat_grid_is_euclidean(make_fixtures, source):
    V, F = make_fixtures.grid()
    d = _exact(V, F, source)
    # a flat convex patch: the geodesic is the straight segment
    assert np.abs(d - np.linalg.norm(V - V[source], axis=1)).max() < 1e-12
    # a list of positions and big-endian faces (libigl refused both), one source as a plain index
    assert np.array_equal(gd.exact_geodesic_distance(V.tolist(), F.astype(">i8"), source), d)


@pytest.mark.parametrize("scale", [1e-30, 1e40])
def test_exact_is_scale_invariant_far_from_unit_size(make_fixtures, scale):
    V, F = make_fixtures.grid()  # flat: the exact distance is the Euclidean one at any scale
    d = _exact(V * scale, F, 0)
    assert np.abs(d / scale - np.linalg.norm(V - V[0], axis=1)).max() < 1e-12


def test_exact_on_sphere_follows_great_circles(make_fixtures):
    V, F = make_fixtures.icosphere(3)  # 642 vertices on the unit sphere
    d = _exact(V, F, 0)
    arc = np.arccos(np.clip(V @ V[0], -1, 1))
    # polyhedral vs smooth sphere: O(h^2) apart (h ~ 0.1 here), measured 0.0079
    assert np.abs(d - arc).max() < 0.012
    assert np.abs(d - arc).mean() < 0.006
    assert d.max() == pytest.approx(np.pi, rel=0.005)


def test_exact_multi_source_is_min_over_sources(make_fixtures):
    V, F = make_fixtures.grid()
    d = _exact(V, F, [0, 440])
    ref = np.minimum(np.linalg.norm(V - V[0], axis=1), np.linalg.norm(V - V[440], axis=1))
    assert np.abs(d - ref).max() < 1e-12


class _Stop(Exception):
    pass


def _crash():
    """What a segfault in compiled code does to the process that runs it."""
    import os
    import signal

    os.kill(os.getpid(), signal.SIGSEGV)


def test_exact_stops_at_once_when_a_signal_handler_raises():
    # The MMP call on a 327,680-face sphere takes minutes. It runs in a child process,
    # so a handler that raises (Ctrl-C, SIGTERM in the command line) interrupts the
    # wait at once: this process spends well under a second of CPU, not the whole
    # computation, and the child is gone afterwards.
    import multiprocessing
    import signal
    import time

    import trimesh

    m = trimesh.creation.icosphere(subdivisions=7)

    def stop(signum, frame):
        raise _Stop

    old = signal.signal(signal.SIGALRM, stop)
    cpu = time.process_time()
    try:
        signal.setitimer(signal.ITIMER_REAL, 0.5)
        with pytest.raises(_Stop):
            gd.exact_geodesic_distance(m.vertices, m.faces, np.array([0]))
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    assert time.process_time() - cpu < 5.0
    assert multiprocessing.active_children() == []


def test_exact_runs_in_a_pool_worker(make_fixtures):
    # a daemonic process (a multiprocessing.Pool worker) may not start children: the call
    # runs in the worker itself (it had raised 'daemonic processes are not allowed to have
    # children')
    import multiprocessing

    V, F = make_fixtures.grid()
    with multiprocessing.get_context("fork").Pool(1) as pool:
        d = pool.apply(gd.exact_geodesic_distance, (V, F, np.array([0])))
    assert np.array_equal(d, gd.exact_geodesic_distance(V, F, np.array([0])))


def test_call_in_child_passes_results_and_errors_back():
    import os

    from geoproc.geodesic.exact import call_in_child

    assert np.array_equal(call_in_child(np.arange, 4), np.arange(4))

    def no_memory():
        raise MemoryError("std::bad_alloc")

    def fails():
        raise ValueError("bad mesh")

    with pytest.raises(MemoryError, match="bad_alloc"):
        call_in_child(no_memory)
    with pytest.raises(RuntimeError, match="ValueError: bad mesh"):
        call_in_child(fails)
    with pytest.raises(RuntimeError, match="exited with code 3 without a result"):
        call_in_child(os._exit, 3)
    # a crash in compiled code (libigl's MMP segfaulted on a non-manifold mesh) is named
    with pytest.raises(RuntimeError, match="was killed by SIGSEGV without a result"):
        call_in_child(_crash)
    # SIGKILL is how the system's out-of-memory killer ends a process: reported as memory
    # (exit 2), not as an internal error (exit 3)
    import signal

    def killed():
        os.kill(os.getpid(), signal.SIGKILL)  # the child's own id, taken in the child

    with pytest.raises(MemoryError, match="killed by SIGKILL .* when memory runs out"):
        call_in_child(killed)


# ---- the heat method family against exact geodesics ----------------------------------------

_EXACT_CACHE: dict = {}


def _shared_exact(shared_data, name, s):
    """Load a shared mesh and its exact distances from vertex ``s`` (cached per run)."""
    if (name, s) not in _EXACT_CACHE:
        m = load_mesh(shared_data / "meshes" / name)
        _EXACT_CACHE[name, s] = (m, _exact(m.V, m.F, s))
    return _EXACT_CACHE[name, s]


@pytest.mark.parametrize("name", ["bunny.off", "fandisk.off"])
@pytest.mark.parametrize("method", ["heat", "log-heat"])
def test_heat_and_log_heat_within_two_percent_of_exact(shared_data, name, method):
    errs = []
    for k in (0, 1):
        m = _shared_exact(shared_data, name, 0)[0]
        s = 0 if k == 0 else len(m.V) // 2
        m, ref = _shared_exact(shared_data, name, s)
        d = gd.geodesic_distance(m.V, m.F, [s], method).distance
        errs.append(gd.compare_to_reference(d, ref)["mean_relative_error"])
    # measured 0.5-1.1 % (heat-method accuracy at t = h^2); the bar is 2 %
    assert max(errs) < 0.02


@pytest.mark.parametrize("method", ["heat", "log-heat"])
def test_several_sources_as_accurate_as_potpourri3d(shared_data, method):
    # one unit of heat per source, as the paper and geometry-central do: with
    # u0 = 1 (heat = the vertex's area) the larger-area sources' fronts reached
    # too far: over these sets on spot the mean error was 1.8 times potpourri3d's
    # (0.020 against 0.011); now both are 0.011
    pp3d = pytest.importorskip("potpourri3d")
    m = load_mesh(shared_data / "meshes" / "spot.obj")
    solver = pp3d.MeshHeatMethodDistanceSolver(m.V, m.F)
    rng = np.random.default_rng(3)
    ours, peer = [], []
    for k in (2, 3, 3, 5, 10):
        src = rng.choice(len(m.V), k, replace=False)
        ref = gd.geodesic_distance(m.V, m.F, src, "exact").distance
        d = gd.geodesic_distance(m.V, m.F, src, method).distance
        ours.append(gd.compare_to_reference(d, ref)["mean_relative_error"])
        peer.append(gd.compare_to_reference(solver.compute_distance_multisource(src), ref)["mean_relative_error"])
    assert np.mean(ours) <= 1.2 * np.mean(peer), (ours, peer)


def test_heat_on_open_grid_with_two_sources(make_fixtures):
    V, F = make_fixtures.grid(41)
    d = gd.geodesic_distance(V, F, [0, 1680], "heat").distance
    ref = np.minimum(np.linalg.norm(V - V[0], axis=1), np.linalg.norm(V - V[1680], axis=1))
    assert gd.compare_to_reference(d, ref)["mean_relative_error"] < 0.02
    assert abs(d[0]) < 1e-3 and abs(d[1680]) < 1e-3


def test_heat_step_keeps_the_heat_positive_by_default(shared_data):
    # the cotan Laplacian's negative weights let the heat go negative (bunny: up to 4 % of
    # the vertices; a bunny with one half twice subdivided: up to 46 %, and 45 times
    # potpourri3d's error); the intrinsic Delaunay heat step, now the default, does not
    m = load_mesh(shared_data / "meshes" / "bunny.off")
    h = gd.mean_edge_length(m.V, m.F)
    default = gd.HeatMethodSolver(m.V, m.F, h * h)
    cotan = gd.HeatMethodSolver(m.V, m.F, h * h, laplacian="cotan", operators="extrinsic")
    sources = range(0, len(m.V), 60)
    assert sum(int((default.heat(np.array([s])) < 0).sum()) for s in sources) == 0
    assert sum(int((cotan.heat(np.array([s])) < 0).sum()) for s in sources) > 100


def test_heat_on_open_mesh_averages_the_neumann_and_dirichlet_solutions(make_fixtures):
    # Crane et al.'s boundary rule: the mean of the heat with free (Neumann) and with
    # zero (Dirichlet) boundary values; with an interior source neither half is zero
    import igl

    V, F = make_fixtures.grid(21)
    h = gd.mean_edge_length(V, F)
    t, s = h * h, 220  # vertex (10, 10), the middle of the grid
    solver = gd.HeatMethodSolver(V, F, t, laplacian="cotan", operators="extrinsic")
    L = sp.csc_matrix(igl.cotmatrix(V, F))
    M = igl.massmatrix(V, F, igl.MASSMATRIX_TYPE_VORONOI).diagonal()
    A = (sp.diags(M) - t * L).tocsc()
    b = np.zeros(len(V))
    b[s] = 1.0
    neumann = spsolve(A, b)
    lo, hi = V.min(axis=0), V.max(axis=0)  # the boundary of the square grid: its four sides
    inner = np.flatnonzero(((V[:, :2] > lo[:2] + 1e-9) & (V[:, :2] < hi[:2] - 1e-9)).all(axis=1))
    dirichlet = np.zeros(len(V))
    dirichlet[inner] = spsolve(A[inner][:, inner].tocsc(), b[inner])
    assert np.abs(dirichlet - neumann).max() > 5e-5 * neumann.max()  # the two differ (near the boundary)
    np.testing.assert_allclose(solver.heat(np.array([s])), 0.5 * (neumann + dirichlet), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("solver", ["HeatMethodSolver", "LogHeatSolver"])
@pytest.mark.parametrize("operators", ["auto", "intrinsic", "extrinsic"])
def test_a_mesh_without_faces_is_refused(solver, operators):
    # libigl's operators end the process on an empty face list (a segmentation fault)
    V = np.random.default_rng(0).random((4, 3))
    with pytest.raises(ValueError, match="no faces"):
        getattr(gd, solver)(V, np.zeros((0, 3), dtype=np.int64), 1.0, operators=operators)


def test_heat_solver_reuses_its_factorization(make_fixtures):
    V, F = make_fixtures.icosphere(3)
    h = gd.mean_edge_length(V, F)
    solver = gd.HeatMethodSolver(V, F, h * h)
    solver.solve([5])
    again = solver.solve([17])[0]
    fresh = gd.heat_method_distance(V, F, np.array([17]), h * h)
    assert np.abs(again - fresh).max() < 1e-12
    arc = np.arccos(np.clip(V @ V[17], -1, 1))
    assert gd.compare_to_reference(again, arc)["mean_relative_error"] < 0.02


def test_varadhan_matches_direct_heat_solve(make_fixtures):
    V, F = make_fixtures.icosphere(2)
    L, M = gd.cotan_laplacian(V, F), gd.lumped_mass(V, F)
    T = 0.05
    d, u = gd.varadhan_distance(L, M, np.array([0]), T, steps=2)
    A = (sp.diags(M) - (T / 2) * L).tocsc()
    u_ref = spsolve(A, M * spsolve(A, M * np.eye(len(M))[0]))
    assert np.allclose(u, u_ref, rtol=1e-10, atol=0)
    assert np.allclose(d, np.sqrt(-4 * T * np.log(u_ref)), rtol=1e-10)
    # the factorization made ahead (the report's setup, reusable for more sources): same bits
    from geoproc.geodesic.varadhan import heat_step_factor

    d2, u2 = gd.varadhan_distance(L, M, np.array([0]), T, steps=2, factor=heat_step_factor(L, M, T / 2))
    assert np.array_equal(d2, d) and np.array_equal(u2, u)


# ---- the discrete log ODE -------------------------------------------------------------------

def _sphere_operators(make_fixtures, sub=2):
    V, F = make_fixtures.icosphere(sub)
    L, M = gd.intrinsic_delaunay_laplacian(V, F)
    return V, F, L, M, gd.mean_edge_length(V, F)


def test_intrinsic_delaunay_laplacian_has_the_needed_signs(make_fixtures):
    V, F = make_fixtures.torus()
    L, M = gd.intrinsic_delaunay_laplacian(V, F)
    off = sp.triu(L, 1).tocoo()
    assert (off.data >= 0).all()
    assert np.abs(np.asarray(L.sum(axis=1))).max() < 1e-12
    assert M.sum() == pytest.approx(4 * np.pi**2 * 1.0 * 0.35, rel=0.01)  # torus area


def test_log_ode_equals_log_of_the_linear_step_where_representable(make_fixtures):
    V, F, L, M, h = _sphere_operators(make_fixtures)
    T = h * h
    w, _ = log_ode_steps(L, M, [0, 40], T, steps=3)
    A = (sp.diags(M) - (T / 3) * L).tocsc()
    u = np.zeros(len(M))
    u[[0, 40]] = 1.0
    for _ in range(3):
        u = spsolve(A, M * u)
    assert np.abs(w - np.log(u)).max() < 1e-10


@pytest.mark.parametrize("factor,steps", [(1.0, 1), (1.0, 3), (1e-3, 2)])
def test_log_ode_fast_solvers_equal_cvxpy_clarabel(make_fixtures, factor, steps):
    pytest.importorskip("cvxpy")
    V, F, L, M, h = _sphere_operators(make_fixtures)
    T = factor * h * h
    w_lu, _ = log_ode_steps(L, M, [0, 100], T, steps, solver="lu")
    w_newton, _ = log_ode_steps(L, M, [0, 100], T, steps, solver="newton")
    w_cvx, _ = log_ode_steps(L, M, [0, 100], T, steps, solver="cvxpy")
    assert np.abs(w_lu - w_cvx).max() < 1e-6
    assert np.abs(w_newton - w_cvx).max() < 1e-6



def _splitting_solver(make_fixtures, n, T, steps):
    from geoproc.geodesic.log_splitting import LogSplittingSolver

    V, F = make_fixtures.grid(n)
    L, M = gd.laplacian_and_mass(V, F, "cotan")
    return V, LogSplittingSolver(V, F, L, M, T, steps)


def test_log_splitting_nonlinear_step_lifts_a_linear_function_by_dt_slope_squared(make_fixtures):
    # w' linear with slope a: its gradient is exact on any triangulation, and the
    # backward-Euler step of dw/dt = |grad w|^2 lifts it by dt |a|^2 (Hopf-Lax: the
    # maximizer sits 2 dt |a| = 0.02 away, under one grid spacing, so the border of
    # the patch does not interfere).
    pytest.importorskip("cvxpy")
    V, S = _splitting_solver(make_fixtures, 21, 2e-4, 1)
    slope = np.array([30.0, -40.0])  # |a| = 50, values span 70 units like a log-heat field
    w1 = V[:, :2] @ slope
    lift = S.dt * 50.0**2
    w = S.nonlinear_step(w1)
    assert np.abs(w - (w1 + lift)).max() < 1e-5 * lift  # measured 1.6e-6



def test_log_splitting_step_from_the_log_floor_reaches_the_optimum(make_fixtures):
    # The program is invariant under w -> w - c (c constant) except for its objective, so
    # at the optimum some constraint is active: min slack 0. From a log-delta at the
    # 1e-300 floor (values down to -690) the unscaled program stopped with every
    # constraint slack by several units.
    pytest.importorskip("cvxpy")
    from geoproc.geodesic.operators import face_gradient_matrix, face_to_vertex_average

    _, S = _splitting_solver(make_fixtures, 21, 1e-3, 1)
    V, F = make_fixtures.grid(21)
    w = np.full(len(V), np.log(1e-300))
    w[220] = 0.0  # the centre
    w1 = S._half.solve(S.M * w)
    w2 = S.nonlinear_step(w1)
    g = (face_gradient_matrix(V, F) @ w2).reshape(3, -1)
    slack = w2 - w1 - S.dt * (face_to_vertex_average(V, F) @ (g**2).sum(axis=0))
    assert slack.min() > -1e-6 * np.ptp(w1) and slack.min() < 1e-6 * np.ptp(w1)

def test_log_splitting_follows_the_plane_heat_kernel_in_log_space(make_fixtures):
    # w = log of the plane heat kernel solves dw/dt = Lap w + |grad w|^2 exactly; away from
    # the patch's (Neumann) border the scheme must track it, better as the step shrinks.
    pytest.importorskip("cvxpy")
    t0, T = 0.01, 0.005
    errors = []
    for steps in (4, 8):
        V, S = _splitting_solver(make_fixtures, 21, T, steps)
        r2 = ((V[:, :2] - 0.5) ** 2).sum(axis=1)

        def kernel(t, r2=r2):
            return -np.log(4 * np.pi * t) - r2 / (4 * t)

        inner = r2 < 0.2**2
        change = np.abs(kernel(t0 + T) - kernel(t0))[inner].max()  # 0.41
        errors.append(np.abs(S.evolve(kernel(t0)) - kernel(t0 + T))[inner].max() / change)
    assert errors[0] < 0.1  # measured 0.043
    assert errors[1] < 0.7 * errors[0]  # measured 0.015 (ratio 0.35)


def _splitting_slack(S, V, F, w1, w2):
    """Constraint slack ``w2 - w1 - dt A |G w2|^2`` (n,) of the nonlinear step, in the mesh's units."""
    from geoproc.geodesic.operators import face_gradient_matrix, face_to_vertex_average

    g = (face_gradient_matrix(V, F) @ w2).reshape(3, -1)
    return w2 - w1 - S.dt * (face_to_vertex_average(V, F) @ (g**2).sum(axis=0))


def test_log_splitting_on_a_shrunk_sliver_mesh_converges_and_scales_with_the_mesh(make_fixtures):
    # A torus triangulated with slivers, shrunk 100 times (mean edge 0.0029, like the shared
    # meshes as stored): posed in the mesh's own length unit, Clarabel stopped there with
    # MaxIterations. In units of the mean edge length every step converges, and since
    # t = h^2 the distances scale exactly with the mesh (cotan L unchanged, M and t times s^2).
    pytest.importorskip("clarabel")
    from geoproc.geodesic.log_splitting import LogSplittingSolver

    V0, F = make_fixtures.torus(r=0.4, nu=60, nv=20, twist=3)
    dist = {}
    for s in (1.0, 0.01):
        V = s * V0
        h = gd.mean_edge_length(V, F)
        L, M = gd.laplacian_and_mass(V, F, "cotan")
        S = LogSplittingSolver(V, F, L, M, h * h)
        dist[s] = S.solve([0])[0]
        assert S.status == "Solved"  # measured 19 iterations at both sizes
        w = np.full(len(V), np.log(S.floor))
        w[0] = 0.0
        w1 = S._half.solve(S.M * w)
        slack = _splitting_slack(S, V, F, w1, S.nonlinear_step(w1)) / np.ptp(w1)
        assert -1e-7 < slack.min() < 1e-7  # feasible, and some constraint active (the optimum)
    assert np.abs(dist[0.01] / 0.01 - dist[1.0]).max() < 1e-6 * dist[1.0].max()


@pytest.mark.slow
def test_log_splitting_converges_on_camelhead_with_default_parameters(shared_data):
    # camelhead (11.4k vertices, h = 0.012, sliver faces with 0.9 and 170 degree corners):
    # with the gradient in the mesh's unit Clarabel stopped with InsufficientProgress.
    pytest.importorskip("clarabel")
    m, ref = _shared_exact(shared_data, "camelhead.off", 0)
    r = gd.geodesic_distance(m.V, m.F, [0], "log-splitting")
    c = gd.compare_to_reference(r.distance, ref)
    assert c["nonfinite_vertices"] == 0
    # measured r 0.665, MAE 0.283: one step of t = h^2 from the log floor is coarse (the
    # method, not the solver); the bar checks that a converged, ordered field comes back
    assert c["pearson_r"] > 0.6


def _chain_reference(n, m, a, lg_b):
    """log of the solution of a path-graph system (diag m+deg*a, off -a) by the
    Thomas algorithm in 60-digit Decimal arithmetic (exponent range 1e-999999)."""
    getcontext().prec = 60
    getcontext().Emin = -999999
    A = [Decimal(a)] * n
    diag = [Decimal(m) + Decimal(a) * (1 if i in (0, n - 1) else 2) for i in range(n)]
    b = [Decimal(0)] * n
    b[0] = Decimal(lg_b).exp()
    c, dd = [Decimal(0)] * n, [Decimal(0)] * n
    c[0], dd[0] = -A[0] / diag[0], b[0] / diag[0]
    for i in range(1, n):
        den = diag[i] + A[i] * c[i - 1]
        c[i] = -A[i] / den
        dd[i] = (b[i] + A[i] * dd[i - 1]) / den
    x = [Decimal(0)] * n
    x[-1] = dd[-1]
    for i in range(n - 2, -1, -1):
        x[i] = dd[i] - c[i] * x[i + 1]
    return np.array([float(v.ln()) for v in x])


def test_log_lu_solve_far_below_double_range():
    # a 400-vertex path with a tiny time step: the answer falls to ~1e-2400
    n, m, a = 400, 1.0, 1e-6
    rows = np.arange(n - 1)
    Lp = sp.coo_matrix((np.full(n - 1, a), (rows, rows + 1)), shape=(n, n))
    Lp = (Lp + Lp.T).tocsr()
    A = sp.diags(m + np.asarray(Lp.sum(axis=1)).ravel()) - Lp
    lb = np.full(n, -np.inf)
    lb[0] = 0.0
    w = LogMMatrixSolver(A).solve_log(lb)
    ref = _chain_reference(n, m, a, 0.0)
    assert ref.min() < -5000 and np.isfinite(w).all()
    assert np.abs(w - ref).max() < 1e-9 * np.abs(ref).max()


def test_log_ode_solver_and_newton_agree_at_tiny_time(make_fixtures):
    V, F, L, M, h = _sphere_operators(make_fixtures, 4)
    T = 1e-12 * h * h
    w_prev = np.full(len(M), -np.inf)
    w_prev[0] = 0.0
    w_lu, _ = LogODESolver(L, M, T).step(w_prev)
    w_nt, it = log_ode_step(LogStepSystem(L, M, T), w_prev)
    assert w_lu.min() < -745.2  # exp(w) is below the smallest double there
    assert np.isfinite(w_lu).all() and np.isfinite(w_nt).all()
    assert np.abs(w_lu - w_nt).max() < 1e-9 * np.abs(w_nt).max()


def test_log_ode_step_polishes_a_slightly_wrong_factorization(make_fixtures):
    # the simplified-Newton refinement of LogODESolver.step: with the factor's diagonal
    # off by 1e-9 (relative) the log-space solve is off by about as much; the
    # refinement, using those same factors, must bring it to the exact step without
    # the Newton fallback (stepping the wrong way, it ends in the fallback)
    V, F, L, M, h = _sphere_operators(make_fixtures, 3)
    dt = h * h
    solver = LogODESolver(L, M, dt)
    solver.lu.solve_log_in_range = lambda log_b: None  # the log-space path, as outside the double range
    _, (indptr, indices, logabs, logdiag) = solver.lu.log_factors()
    solver.lu._U = (indptr, indices, logabs + 1e-9, logdiag + 1e-9)
    b = np.zeros(len(M))
    b[0] = 1.0 / M[0]
    with np.errstate(divide="ignore"):
        w_prev = np.log(b)
    w, passes = solver.step(w_prev)
    u = spsolve((sp.diags(M) - dt * L).tocsc(), M * b)
    assert passes >= 1 and solver.fallbacks == 0
    assert np.abs(np.exp(w) - u).max() < 1e-12 * u.max()


@pytest.mark.parametrize("method,lap", [("log-ode", "intrinsic-delaunay"), ("varadhan", "intrinsic-delaunay"),
                                        ("log-heat", "intrinsic-delaunay"), ("heat", "cotan")])
def test_faces_whose_edge_lengths_give_zero_area_are_refused_by_every_method(make_fixtures, method, lap):
    # a point 2e-12 edge lengths off an edge's midpoint: the cross product gives an area, the
    # edge lengths none; the intrinsic methods were let through, and libigl's intrinsic
    # Delaunay flips then allocated without end (a bunny with 20 such faces was killed)
    from geoproc.geodesic.distance import require_method_mesh

    V, F = make_fixtures.icosphere(2)
    V, F = [tuple(v) for v in V], [list(f) for f in F]
    for i in (10, 50, 90, 130):
        a, b, c = F[i]
        A, B, C = map(np.array, (V[a], V[b], V[c]))
        mid, h = (A + B) / 2, np.linalg.norm(B - A)
        V.append(tuple(mid + (C - mid) / np.linalg.norm(C - mid) * h * 2e-12))
        p = len(V) - 1
        F[i] = [a, b, p]
        F += [[b, c, p], [c, a, p]]
    V, F = np.array(V), np.array(F)
    with pytest.raises(InputError, match="faces are too thin .* their edge lengths give zero area"):
        require_method_mesh(V, F, method, lap=lap, ops="intrinsic" if method == "log-heat" else None, path="m.ply")


def test_negative_distance_vertices_counts_clipped_vertices_not_sources(make_fixtures):
    # the count took the sources too, which are set to 0 whatever they came out as:
    # every other torus vertex a source gave 288, all of them sources, none clipped
    from geoproc.geodesic.heat import HeatMethodSolver

    V, F = make_fixtures.torus()
    h = gd.mean_edge_length(V, F)
    src = np.random.default_rng(0).choice(len(V), 200, replace=False)
    raw, _ = HeatMethodSolver(V, F, h * h).solve(src)  # before the clipping
    others = np.setdiff1d(np.arange(len(V)), src)
    res = gd.geodesic_distance(V, F, src, "heat")
    assert res.stats["negative_distance_vertices"] == int((raw[others] < 0).sum()) > 0
    assert (res.distance >= 0).all() and (res.distance[src] == 0).all()
    every_other = np.arange(0, len(V), 2)
    raw, _ = HeatMethodSolver(V, F, h * h).solve(every_other)
    assert (raw[every_other] < 0).sum() > 100  # sources below 0: not counted
    assert gd.geodesic_distance(V, F, every_other, "heat").stats["negative_distance_vertices"] == \
        int((raw[1::2] < 0).sum())


def test_pearson_r_stays_within_one():
    from geoproc.geodesic.compare import compare_to_reference

    ref = np.array([1.6, 0.9, 1.5, 2.7, 2.8, 1.1, 1.7])  # d == ref: rounding gave 1.0000000000000002
    assert compare_to_reference(ref.copy(), ref)["pearson_r"] == 1.0
    assert compare_to_reference(-ref + 5, ref)["pearson_r"] == -1.0


def test_log_lu_solves_in_ordinary_arithmetic_only_within_the_double_range(make_fixtures):
    V, F, L, M, h = _sphere_operators(make_fixtures, 3)
    lu = LogMMatrixSolver(sp.diags(M) - h * h * L)
    lb = np.full(len(M), -np.inf)
    lb[[0, 7]] = [0.0, -3.0]
    w = lu.solve_log_in_range(lb)
    assert w is not None
    assert np.abs(w - lu.solve_log(lb)).max() < 1e-13 * np.abs(w).max()
    # the tiny-time path graph of test_log_lu_solve_far_below_double_range: declined
    n, a = 400, 1e-6
    rows = np.arange(n - 1)
    Lp = sp.coo_matrix((np.full(n - 1, a), (rows, rows + 1)), shape=(n, n))
    Lp = (Lp + Lp.T).tocsr()
    path = LogMMatrixSolver(sp.diags(1.0 + np.asarray(Lp.sum(axis=1)).ravel()) - Lp)
    lb = np.full(n, -np.inf)
    lb[0] = 0.0
    assert path.solve_log_in_range(lb) is None
    # a vertex the heat cannot reach (two separate blocks), or b beyond exp's range: declined
    two = LogMMatrixSolver(sp.block_diag([sp.diags(M) - h * h * L] * 2))
    lb = np.full(2 * len(M), -np.inf)
    lb[0] = 0.0
    assert two.solve_log_in_range(lb) is None
    lb[len(M)] = -800.0
    assert two.solve_log_in_range(lb) is None


def test_log_space_factors_are_built_only_when_a_solve_needs_them(make_fixtures):
    # they took as much memory as the factorization (log-heat on a 345k-face armadillo:
    # 970 MB peak with them always built, 767 MB without)
    V, F, L, M, h = _sphere_operators(make_fixtures, 3)
    w_prev = np.full(len(M), -np.inf)
    w_prev[0] = -np.log(M[0])
    solver = LogODESolver(L, M, h * h)
    solver.step(w_prev)
    assert solver.lu._L is None  # every value in the double range: not built
    V, F, L, M, h = _sphere_operators(make_fixtures, 4)
    w_prev = np.full(len(M), -np.inf)
    w_prev[0] = 0.0
    tiny = LogODESolver(L, M, 1e-12 * h * h)  # exp(w) below the smallest double: on logarithms
    w, _ = tiny.step(w_prev)
    assert w.min() < -745.2 and tiny.lu._L is not None


def test_log_ode_step_redoes_a_bad_ordinary_solve_on_logs(make_fixtures):
    # an ordinary-arithmetic result whose residual is not small is replaced by
    # the log-space solve (not polished from, and not sent to the Newton fallback)
    V, F, L, M, h = _sphere_operators(make_fixtures, 3)
    dt = h * h
    solver = LogODESolver(L, M, dt)
    exact = solver.lu.solve_log_in_range
    solver.lu.solve_log_in_range = lambda log_b: exact(log_b) + np.linspace(0.0, 1e-3, len(M))
    w_prev = np.full(len(M), -np.inf)
    w_prev[0] = -np.log(M[0])
    w, passes = solver.step(w_prev)
    u = spsolve((sp.diags(M) - dt * L).tocsc(), np.eye(len(M))[0])
    assert solver.fallbacks == 0 and passes <= 1
    assert np.abs(np.exp(w) - u).max() < 1e-12 * u.max()


def test_log_ode_residual_is_the_log_of_the_linear_residual(make_fixtures):
    # g = w + c - lse(w) is log of (M - dt L) e^w over the right-hand side M e^w_prev;
    # checked in ordinary arithmetic, where nothing underflows
    V, F, L, M, h = _sphere_operators(make_fixtures, 3)
    dt = h * h
    solver = LogODESolver(L, M, dt)
    rng = np.random.default_rng(2)
    w_prev, w = rng.normal(-3, 1, len(M)), rng.normal(-3, 1, len(M))
    g, val = solver.residual(w, w_prev)
    u, u_prev = np.exp(w), np.exp(w_prev)
    rhs = M * u_prev + dt * (L @ u - L.diagonal() * u)  # M_i u_prev_i + dt sum_(j != i) L_ij u_j
    assert np.abs(val - np.log(rhs)).max() < 1e-13
    assert np.abs(g - np.log((M - dt * L.diagonal()) * u / rhs)).max() < 1e-13
    w[:5] = -np.inf  # no heat there: no residual, and no heat from there
    w_prev[:5] = -np.inf
    g, val = solver.residual(w, w_prev)
    assert (g[:5] == 0).all() and np.isfinite(g).all() and np.isfinite(val[5:]).all()


def test_face_heat_direction_is_the_gradient_of_the_heat(make_fixtures):
    from geoproc.geodesic.log_heat import face_heat_direction
    from geoproc.geodesic.operators import face_gradient_coefficients, face_gradient_matrix

    V, F = make_fixtures.icosphere(2)
    coef = face_gradient_coefficients(V, F)
    rng = np.random.default_rng(4)
    w = rng.normal(-3, 1, len(V))
    f0, f1, f2 = 0, 100, 200
    assert len(np.unique(F[[f0, f1, f2]])) == 9  # no shared vertex
    w[F[f0]] = -np.inf  # a face without heat
    w[F[f1]] = [-np.inf, -3.0, -2.0]  # heat on two corners only
    w[F[f2]] = -2.5  # constant: no direction
    ref = (face_gradient_matrix(V, F) @ np.exp(w)).reshape(3, -1).T
    live = np.ones(len(F), dtype=bool)
    live[[f0, f2]] = False
    for shift in (0.0, -1e4):  # e^w below the double range: the direction stays
        g = face_heat_direction(coef, F, w + shift)
        cos = np.einsum("ij,ij->i", g, ref)[live] / np.linalg.norm(g[live], axis=1) / np.linalg.norm(ref[live], axis=1)
        assert np.abs(cos - 1).max() < 1e-9
        assert (g[[f0, f2]] == 0).all()


def test_log_ode_refuses_negative_weights(make_fixtures):
    V, F = make_fixtures.icosphere(2)
    V = V * np.array([1.0, 1.0, 0.05])  # flattened: obtuse triangles, negative cotan weights
    L, M = gd.cotan_laplacian(V, F), gd.lumped_mass(V, F)
    with pytest.raises(UsageError, match="intrinsic-delaunay"):
        log_ode_steps(L, M, [0], 0.01)


# ---- dispatcher checks -----------------------------------------------------------------------

def test_unreachable_vertices_are_inf(make_fixtures):
    V1, F1 = make_fixtures.grid(11)
    V = np.vstack([V1, V1 + [2.0, 0, 0]])
    F = np.vstack([F1, F1 + len(V1)])
    for method in ("exact", "heat", "log-ode", "log-heat", "varadhan"):
        r = gd.geodesic_distance(V, F, [0], method)
        assert r.stats["unreachable_vertices"] == len(V1)
        assert np.isinf(r.distance[len(V1):]).all() and np.isfinite(r.distance[:len(V1)]).all()


@pytest.mark.parametrize("kwargs,err", [
    ({"sources": [441]}, InputError),
    ({"sources": []}, UsageError),
    ({"time": 0.0}, UsageError),
    ({"time": float("inf")}, UsageError),
    ({"time_factor": -1.0}, UsageError),
    ({"steps": 0}, UsageError),
    ({"method": "dijkstra"}, UsageError),
])
def test_bad_arguments(make_fixtures, kwargs, err):
    V, F = make_fixtures.grid()
    args = {"sources": [0]} | kwargs
    with pytest.raises(err):
        gd.geodesic_distance(V, F, args.pop("sources"), args.pop("method", "heat"), **args)


def test_compare_to_reference_by_hand():
    ref = np.array([0.0, 1.0, 2.0, 4.0])
    d = np.array([0.0, 1.4, 2.0, 3.6])
    c = gd.compare_to_reference(d, ref)
    assert c["mae"] == pytest.approx(0.8 / 4 / 4)
    assert c["rmse"] == pytest.approx(np.sqrt((0.1**2 + 0.1**2) / 4))
    assert c["max_relative_error"] == pytest.approx(0.1)
    assert c["pearson_r"] == pytest.approx(np.corrcoef(d, ref)[0, 1])


def test_intrinsic_delaunay_laplacian_matches_robust_laplacian(shared_data):
    import robust_laplacian

    m = load_mesh(shared_data / "meshes" / "bunny.off")
    L, M = gd.intrinsic_delaunay_laplacian(m.V, m.F)
    Lr, Mr = robust_laplacian.mesh_laplacian(m.V, m.F, mollify_factor=0.0)
    assert abs(L + Lr).max() < 1e-9 * abs(Lr).max()
    assert np.abs(M - Mr.diagonal()).max() < 1e-12 * M.max()


def test_face_gradient_weights_equal_libigl_grad(make_fixtures):
    import igl

    from geoproc.geodesic.operators import face_gradient_coefficients, stack_gradient_coefficients

    V, F = make_fixtures.icosphere(2)
    V = V * np.array([1.0, 0.5, 2.0])  # anisotropic: faces of varied shapes
    G = stack_gradient_coefficients(face_gradient_coefficients(V, F), F, len(V))
    ref = sp.csr_matrix(igl.grad(V, F))
    assert abs(G - ref).max() <= 1e-10 * abs(ref).max()
    # a linear function's gradient is its slope projected onto each face's plane
    a = np.array([0.3, -1.2, 0.7])
    N = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    assert np.allclose((G @ (V @ a)).reshape(3, -1).T, a - (N @ a)[:, None] * N, atol=1e-12)


def test_stacked_gradient_and_divergence_equal_their_dense_definitions(make_fixtures):
    from geoproc.geodesic.operators import (
        face_areas,
        face_gradient_coefficients,
        integrated_divergence,
        stack_gradient_coefficients,
    )

    V, F = make_fixtures.icosphere(1)
    V = V * np.array([1.0, 0.5, 2.0])
    F = np.vstack([F, [[0, 0, 5]]])  # a repeated vertex: its entries add up (to zero: no area)
    coef = face_gradient_coefficients(V, F)
    for f in (F, F[:, ::-1]):  # corners out of column order
        c = coef if f is F else coef[:, :, ::-1]
        dense = np.zeros((3 * len(f), len(V)))
        for a in range(3):
            for k in range(len(f)):
                for j in range(3):
                    dense[a * len(f) + k, f[k, j]] += c[a, k, j]
        G = stack_gradient_coefficients(c, f, len(V))
        assert np.array_equal(G.toarray(), dense)
        area = face_areas(V, f)
        assert np.array_equal(integrated_divergence(G, area).toarray(), -(dense * np.tile(area, 3)[:, None]).T)


def test_divergence_leaves_out_faces_without_area(make_fixtures):
    # libigl's gradient is NaN on a zero-area face; the face carries no area, so no divergence
    V, F = make_fixtures.icosphere(1)
    V = np.vstack([V, [[3.0, 0, 0], [4, 0, 0], [5, 0, 0]]])
    n = len(V)
    for extra in ([n - 3, n - 2, n - 1], [0, 0, 5]):  # collinear corners, a repeated vertex
        Fx = np.vstack([F, [extra]])
        D = gd.divergence_matrix(V, Fx)
        assert np.isfinite(D.data).all()
        X = np.random.default_rng(0).standard_normal(3 * len(Fx))
        Dref = gd.divergence_matrix(V, F)  # the same mesh without that face
        keep = np.r_[np.arange(len(F)), len(Fx) + np.arange(len(F)), 2 * len(Fx) + np.arange(len(F))]
        assert np.abs(D @ X - Dref @ X[keep]).max() <= 1e-12 * np.abs(Dref @ X[keep]).max()


def test_upper_triangle_for_the_factorization_equals_scipy_triu():
    from geoproc.geodesic.operators import factor_sparse, upper_triangle_csc

    rng = np.random.default_rng(3)
    R = sp.random(40, 40, density=0.1, random_state=rng)
    A = (R + R.T + 40 * sp.eye(40)).tocsr()
    ref = sp.triu(A, format="csc")
    for X in (A, A.tocsc(), A.tocoo(), sp.coo_matrix((np.r_[A.tocoo().data, 1.0], (np.r_[A.tocoo().row, 3],
                                                              np.r_[A.tocoo().col, 3])))):
        U = upper_triangle_csc(X)
        if X.nnz > A.nnz:  # a duplicate entry, summed
            assert U[3, 3] == A[3, 3] + 1.0
            continue
        assert abs(U - ref).max() == 0 and U.nnz == ref.nnz and U.has_sorted_indices
    b = rng.standard_normal(40)
    assert np.abs(A @ factor_sparse(A).solve(b) - b).max() < 1e-12
    N = (A + sp.triu(sp.random(40, 40, density=0.1, random_state=rng), 1)).tocsr()  # not symmetric
    assert abs(upper_triangle_csc(N) - sp.triu(N, format="csc")).max() == 0
    U = sp.triu(N)  # QDLDL reads the upper triangle: the solution is that of U + U^T - diag
    S = (U + U.T - sp.diags(N.diagonal())).tocsr()
    assert np.abs(S @ factor_sparse(N).solve(b) - b).max() < 1e-12


def test_compiled_face_kernels_agree_with_numpy(make_fixtures):
    from geoproc.geodesic.face_kernels import face_gradient_coefficients_compiled, smallest_angles_compiled
    from geoproc.geodesic.operators import face_gradient_coefficients, smallest_angles

    V, F = make_fixtures.icosphere(2)
    V = V * np.array([1.0, 0.3, 2.0])
    # a needle, a face repeating a vertex, one repeating it three times, and three corners at one point
    V = np.vstack([V, [[0.0, 0, 0], [1, 0, 0], [0.5, 0.5e-12, 0], [2, 2, 2], [2, 2, 2], [2, 2, 2]]])
    n = len(V)
    F = np.vstack([F, [[n - 6, n - 5, n - 4], [0, 0, 1], [7, 7, 7], [n - 3, n - 2, n - 1]]])
    a, b = smallest_angles_compiled(V, F), smallest_angles(V, F)
    assert np.abs(a - b).max() <= 1e-15 * np.pi and (a[-3:] == 0).all() and (b[-3:] == 0).all()
    assert np.isclose(a[-4], 2e-12, rtol=1e-6)
    c, d = face_gradient_coefficients_compiled(V, F), face_gradient_coefficients(V, F)
    assert np.abs(c - d).max() <= 1e-15 * np.abs(d).max() and (c[:, -3:] == 0).all()


def test_negative_weights_are_counted_once_per_edge(make_fixtures):
    from geoproc.geodesic.operators import cotan_laplacian, negative_offdiagonal_count

    V, F = make_fixtures.icosphere(2)
    for stretch in ([1.0, 1.0, 1.0], [1.0, 0.2, 3.0]):  # Delaunay, then with obtuse angles
        L = cotan_laplacian(V * np.array(stretch), F)
        expected = int((np.triu(L.toarray(), 1) < 0).sum())
        assert negative_offdiagonal_count(L) == expected
        assert negative_offdiagonal_count(L.tocoo()) == expected
        # stored twice, in halves (not canonical)
        dup = sp.csr_matrix((np.repeat(L.data / 2, 2), np.repeat(L.indices, 2), 2 * L.indptr), shape=L.shape)
        assert not dup.has_canonical_format and negative_offdiagonal_count(dup) == expected
    assert expected > 0
    P = sp.csr_matrix(np.array([[1.0, -1.0], [-1.0, -2.0]]))  # a positive diagonal entry beside a negative weight
    assert negative_offdiagonal_count(P) == 1


def test_smallest_angle_against_the_arccosine_of_each_corner(make_fixtures):
    from geoproc.geodesic.operators import smallest_angles

    V, F = make_fixtures.icosphere(2)
    V = V * np.array([1.0, 0.3, 2.0])
    P = V[F]
    ref = np.full(len(F), np.pi)
    for c in range(3):
        u, v = P[:, (c + 1) % 3] - P[:, c], P[:, (c + 2) % 3] - P[:, c]
        cos = np.einsum("ij,ij->i", u, v) / np.linalg.norm(u, axis=1) / np.linalg.norm(v, axis=1)
        ref = np.minimum(ref, np.arccos(cos))
    assert np.abs(smallest_angles(V, F) - ref).max() < 1e-12
    # a needle of 1e-12 rad (its arccosine is 0) and a face with a repeated vertex
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 0.5e-12, 0]])
    assert np.isclose(smallest_angles(V, np.array([[0, 1, 2]]))[0], 2e-12, rtol=1e-6)
    assert smallest_angles(V, np.array([[0, 1, 2], [0, 0, 1]]))[1] == 0.0


# ---- operators on the intrinsic Delaunay triangulation ----------------------------------------

def test_intrinsic_gradient_and_divergence_give_the_intrinsic_laplacian(make_fixtures):
    import igl

    from geoproc.geodesic.intrinsic import intrinsic_face_operators

    V, F = make_fixtures.torus(r=0.4, nu=60, nv=20, twist=3)
    Li, l, Fi = igl.intrinsic_delaunay_cotmatrix(V, F)
    coef, G, D = intrinsic_face_operators(Fi, l, len(V))
    assert abs(D @ G - sp.csr_matrix(Li)).max() < 1e-9 * abs(Li).max()
    # on a flat sheared grid a linear function keeps its slope's length on every intrinsic face
    n = 12
    ys, xs = np.divmod(np.arange(n * n), n)
    Vp = np.c_[xs + 3.0 * ys, ys, np.zeros(n * n)]
    a, b, c, d = (np.add.outer(np.arange(n - 1) * n, np.arange(n - 1)).ravel() + k for k in (0, 1, n + 1, n))
    Fp = np.r_[np.c_[a, b, c], np.c_[a, c, d]]
    _, lp, Fip = igl.intrinsic_delaunay_cotmatrix(Vp, Fp)
    _, Gp, _ = intrinsic_face_operators(Fip, lp, len(Vp))
    a = np.array([0.6, -0.8, 0.0])
    assert np.allclose(np.linalg.norm((Gp @ (Vp @ a)).reshape(2, -1), axis=0), 1.0, atol=1e-9)


def test_sliver_share_counts_faces_with_a_small_angle():
    from geoproc.geodesic.intrinsic import sliver_share

    V = np.array([[0, 0, 0], [1, 0, 0], [0.5, np.sqrt(3) / 2, 0], [2, 0, 0], [1.5, 0.05, 0]], float)
    F = np.array([[0, 1, 2], [1, 3, 4]])  # equilateral, and a face with a ~5.7 deg corner
    assert sliver_share(V, F) == 0.0
    assert sliver_share(V, F, angle_deg=6.0) == 0.5


def test_negative_weight_share_by_hand():
    from geoproc.geodesic.intrinsic import negative_weight_share
    from geoproc.geodesic.operators import cotan_laplacian

    # a flat diamond of two triangles, 0.4 high and 2 wide: the shared edge faces two
    # 157-degree angles, weight (cot + cot) / 2 = -(1 - 0.2^2) / (2 * 0.2) = -2.4; the
    # four outer edges face 11.3-degree angles, weight cot / 2 = 2.5 each
    V = np.array([[-1, 0, 0], [1, 0, 0], [0, 0.2, 0], [0, -0.2, 0]], float)
    F = np.array([[0, 1, 2], [1, 0, 3]])
    assert negative_weight_share(cotan_laplacian(V, F)) == pytest.approx(2.4 / 12.4, rel=1e-12)
    V[2:, 1] *= 5  # 1 high: the angles facing the shared edge are 90 degrees, weight 0
    assert negative_weight_share(cotan_laplacian(V, F)) == 0.0


@pytest.mark.parametrize("method", ["heat", "log-heat"])
def test_auto_takes_intrinsic_operators_on_a_sheared_grid(method):
    # a flat grid sheared by x += y: obtuse, non-Delaunay triangles (18 to 135 degrees), no
    # sliver. With the mesh's own operators heat's error was 5.4 % of the largest distance
    # (log-heat's 25 %) and did not fall with refinement; potpourri3d's is 0.56 %
    n = 41
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    V = np.c_[x.ravel() + y.ravel(), y.ravel(), np.zeros(n * n)]
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    F = np.r_[np.c_[a, a + 1, a + n + 1], np.c_[a, a + n + 1, a + n]]
    src = (n // 2) * n + n // 2
    res = gd.geodesic_distance(V, F, [src], method=method)
    err = np.abs(res.distance - np.linalg.norm(V - V[src], axis=1)).mean() / np.linalg.norm(V - V[src], axis=1).max()
    assert res.stats["operators"] == "intrinsic" and err < 0.01


def test_heat_and_log_heat_with_intrinsic_operators_on_slivers(make_fixtures):
    V, F = make_fixtures.torus(r=0.4, nu=60, nv=20, twist=3)
    h = gd.mean_edge_length(V, F)
    ref = gd.exact_geodesic_distance(V, F, np.array([0]))
    err = {}
    for ops in ("auto", "extrinsic", "intrinsic"):
        solver = gd.LogHeatSolver(V, F, h * h, operators=ops)
        err[ops] = np.abs(solver.solve([0])[0] - ref).mean() / ref.max()
        assert solver.operators == ("extrinsic" if ops == "extrinsic" else "intrinsic")
    heat = gd.HeatMethodSolver(V, F, h * h, operators="intrinsic")
    err["heat"] = np.abs(heat.solve([0])[0] - ref).mean() / ref.max()
    # measured: 0.017 on the intrinsic triangulation, 0.21 with the slivers' own gradients
    assert err["auto"] == err["intrinsic"] < 0.03 < 0.1 < err["extrinsic"]
    assert err["heat"] < 0.03


def test_distances_are_zero_at_sources_and_never_negative(fixture_dir):
    m = load_mesh(fixture_dir / "torus.ply")
    every = np.arange(len(m.V))
    src = [0, 1, 2, 500]
    exact = gd.geodesic_distance(m.V, m.F, src, "exact").distance
    for method in ("heat", "log-heat"):
        # every vertex a source: the heat is the same everywhere up to rounding, so no
        # face has a direction (the normalized rounding noise once left the Poisson
        # step half of the vertices negative, 574 / 558, clipped to 0)
        res = gd.geodesic_distance(m.V, m.F, every, method)
        assert (res.distance == 0).all()
        res = gd.geodesic_distance(m.V, m.F, src, method)
        assert (res.distance >= 0).all() and (res.distance[src] == 0).all()
        assert np.abs(res.distance - exact).mean() < 0.05 * exact.max()


@pytest.mark.parametrize("scale", [1.0, 1e20])
@pytest.mark.parametrize("method", ["heat", "log-heat"])
def test_symmetric_corner_gives_equal_distances(method, scale):
    # the corner tetrahedron is symmetric under permuting the axes, so the three
    # vertices next to the corner are equidistant from it; the far face has a
    # constant heat, whose rounding-noise gradient, normalized, made log-heat
    # give 1.08 / 0.55 / 0.49 (and heat at 1e20 1.04 / 0.38 / 0.71 x 1e20)
    V = scale * np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    F = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    d = gd.geodesic_distance(V, F, [0], method).distance[1:]
    assert np.ptp(d) <= 1e-12 * d.max() and d.max() > 0


def test_sources_must_be_integer_indices_and_arrays_are_checked(make_fixtures):
    V, F = make_fixtures.grid(5)
    for bad in ([1.5], ["1"], [True], None):
        with pytest.raises(UsageError):
            gd.geodesic_distance(V, F, bad, method="exact")
    d = gd.geodesic_distance(V.tolist(), F.astype(np.int32), np.array([0], dtype=np.uint16), method="exact")
    assert np.allclose(d.distance, np.linalg.norm(V - V[0], axis=1), atol=1e-12)
    Vn = V.copy()
    Vn[3] = np.nan
    with pytest.raises(InputError, match="non-finite coordinates"):
        gd.geodesic_distance(Vn, F, [0])
    with pytest.raises(InputError, match="references vertex -1"):
        gd.geodesic_distance(V, np.r_[F, [[0, 5, -1]]], [0])


@pytest.mark.parametrize("corners", [5, 6])
def test_log_heat_interior_vertex_whose_neighbours_all_lie_on_the_boundary(corners):
    # a pentagon or hexagon fanned around its centre: in the Dirichlet half
    # (u = 0 on the boundary) that vertex has no neighbour left, which used to
    # be refused as an isolated vertex; the reference is backward Euler solved
    # in u (not in log u) with libigl's cotan Laplacian and Voronoi mass
    import igl
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    a = 2 * np.pi * np.arange(corners) / corners
    V = np.vstack([np.column_stack([np.cos(a), np.sin(a), np.zeros(corners)]), [[0.0, 0.0, 0.0]]])
    c = corners  # the centre's index
    F = np.array([[k, (k + 1) % c, c] for k in range(c)])
    t, steps = 0.3, 2
    L = sp.csc_matrix(igl.cotmatrix(V, F))
    M = sp.diags(igl.massmatrix(V, F, igl.MASSMATRIX_TYPE_VORONOI).diagonal())
    A = (M - (t / steps) * L).tocsc()
    for source in (c, 1):
        u0 = np.zeros(len(V))
        u0[source] = 1.0 / M.diagonal()[source]  # one unit of heat
        un, ud = u0.copy(), u0.copy()
        ud[:c] = 0.0
        for _ in range(steps):
            un = spla.spsolve(A, M @ un)
            ud[c] = (M @ ud)[c] / A[c, c]  # interior block: the centre alone
        solver = gd.LogHeatSolver(V, F, t, steps, laplacian="cotan", operators="extrinsic")
        w = solver.log_heat(np.array([source]))
        assert np.allclose(np.exp(w), (un + ud) / 2, rtol=1e-10, atol=0), (source, np.exp(w), (un + ud) / 2)
        d, _ = solver.solve([source])
        assert np.isfinite(d).all() and d[source] == 0 and (d >= 0).all()


def test_unweighted_vertex_is_named_by_its_input_index_and_file(make_fixtures, monkeypatch):
    # the methods run on the part of the mesh connected to a source; a vertex
    # their Laplacian cannot reach is reported in the input's numbering
    from geoproc.errors import InputError
    from geoproc.geodesic import distance
    from geoproc.geodesic.log_ode import LogStepSystem, UnweightedVertexError

    L = np.array([[-1.0, 1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 0.0, 0.0]])
    with pytest.raises(UnweightedVertexError) as info:
        LogStepSystem(L, np.ones(3), 0.1)
    assert info.value.vertex == 2 and info.value.path is None
    V, F = make_fixtures.icosphere(1)
    V2 = np.vstack([V, V + [3.0, 0.0, 0.0]])  # a second sphere: the source's starts at vertex len(V)
    F2 = np.vstack([F, F + len(V)])

    def unreachable_vertex_5(*args, **kwargs):
        raise UnweightedVertexError(5)

    monkeypatch.setattr(distance, "_run_method", unreachable_vertex_5)
    with pytest.raises(InputError) as info:
        gd.geodesic_distance(V2, F2, [len(V) + 1], "log-ode", path="two.ply")
    assert info.value.line().startswith(f"two.ply: vertex {len(V) + 5} has no neighbour")


def test_heat_uniform_to_rounding_is_refused_not_returned_as_zeros(make_fixtures):
    # 20 steps to 1e4 h^2 leave log-heat constant to the last bit: every
    # distance was 0 with no warning; one step to the same time still works
    from geoproc.errors import InputError

    V, F = make_fixtures.grid(16)
    with pytest.raises(InputError, match="^grid.ply: the heat .* is uniform in double precision"):
        gd.geodesic_distance(V, F, [0], "log-heat", time_factor=1e4, steps=20, path="grid.ply")
    d = gd.geodesic_distance(V, F, [0], "log-heat", time_factor=1e4, steps=1).distance
    assert d.max() > 0


def test_render_hides_what_is_behind_the_surface(make_fixtures):
    # two spheres along the view axis: the front one is unreachable (grey), and the
    # back one's isolines and source had been drawn across it
    import io

    import matplotlib.image

    from geoproc.geodesic.render import render_distance_png

    V, F = make_fixtures.icosphere(3)
    V2 = np.vstack([V, V + [0.0, 0.0, 3.0]])
    F2 = np.vstack([F, F + len(V)])
    d = np.concatenate([np.linalg.norm(V - V[0], axis=1), np.full(len(V), np.inf)])
    src = [int(np.argmin(V[:, 2]))]  # on the far side of the back sphere
    stacked = matplotlib.image.imread(io.BytesIO(render_distance_png(V2, F2, d, src)))[..., :3]
    alone = matplotlib.image.imread(io.BytesIO(render_distance_png(V, F, d[:len(V)], src)))[..., :3]
    dark = lambda img: (img.max(axis=-1) < 0.15).mean()  # noqa: E731  black isoline pixels
    red = lambda img: ((img[..., 0] > 0.8) & (img[..., 1] < 0.3)).sum()  # noqa: E731
    assert dark(alone) > 0.001 and dark(stacked) == 0.0
    assert red(stacked) == 0
    # one source as a plain index, the distances as a list: the same picture
    assert render_distance_png(V, F, d[:len(V)].tolist(), src[0]) == render_distance_png(V, F, d[:len(V)], src)


def test_render_draws_isolines_whatever_the_winding_frames_the_surface_and_keeps_dollars(make_fixtures):
    # isolines went on the faces whose winding faced the camera: none on a mesh wound
    # inwards; vertices no face uses stretched the frame; a '$' in the title (the file's
    # name) was read as matplotlib math and ended the run as an internal error
    import io

    import matplotlib.image

    from geoproc.geodesic.render import render_distance_png

    V, F = make_fixtures.icosphere(3)
    d = np.linalg.norm(V - V[0], axis=1)
    img = lambda *a, **k: matplotlib.image.imread(io.BytesIO(render_distance_png(*a, **k)))[..., :3]  # noqa: E731
    dark = lambda im: (im.max(axis=-1) < 0.15).mean()  # noqa: E731  black isoline pixels
    out, inward = img(V, F, d), img(V, F[:, ::-1], d)
    assert dark(out) > 0.001 and abs(dark(inward) - dark(out)) < 0.1 * dark(out)
    far = np.vstack([V, [[9.0, 9.0, 9.0]]])
    assert np.array_equal(img(far, F, np.append(d, np.inf)), out)
    assert img(V, F, d, title="a$_$b.ply: heat").shape == out.shape


@pytest.mark.parametrize("method,options", [
    ("log-ode", {}), ("log-heat", {}), ("heat", {"operators": "intrinsic"}),
    ("varadhan", {"laplacian": "intrinsic-delaunay"}),
])
def test_intrinsic_operators_do_not_depend_on_the_unit_or_position(fixture_dir, method, options):
    # every square of the grid is cocircular: either diagonal is Delaunay, and rounding picked one
    # (log-ode differed by 4 % of max d at 1000x, the heat operators by 1 %)
    m = load_mesh(fixture_dir / "grid.ply")
    d = gd.geodesic_distance(m.V, m.F, [0], method=method, **options).distance
    for V, s in ((m.V * 1000.0, 1000.0), (m.V * 1e-3, 1e-3), (m.V + [1e4, -3e4, 2e4], 1.0)):
        other = gd.geodesic_distance(V, m.F, [0], method=method, **options).distance / s
        assert np.abs(other - d).max() <= 1e-10 * d.max()


@pytest.mark.parametrize("method", ["log-ode", "log-heat"])
def test_intrinsic_operators_do_not_depend_on_storage_precision(fixture_dir, tmp_path, method):
    # the torus's trapezoids are cocircular; stored as float32 or at 8 decimals their
    # cotangent sums came back up to 1e-6 from zero, beyond the old 1e-9 tolerance, and
    # the rounding chose the diagonals again: log-ode moved by 4.8e-3 (float32 PLY) and
    # 4.4e-2 (OBJ) of max d, log-heat by 4.0e-3 and 2.8e-3; the positions by 6e-8 at most
    import trimesh
    from trimesh.exchange import ply

    m = load_mesh(fixture_dir / "torus.ply")
    tm = trimesh.Trimesh(m.V, m.F, process=False)
    (tmp_path / "f32.ply").write_bytes(ply.export_ply(tm, encoding="binary"))  # float32 coordinates
    tm.export(tmp_path / "t.obj")  # 8 decimals
    d = gd.geodesic_distance(m.V, m.F, [0], method=method).distance
    for name in ("f32.ply", "t.obj"):
        o = load_mesh(tmp_path / name)
        assert o.F.tolist() == m.F.tolist() and 0 < np.abs(o.V - m.V).max() <= 1e-7
        other = gd.geodesic_distance(o.V, o.F, [0], method=method).distance
        assert np.abs(other - d).max() <= 1e-6 * d.max()


@pytest.mark.parametrize("method,options", [
    ("log-ode", {}), ("log-heat", {}), ("heat", {"operators": "intrinsic"}),
    ("varadhan", {"laplacian": "intrinsic-delaunay"}),
])
@pytest.mark.parametrize("name", ["grid.ply", "torus.ply"])
def test_intrinsic_operators_do_not_depend_on_the_numbering(fixture_dir, name, method, options):
    # cocircular quads took the diagonal of their smallest vertex index: relabelling the
    # vertices moved the barycentric mass by up to 49 % and the distances by up to 7 % of max d
    m = load_mesh(fixture_dir / name)
    d = gd.geodesic_distance(m.V, m.F, [0], method=method, **options).distance
    rng = np.random.default_rng(1)
    perm = rng.permutation(len(m.V))  # new vertex k is old vertex perm[k]
    inv = np.argsort(perm)
    F = np.roll(inv[m.F], 1, axis=1)[rng.permutation(len(m.F))]  # faces reordered, corners rotated
    other = gd.geodesic_distance(m.V[perm], F, [inv[0]], method=method, **options).distance[inv]
    assert np.abs(other - d).max() <= 1e-10 * d.max()


@pytest.mark.parametrize("method,options", [
    ("log-ode", {}), ("heat", {"operators": "intrinsic"}), ("varadhan", {"laplacian": "intrinsic-delaunay"}),
])
@pytest.mark.parametrize("turned", [0.05, 0.5])
def test_intrinsic_operators_do_not_depend_on_the_winding(make_fixtures, method, options, turned):
    # libigl's flips read each face's winding: on bunny with 50 faces stored the other way
    # round the distances moved by up to 1.1 % of max d, and with 2,000 the flips left
    # negative weights inside, so that --operators intrinsic fell back to extrinsic ones
    V, F = make_fixtures.grid(25)
    rng = np.random.default_rng(3)
    V = V + np.c_[0.3 * rng.uniform(-1, 1, (len(V), 2)) / 24, np.zeros(len(V))]  # needs flips
    d = gd.geodesic_distance(V, F, [0], method=method, **options)
    Fm = F.copy()
    back = rng.random(len(F)) < turned
    Fm[back] = Fm[back][:, ::-1]
    other = gd.geodesic_distance(V, Fm, [0], method=method, **options)
    assert np.abs(other.distance - d.distance).max() <= 1e-10 * d.distance.max()
    if method == "heat":
        assert other.stats["operators"] == d.stats["operators"] == "intrinsic"


def test_cocircular_quads_keep_the_input_diagonal(fixture_dir):
    import igl

    from geoproc.geodesic.cocircular import canonical_cocircular_diagonals, cocircular_edges
    from geoproc.mesh.topology import unique_edges

    m = load_mesh(fixture_dir / "grid.ply")
    given = {tuple(e) for e in np.sort(unique_edges(m.F)[0], axis=1).tolist()}
    for V in (m.V, m.V * 1000.0, m.V + [1e4, -3e4, 2e4]):
        _, l, Fi = igl.intrinsic_delaunay_cotmatrix(V, m.F)
        Fi, l, _, _ = canonical_cocircular_diagonals(Fi, l, F=m.F)
        E = np.sort(cocircular_edges(Fi, l), axis=1)
        assert len(E) > 0 and all(tuple(e) in given for e in E.tolist())
        assert {tuple(e) for e in np.sort(unique_edges(Fi)[0], axis=1).tolist()} == given


def test_cocircular_quads_take_the_diagonal_of_their_smallest_vertex(fixture_dir):
    # without the input faces (or where no input edge crosses the quad)
    import igl

    from geoproc.geodesic.cocircular import canonical_cocircular_diagonals, cocircular_edges

    m = load_mesh(fixture_dir / "grid.ply")
    out = []
    for V in (m.V, m.V * 1000.0, m.V + [1e4, -3e4, 2e4]):
        _, l, Fi = igl.intrinsic_delaunay_cotmatrix(V, m.F)
        Fi, l, _, _ = canonical_cocircular_diagonals(Fi, l)
        out.append(Fi)
        E = cocircular_edges(Fi, l)
        assert len(E) > 0  # the grid's diagonals
        quads = [set(Fi[f]) | set(Fi[g]) for f, g in _faces_of_edges(Fi, E)]
        assert all(min(q) in e for q, e in zip(quads, E.tolist(), strict=True))
    assert all(np.array_equal(sorted(map(tuple, np.sort(o, axis=1))), sorted(map(tuple, np.sort(out[0], axis=1))))
               for o in out[1:])


def _scaled_vertices(make_fixtures, seed, cube):
    """A grid or a cube with a few vertices scaled away from the origin: their
    intrinsic Delaunay triangulations can join a vertex pair by two edges."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(5, 16))
    V, F = make_fixtures.cube(int(rng.integers(2, 6))) if cube else make_fixtures.grid(n)
    V = V.copy()
    idx = rng.choice(len(V), int(rng.integers(1, 6)), replace=False)
    V[idx] *= rng.uniform(1.5, 5)
    return V, np.ascontiguousarray(F, dtype=np.int64)


@pytest.mark.parametrize("seed, cube", [(23, False), (11, False), (12, True)])
def test_twin_half_edges_of_an_intrinsic_triangulation_with_double_edges(make_fixtures, seed, cube):
    # twins are told apart by their length, not only by their two vertices: pairing by
    # vertices alone matched half-edges of different edges, missed cocircular quads
    # and zeroed the weight of an edge that is not cocircular
    import igl

    from geoproc.geodesic.cocircular import _interior_edges
    from geoproc.mesh.topology import halfedges

    V, F = _scaled_vertices(make_fixtures, seed, cube)
    Li, l, Fi = igl.intrinsic_delaunay_cotmatrix(V, F)
    Fi, l = np.asarray(Fi, dtype=np.int64), np.asarray(l)
    h, t, a, b = _interior_edges(Fi, l)
    ha, hb = halfedges(np.roll(Fi, -1, axis=1)).T
    both = np.concatenate([h, t])
    assert len(np.unique(both)) == len(both)  # each half-edge in one pair at most
    assert np.array_equal(ha[h], hb[t]) and np.array_equal(hb[h], ha[t]) and (a < b).all()
    assert np.array_equal(l.ravel()[h], l.ravel()[t])
    keys = np.minimum(ha, hb) * len(V) + np.maximum(ha, hb)
    _, count = np.unique(keys, return_counts=True)
    loops = int((ha == hb).sum())  # half-edges from a vertex to itself are left out
    edges = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    boundary = int((np.unique(edges, axis=0, return_counts=True)[1] == 1).sum())  # flips keep the boundary
    assert 2 * len(h) == 3 * len(Fi) - boundary - loops
    if not cube:
        assert (count > 2).any()  # the double edges are there
    # the canonical diagonals change only weights that are zero: L is libigl's
    from geoproc.geodesic.operators import _flipped_triangulation

    L = _flipped_triangulation(V, F).L.toarray()
    Lref = np.asarray(sp.csr_matrix(Li).todense())
    assert np.abs(L - Lref).max() <= 1e-9 * np.abs(Lref).max()


def _faces_of_edges(Fi, E):
    faces = {}
    for f, tri in enumerate(Fi.tolist()):
        for k in range(3):
            faces.setdefault(frozenset((tri[k], tri[(k + 1) % 3])), []).append(f)
    return [faces[frozenset(e)] for e in E.tolist()]


# ---- flat grids with slivers, needles and obtuse angles at the boundary -------------------

def _pulled_grid(make_fixtures, factor, n=30, count=150, seed=3):
    """The n x n unit grid with ``count`` interior vertices pulled to ``factor`` of an
    edge from a neighbour: slivers inside, and obtuse angles facing boundary edges."""
    V, F = make_fixtures.grid(n)
    rng = np.random.default_rng(seed)
    interior = [i * n + j for i in range(1, n - 1) for j in range(1, n - 1)]
    for v in rng.choice(interior, count, replace=False):
        i, j = divmod(int(v), n)
        di, dj = [(1, 0), (0, 1), (-1, 0), (0, -1), (1, 1), (-1, -1)][rng.integers(6)]
        w = (i + di) * n + (j + dj)
        V[v] = V[w] + (V[v] - V[w]) * factor
    return V, F


@pytest.mark.parametrize("count, kind", [(4, "extrinsic"), (6, "intrinsic")])
def test_auto_operators_switch_at_half_a_percent_of_slivers(make_fixtures, count, kind):
    # 4 pulled vertices make 8 of the 1682 faces slivers (0.48 %), 6 make 12 (0.71 %):
    # auto goes intrinsic from 0.5 % of faces with an angle below 5 degrees
    V, F = _pulled_grid(make_fixtures, 1e-2, count=count)
    P = V[F]
    cosines = []
    for k in range(3):
        u, v = P[:, (k + 1) % 3] - P[:, k], P[:, (k + 2) % 3] - P[:, k]
        cosines.append(np.einsum("ij,ij->i", u, v) / np.linalg.norm(u, axis=1) / np.linalg.norm(v, axis=1))
    slivers = int((np.degrees(np.arccos(np.clip(np.max(cosines, axis=0), -1, 1))) < 5.0).sum())
    assert slivers == 2 * count and len(F) == 1682
    h = gd.mean_edge_length(V, F)
    assert gd.HeatMethodSolver(V, F, h * h).operators == kind
    assert gd.LogHeatSolver(V, F, h * h).operators == kind


def _mean_error_on_flat(V, d, s=0):
    ref = np.linalg.norm(V - V[s], axis=1)
    return np.abs(d - ref).mean() / ref.max()


@pytest.mark.parametrize("method", ["heat", "log-heat"])
@pytest.mark.parametrize("factor", [1e-2, 1e-4])
def test_intrinsic_operators_apply_with_obtuse_angles_at_the_boundary(make_fixtures, method, factor):
    # no flip removes an obtuse angle facing a boundary edge: its negative weight made the
    # intrinsic triangulation fall back to the extrinsic operators without a word
    # (mean error 2.5-3.8 % of the largest distance; with 1e-4 even below the needle limit)
    V, F = _pulled_grid(make_fixtures, factor)
    res = gd.geodesic_distance(V, F, [0], method=method, operators="intrinsic")
    assert res.stats["operators"] == "intrinsic"
    err = _mean_error_on_flat(V, res.distance)
    pp3d = pytest.importorskip("potpourri3d")
    ref = _mean_error_on_flat(V, pp3d.MeshHeatMethodDistanceSolver(V, F, use_robust=True).compute_distance(0))
    assert err < 0.008 and err < 1.05 * ref  # measured 0.58-0.59 % (potpourri3d 0.64 %)


def _delaunay_of_points(P):
    """The Delaunay triangulation of 2D points (k, 2), counter-clockwise, as a flat mesh."""
    from scipy.spatial import Delaunay

    F = Delaunay(P).simplices.astype(np.int64)
    a, b = P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]
    F[a[:, 0] * b[:, 1] < a[:, 1] * b[:, 0]] = F[a[:, 0] * b[:, 1] < a[:, 1] * b[:, 0]][:, [0, 2, 1]]
    return np.c_[P, np.zeros(len(P))], F


def test_heat_step_keeps_non_negative_weights_along_a_hull_of_slivers():
    # a Delaunay triangulation of random points is lined with slivers along its hull, whose
    # obtuse angles face boundary edges (weights down to -435): heat's heat step on those
    # weights went negative on 536 of the 1000 vertices, a mean error of 32 % of the largest
    # distance; with robust-laplacian's weights in the heat step 1.39 %, and with every step
    # on the doubled cover's triangulation 0.67 % (potpourri3d's robust mode 0.71 %)
    V, F = _delaunay_of_points(np.random.default_rng(0).random((1000, 2)))
    for method in ("heat", "log-heat"):
        res = gd.geodesic_distance(V, F, [1], method=method)
        assert res.stats["operators"] == "intrinsic"  # auto: 3.6 % of the faces are slivers
        assert res.stats.get("negative_heat_vertices", 0) == 0
        assert _mean_error_on_flat(V, res.distance, s=1) < 0.008


@pytest.mark.parametrize("sources, bound", [([0], 0.008), ([1803], 0.034), ([0, 1803], 0.008)])
def test_heat_method_on_a_dense_cluster_with_a_hull_of_slivers(sources, bound):
    # 1500 of 1804 random points in a cluster of 1/400 of the unit square: the mesh's own
    # intrinsic flips left negative weights on the hull, and heat's mean error was 1.53 /
    # 6.05 / 8.03 % of the largest distance; on the doubled cover's triangulation 0.67 /
    # 3.07 / 0.68 %, potpourri3d's robust mode (its tufted cover) 0.81 / 3.58 / 1.23 %
    rng = np.random.default_rng(0)
    P = np.r_[rng.random((300, 2)), 0.05 * rng.random((1500, 2)) + 0.4, [[0, 0], [1, 0], [0, 1], [1, 1]]]
    V, F = _delaunay_of_points(P)
    d = gd.geodesic_distance(V, F, sources, method="heat").distance
    exact = np.min([np.linalg.norm(V - V[s], axis=1) for s in sources], axis=0)
    assert np.abs(d - exact).mean() / exact.max() < bound


def test_doubled_cover_operators_fold_onto_the_mesh(make_fixtures):
    # the pulled grid's obtuse angles at the boundary send the flips to the doubled cover: its
    # folded Laplacian has no negative weight, rows summing to zero, D G = L on the folded
    # faces, the mass is the mesh's area and the energy of a function is the cover's halved
    from geoproc.geodesic.doubled_cover import doubled_cover
    from geoproc.geodesic.intrinsic import intrinsic_face_operators
    from geoproc.geodesic.operators import _flipped_triangulation, intrinsic_delaunay_mesh, upper_entries
    from geoproc.mesh.topology import face_areas

    V, F = _pulled_grid(make_fixtures, 1e-2)
    plain = _flipped_triangulation(V, F)
    assert (upper_entries(plain.L)[2] < 0).any()
    C, lc, twin, original = doubled_cover(plain.F, plain.l, F, len(V))
    e = np.arange(len(twin))
    assert len(C) == 2 * len(F) and np.array_equal(twin[twin], e) and (twin != e).all()
    ends = lambda e: original[C.ravel()[3 * (e // 3) + np.array([(e + 1) % 3, (e + 2) % 3])]]  # noqa: E731
    assert np.array_equal(ends(e), ends(twin[e])[::-1]) and np.array_equal(lc.ravel(), lc.ravel()[twin])
    tri = intrinsic_delaunay_mesh(V, F)
    assert tri.face_share == 0.5 and len(tri.F) == 2 * len(F)
    assert (upper_entries(tri.L)[2] >= 0).all()
    assert np.abs(tri.L.sum(axis=1)).max() < 1e-12 * abs(tri.L).max()
    assert np.isclose(tri.M.sum(), face_areas(V, F).sum(), rtol=1e-12)
    _, G, D = intrinsic_face_operators(tri.F, tri.l, len(V), tri.face_share)
    assert abs(D @ G - tri.L).max() < 1e-9 * abs(tri.L).max()
    # some boundary edge flipped into an edge from a vertex to its own mirror image
    assert (tri.F == np.roll(tri.F, 1, axis=1)).any()


def test_doubled_cover_holds_an_edge_between_two_boundary_vertices_twice():
    # a grid sheared by x += 2 y: its corner triangles join two boundary vertices by an
    # interior edge, which the cover holds twice (as a mesh it would be non-manifold, and the
    # intrinsic operators fell back to the extrinsic ones: heat's mean error 15.00 % of the
    # largest distance; with the mesh's own flips and its negative weights kept, 0.29 %; now
    # 0.19 %, potpourri3d 0.38 %)
    n = 41
    ys, xs = np.divmod(np.arange(n * n), n)
    V = np.c_[xs + 2.0 * ys, ys, np.zeros(n * n)] / (n - 1)
    a, b, c, d = (np.add.outer(np.arange(n - 1) * n, np.arange(n - 1)).ravel() + k for k in (0, 1, n + 1, n))
    F = np.r_[np.c_[a, b, c], np.c_[a, c, d]]
    centre = (n // 2) * n + n // 2
    res = gd.geodesic_distance(V, F, [centre], method="heat")
    assert res.stats["operators"] == "intrinsic"
    assert _mean_error_on_flat(V, res.distance, s=centre) < 0.0025


def test_log_methods_run_on_needles_beside_an_obtuse_boundary_angle(make_fixtures):
    # a column of needles of 1e-7 rad and an obtuse angle facing a boundary edge: robust-laplacian's
    # weights of zero came out at -5e-12 of the largest, and log-heat and log-ode refused the mesh
    n = 30
    V, F = make_fixtures.grid(n)
    h = 1.0 / (n - 1)
    V[10 * n: 11 * n, 0] = V[11 * n: 12 * n, 0] - 1e-7 * h
    V[n + 15, :2] = [0.05 * h, 14.5 * h]
    res = gd.geodesic_distance(V, F, [0], method="log-heat")
    assert _mean_error_on_flat(V, res.distance) < 0.012  # measured 0.90 % (potpourri3d 0.90 %)
    assert np.isfinite(gd.geodesic_distance(V, F, [0], method="log-ode").distance).all()


@pytest.mark.parametrize("method", ["heat", "log-heat"])
def test_auto_operators_go_intrinsic_on_a_few_needles(make_fixtures, method):
    # 2 faces of 1682 below 1e-6 rad (0.1 % slivers, under auto's 0.5 %): the extrinsic
    # Poisson step is refused on such needles, so auto takes the intrinsic operators
    n = 30
    V, F = make_fixtures.grid(n)
    v, w = 15 * n + 14, 15 * n + 15
    V[v] = V[w] + (V[v] - V[w]) * 1e-7
    res = gd.geodesic_distance(V, F, [0], method=method, operators="auto")
    assert res.stats["operators"] == "intrinsic"
    assert _mean_error_on_flat(V, res.distance) < 0.01  # measured 0.83 %
    with pytest.raises(InputError, match="extrinsic operators loses its accuracy"):
        gd.geodesic_distance(V, F, [0], method=method, operators="extrinsic")


def test_exact_distance_is_infinite_where_no_source_reaches():
    # two triangles apart, a vertex no face uses: libigl gives 0 beyond the source's component
    from geoproc.geodesic.exact import exact_geodesic_distance

    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 0, 0], [6, 0, 0], [5, 1, 0], [9, 9, 9]], dtype=float)
    F = np.array([[0, 1, 2], [3, 4, 5]])
    d = exact_geodesic_distance(V, F, [0])
    np.testing.assert_allclose(d[:3], [0, 1, 1], atol=1e-12)
    assert np.isinf(d[3:]).all()
    d = exact_geodesic_distance(V, F, [0, 4])
    np.testing.assert_allclose(d[:6], [0, 1, 1, 1, 0, np.sqrt(2)], atol=1e-12)
    assert np.isinf(d[6])


def test_isoline_segment_on_one_triangle_by_hand():
    from geoproc.geodesic.render import isoline_segments

    P = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    seg, faces = isoline_segments(P, np.array([[0, 1, 2]]), np.array([0.0, 1.0, 2.0]), np.array([0.25]))
    # d = 0.25 a quarter of the way along edge 0-1, and 7/8 of the way from vertex 2 to 0
    np.testing.assert_allclose(seg, [[[0.25, 0.0], [0.0, 0.125]]], atol=1e-15)
    assert faces.tolist() == [0]


def test_poisson_solver_pins_one_vertex_of_every_component(make_fixtures):
    # two separate grids: a right-hand side summing to zero on each is solved exactly, with
    # phi = 0 at the first vertex of each (with only the first component pinned, the second
    # component's block is singular)
    import igl

    from geoproc.geodesic.poisson import PoissonSolver

    V, F = make_fixtures.grid(6)
    V2, F2 = np.vstack([V, V + [3.0, 0, 0]]), np.vstack([F, F + len(V)])
    L = sp.csr_matrix(igl.cotmatrix(V2, F2))
    b = np.random.default_rng(1).standard_normal(len(V2))
    b[: len(V)] -= b[: len(V)].mean()
    b[len(V):] -= b[len(V):].mean()
    phi = PoissonSolver(L).solve(b)
    assert phi[0] == 0 and phi[len(V)] == 0
    assert np.abs(L @ phi - b).max() < 1e-10 * np.abs(b).max()


@pytest.mark.parametrize("squash, bound", [(3e-6, 1e-3), (1e-6, 1e-2)])
def test_a_thin_strip_keeps_its_weights_along_the_strip(make_fixtures, squash, bound):
    # the 21 x 21 grid squashed to 1 x 3e-6: the weights along the strip (cot 3e-6) lie
    # within the cocircular tolerance, and zeroing them cut the strip's length: heat's mean
    # error was 9.96 (16.2 at 1e-6) times the largest distance; now 1.9e-4 (3.8e-3), and
    # log-ode's intrinsic Delaunay Laplacian is the cotan one again, as on any grid of rectangles
    V, F = make_fixtures.grid(21)
    V = V * [1.0, squash, 1.0]
    res = gd.geodesic_distance(V, F, [220], method="heat")
    assert res.stats["operators"] == "intrinsic"
    assert _mean_error_on_flat(V, res.distance, s=220) < bound
    a, b = (gd.geodesic_distance(V, F, [220], method="log-ode", laplacian=lap).distance
            for lap in ("intrinsic-delaunay", "cotan"))
    # (they were 56 % apart; what is left is the rounding of the rectangles' right angles, whose
    # cotangents of ~1e-11 stand beside weights of 3e-6)
    assert np.abs(a - b).max() < 1e-4 * b.max()


def test_varadhan_writes_no_negative_zero(make_fixtures):
    # at a tiny time the heat at a source rounds to 1 or more: -sqrt(0 * log u) gave -0.0,
    # which a PLY keeps with its sign bit
    V, F = make_fixtures.icosphere(3)
    d = gd.geodesic_distance(V, F, [0, 5], method="varadhan", time_factor=1e-30).distance
    assert not np.signbit(d).any()


def test_doubled_cover_does_not_depend_on_the_winding():
    # the cover pairs half-edges that run opposite ways: one face of 5,969 wound the other way
    # had turned it off, and heat fell back to the extrinsic operators (0.878 % -> 4.449 % of the
    # largest distance from three sources); the faces are now turned consistent first
    V, F = _delaunay_of_points(np.random.default_rng(0).random((3000, 2)))
    F2 = F.copy()
    F2[100, [1, 2]] = F2[100, [2, 1]]
    sources = [2832, 1874, 2052]
    a, b = (gd.geodesic_distance(V, FF, sources, method="heat") for FF in (F, F2))
    assert a.stats["operators"] == b.stats["operators"] == "intrinsic"
    assert np.abs(a.distance - b.distance).max() < 1e-12 * a.distance.max()


def _capped_grid(nx: int, caps) -> tuple[np.ndarray, np.ndarray]:
    """An nx by nx planar grid whose row-1 vertices ``caps`` sit 0.02 of a cell
    above the boundary edge below them: their obtuse angles face that edge, so
    the intrinsic Delaunay triangulation is built on the doubled cover."""
    x, y = np.meshgrid(np.linspace(0, 1, nx), np.linspace(0, 1, nx))
    V = np.c_[x.ravel(), y.ravel(), np.zeros(nx * nx)]
    a = (np.arange(nx - 1)[None, :] + nx * np.arange(nx - 1)[:, None]).ravel()
    F = np.stack([np.c_[a, a + 1, a + nx + 1], np.c_[a, a + nx + 1, a + nx]], axis=1).reshape(-1, 3)
    dx = 1.0 / (nx - 1)
    for k in caps:
        V[nx + k, 0] -= 0.5 * dx
        V[nx + k, 1] = 0.02 * dx
    return V, F


def test_vertex_rank_follows_the_vertices_not_their_numbers_or_pose():
    from scipy.spatial import Delaunay
    from scipy.spatial.transform import Rotation

    from geoproc.geodesic.cocircular import vertex_rank

    xy = np.random.default_rng(3).random((300, 2))
    V, F = np.c_[xy, 0.1 * np.sin(3 * xy[:, 0])], Delaunay(xy).simplices
    rank = vertex_rank(V, F)
    perm = np.random.default_rng(4).permutation(len(V))
    inv = np.argsort(perm)
    R = Rotation.from_euler("xyz", [0.3, 0.7, 1.1]).as_matrix()
    assert np.array_equal(vertex_rank(V[perm], inv[F]), rank[perm])
    assert np.array_equal(vertex_rank(V @ R.T * 3.0 + [5.0, -2.0, 1.0], F[:, [1, 2, 0]]), rank)
    # a regular grid's boundary vertices share angle sum and face count; one moved vertex
    # sets apart the boundary vertices near it (the index had ordered them all)
    G, FG = _capped_grid(9, [7])
    r = vertex_rank(G, FG)
    p2 = np.random.default_rng(5).permutation(len(G))
    r2 = vertex_rank(G[p2], np.argsort(p2)[FG])[np.argsort(p2)]
    assert np.array_equal(r2[[6, 7, 8]], r[[6, 7, 8]])


@pytest.mark.parametrize("caps", [range(4, 20, 6), [19], [1, 2, 10, 18]])
def test_doubled_cover_does_not_depend_on_the_numbering_pose_or_unit(caps):
    # the cover's cocircular quads that no input edge (or two) crosses, rectangles here, took
    # the diagonal of their smallest vertex index: relabelling the vertices of this grid moved
    # the mass by 22 % of the largest, and the distances by 9.3e-4 (heat, for its intrinsic
    # Delaunay heat step), 3.8e-3 (heat, intrinsic operators) and 1.7e-3 (log-ode) of the
    # largest. Ordered by position instead, a turn of the mesh moved them by 1.3e-3 to 4.5e-3;
    # by angle sum and face count alone, a cap beside the grid's corner (19) left the index
    # to order boundary vertices (mass 22 %); now the shorter diagonal, then colour refinement
    # of angle sums, face counts and edge lengths decide
    from scipy.spatial.transform import Rotation

    from geoproc.geodesic.operators import laplacian_and_mass

    V, F = _capped_grid(21, caps)
    rng = np.random.default_rng(0)
    perm = rng.permutation(len(V))  # new vertex k is old vertex perm[k]
    inv = np.argsort(perm)
    F1 = np.roll(inv[F], 1, axis=1)[rng.permutation(len(F))]  # faces reordered, corners rotated
    R = Rotation.from_euler("xyz", [0.3, 0.7, 1.1]).as_matrix()
    _, M = laplacian_and_mass(V, F, "intrinsic-delaunay")
    for V1, s in ((V[perm], 1.0), (V[perm] * 1000.0 + [1e4, -3e4, 2e4], 1000.0), (V[perm] @ R.T, 1.0)):
        _, M1 = laplacian_and_mass(V1, F1, "intrinsic-delaunay")
        assert np.abs(M1[inv] / s**2 - M).max() <= 1e-12 * M.max()
        for method, options in (("heat", {}), ("heat", {"operators": "intrinsic"}), ("log-ode", {})):
            d = gd.geodesic_distance(V, F, [0], method=method, **options).distance
            other = gd.geodesic_distance(V1, F1, [inv[0]], method=method, **options).distance[inv] / s
            assert np.abs(other - d).max() <= 1e-12 * d.max()


def test_a_moebius_band_with_obtuse_boundary_angles_keeps_the_intrinsic_operators():
    # a non-orientable mesh has no doubled cover (its half-edges do not pair up): the
    # triangulation with negative boundary weights had been dropped for the extrinsic operators
    nu, nv = 60, 6
    rows = [-1.0, -0.99, *np.linspace(-1, 1, nv + 1)[2:-2], 0.99, 1.0]  # thin boundary rows: obtuse angles
    t = 2 * np.pi * np.arange(nu)[:, None] / nu
    w = 0.3 * np.array(rows)[None, :]
    V = np.stack([(1 + w * np.cos(t / 2)) * np.cos(t), (1 + w * np.cos(t / 2)) * np.sin(t),
                  w * np.sin(t / 2)], axis=-1).reshape(-1, 3)

    def vid(i, j):
        return j + (nv + 1) * i if i < nu else nv - j  # the last column joins the first turned over

    quads = [(vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1)) for i in range(nu) for j in range(nv)]
    F = np.array([f for a, b, c, d in quads for f in ([a, b, c], [a, c, d])])
    from geoproc.geodesic.operators import _flipped_triangulation, upper_entries

    assert (upper_entries(_flipped_triangulation(V, F).L)[2] < 0).any()
    for method in ("heat", "log-heat"):
        res = gd.geodesic_distance(V, F, [3], method=method, operators="intrinsic")
        assert res.stats["operators"] == "intrinsic"
        assert np.isfinite(res.distance).all() and res.stats.get("negative_heat_vertices", 0) == 0


def _strip(length: int, width: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """A flat strip of length x width unit squares, two triangles each."""
    i, j = np.meshgrid(np.arange(length + 1), np.arange(width + 1), indexing="ij")
    V = np.column_stack([i.ravel(), j.ravel(), np.zeros(i.size)]).astype(float)
    a, b = np.meshgrid(np.arange(length), np.arange(width), indexing="ij")
    c = (a * (width + 1) + b).ravel()
    F = np.concatenate([np.column_stack([c, c + width + 1, c + width + 2]),
                        np.column_stack([c, c + width + 2, c + 1])])
    return V, F


def test_heat_that_underflows_is_solved_in_the_log_domain():
    # at t = h^2 one backward-Euler step's heat falls by about e per edge: 1,200 edges
    # from the source it is 0 in double precision, the direction 0/0 there, and the plain
    # heat method's largest distance on this strip was 430 for 1,200 (861 once tiny
    # gradients kept their direction)
    V, F = _strip(1200)
    exact = np.linalg.norm(V - V[0], axis=1)  # a flat convex strip: the straight line
    res = gd.geodesic_distance(V, F, [0], "heat")
    assert res.stats["zero_heat_vertices"] > 1000 and res.stats["heat_step_in_log_domain"]
    assert res.stats["underflow_heat_vertices"] >= res.stats["zero_heat_vertices"]
    assert np.abs(res.distance - exact).max() < 1e-3 * exact.max()
    plain = gd.geodesic_distance(V, F, [0], "heat", heat_underflow="keep")
    assert not plain.stats["heat_step_in_log_domain"] and plain.distance.max() < 0.8 * exact.max()
    # where nothing underflows nothing is solved again: the plain step's result
    short = _strip(100)
    a = gd.geodesic_distance(*short, [0], "heat")
    assert a.stats["zero_heat_vertices"] == 0 and not a.stats["heat_step_in_log_domain"]
    kept = gd.geodesic_distance(*short, [0], "heat", heat_underflow="keep")
    np.testing.assert_array_equal(a.distance, kept.distance)


def test_heat_time_too_small_for_the_log_domain_is_refused(fixture_dir):
    # at t = 1e-310 h^2 on the torus the plain step's heat is 0 beyond the source's ring and
    # the log domain's t L_ij underflows: that refusal had been taken for negative weights
    # and the plain step kept (largest distance 0.2 for 3.44, exit status 0); with
    # --heat-underflow keep the plain step is still what is asked for
    m = load_mesh(fixture_dir / "torus.ply")
    with pytest.raises(InputError, match="too small"):
        gd.geodesic_distance(m.V, m.F, [0], "heat", time_factor=1e-310, path="torus.ply")
    kept = gd.geodesic_distance(m.V, m.F, [0], "heat", time_factor=1e-310, heat_underflow="keep")
    assert not kept.stats["heat_step_in_log_domain"] and kept.stats["underflow_heat_vertices"] > 0
    # where the log domain takes the time step, it is still used
    res = gd.geodesic_distance(m.V, m.F, [0], "heat", time_factor=1e-300)
    assert res.stats["heat_step_in_log_domain"]


@pytest.mark.parametrize("length", [500, 600, 750])
def test_heat_gradients_below_the_square_range_keep_their_direction(length):
    # 430 to 750 edges from the source u is still a normal double but its gradient is
    # below 1e-154, whose square underflows: those faces had no direction, and the strip's
    # largest distance was 428 for 500, 600 and 750 (potpourri3d: 423-428)
    V, F = _strip(length)
    exact = np.linalg.norm(V - V[0], axis=1)
    res = gd.geodesic_distance(V, F, [0], "heat")
    assert res.stats["underflow_heat_vertices"] == 0 and not res.stats["heat_step_in_log_domain"]
    assert np.abs(res.distance - exact).max() < 2e-3 * exact.max()


def test_normalized_direction_of_tiny_and_huge_rows():
    from geoproc.geodesic.operators import normalized_direction

    X = np.array([[3e-200, 4e-200, 0], [3e200, 4e200, 0], [3, 4, 0], [1e-320, 0, 0], [0, 0, 0], [np.nan, 1, 1]])
    expected = [[0.6, 0.8, 0], [0.6, 0.8, 0], [0.6, 0.8, 0], [1, 0, 0], [0, 0, 0], [0, 0, 0]]
    np.testing.assert_allclose(normalized_direction(X), expected, rtol=1e-15, atol=0)


@pytest.mark.parametrize("method", ["heat", "log-heat", "varadhan"])
def test_progress_is_reported_after_the_setup(method):
    # the bar stayed at 0 % through the operators and factorizations, most of a run
    V, F = _strip(20)
    seen = []
    gd.geodesic_distance(V, F, [0], method, progress=seen.append)
    assert seen and seen[0] == pytest.approx(0.8)
