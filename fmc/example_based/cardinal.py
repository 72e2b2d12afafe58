"""Cardinal basis functions: one weight function per example, 1 at it and 0 at the others.

For examples at parameters p_1 … p_N, the weight function of example i is a linear
polynomial plus radial cubic B-splines centred on the examples,

    w_i(p) = Σ_l a_il A_l(p) + Σ_j r_ij R_j(p),   A = (1, p_1, …, p_d),
    R_j(p) = B(‖p − p_j‖ / α_j),

with α_j the distance from p_j to its nearest other example. The linear part is the
least-squares fit of the δ_ij at the examples; the radial part interpolates what it
leaves, so w_i(p_j) = δ_ij exactly (Sloan, Rose and Cohen; used by Pyun et al. for the
weights of the target key-models).

References
----------
.. [1] P.-P. Sloan, C. F. Rose, M. F. Cohen, "Shape by example", Proc. Symposium on
   Interactive 3D Graphics (2001) 135-143.
.. [2] H. Pyun et al., "An example-based approach for facial expression cloning",
   SCA 2003, section 5.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial.distance import cdist

from mpeg4.errors import InputError

__all__ = ["cubic_bspline", "CardinalBasis"]


def cubic_bspline(t: np.ndarray) -> np.ndarray:
    """The uniform cubic B-spline centred at 0 (support |t| < 2, value 2/3 at 0).

    Examples
    --------
    >>> cubic_bspline(np.array([0.0, 1.0, 2.0]))
    array([0.66666667, 0.16666667, 0.        ])
    """
    t = np.abs(np.asarray(t, dtype=np.float64))
    inner = 2.0 / 3.0 - t * t + 0.5 * t ** 3
    outer = (2.0 - np.minimum(t, 2.0)) ** 3 / 6.0
    return np.where(t < 1.0, inner, outer)


class CardinalBasis:
    """Weight functions interpolating δ_ij at a set of examples.

    Parameters
    ----------
    params : (N, d) float
        The examples' parameter vectors.
    names : sequence of str, optional
        Their names, for error messages.

    Attributes
    ----------
    params : (N, d) float
    dilation : (N,) float
        α_j, the distance from each example to its nearest other one.
    coefficients : (d + 1 + N, N) float
        Column i holds a_i (constant, then linear) and then r_i.

    Examples
    --------
    >>> import numpy as np
    >>> basis = CardinalBasis(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]))
    >>> np.round(basis(basis.params), 12) + 0.0
    array([[1., 0., 0., 0.],
           [0., 1., 0., 0.],
           [0., 0., 1., 0.],
           [0., 0., 0., 1.]])
    """

    def __init__(self, params: np.ndarray, names: Sequence[str] | None = None):
        p = np.asarray(params, dtype=np.float64)
        if p.ndim != 2 or len(p) < 2:
            raise InputError(f"weight functions need at least two examples as an (N, d) array, got shape {p.shape}")
        if not np.isfinite(p).all():
            raise InputError("example parameters contain NaN or infinity")
        n = len(p)
        names = [f"example {i}" for i in range(n)] if names is None else list(names)
        dist = cdist(p, p)
        np.fill_diagonal(dist, np.inf)
        nearest = dist.argmin(axis=1)
        dilation = dist[np.arange(n), nearest]
        scale = max(float(np.abs(p).max()), 1e-300)
        bad = np.flatnonzero(dilation <= 1e-9 * scale)
        if len(bad):
            i = int(bad[0])
            j = int(nearest[i])
            raise InputError(f"key-models '{names[min(i, j)]}' and '{names[max(i, j)]}' have the same parameters "
                             "(the feature points move alike in both), so no weight function can tell them apart",
                             fix="remove one of them, make them differ at the feature points, or add feature points "
                                 "where they differ")
        linear = np.c_[np.ones(n), p]
        a = np.linalg.lstsq(linear, np.eye(n), rcond=None)[0]  # (d + 1, N)
        residual = np.eye(n) - linear @ a
        np.fill_diagonal(dist, 0.0)
        radial = cubic_bspline(dist / dilation[None, :])  # R[j, k] = R_k(p_j)
        cond = np.linalg.cond(radial)
        if not np.isfinite(cond) or cond > 1e12:
            raise InputError(f"the radial basis of the {n} key-models is singular (condition number {cond:.3g})",
                             fix="remove key-models that nearly repeat others or lie between them")
        r = np.linalg.solve(radial, residual)  # (N, N)
        self.params = p
        self.names = names
        self.dilation = dilation
        self.coefficients = np.vstack([a, r])

    @property
    def n_examples(self) -> int:
        return len(self.params)

    def basis(self, params: np.ndarray) -> np.ndarray:
        """(F, d + 1 + N) values of the linear and radial basis functions at (F, d) points."""
        p = np.atleast_2d(np.asarray(params, dtype=np.float64))
        if p.shape[1] != self.params.shape[1]:
            raise InputError(f"parameters have {p.shape[1]} components, the examples {self.params.shape[1]}")
        radial = cubic_bspline(cdist(p, self.params) / self.dilation)
        return np.concatenate([np.ones((len(p), 1)), p, radial], axis=1)

    def __call__(self, params: np.ndarray) -> np.ndarray:
        """(F, N) weights of every example at (F, d) points."""
        return self.basis(params) @ self.coefficients
