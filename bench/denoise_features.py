"""Feature identification and time-varying-cloud outliers of geoproc denoise.

1. Per-face features of the denoised mesh (default parameters) against the
   clean mesh's creases (faces with an edge whose clean dihedral angle exceeds
   30 degrees): precision, recall and F1 of the l1 identification (default,
   ``--features l1``) and of the 30-degree threshold on the filtered normals
   (``--features dihedral``), on the shared noisy/clean pairs and the perturbed
   fandisk and cube (sigma 0.3, seed 1).
2. Time-varying clouds: the elephant animation's vertices (every 16th and every
   4th frame) as
   a moving point cloud with 20 % outliers per frame within 1/50 of the
   diagonal (``perturb``'s protocol, seed 3), RPCA on the animation matrix
   against the static neighbourhood RPCA frame by frame.
3. The refinement of static cloud outliers (``--refined``): bunny and fandisk
   sampled at 100,000 points, noise 0.3 along the normals and 20 % outliers
   within 1/50 of the diagonal; mean distance of the kept points to the clean
   mesh before and after the refinement.

Usage: python bench/denoise_features.py
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"

from geoproc.denoise import DenoiseParams, denoise_mesh, detection_scores, rpca_outliers  # noqa: E402
from geoproc.denoise.face_geometry import face_edge_neighbors, face_normals_and_areas  # noqa: E402
from geoproc.denoise.features import dihedral_feature_faces, l1_feature_faces  # noqa: E402
from geoproc.denoise.outliers import rpca_animation_outliers  # noqa: E402
from geoproc.mesh import load_mesh  # noqa: E402
from geoproc.perturb import NoiseSpec, perturb_positions  # noqa: E402


def _module(path: Path, name: str):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _prf(pred, truth):
    pred = np.asarray(pred) > 0
    tp = float((pred & truth).sum())
    p = tp / max(pred.sum(), 1)
    r = tp / max(truth.sum(), 1)
    return p, r, (2 * p * r / (p + r) if p + r else 0.0)


def feature_inputs():
    for d in sorted((SHARED / "denoise").iterdir()):
        if (d / "Noisy.obj").exists() and (d / "Original.obj").exists():
            a = load_mesh(d / "Noisy.obj", clean=False)
            b = load_mesh(d / "Original.obj", clean=False)
            yield d.name, a.V, a.F, b.V
    fx = _module(ROOT / "fixtures" / "denoise_fixtures.py", "denoise_fixtures")
    m = load_mesh(SHARED / "meshes" / "fandisk.off")
    cube = fx.subdivided_cube(16)
    for name, (V, F) in (("fandisk +0.3", (m.V, m.F)), ("cube +0.3", cube)):
        Vn, _ = perturb_positions(V, F, NoiseSpec(sigma=0.3), np.random.default_rng(1))
        yield name, Vn, F, V


def feature_table() -> str:
    rows = ["| input | crease faces | l1 P | l1 R | l1 F1 | l1 time s | dihedral P | dihedral R | dihedral F1 |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name, Vn, F, V in feature_inputs():
        N, _ = face_normals_and_areas(V, F)
        truth = dihedral_feature_faces(N, face_edge_neighbors(F), 30.0) > 0
        res = denoise_mesh(Vn, F, params=DenoiseParams(features="none"))
        t0 = time.perf_counter()
        l1, _ = l1_feature_faces(res.V, F)
        t = time.perf_counter() - t0
        dih = dihedral_feature_faces(res.normals, face_edge_neighbors(F), 30.0)
        a, b = _prf(l1, truth), _prf(dih, truth)
        rows.append(f"| {name} | {int(truth.sum())} | {a[0]:.3f} | {a[1]:.3f} | {a[2]:.3f} | {t:.2f} | "
                    f"{b[0]:.3f} | {b[1]:.3f} | {b[2]:.3f} |")
        print(rows[-1], flush=True)
    return "\n".join(rows)


def animation_table() -> str:
    pairs = _module(ROOT / "bench" / "denoise_pairs.py", "denoise_pairs")
    rows = ["| elephant vertices as a moving cloud, 20 % outliers within 1/50 diag | frames | points | method | "
            "precision | recall | F1 | time s |", "|---|---:|---:|---|---:|---:|---:|---:|"]
    for step in (16, 4):
        V, _ = pairs.elephant(step)
        rng = np.random.default_rng(3)
        spec = NoiseSpec(outliers=0.2, outlier_range=0.02)
        noisy, flags = zip(*(perturb_positions(V[t], np.zeros((0, 3), dtype=np.int64), spec, rng)
                             for t in range(len(V))), strict=True)
        Vn, flag = np.stack(noisy), np.stack(flags) > 0
        t0 = time.perf_counter()
        dyn = rpca_animation_outliers(Vn)
        t_dyn = time.perf_counter() - t0
        t0 = time.perf_counter()
        static = np.stack([rpca_outliers(Vn[t], k=16).outlier for t in range(len(V))])
        t_static = time.perf_counter() - t0
        a, b = detection_scores(dyn.outlier, flag), detection_scores(static, flag)
        rows += [f"| every {step}th frame | {len(V)} | {V.shape[1]} | RPCA on the animation matrix "
                 f"(basis {dyn.rank}) | {a['precision']:.3f} | {a['recall']:.3f} | {a['f1']:.3f} | {t_dyn:.1f} |",
                 f"| | | | static neighbourhood RPCA per frame | {b['precision']:.3f} | {b['recall']:.3f} | "
                 f"{b['f1']:.3f} | {t_static:.1f} |"]
        print("\n".join(rows[-2:]), flush=True)
    return "\n".join(rows)


def refine_table() -> str:
    import igl
    import trimesh

    rows = ["| cloud (σ 0.3 along normals, 20 % outliers) | points | kept | mean distance to the clean mesh, "
            "input | refined | ratio |", "|---|---:|---:|---:|---:|---:|"]
    for name in ("bunny.off", "fandisk.off"):
        m = load_mesh(SHARED / "meshes" / name)
        pts, _ = trimesh.sample.sample_surface(trimesh.Trimesh(m.V, m.F, process=False), 100000, seed=1)
        P, _ = perturb_positions(np.asarray(pts), np.zeros((0, 3), int),
                                 NoiseSpec(sigma=0.3, outliers=0.2, outlier_range=0.02), np.random.default_rng(2))
        res = rpca_outliers(P, k=16)
        keep = ~res.outlier
        d0 = np.sqrt(igl.point_mesh_squared_distance(P[keep], m.V, m.F)[0]).mean()
        d1 = np.sqrt(igl.point_mesh_squared_distance(res.refined[keep], m.V, m.F)[0]).mean()
        rows.append(f"| {name} | {len(P)} | {int(keep.sum())} | {d0:.3g} | {d1:.3g} | {d1 / d0:.2f} |")
        print(rows[-1], flush=True)
    return "\n".join(rows)


def main(argv: list[str]) -> int:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args(argv)  # --help, and no stray arguments
    if not (SHARED / "denoise").is_dir():
        print(f"shared data not found at {SHARED}; nothing to benchmark")
        return 0
    parts = ["## denoise: feature faces against the clean creases (dihedral > 30°)", feature_table(),
             "## denoise --outliers on a time-varying cloud", animation_table(),
             "## denoise --outliers --refined", refine_table()]
    print()
    print("\n\n".join(parts))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
