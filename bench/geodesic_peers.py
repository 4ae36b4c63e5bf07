"""geoproc geodesic against peer libraries, same meshes, same sources, same run.

For armadillo and three other meshes from ../shared/data/meshes: potpourri3d's
MeshHeatMethodDistanceSolver (intrinsic Delaunay heat method, t = h^2),
libigl's heat_geodesics (t = h^2; plain cotan and its intrinsic-Delaunay option),
and geoproc's heat and log-heat, all against libigl's exact geodesics. Reports
setup time, mean per-source solve time, mean relative error (mean |d - d*| /
max d*, averaged over the sources), and ratios to potpourri3d measured in this
run. Then the log-ODE solvers: the log-space LU solver (default) and Newton
against the CVXPY/Clarabel convex program on a ~2.9k-vertex mesh (agreement in w
and speed-up).

Usage: python bench/geodesic_peers.py [--sources K] [--out out/bench]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data" / "meshes"
MESHES = ["armadillo.obj", "bunny.off", "fertility.off", "camelhead.off"]


def best_of(fn, repeat=5, budget=1.0, most=30):
    """(result, best wall time) over at least ``repeat`` runs, more (up to
    ``most``) while they have taken less than ``budget`` seconds: on a shared
    machine thirty bunny setups in one process took 46 to 74 ms, so a best of
    five short runs moved from one run of the script to the next."""
    best, out, spent, runs = np.inf, None, 0.0, 0
    while runs < repeat or (spent < budget and runs < most):
        t = time.perf_counter()
        out = fn()
        took = time.perf_counter() - t
        best, spent, runs = min(best, took), spent + took, runs + 1
    return out, best


def peer_rows(name, k, rng):
    import igl
    import potpourri3d as pp3d

    import geoproc.geodesic as gd
    from geoproc.mesh import load_mesh

    m = load_mesh(SHARED / name)
    V, F = m.V, m.F
    h = gd.mean_edge_length(V, F)
    sources = rng.choice(len(V), k, replace=False)
    exact = [gd.exact_geodesic_distance(V, F, np.array([s])) for s in sources]

    def err(ds):
        return float(np.mean([gd.compare_to_reference(d, e)["mean_relative_error"]
                              for d, e in zip(ds, exact, strict=True)]))

    def run(label, setup, solve):
        solver, t_setup = best_of(setup)
        ds, t_solve = [], []
        for s in sources:
            d, t = best_of(lambda s=s: solve(solver, s))
            ds.append(np.asarray(d))
            t_solve.append(t)
        return {"mesh": name, "n": len(V), "method": label, "setup": t_setup,
                "solve": float(np.mean(t_solve)), "err": err(ds)}

    def igl_setup(intrinsic):
        def f():
            data = igl.HeatGeodesicsData()
            data.use_intrinsic_delaunay = intrinsic
            igl.heat_geodesics_precompute(V, F, h * h, data)
            return data
        return f

    rows = [
        run("potpourri3d MeshHeatMethodDistanceSolver", lambda: pp3d.MeshHeatMethodDistanceSolver(V, F),
            lambda s, i: s.compute_distance(int(i))),
        run("libigl heat_geodesics (cotan)", igl_setup(False),
            lambda s, i: igl.heat_geodesics_solve(s, np.array([i], dtype=np.int64))),
        run("libigl heat_geodesics (intrinsic Delaunay)", igl_setup(True),
            lambda s, i: igl.heat_geodesics_solve(s, np.array([i], dtype=np.int64))),
        run("geoproc heat (cotan)",
            lambda: gd.HeatMethodSolver(V, F, h * h, laplacian="cotan", operators="extrinsic"),
            lambda s, i: s.solve([i])[0]),
        run("geoproc heat (defaults: intrinsic Delaunay heat step, operators auto)",
            lambda: gd.HeatMethodSolver(V, F, h * h), lambda s, i: s.solve([i])[0]),
        run("geoproc log-heat", lambda: gd.LogHeatSolver(V, F, h * h),
            lambda s, i: s.solve([i])[0]),
    ]
    return rows


def log_ode_rows(name):
    import scipy.sparse as sp  # noqa: F401

    import geoproc.geodesic as gd
    from geoproc.geodesic.log_ode import LogODESolver, log_ode_steps
    from geoproc.mesh import load_mesh

    m = load_mesh(SHARED / name)
    L, M = gd.intrinsic_delaunay_laplacian(m.V, m.F)
    h = gd.mean_edge_length(m.V, m.F)
    out = []
    w0 = np.full(len(M), -np.inf)
    w0[0] = 0.0
    for factor in (1.0, 1e-4):
        T = factor * h * h
        check = LogODESolver(L, M, T)  # residual of the log-sum-exp equations

        def resid(w, check=check):
            return float(np.abs(check.residual(w, w0)[0]).max())

        t0 = time.perf_counter()
        w_cvx, _ = log_ode_steps(L, M, [0], T, 1, solver="cvxpy")
        t_cvx = time.perf_counter() - t0
        for solver in ("lu", "newton"):
            (w, _), t = best_of(lambda solver=solver, T=T: log_ode_steps(L, M, [0], T, 1, solver=solver))
            out.append({"mesh": name, "n": len(m.V), "t/h2": factor, "solver": solver, "time": t,
                        "cvxpy": t_cvx, "dw": float(np.abs(w - w_cvx).max()),
                        "rel": float(np.abs(w - w_cvx).max() / np.abs(w_cvx).max()),
                        "res": resid(w), "res_cvx": resid(w_cvx), "wmin": float(w_cvx.min())})
    return out


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sources", type=int, default=10)
    ap.add_argument("--out", default=str(ROOT / "out" / "bench"))
    ap.add_argument("--meshes", nargs="*", default=MESHES)
    args = ap.parse_args(argv)
    if not SHARED.is_dir():
        print(f"skipped: {SHARED} not found")
        return 0
    rng = np.random.default_rng(20260)
    lines = [f"### geodesic vs peers ({args.sources} random sources per mesh, seed 20260, t = h^2)", "",
             "| mesh | vertices | method | setup s | per-source s | setup + 1 solve vs pp3d | "
             "mean rel. error | error vs pp3d |",
             "|---|---:|---|---:|---:|---:|---:|---:|"]
    summary = []
    for name in args.meshes:
        rows = peer_rows(name, args.sources, rng)
        ref = rows[0]
        for r in rows:
            ratio = (r["setup"] + r["solve"]) / (ref["setup"] + ref["solve"])
            lines.append(f"| {r['mesh']} | {r['n']} | {r['method']} | {r['setup']:.3f} | {r['solve']:.4f} | "
                         f"{ratio:.2f}x | {100 * r['err']:.3f} % | {r['err'] / ref['err']:.3f} |")
        lh = rows[-1]
        summary.append((name, lh["err"] <= ref["err"],
                        (lh["setup"] + lh["solve"]) / (ref["setup"] + ref["solve"])))
        print(lines[-1], file=sys.stderr, flush=True)
    lines += ["", "### log-ODE step: fast solvers vs the CVXPY/Clarabel convex program (1 step, source 0)", "",
              "| mesh | vertices | t / h^2 | solver | time s | cvxpy s | speed-up | max abs dw | "
              "max dw / max abs w | residual (ours) | residual (cvxpy) | min w |",
              "|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in log_ode_rows("spot.obj"):
        lines.append(f"| {r['mesh']} | {r['n']} | {r['t/h2']:g} | {r['solver']} | {r['time']:.4f} | "
                     f"{r['cvxpy']:.2f} | {r['cvxpy'] / r['time']:.0f}x | {r['dw']:.1e} | {r['rel']:.1e} | "
                     f"{r['res']:.1e} | {r['res_cvx']:.1e} | {r['wmin']:.1f} |")
    lines += ["", "Targets: log-heat error <= potpourri3d's on every mesh: "
              + ", ".join(f"{n} {'met' if ok else 'MISSED'}" for n, ok, _ in summary)
              + "; log-heat setup + one solve <= 2x potpourri3d's: "
              + ", ".join(f"{n} {r:.2f}x" for n, _, r in summary) + "."]
    text = "\n".join(lines)
    print(text)
    os.makedirs(args.out, exist_ok=True)
    Path(args.out, "geodesic_peers.md").write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    sys.exit(main(sys.argv[1:]))
