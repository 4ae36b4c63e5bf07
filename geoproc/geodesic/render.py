"""A PNG picture of a distance field: the mesh colored by distance, with isolines."""

from __future__ import annotations

import io

import numpy as np


def render_distance_png(V: np.ndarray, F: np.ndarray, d: np.ndarray, sources=None, isolines: int = 20,
                        view: str = "z", size_px: int = 900, title: str | None = None) -> bytes:
    """Render ``d`` on the mesh as a PNG (matplotlib, Agg backend).

    Orthographic view along ``+view`` (the axis points at the viewer), faces
    drawn back to front with Lambert shading, colored by distance (viridis);
    isolines at ``isolines`` equal spacings of the finite range (drawn on the
    faces that face the viewer); vertices at +inf in grey; sources as red dots.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
    d : (n,) float array
    sources : (k,) int array, optional
    isolines : int
        Number of isoline levels (0 for none).
    view : {"x", "y", "z", "-x", "-y", "-z"}
    size_px : int
        Width and height in pixels.
    title : str, optional

    Returns
    -------
    bytes
        The PNG file (no timestamp in its metadata: same input, same bytes).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection, PolyCollection

    sign = -1.0 if view.startswith("-") else 1.0
    axis = "xyz".index(view[-1])
    # screen (right, up) for a camera on the +axis side (sign flips for -axis)
    screen = {0: (V[:, 1] * sign, V[:, 2]), 1: (-V[:, 0] * sign, V[:, 2]), 2: (V[:, 0] * sign, V[:, 1])}
    P = np.column_stack(screen[axis])
    depth = sign * V[:, axis]
    N = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    nz = sign * N[:, axis] / np.maximum(np.linalg.norm(N, axis=1), 1e-300)
    order = np.argsort(depth[F].mean(axis=1), kind="stable")

    fin = np.isfinite(d)
    lo, hi = (float(d[fin].min()), float(d[fin].max())) if fin.any() else (0.0, 1.0)
    span = hi - lo if hi > lo else 1.0
    cmap = plt.get_cmap("viridis")
    df = d[F]
    face_fin = np.isfinite(df).all(axis=1)
    val = np.where(face_fin, (np.where(np.isfinite(df), df, 0).mean(axis=1) - lo) / span, 0.0)
    rgb = np.where(face_fin[:, None], cmap(val)[:, :3], 0.6)
    shade = 0.35 + 0.65 * np.abs(nz)
    colors = np.clip(rgb * shade[:, None], 0, 1)

    fig = plt.figure(figsize=(size_px / 100, size_px / 100), dpi=100)
    ax = fig.add_axes((0, 0, 1, 1) if title is None else (0, 0, 1, 0.95))
    ax.add_collection(PolyCollection(P[F[order]], facecolors=colors[order], edgecolors="none",
                                     antialiaseds=False))
    if isolines > 0 and fin.any():
        segs = isoline_segments(P, F[nz > 0], d, np.linspace(lo, hi, isolines + 2)[1:-1])
        if len(segs):
            ax.add_collection(LineCollection(segs, colors="black", linewidths=0.6))
    if sources is not None:
        s = np.asarray(sources)
        ax.plot(P[s, 0], P[s, 1], "o", color="red", markersize=4)
    pad = 0.03 * max(np.ptp(P[:, 0]), np.ptp(P[:, 1]))
    ax.set_xlim(P[:, 0].min() - pad, P[:, 0].max() + pad)
    ax.set_ylim(P[:, 1].min() - pad, P[:, 1].max() + pad)
    ax.set_aspect("equal")
    ax.axis("off")
    if title:
        fig.suptitle(title, fontsize=10)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()


def isoline_segments(P: np.ndarray, F: np.ndarray, d: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """(k, 2, 2) line segments where the piecewise-linear ``d`` crosses each level.

    ``P`` (n, 2) are projected positions; faces with a non-finite value are skipped.
    """
    df = d[F]
    ok = np.isfinite(df).all(axis=1)
    F, df = F[ok], df[ok]
    out = []
    for c in levels:
        above = df > c
        cnt = above.sum(axis=1)
        cut = (cnt == 1) | (cnt == 2)
        if not cut.any():
            continue
        f, v = F[cut], df[cut]
        pts = []
        for a, b in ((0, 1), (1, 2), (2, 0)):
            crosses = (v[:, a] > c) != (v[:, b] > c)
            den = np.where(crosses, v[:, b] - v[:, a], 1.0)
            s = np.where(crosses, (c - v[:, a]) / den, np.nan)
            pts.append(P[f[:, a]] + s[:, None] * (P[f[:, b]] - P[f[:, a]]))
        pts = np.stack(pts, axis=1)  # (k, 3 edges, 2)
        has = np.isfinite(pts[:, :, 0])
        idx = np.argsort(~has, axis=1, kind="stable")[:, :2]
        seg = np.take_along_axis(pts, idx[:, :, None], axis=1)
        out.append(seg)
    return np.concatenate(out) if out else np.zeros((0, 2, 2))
