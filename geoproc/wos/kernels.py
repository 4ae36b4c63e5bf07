"""Harmonic kernels for control variates.

- Green's function of the plane, ``phi(x) = -(1/2 pi) log|x - y|``, with the
  center ``y`` outside the domain.
- Segment angle kernel: the signed angle the directed segment ``[a, b]`` subtends
  at ``x``, ``atan2(det(a - x, b - x), (a - x).(b - x))``, harmonic off the
  segment (a double-layer potential of unit density, as in generalized winding
  numbers). A kernel may be a chain of segments (an arc of the boundary): the
  sum of their angles.

A :class:`KernelSet` is a list of elements (points or segments), each feeding
one column (kernel) ``col[e]``; a control variate is
``c(x) = c0 + sum_e w[e] phi_e(x)`` with ``w[e] = sigma[col[e]]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np

GREEN, ANGLE = 1, 2
_INV2PI = 1.0 / (2.0 * math.pi)


@dataclass
class KernelSet:
    """Kernels of one family.

    Attributes
    ----------
    kind : int
        ``GREEN`` or ``ANGLE``.
    P : (E, 2) float64
        Green centers, or segment starts.
    Q : (E, 2) float64
        Segment ends (copies of P for Green kernels).
    col : (E,) int64
        Kernel (column) index of each element, in ``range(M)``; for angle
        kernels non-decreasing, so kernel ``j`` is the chain of segments
        ``arcs[j, 0] <= e < arcs[j, 1]``.
    M : int
        Number of kernels.
    arcs : (M, 2) int64
        Element range of each angle kernel (empty for Green kernels).
    boxes : (M, 4) float64
        Bounding box ``xmin, ymin, xmax, ymax`` of each angle kernel's chain.
    """

    kind: int
    P: np.ndarray
    Q: np.ndarray
    col: np.ndarray
    M: int
    arcs: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    boxes: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))

    def __post_init__(self):
        if self.kind == ANGLE and len(self.arcs) == 0:
            if np.any(np.diff(self.col) < 0):
                raise ValueError("angle kernel elements must be grouped by kernel")
            first = np.searchsorted(self.col, np.arange(self.M), side="left")
            last = np.searchsorted(self.col, np.arange(self.M), side="right")
            self.arcs = np.ascontiguousarray(np.stack([first, last], axis=1).astype(np.int64))
            lo = np.minimum(self.P, self.Q)
            hi = np.maximum(self.P, self.Q)
            self.boxes = np.ascontiguousarray(np.stack(
                [np.minimum.reduceat(lo[:, 0], first), np.minimum.reduceat(lo[:, 1], first),
                 np.maximum.reduceat(hi[:, 0], first), np.maximum.reduceat(hi[:, 1], first)], axis=1))

    def weights(self, sigma: np.ndarray) -> np.ndarray:
        """Weights for the numba evaluators: per element (Green) or per kernel (angle)."""
        sigma = np.asarray(sigma, dtype=np.float64)
        return np.ascontiguousarray(sigma if self.kind == ANGLE else sigma[self.col])


def green_kernel(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Green's function ``-(1/2 pi) log|x - y|`` for all pairs: X (n, 2), Y (m, 2) -> (n, m)."""
    d2 = ((X[:, None, :] - Y[None, :, :]) ** 2).sum(axis=-1)
    return -0.25 / np.pi * np.log(d2)


