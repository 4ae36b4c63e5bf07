"""Benchmark: geoproc morse-simplify's pipeline against gudhi's lower-star persistence.

geoproc: vertices relabelled by value and the edges and incidences built,
discrete gradient (ProcessLowerStars), persistence pairs, simplification at
P = 1% of the range (the steps of geoproc.morse.morse_simplify). gudhi: SimplexTree built by batch
inserts (vertices, edges, triangles, each at the max of its vertex values; the
edge list is extracted with numpy and counted in gudhi's time), then
compute_persistence. Same mesh, same field: armadillo with a noisy height field
(y + 2% Gaussian noise, seed 0) and the same mesh subdivided twice (libigl
upsample, 4x per step). Each side runs in its own process (numba compiled and
warmed up first), so peak memory is the process's maximum resident set size
(getrusage); "extra" is the peak above the process's size after loading the
mesh. Times are medians over the repeats.

Usage: python bench/morse_vs_gudhi.py [--levels 0 2] [--repeat 3] [--out out/bench]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

# single-threaded unless told otherwise, as the README's figures were measured (make bench sets nothing);
# before numpy and numba load, and inherited by the worker processes
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ARMADILLO = ROOT.parent / "shared" / "data" / "meshes" / "armadillo.obj"


def rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def load(level: int):
    import igl

    from geoproc.mesh import load_mesh

    m = load_mesh(ARMADILLO)
    V, F = m.V, m.F
    for _ in range(level):
        V, F = igl.upsample(V, F)
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    h = V[:, 1]
    f = h + 0.02 * (h.max() - h.min()) * np.random.default_rng(0).standard_normal(len(V))
    return V, F, f


def geoproc_run(V, F, f, P):
    """geoproc.morse.morse_simplify's steps, timed one by one."""
    from geoproc.morse import discrete_gradient, lower_star_persistence, simplify_function, surface_complex
    from geoproc.morse.order import vertex_order

    t = [time.perf_counter()]
    order, rank = vertex_order(f)  # relabel vertices by value (memory locality)
    cx = surface_complex(rank[F], len(V))
    fr = f[order]
    t.append(time.perf_counter())
    grad = discrete_gradient(cx, fr)
    t.append(time.perf_counter())
    pp = lower_star_persistence(cx, fr)
    t.append(time.perf_counter())
    s = simplify_function(cx, fr, P, grad)
    g = np.empty(len(f))
    g[order] = s.g
    t.append(time.perf_counter())
    kept = [int((pp.persistence(d) >= P).sum()) for d in (0, 1)]
    return np.diff(t), kept, s


def barycentric_run(V, F, f, P):
    from geoproc.morse import barycentric_simplify

    t = time.perf_counter()
    b = barycentric_simplify(V, F, f, P)
    t = time.perf_counter() - t
    return t, b.pairs_kept, b.max_abs_change / P


