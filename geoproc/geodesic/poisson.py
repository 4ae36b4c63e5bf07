"""The Poisson step of the heat method: recover a function from its gradient field."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from geoproc.geodesic.operators import factor_sparse, normalized_direction


class PoissonSolver:
    """Factor ``-L`` once (one vertex pinned per connected component) and solve
    ``L phi = b`` for many right-hand sides.

    Parameters
    ----------
    L : (n, n) sparse
        A Laplacian (rows sum to zero) whose null space is the constants on each
        connected component of its graph.
    """

    def __init__(self, L: sp.spmatrix):
        L = sp.csr_matrix(L)
        n = L.shape[0]
        _, labels = connected_components(L, directed=False)
        _, pins = np.unique(labels, return_index=True)
        keep = np.ones(n, dtype=bool)
        keep[pins] = False
        self.n, self.keep, self.labels = n, np.flatnonzero(keep), labels
        A = (-L)[self.keep][:, self.keep].tocsc()
        self._lu = factor_sparse(A) if A.shape[0] else None

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``phi`` (n,) with ``L phi = b`` where solvable, 0 at each pinned vertex.

        ``b`` must sum to zero on each component (true for a divergence).
        """
        phi = np.zeros(self.n)
        if self._lu is not None:
            phi[self.keep] = self._lu.solve(-np.asarray(b, dtype=np.float64)[self.keep])
        return phi

    def distance_from_direction(self, D: sp.spmatrix, g: np.ndarray, sources: np.ndarray) -> np.ndarray:
        """The heat method's last two steps: ``X = -g / |g|`` per face (``g`` (m, 3)
        parallel to the heat gradient), ``L phi = D X`` (``D`` (n, 3m) the integrated
        divergence), shifted so the sources are at 0. Returns ``phi`` (n,)."""
        X = -normalized_direction(g)
        return self.shift_to_sources(self.solve(D @ X.T.reshape(-1)), sources)

    def shift_to_sources(self, phi: np.ndarray, sources: np.ndarray) -> np.ndarray:
        """Shift ``phi`` per component so its mean over that component's sources is 0."""
        out = phi.copy()
        lab = self.labels
        for c in np.unique(lab[sources]):
            s = sources[lab[sources] == c]
            out[lab == c] -= phi[s].mean()
        return out