def segment_angle_kernel(X: np.ndarray, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Signed angle of directed segments ``A -> B`` (m, 2) seen from X (n, 2) -> (n, m), radians."""
    ax = A[None, :, 0] - X[:, None, 0]
    ay = A[None, :, 1] - X[:, None, 1]
    bx = B[None, :, 0] - X[:, None, 0]
    by = B[None, :, 1] - X[:, None, 1]
    return np.arctan2(ax * by - ay * bx, ax * bx + ay * by)


ELEMENT_BLOCK = 1 << 21
"""Point-element pairs evaluated at once by :func:`kernel_matrix` and
:func:`kernel_normal_matrix` (16 MB per array): an angle kernel has one
element per boundary segment, and all pairs at once had taken 11 GB for
640 fit points on a 320,000-segment domain."""


def _sum_over_elements(n: int, ks: KernelSet, elements) -> np.ndarray:
    """(n, M): ``elements(lo, hi)``, the (n, hi - lo) values of elements lo to hi
    at n points, summed into their kernels' columns, a block of elements at a
    time (in element order, as one ``np.add.at`` over all of them adds)."""
    Phi = np.zeros((n, ks.M))
    count = len(ks.col)
    block = max(1, ELEMENT_BLOCK // max(n, 1))
    for lo in range(0, count, block):
        hi = min(lo + block, count)
        np.add.at(Phi.T, ks.col[lo:hi], elements(lo, hi).T)
    return Phi


def kernel_matrix(X: np.ndarray, ks: KernelSet) -> np.ndarray:
    """Design matrix (n, M): every kernel of ``ks`` at the points X (n, 2)."""
    if ks.kind == GREEN:
        return _sum_over_elements(len(X), ks, lambda lo, hi: green_kernel(X, ks.P[lo:hi]))
    return _sum_over_elements(len(X), ks, lambda lo, hi: segment_angle_kernel(X, ks.P[lo:hi], ks.Q[lo:hi]))


def kernel_normal_matrix(X: np.ndarray, N: np.ndarray, ks: KernelSet) -> np.ndarray:
    """Normal derivatives (n, M): the gradient of every kernel at X (n, 2) dotted with N (n, 2)."""
    def green(lo, hi):
        D = X[:, None, :] - ks.P[None, lo:hi, :]
        r2 = (D**2).sum(axis=-1)
        return -(D * N[:, None, :]).sum(axis=-1) / (2 * np.pi * r2)

    def darg(Q):  # gradient in x of arg(q - x): (v_y, -v_x) / |v|^2, v = q - x
        v = Q[None, :, :] - X[:, None, :]
        r2 = (v**2).sum(axis=-1)
        return (v[..., 1] * N[:, None, 0] - v[..., 0] * N[:, None, 1]) / r2

    if ks.kind == GREEN:
        return _sum_over_elements(len(X), ks, green)
    return _sum_over_elements(len(X), ks, lambda lo, hi: darg(ks.Q[lo:hi]) - darg(ks.P[lo:hi]))


@numba.njit(cache=True, nogil=True, inline="always")
def _angle(px, py, ax, ay, bx, by):
    ax -= px
    ay -= py
    bx -= px
    by -= py
    return math.atan2(ax * by - ay * bx, ax * bx + ay * by)


@numba.njit(cache=True, nogil=True)
def cv_value(px, py, kind, KP, KQ, W, ARC, BOX):
    """Control variate ``sum_j W[j] phi_j(p)`` at one point (numba).

    An angle kernel seen from outside its chain's bounding box is the angle of
    its chord (the chain lies in a half plane without p, so the angles add up
    to the chord's); inside the box its segments are summed.
    """
    s = 0.0
    if kind == GREEN:
        for e in range(W.shape[0]):
            dx = px - KP[e, 0]
            dy = py - KP[e, 1]
            s -= W[e] * 0.5 * _INV2PI * math.log(dx * dx + dy * dy)
    elif kind == ANGLE:
        for j in range(W.shape[0]):
            e0 = ARC[j, 0]
            e1 = ARC[j, 1]
            if px < BOX[j, 0] or px > BOX[j, 2] or py < BOX[j, 1] or py > BOX[j, 3]:
                s += W[j] * _angle(px, py, KP[e0, 0], KP[e0, 1], KQ[e1 - 1, 0], KQ[e1 - 1, 1])
            else:
                a = 0.0
                for e in range(e0, e1):
                    a += _angle(px, py, KP[e, 0], KP[e, 1], KQ[e, 0], KQ[e, 1])
                s += W[j] * a
    return s


@numba.njit(cache=True, nogil=True)
def cv_gradient(px, py, kind, KP, KQ, W, ARC):
    """Gradient ``(gx, gy)`` of the control variate at one point (numba)."""
    gx = 0.0
    gy = 0.0
    if kind == GREEN:
        for e in range(W.shape[0]):
            dx = px - KP[e, 0]
            dy = py - KP[e, 1]
            r2 = dx * dx + dy * dy
            gx -= W[e] * _INV2PI * dx / r2
            gy -= W[e] * _INV2PI * dy / r2
    elif kind == ANGLE:
        # d/dx arg(q - x) = (v_y, -v_x) / |v|^2 with v = q - x
        for j in range(W.shape[0]):
            for e in range(ARC[j, 0], ARC[j, 1]):
                bx = KQ[e, 0] - px
                by = KQ[e, 1] - py
                ax = KP[e, 0] - px
                ay = KP[e, 1] - py
                rb = bx * bx + by * by
                ra = ax * ax + ay * ay
                gx += W[j] * (by / rb - ay / ra)
                gy += W[j] * (-bx / rb + ax / ra)
    return gx, gy
