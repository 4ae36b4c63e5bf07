"""Accuracy of a distance field against a reference (e.g. exact geodesics)."""

from __future__ import annotations

import numpy as np


def compare_to_reference(d: np.ndarray, ref: np.ndarray) -> dict:
    """Error metrics of ``d`` against ``ref`` on distances divided by ``max(ref)``,
    the largest finite reference distance (over every vertex a source reaches,
    compared or not).

    Compared over the vertices where ``ref`` is finite. A vertex where ``ref``
    is finite but ``d`` is not is counted in ``nonfinite_vertices`` and left
    out of the other metrics (which are then over the rest); one where ``d``
    is finite but ``ref`` is not (a reference from other sources, or another
    mesh, that does not reach it) in ``reference_nonfinite_vertices``. With fewer than
    two compared vertices, or ``max(ref) = 0`` (every vertex a source), the
    error metrics are NaN.

    Returns
    -------
    dict
        ``pearson_r`` (correlation of d and ref), ``rmse`` and ``mae`` of
        ``(d - ref) / max(ref)``, ``mean_relative_error`` = mean ``|d - ref| /
        max(ref)`` (equal to ``mae`` by this definition), ``max_relative_error``
        = max ``|d - ref| / max(ref)``, ``compared_vertices``,
        ``nonfinite_vertices`` and ``reference_nonfinite_vertices``.
    """
    d = np.asarray(d, dtype=np.float64)
    ref = np.asarray(ref, dtype=np.float64)
    reach = np.isfinite(ref)
    ok = reach & np.isfinite(d)
    out = {"compared_vertices": int(ok.sum()), "nonfinite_vertices": int((reach & ~ok).sum()),
           "reference_nonfinite_vertices": int((~reach & np.isfinite(d)).sum())}
    scale = float(ref[reach].max()) if reach.any() else 0.0
    if ok.sum() < 2 or not scale > 0:  # nothing to compare, or every vertex a source
        return out | {k: float("nan") for k in
                      ("pearson_r", "rmse", "mae", "mean_relative_error", "max_relative_error")}
    e = (d[ok] - ref[ok]) / scale
    a, b = d[ok], ref[ok]
    sa, sb = a.std(), b.std()
    r = float(((a - a.mean()) * (b - b.mean())).mean() / (sa * sb)) if sa > 0 and sb > 0 else float("nan")
    r = min(max(r, -1.0), 1.0) if r == r else r  # rounding took d = ref to 1.0000000000000002
    out.update(
        pearson_r=r,
        rmse=float(np.sqrt(np.mean(e**2))),
        mae=float(np.mean(np.abs(e))),
        mean_relative_error=float(np.mean(np.abs(e))),
        max_relative_error=float(np.max(np.abs(e))),
    )
    return out
