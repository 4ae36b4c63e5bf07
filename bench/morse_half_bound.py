"""How close morse-simplify gets to ||f - g||_inf <= P/2, with and without the exact windows.

The noisy height fields of the tests (height + 2% Gaussian noise of the height
range, numpy default_rng(seed)) on the shared meshes, P a fraction of f's
range. For each case and each setting of ``exact_windows`` (0: none, 4: the
default, -1: all, wider where still beyond P/2): the vertices with
|f - g| > P/2, max |f - g| / P, the kept saddle edges whose highest vertex
under g is not their own under f (of all kept saddle edges), and the time of
simplify_function (single-threaded numba compiled first; one run). A last row
per case: geoproc.morse.barycentric_simplify (g on the barycentric subdivision,
f there the lower-star extension; its kept saddles are the kept edges' own
midpoints by construction), with the whole function's time.

Usage: python bench/morse_half_bound.py [--settings 0 4 -1] [--cases bunny camelhead ...]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MESHES = ROOT.parent / "shared" / "data" / "meshes"
# name, file, height axis, P / range, noise seed (as in tests/geoproc/test_morse_simplify.py)
CASES = [("bunny", "bunny.off", 1, 0.01, 10), ("camelhead", "camelhead.off", 1, 0.05, 10),
         ("fertility", "fertility.off", 2, 0.02, 10), ("spot", "spot.obj", 1, 0.05, 10),
         ("armadillo", "armadillo.obj", 1, 0.01, 0), ("armadillo", "armadillo.obj", 1, 0.05, 0)]


def moved_saddles(cx, f, g, P) -> tuple[int, int]:
    from geoproc.morse import discrete_gradient, lower_star_persistence

    pf, pg = lower_star_persistence(cx, f), lower_star_persistence(cx, g)
    pers0 = f[pf.edge_top[pf.min_saddle_edge]] - f[pf.min_vertex]
    pers1 = f[pf.triangle_top[pf.max_triangle]] - f[pf.edge_top[pf.saddle_edge]]
    kept = np.concatenate([pf.min_saddle_edge[pers0 >= P], pf.saddle_edge[pers1 >= P], pf.essential_edges])
    want = Counter(pf.edge_top[kept].tolist())
    have = Counter(pg.edge_top[discrete_gradient(cx, g).critical_edges].tolist())
    return sum(want.values()) - sum((want & have).values()), sum(want.values())


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--settings", type=int, nargs="+", default=[0, 4, -1])
    ap.add_argument("--cases", nargs="+", help="mesh names to run (default: all)")
    a = ap.parse_args(argv)
    if not MESHES.is_dir():
        print(f"skipped: {MESHES} not found (needs ../shared)")
        return 0
    from geoproc.mesh import load_mesh
    from geoproc.morse import barycentric_simplify, simplify_function, surface_complex

    sv = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    simplify_function(surface_complex(np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]]), 4),
                      sv[:, 0] + 0.1, 0.5)  # compile numba
    barycentric_simplify(sv, np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]]), sv[:, 0] + 0.1, 0.5)
    lines = ["| mesh | P / range | exact_windows | vertices beyond P/2 | max abs change / P | "
             "kept saddle edges elsewhere | simplify s |", "|---|---|---|---|---|---|---|"]
    for name, file, axis, rel, seed in CASES:
        if a.cases and name not in a.cases:
            continue
        V = load_mesh(MESHES / file).V
        F = load_mesh(MESHES / file).F
        h = V[:, axis]
        f = h + 0.02 * (h.max() - h.min()) * np.random.default_rng(seed).standard_normal(len(V))
        P = rel * (f.max() - f.min())
        cx = surface_complex(F, len(f))
        for k in a.settings:
            t = time.perf_counter()
            s = simplify_function(cx, f, P, exact_windows=k)
            t = time.perf_counter() - t
            mv, nk = moved_saddles(cx, f, s.g, P)
            lines.append(f"| {name} | {rel:g} | {k} | {len(s.widened_vertices)} | {s.max_abs_change / P:.4f} | "
                         f"{mv} of {nk:,} | {t:.2f} |")
            print(lines[-1], file=sys.stderr, flush=True)
        t = time.perf_counter()
        b = barycentric_simplify(V, F, f, P)
        t = time.perf_counter() - t
        beyond = int((np.abs(b.g - b.f) > P / 2 * (1 + 1e-12)).sum())
        lines.append(f"| {name} | {rel:g} | barycentric ({len(b.g):,} cells) | {beyond} | "
                     f"{b.max_abs_change / P:.4f} | 0 | {t:.2f} |")
        print(lines[-1], file=sys.stderr, flush=True)
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
