"""What a morse-simplify run reports: the persistence of g, the counts of
critical cells before and after, and the checks that tie them together."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geoproc.morse.barycentric import BarycentricSimplification
from geoproc.morse.complex import SurfaceComplex, surface_complex
from geoproc.morse.critical_table import critical_counts, finite_persistence
from geoproc.morse.persistence import PersistencePairs, lower_star_persistence
from geoproc.morse.pipeline import MorseSimplification
from geoproc.morse.vpath import find_closed_vpath
from geoproc.morse.window_repair import half_bound_tolerance


@dataclass
class SimplificationSummary:
    """Persistence before and after a simplification, and its metrics.

    Attributes
    ----------
    before, after : PersistencePairs
        Of f on the (relabelled) mesh, and of g on the complex it is written
        on: the relabelled mesh, or the barycentric subdivision.
    cx_after : SurfaceComplex
        The complex of ``after``.
    order_after : (n,) int64 array or None
        Input vertex of each vertex of ``cx_after`` (None: the subdivision's
        own numbering).
    f_ref, g : (k,) float64 arrays
        The field g is compared with (f, or its lower-star extension on the
        subdivision) and g, on the output's vertices.
    metrics : dict
        Counts of minima, saddles and maxima before and after,
        ``euler_characteristic``, ``betti_0/1/2``, ``pairs_removed``,
        ``pairs_kept``, ``max_abs_change``, ``threshold`` and
        ``vertices_beyond_half_threshold`` (moves past P/2 beyond rounding and
        tie-breaking, :func:`~geoproc.morse.window_repair.half_bound_tolerance`).
    tie_rise : float
        The largest move that breaking g's ties made (units in the last place,
        unless the field's range holds too few doubles for its vertices).
    """

    before: PersistencePairs
    after: PersistencePairs
    cx_after: SurfaceComplex
    order_after: np.ndarray | None
    f_ref: np.ndarray
    g: np.ndarray
    metrics: dict
    tie_rise: float = 0.0


def simplification_summary(res: MorseSimplification | BarycentricSimplification, f: np.ndarray,
                           threshold: float) -> SimplificationSummary:
    """Persistence of g and the run's metrics, after checking the result.

    Parameters
    ----------
    res : MorseSimplification or BarycentricSimplification
        From :func:`~geoproc.morse.morse_simplify` or
        :func:`~geoproc.morse.barycentric_simplify`.
    f : (n,) float64 array
        The input field, on the input's vertices.
    threshold : float
        The absolute persistence threshold P used.

    Raises
    ------
    RuntimeError
        When the gradient has a closed V-path, the critical cells of f or g
        miss the Euler characteristic, or the gradient's critical cells are
        not those of the persistence pairs: each would be a defect of the
        construction, not of the input.
    """
    cx, grad, before = res.cx, res.gradient, res.pairs
    cycle = find_closed_vpath(cx, grad)
    if cycle is not None:
        raise RuntimeError(f"the discrete gradient has a closed V-path of dimension {cycle[0]}")
    if isinstance(res, BarycentricSimplification):
        cx_after = surface_complex(res.F, len(res.g))
        after = lower_star_persistence(cx_after, res.g)
        order_after, f_ref, g = None, res.f, res.g
        max_change, tie_slack = res.max_abs_change, res.tie_slack
    else:
        cx_after, order_after, f_ref, g = res.cx, res.order, f, res.g
        after = lower_star_persistence(cx_after, res.simplification.g)
        max_change, tie_slack = res.simplification.max_abs_change, res.tie_slack
    chi = cx.euler_characteristic
    c_before, c_after = critical_counts(before), critical_counts(after)
    for c, when in [(c_before, "f"), (c_after, "g")]:
        if c[0] - c[1] + c[2] != chi:
            raise RuntimeError(f"critical cells of {when} give c0 - c1 + c2 = {c[0] - c[1] + c[2]} "
                               f"!= V - E + F = {chi}")
    if (len(grad.critical_vertices), len(grad.critical_edges), len(grad.critical_triangles)) != c_before:
        raise RuntimeError("gradient critical cells do not match the persistence pairs")
    pers = finite_persistence(before)
    # a move past P/2 by at most 64 units in the last place of the field's
    # largest value is rounding of the assigned values, and one unit per
    # tied vertex is tie-breaking, not a move beyond P/2; with P = 0
    # (nothing removed), the barycentric path breaks the lower-star extension's
    # ties by units in the last place
    # (the rounding allowance from the surface's values: a vertex no face uses keeps its own)
    half_tol = half_bound_tolerance(f_ref if order_after is None else f_ref[order_after], threshold / 2.0, tie_slack)
    beyond = int(np.count_nonzero(np.abs(g - f_ref) > half_tol)) if threshold > 0 else 0
    b0, b1, b2 = before.betti
    metrics = {
        "minima_before": c_before[0], "saddles_before": c_before[1], "maxima_before": c_before[2],
        "minima_after": c_after[0], "saddles_after": c_after[1], "maxima_after": c_after[2],
        "euler_characteristic": chi,
        "betti_0": b0, "betti_1": b1, "betti_2": b2,
        "pairs_removed": int(np.count_nonzero(pers < threshold)),
        "pairs_kept": int(np.count_nonzero(pers >= threshold)),
        "max_abs_change": max_change,
        "threshold": threshold,
        "vertices_beyond_half_threshold": beyond,
    }
    return SimplificationSummary(before, after, cx_after, order_after, f_ref, g, metrics,
                                 float(np.max(tie_slack, initial=0.0)))
