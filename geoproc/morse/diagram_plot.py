"""Persistence diagrams as a PNG image (matplotlib, Agg backend)."""

from __future__ import annotations

import io

import numpy as np

from geoproc.morse.persistence import PersistencePairs


def persistence_diagram_png(before: PersistencePairs, after: PersistencePairs, threshold: float,
                            title: str = "") -> bytes:
    """Side-by-side persistence diagrams of f (before) and g (after).

    Minimum-saddle pairs are blue dots, saddle-maximum pairs red triangles;
    essential classes sit on the dashed line at the top. The grey band marks
    pairs with persistence below the threshold (the ones removed).

    Returns
    -------
    bytes
        PNG image, 1200 x 560 pixels.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 5.6), dpi=100)
    FigureCanvasAgg(fig)
    lo = float(min(before.f.min(), after.f.min()))
    hi = float(max(before.f.max(), after.f.max()))
    scale = plot_scale(lo, hi)
    lo, hi, band = lo / scale, hi / scale, threshold / scale
    unit = "" if scale == 1.0 else f" (× {scale:.6g})"
    pad = 0.05 * (hi - lo if hi > lo else 1.0)
    top = hi + 2 * pad
    for k, (pp, name) in enumerate([(before, "before (f)"), (after, "after (g)")]):
        ax = fig.add_subplot(1, 2, k + 1)
        xs = np.array([lo - pad, top])
        # the band's top edge is clipped to the plot: at P near the float range matplotlib's
        # transform overflowed and the band vanished
        ax.fill_between(xs, xs, np.minimum(xs + band, top + pad), color="0.85", lw=0,
                        label=f"persistence < {threshold:.4g}")
        ax.plot(xs, xs, color="0.4", lw=0.8)
        ax.axhline(top, color="0.4", lw=0.8, ls="--")
        for dim, style, colour in [(0, "o", "tab:blue"), (1, "^", "tab:red"), (2, "s", "tab:green")]:
            d = pp.diagram(dim) / scale
            if not len(d):
                continue
            fin = np.isfinite(d[:, 1])
            label = ["min-saddle", "saddle-max", "max (essential)"][dim]
            n_fin = int(fin.sum())
            ax.scatter(d[fin, 0], d[fin, 1], s=9, marker=style, color=colour,
                       label=f"{label} ({n_fin})" if dim < 2 else None)
            ax.scatter(d[~fin, 0], np.full(int((~fin).sum()), top), s=30, marker=style,
                       color=colour, edgecolors="k",
                       label=f"essential dim {dim} ({int((~fin).sum())})")
        ax.set_xlim(lo - pad, top + pad)
        ax.set_ylim(lo - pad, top + pad)
        ax.set_xlabel("birth" + unit, parse_math=False)
        ax.set_ylabel("death" + unit, parse_math=False)
        ax.set_title(name, parse_math=False)
        ax.set_aspect("equal")
        ax.legend(loc="lower right", fontsize=8)
    if title:
        fig.suptitle(title, parse_math=False)  # a file name may hold '$'
    buf = io.BytesIO()
    fig.savefig(buf, format="png", metadata={"Software": None})
    return buf.getvalue()


def plot_scale(lo: float, hi: float) -> float:
    """Power of two the diagram's values are divided by before plotting: 1
    unless the values (between ``lo`` and ``hi``) or their span exceed 1e300,
    where the plot's margins and matplotlib's transforms would overflow."""
    big = max(abs(lo), abs(hi), 2.0 * (hi / 2 - lo / 2))
    return 1.0 if big <= 1e300 else float(2.0 ** np.floor(np.log2(big)))
