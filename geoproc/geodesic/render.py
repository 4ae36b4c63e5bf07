"""A PNG picture of a distance field: the mesh colored by distance, with isolines."""

from __future__ import annotations

import io

import numpy as np

FRAME_MARGIN = 0.03
"""The picture's margin on each side, as a fraction of the surface's larger extent."""


def render_distance_png(V: np.ndarray, F: np.ndarray, d: np.ndarray, sources=None, isolines: int = 20,
                        view: str = "z", size_px: int = 900, title: str | None = None) -> bytes:
    """Render ``d`` on the mesh as a PNG (matplotlib, Agg backend).

    Orthographic view along ``+view`` (the axis points at the viewer), faces
    drawn back to front with Lambert shading, colored by distance (viridis);
    isolines at ``isolines`` equal spacings of the finite range (drawn on the
    faces that face the viewer); vertices at +inf in grey; sources as red dots.
    Isolines and sources behind the surface are left out: a face-index picture
    of the same view tells which faces are in front at each pixel.

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

    V, F, d = np.asarray(V, dtype=np.float64), np.asarray(F, dtype=np.int64), np.asarray(d, dtype=np.float64)

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
    Pu = P[np.unique(F)]  # framed on the surface (vertices no face uses are not drawn)
    pad = FRAME_MARGIN * max(np.ptp(Pu[:, 0]), np.ptp(Pu[:, 1]))
    ax.set_xlim(Pu[:, 0].min() - pad, Pu[:, 0].max() + pad)
    ax.set_ylim(Pu[:, 1].min() - pad, Pu[:, 1].max() + pad)
    ax.set_aspect("equal")
    ax.axis("off")
    front = _front_face_image(fig, ax, P, F, order)
    ax.add_collection(PolyCollection(P[F[order]], facecolors=colors[order], edgecolors="none",
                                     antialiaseds=False))
    if isolines > 0 and fin.any():
        # every face, the hidden ones left out by the face-index image: picking the faces
        # whose winding faces the camera drew none on a mesh wound inwards
        segs, seg_face = isoline_segments(P, F, d, np.linspace(lo, hi, isolines + 2)[1:-1])
        if len(segs):
            keep = _seen(ax, front, F, segs.mean(axis=1), F[seg_face])
            ax.add_collection(LineCollection(segs[keep], colors="black", linewidths=0.6))
    if sources is not None:
        s = np.atleast_1d(np.asarray(sources, dtype=np.int64))
        s = s[_seen(ax, front, F, P[s], s[:, None])] if len(s) else s
        ax.plot(P[s, 0], P[s, 1], "o", color="red", markersize=4)
    if title:
        fig.suptitle(title, fontsize=10, parse_math=False)  # a file name may hold '$'
    buf = io.BytesIO()
    fig.savefig(buf, format="png", metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()


def seen_area_pixels(V: np.ndarray, F: np.ndarray, view: str = "z", size_px: int = 900) -> float:
    """The surface's area as :func:`render_distance_png`'s picture of it along
    ``view`` shows it, in square pixels: the faces' areas projected on the
    picture plane, summed, at the picture's scale (framed on the vertices
    faces use, with its margin). Below ``size_px`` (one pixel's width across
    the picture) the picture shows next to nothing: every face seen edge-on
    (a flat mesh, or a tube along the view), up to the file's rounding."""
    V, F = np.asarray(V, dtype=np.float64), np.asarray(F, dtype=np.int64)
    if not len(F):
        return 0.0
    axis = "xyz".index(view[-1])
    N = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    Pu = np.delete(V[np.unique(F)], axis, axis=1)  # the picture's two axes, up to sign and order
    extent = (1 + 2 * FRAME_MARGIN) * float(np.ptp(Pu, axis=0).max())
    if not extent > 0:
        return 0.0
    return float(np.abs(N[:, axis]).sum()) / 2 * (size_px / extent) ** 2


def _front_face_image(fig, ax, P: np.ndarray, F: np.ndarray, order: np.ndarray) -> np.ndarray:
    """(H, W) index of the face seen at each pixel (-1 for none): the faces drawn
    back to front, as the picture draws them, each in a colour that spells its
    index, then read back from the canvas."""
    from matplotlib.collections import PolyCollection

    ids = order.astype(np.int64) + 1
    rgb = np.stack([(ids >> 16) & 255, (ids >> 8) & 255, ids & 255], axis=1) / 255.0
    coll = ax.add_collection(PolyCollection(P[F[order]], facecolors=rgb, edgecolors="none",
                                            antialiaseds=False))
    fig.canvas.draw()
    buf = np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(np.int64)
    coll.remove()
    face = ((buf[..., 0] << 16) | (buf[..., 1] << 8) | buf[..., 2]) - 1
    return np.where(face < len(F), face, -1)


def _seen(ax, front: np.ndarray, F: np.ndarray, Q: np.ndarray, owners: np.ndarray) -> np.ndarray:
    """(k,) whether the points ``Q`` (k, 2) are in sight: within a pixel of each
    point some front face shares a vertex with the point's own ``owners`` (k, c)
    vertex indices (its face's corners, or a source vertex)."""
    H, W = front.shape
    xy = ax.transData.transform(Q)
    col = np.clip(np.floor(xy[:, 0]).astype(np.int64), 0, W - 1)
    row = np.clip(H - 1 - np.floor(xy[:, 1]).astype(np.int64), 0, H - 1)
    seen = np.zeros(len(Q), dtype=bool)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            f = front[np.clip(row + dr, 0, H - 1), np.clip(col + dc, 0, W - 1)]
            corners = np.where(f[:, None] >= 0, F[np.maximum(f, 0)], -1)  # (k, 3)
            seen |= (corners[:, :, None] == owners[:, None, :]).any(axis=(1, 2)) & (f >= 0)
    return seen


def isoline_segments(P: np.ndarray, F: np.ndarray, d: np.ndarray,
                     levels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(k, 2, 2) line segments where the piecewise-linear ``d`` crosses each level,
    and (k,) the index into ``F`` of the face each lies on.

    ``P`` (n, 2) are projected positions; faces with a non-finite value are skipped.
    """
    df = d[F]
    ok = np.flatnonzero(np.isfinite(df).all(axis=1))
    F, df = F[ok], df[ok]
    out, faces = [], []
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
        faces.append(ok[cut])
    if not out:
        return np.zeros((0, 2, 2)), np.zeros(0, dtype=np.int64)
    return np.concatenate(out), np.concatenate(faces)