def gudhi_run(V, F, f, P):
    import gudhi

    t0 = time.perf_counter()
    n = len(f)
    H = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    key = np.unique(H[:, 0] * n + H[:, 1])
    E = np.column_stack([key // n, key % n])
    st = gudhi.SimplexTree()
    st.insert_batch(np.arange(len(f))[None, :], f)
    st.insert_batch(E.T, f[E].max(axis=1))
    st.insert_batch(F.T, f[F].max(axis=1))
    t1 = time.perf_counter()
    st.compute_persistence(homology_coeff_field=2, persistence_dim_max=True)
    t2 = time.perf_counter()
    kept = []
    for d in (0, 1):
        iv = st.persistence_intervals_in_dimension(d).reshape(-1, 2)
        iv = iv[np.isfinite(iv[:, 1])]
        kept.append(int((iv[:, 1] - iv[:, 0] >= P).sum()))
    del st
    return (t1 - t0, t2 - t1), kept


def worker(side: str, level: int, repeat: int) -> dict:
    V, F, f = load(level)
    P = 0.01 * float(f.max() - f.min())
    if side != "gudhi":  # compile and warm up numba on a small mesh first
        import trimesh

        s = trimesh.creation.icosphere(subdivisions=2)
        sv = np.asarray(s.vertices)
        run = geoproc_run if side == "geoproc" else barycentric_run
        run(sv, np.asarray(s.faces, dtype=np.int64), sv[:, 2] + 0.1 * np.sin(7 * sv[:, 0]), 0.1)
    base = rss_mb()
    runs, kept = [], None
    for _ in range(repeat):
        if side == "geoproc":
            phases, kept, s = geoproc_run(V, F, f, P)
            runs.append([float(x) for x in phases])
            extra = {"max_abs_change_over_P": float(s.max_abs_change / P),
                     "beyond_half": int(len(s.widened_vertices)),
                     "pairs_removed": s.pairs_removed}
        elif side == "barycentric":
            tb, pairs_kept, change = barycentric_run(V, F, f, P)
            runs.append([tb])
            kept = pairs_kept
            extra = {"max_abs_change_over_P": change}
        else:
            phases, kept = gudhi_run(V, F, f, P)
            runs.append([float(x) for x in phases])
            extra = {}
    return {"n": len(V), "m": len(F), "runs": runs, "kept": kept, "rss_peak_mb": rss_mb(),
            "rss_base_mb": base, **extra}


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=int, nargs="+", default=[0, 2])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "bench")
    ap.add_argument("--worker", choices=["geoproc", "barycentric", "gudhi"], help=argparse.SUPPRESS)
    ap.add_argument("--level", type=int, default=0, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.worker:
        print(json.dumps(worker(a.worker, a.level, a.repeat)))
        return 0
    if not ARMADILLO.is_file():
        print(f"skipped: {ARMADILLO} not found (needs ../shared)")
        return 0
    rows = []
    for level in a.levels:
        res = {}
        for side in ("geoproc", "barycentric", "gudhi"):
            out = subprocess.run([sys.executable, __file__, "--worker", side, "--level", str(level),
                                  "--repeat", str(a.repeat)], capture_output=True, text=True, check=True)
            res[side] = json.loads(out.stdout.strip().splitlines()[-1])
        geo, bar, gud = res["geoproc"], res["barycentric"], res["gudhi"]
        tb = float(np.median([sum(r) for r in bar["runs"]]))
        tg = float(np.median([sum(r) for r in geo["runs"]]))
        tu = float(np.median([sum(r) for r in gud["runs"]]))
        ph = np.median(np.array(geo["runs"]), axis=0)
        rows.append({
            "mesh": "armadillo" + (f" subdivided x{level}" if level else ""),
            "vertices": geo["n"], "faces": geo["m"], "geoproc_s": tg, "gudhi_s": tu, "ratio": tg / tu,
            "phases": "relabel+complex {:.2f} + gradient {:.2f} + pairs {:.2f} + simplify {:.2f}".format(*ph),
            "gudhi_phases": "build {:.2f} + persistence {:.2f}".format(*np.median(np.array(gud["runs"]), axis=0)),
            "geoproc_mb": f"{geo['rss_peak_mb']:.0f} (+{geo['rss_peak_mb'] - geo['rss_base_mb']:.0f})",
            "gudhi_mb": f"{gud['rss_peak_mb']:.0f} (+{gud['rss_peak_mb'] - gud['rss_base_mb']:.0f})",
            "pairs_agree": geo["kept"] == gud["kept"],
            "max_abs_change_over_P": geo["max_abs_change_over_P"],
            "beyond_half": geo["beyond_half"],
            "bary_s": tb, "bary_ratio": tb / tu, "bary_change": bar["max_abs_change_over_P"],
            "bary_mb": f"{bar['rss_peak_mb']:.0f} (+{bar['rss_peak_mb'] - bar['rss_base_mb']:.0f})",
            "bary_agree": bar["kept"] == sum(gud["kept"]),
        })
    head = ("| mesh | vertices | geoproc pipeline s | gudhi lower-star s | ratio | geoproc phases s | "
            "gudhi phases s | peak RSS MB geoproc (extra) | peak RSS MB gudhi (extra) | pairs >= P agree | "
            "max abs change / P | vertices beyond P/2 | --barycentric s | ratio | peak RSS MB (extra) | "
            "pairs agree | max abs change / P |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        lines.append(f"| {r['mesh']} | {r['vertices']:,} | {r['geoproc_s']:.3f} | {r['gudhi_s']:.3f} | "
                     f"{r['ratio']:.2f}x | {r['phases']} | {r['gudhi_phases']} | {r['geoproc_mb']} | "
                     f"{r['gudhi_mb']} | {'yes' if r['pairs_agree'] else 'NO'} | "
                     f"{r['max_abs_change_over_P']:.3f} | {r['beyond_half']:,} | {r['bary_s']:.3f} | "
                     f"{r['bary_ratio']:.2f}x | {r['bary_mb']} | {'yes' if r['bary_agree'] else 'NO'} | "
                     f"{r['bary_change']:.3f} |")
    table = "\n".join(lines)
    print(table)
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "morse_vs_gudhi.md").write_text(table + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
