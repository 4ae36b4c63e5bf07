"""wos-solve benchmark: control variates over 20+ domains, and walk throughput against fcpw.

Part 1 (accuracy): for every generated domain (star-shaped, non-convex, with
holes, font glyph outlines) and each of its harmonic boundary functions
(Re z^3, e^x cos y, log|z - p| with p outside), solve with naive, cv-green and
cv-angle at 128 walks per point and report the RMSE against the exact solution
(the boundary function itself; ``--reference-walks N`` compares against an
N-walk naive solve instead), over grid points inside and farther than 2 eps
from the boundary.

Part 2 (throughput): a 256-segment star domain. Our walks (numba, parallel
over points, uniform-grid closest-point queries) against a baseline that
advances all walkers together from numpy with one batched fcpw closest-point
call per step, in the same run; plus a full grid x 128-walk naive solve,
reported as a ratio to the baseline's time at its measured rate.

Defaults run in a few minutes (grid 40); ``--full`` uses the seed protocol's
256^2 grid (with the exact solution as reference).

    .venv/bin/python bench/wos_domains.py [--grid 40] [--full] [--out out/bench/wos_domains.md]
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from geoproc.wos.domain import build_domain  # noqa: E402
from geoproc.wos.expression import parse_expression  # noqa: E402
from geoproc.wos.problem import WalkProblem, pass_seed  # noqa: E402
from geoproc.wos.solve import grid_over, solve_laplace  # noqa: E402


def _fixtures():
    spec = importlib.util.spec_from_file_location("wos_fixtures", ROOT / "fixtures" / "wos_fixtures.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def accuracy(grid: int, walks: int, ref_walks: int | None, eps: float, kernels: int, seed: int):
    wf = _fixtures()
    rows = []
    for name, doc, fns in wf.domains(256):
        dom = build_domain(doc["loops"])
        for fn in fns:
            g = parse_expression(fn)
            res = {}
            for m in ("naive", "cv-green", "cv-angle"):
                r = solve_laplace(dom, g, method=m, walks=walks, grid=grid, eps=eps, kernels=kernels,
                                  seed=seed, exact=True)
                res[m] = r
            if ref_walks:
                ref = solve_laplace(dom, g, walks=ref_walks, grid=grid, eps=eps, seed=seed + 1).U
                sc = res["naive"].scored
                rmse = {m: float(np.sqrt(np.mean((r.U[sc] - ref[sc]) ** 2))) for m, r in res.items()}
            else:
                rmse = {m: r.metrics["rmse"] for m, r in res.items()}
            t = {m: r.metrics["residual_seconds"] + r.metrics.get("fit_seconds", 0.0)
                 for m, r in res.items()}
            fit = res["cv-green"].metrics["fit_seconds"]
            rows.append((name, fn, dom.n_segments, rmse, t, fit))
            print(f"  {name:13s} {fn[:38]:38s} naive {rmse['naive']:.4f} green {rmse['cv-green']:.4f} "
                  f"angle {rmse['cv-angle']:.4f}", file=sys.stderr, flush=True)
    return rows


def fcpw_baseline(dom, X: np.ndarray, walks: int, eps: float, seed: int):
    """Walk on Spheres from numpy: all walkers advance together, one fcpw call per step."""
    import fcpw

    V = np.asarray(np.concatenate(dom.loops), dtype=np.float32)
    starts = np.cumsum([0] + [len(L) for L in dom.loops])
    idx = np.concatenate([np.c_[np.arange(a, b), np.r_[np.arange(a + 1, b), a]]
                          for a, b in zip(starts[:-1], starts[1:], strict=True)]).astype(np.int32)
    scene = fcpw.scene_2D()
    scene.set_object_count(1)
    scene.set_object_vertices(np.asfortranarray(V), 0)
    scene.set_object_line_segments(np.asfortranarray(idx), 0)
    scene.build(fcpw.aggregate_type.bvh_surface_area, True)
    rng = np.random.default_rng(seed)
    P = np.repeat(X, walks, axis=0).astype(np.float64)
    active = np.arange(len(P))
    steps = 0
    t_query = 0.0
    t0 = time.perf_counter()
    while len(active):
        q = np.asfortranarray(P[active].astype(np.float32))
        inter = fcpw.interaction_2D_list()
        tq = time.perf_counter()
        scene.find_closest_points(q, np.full(len(q), np.inf, dtype=np.float32), inter)
        t_query += time.perf_counter() - tq
        d = np.fromiter((i.d for i in inter), dtype=np.float64, count=len(q))
        done = d < eps
        active = active[~done]
        d = d[~done]
        th = rng.uniform(0, 2 * np.pi, len(active))
        P[active] += d[:, None] * np.c_[np.cos(th), np.sin(th)]
        steps += len(active)
    return steps, time.perf_counter() - t0, t_query


def throughput(full_grid: int, walks: int, eps: float, seed: int, base_points: int):
    import numba

    wf = _fixtures()
    dom = build_domain(wf.star(256, 5, 0.3)["loops"])
    g = parse_expression("x**3 - 3*x*y**2")
    pb = WalkProblem(dom, g, None, eps)
    P = grid_over(dom, 256).points()
    X = P[dom.contains(P)]
    sub = X[np.linspace(0, len(X) - 1, base_points).astype(int)]
    pb.estimate(sub[:4], 2, pass_seed(seed, 0))  # compile / load cache
    # ours on the same points and walks as the baseline (best of 3)
    ours = []
    for _ in range(3):
        t, c = time.perf_counter(), time.process_time()
        _, _, st = pb.estimate(sub, walks, pass_seed(seed, 1))
        ours.append((int(st.sum()), time.perf_counter() - t, time.process_time() - c))
    o_steps, o_time, o_cpu = min(ours, key=lambda s: s[1])
    c = time.process_time()
    b_steps, b_time, b_query = fcpw_baseline(dom, sub, walks, eps, seed)
    b_cpu = time.process_time() - c
    # closest-point queries alone: our grid vs fcpw (same random query points)
    import fcpw

    from geoproc.wos.closest import closest_points

    rng = np.random.default_rng(0)
    lo, hi = dom.bbox
    Q = rng.uniform(lo, hi, (500_000, 2))
    Q = Q[dom.contains(Q)]
    closest_points(Q[:10], pb.A, pb.B, pb.grid_all)
    tq = min(_timed(lambda: closest_points(Q, pb.A, pb.B, pb.grid_all)) for _ in range(3))
    V = np.asarray(dom.A, dtype=np.float32)
    n = len(V)
    idx = np.c_[np.arange(n), np.r_[np.arange(1, n), 0]].astype(np.int32)
    scene = fcpw.scene_2D()
    scene.set_object_count(1)
    scene.set_object_vertices(np.asfortranarray(V), 0)
    scene.set_object_line_segments(np.asfortranarray(idx), 0)
    scene.build(fcpw.aggregate_type.bvh_surface_area, True)
    q32 = np.asfortranarray(Q.astype(np.float32))
    r2 = np.full(len(Q), np.inf, dtype=np.float32)
    tf = min(_timed(lambda: scene.find_closest_points(q32, r2, fcpw.interaction_2D_list()))
             for _ in range(3))
    # the full naive solve
    t, c = time.perf_counter(), time.process_time()
    r = solve_laplace(dom, g, walks=walks, grid=full_grid, eps=eps, seed=seed, exact=True)
    full_time = time.perf_counter() - t
    full_cpu = time.process_time() - c
    full_steps = r.metrics["total_steps"]
    b_rate = b_steps / b_time
    return {
        "threads": numba.get_num_threads(), "segments": dom.n_segments,
        "base_points": len(sub), "walks": walks,
        "ours_steps": o_steps, "ours_time": o_time, "ours_rate": o_steps / o_time, "ours_cpu": o_cpu,
        "base_steps": b_steps, "base_time": b_time, "base_rate": b_rate, "base_query_time": b_query,
        "base_cpu": b_cpu, "full_cpu": full_cpu,
        "q_ours": len(Q) / tq, "q_fcpw": len(Q) / tf,
        "full_grid": f"{r.grid.nx}x{r.grid.ny}", "full_points": r.metrics["grid_points_inside"],
        "full_time": full_time, "full_steps": full_steps, "full_rate": r.metrics["steps_per_second"],
        "full_base_est": full_steps / b_rate, "rmse": r.metrics["rmse"],
    }


def _timed(f) -> float:
    t = time.perf_counter()
    f()
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", type=int, default=40, help="accuracy grid (pixels on the long side)")
    ap.add_argument("--walks", type=int, default=128)
    ap.add_argument("--kernels", type=int, default=80)
    ap.add_argument("--epsilon", type=float, default=1e-3)
    ap.add_argument("--reference-walks", type=int, default=0,
                    help="compare against an N-walk naive solve instead of the exact solution")
    ap.add_argument("--full", action="store_true", help="seed protocol: 256^2 accuracy grid")
    ap.add_argument("--full-grid", type=int, default=256, help="grid of the full naive solve")
    ap.add_argument("--base-points", type=int, default=2048,
                    help="points of the throughput comparison with the fcpw baseline")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--skip-accuracy", action="store_true")
    ap.add_argument("--out", default=str(ROOT / "out" / "bench" / "wos_domains.md"))
    a = ap.parse_args()
    grid = 256 if a.full else a.grid
    lines = [f"## wos-solve benchmark (`bench/wos_domains.py{' --full' if a.full else ''}`)", ""]
    if not a.skip_accuracy:
        rows = accuracy(grid, a.walks, a.reference_walks or None, a.epsilon, a.kernels, a.seed)
        ref = f"{a.reference_walks}-walk naive solve" if a.reference_walks else "exact solution"
        lines += [f"Accuracy: {len(rows)} problems on {len({r[0] for r in rows})} domains, grid {grid} "
                  f"(long side), {a.walks} walks, eps {a.epsilon}, {a.kernels} kernels, "
                  f"fit {8 * a.kernels} points x 128 walks, ridge 1 (cv-green) and 0.1 (cv-angle); "
                  f"RMSE against the {ref}.", "",
                  "| domain | boundary function | naive | cv-green | cv-angle | green/naive | angle/naive |",
                  "|---|---|---:|---:|---:|---:|---:|"]
        rg, ra = [], []
        for name, fn, _, rmse, _, _ in rows:
            g, an = rmse["cv-green"] / rmse["naive"], rmse["cv-angle"] / rmse["naive"]
            rg.append(g)
            ra.append(an)
            lines.append(f"| {name} | `{fn}` | {rmse['naive']:.4f} | {rmse['cv-green']:.4f} | "
                         f"{rmse['cv-angle']:.4f} | {g:.3f} | {an:.3f} |")
        rg, ra = np.array(rg), np.array(ra)
        tn = np.median([r[4]["naive"] for r in rows])
        tg = np.median([r[4]["cv-green"] for r in rows])
        tfit = np.median([r[5] for r in rows])
        lines += ["", "| summary | cv-green | cv-angle |", "|---|---:|---:|",
                  f"| median RMSE ratio to naive | {np.median(rg):.3f} | {np.median(ra):.3f} |",
                  f"| worst RMSE ratio to naive | {rg.max():.3f} | {ra.max():.3f} |",
                  f"| problems better than naive | {(rg < 1).sum()}/{len(rg)} | {(ra < 1).sum()}/{len(ra)} |",
                  f"| domains where better on every function | "
                  f"{_per_domain(rows, 'cv-green')} | {_per_domain(rows, 'cv-angle')} |",
                  "", f"Median time per problem: naive {tn:.2f} s, cv-green {tg:.2f} s "
                  f"(of which fit {tfit:.2f} s).", ""]
    tp = throughput(a.full_grid, a.walks, a.epsilon, a.seed, a.base_points)
    lines += [f"Throughput: 256-segment star domain, {tp['walks']} walks per point, eps {a.epsilon}, "
              f"numba threads {tp['threads']}, {os.cpu_count()} CPUs.", "",
              "| walker | points | steps | seconds | steps/s | ratio | CPU s | steps per CPU s |",
              "|---|---:|---:|---:|---:|---:|---:|---:|",
              f"| ours (numba, grid queries) | {tp['base_points']} | {tp['ours_steps']} | "
              f"{tp['ours_time']:.2f} | {tp['ours_rate'] / 1e6:.2f} M | "
              f"{tp['ours_rate'] / tp['base_rate']:.1f}x | {tp['ours_cpu']:.2f} | "
              f"{tp['ours_steps'] / tp['ours_cpu'] / 1e6:.2f} M |",
              f"| numpy + one batched fcpw call per step | {tp['base_points']} | {tp['base_steps']} | "
              f"{tp['base_time']:.2f} | {tp['base_rate'] / 1e6:.2f} M | 1.0x | {tp['base_cpu']:.2f} | "
              f"{tp['base_steps'] / tp['base_cpu'] / 1e6:.2f} M |",
              f"| ours, full naive solve {tp['full_grid']} | {tp['full_points']} | {tp['full_steps']} | "
              f"{tp['full_time']:.2f} | {tp['full_rate'] / 1e6:.2f} M | "
              f"{tp['full_base_est'] / tp['full_time']:.1f}x | {tp['full_cpu']:.2f} | "
              f"{tp['full_steps'] / tp['full_cpu'] / 1e6:.2f} M |", "",
              "CPU s: processor time of this process (all its threads), which shows how much of "
              "the 2 cores the run actually got on a shared machine; the full solve's CPU time "
              "includes setup (grid, inside test, error metrics).", "",
              f"Baseline time inside fcpw calls: {tp['base_query_time']:.2f} s of {tp['base_time']:.2f} s. "
              f"Full solve: {tp['full_time']:.1f} s measured against {tp['full_base_est']:.1f} s for the "
              f"baseline at its measured rate (rmse {tp['rmse']:.4f}). Closest-point queries alone "
              f"(500k random points, one batch): our grid {tp['q_ours'] / 1e6:.1f} M/s, fcpw "
              f"{tp['q_fcpw'] / 1e6:.1f} M/s (without reading the results back).", ""]
    text = "\n".join(lines)
    print(text)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(text)


def _per_domain(rows, method) -> str:
    names = sorted({r[0] for r in rows})
    good = sum(all(r[3][method] < r[3]["naive"] for r in rows if r[0] == n) for n in names)
    return f"{good}/{len(names)}"


if __name__ == "__main__":
    main()
