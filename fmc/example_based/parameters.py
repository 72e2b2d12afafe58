"""Parameters of a face: its feature points' displacements, reduced by PCA.

A key-model, or a frame of an input animation, is described by the displacements of about
20 feature points of the source base model from their neutral positions, stacked into a
vector v (3 numbers a point). Principal component analysis of the key-models' vectors
keeps the directions whose eigenvalue exceeds a threshold; their rows form the feature
matrix F, and the parameter vector of a face is p = F v (Pyun et al., section 4).

The default points, :data:`FEATURE_POINTS`, are the MPEG-4 subset listed with the reason
for each in ``fmc/data/example_based_points.toml``.

References
----------
.. [1] H. Pyun, Y. Kim, W. Chae, H. W. Kang, S. Y. Shin, "An example-based approach for
   facial expression cloning", SCA 2003, section 4.
"""

from __future__ import annotations

import tomllib
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources

import numpy as np

from mpeg4.catalogue import check_fp_id
from mpeg4.errors import InputError

from .key_models import KeyModels, _offsets

__all__ = ["FEATURE_POINTS", "load_feature_points", "feature_matrix", "Parameterisation"]


def load_feature_points() -> list[dict]:
    """The documented feature-point subset: a list of ``{"id", "moves_with"}`` records."""
    data = tomllib.loads(resources.files("fmc").joinpath("data/example_based_points.toml").read_text())
    points = data["point"]
    for p in points:
        check_fp_id(p["id"], where="fmc/data/example_based_points.toml")
    return points


#: The MPEG-4 feature points that parameterise key-models by default (20 points).
FEATURE_POINTS: tuple[str, ...] = tuple(p["id"] for p in load_feature_points())


def feature_matrix(vectors: np.ndarray, threshold: float = 1e-5) -> tuple[np.ndarray, np.ndarray]:
    """Principal directions of a set of displacement vectors.

    Parameters
    ----------
    vectors : (n, D) float
        One displacement vector per example (D = 3 × the number of feature points).
    threshold : float
        Directions are kept whose eigenvalue of the covariance exceeds ``threshold``
        times the largest (the paper's 1e-5; relative, so the choice of length unit
        does not change it).

    Returns
    -------
    F : (d, D) float
        Orthonormal rows, by decreasing eigenvalue.
    eigenvalues : (D,) float
        All eigenvalues of the covariance, decreasing (units of ``vectors`` squared).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> F, ev = feature_matrix(rng.normal(size=(30, 2)) @ rng.normal(size=(2, 6)))
    >>> F.shape
    (2, 6)
    """
    x = np.asarray(vectors, dtype=np.float64)
    if x.ndim != 2 or len(x) < 2:
        raise InputError(f"PCA needs at least two displacement vectors as an (n, D) array, got shape {x.shape}")
    x = x - x.mean(axis=0)
    ev, vec = np.linalg.eigh(x.T @ x / len(x))
    order = np.argsort(ev)[::-1]
    ev, vec = np.clip(ev[order], 0.0, None), vec[:, order]
    if ev[0] <= 0:
        raise InputError("the key-models do not move the feature points: every parameter would be zero",
                         fix="give key-models that differ from the neutral at the feature points, "
                             "or choose feature points that the key-models move")
    keep = ev > threshold * ev[0]
    return vec[:, keep].T.copy(), ev


@dataclass
class Parameterisation:
    """Feature-point displacements of whole faces and the PCA map to parameters.

    Attributes
    ----------
    feature_points : list of str
        Feature point ids (or ``"#k"`` for a vertex given by index).
    vertices : (c,) int
        Stacked vertex indices the points are made of.
    weights : (m, c) float
        Each point as an affine combination of those vertices.
    neutral : (3 m,) float
        The points on the base model, metres.
    matrix : (d, 3 m) float
        The feature matrix F.
    eigenvalues : (3 m,) float
        The PCA spectrum the matrix was cut from.
    """

    feature_points: list
    vertices: np.ndarray
    weights: np.ndarray
    neutral: np.ndarray
    matrix: np.ndarray
    eigenvalues: np.ndarray

    @classmethod
    def fit(cls, keys: KeyModels, feature_points: Sequence[str | int] | None = None,
            threshold: float = 1e-5) -> Parameterisation:
        """The parameterisation of a key-model set (its neutral included, at p = F·0 = 0).

        Parameters
        ----------
        keys : KeyModels
            The source key-models.
        feature_points : sequence of str or int, optional
            MPEG-4 feature point ids on ``keys.head`` (default :data:`FEATURE_POINTS`),
            or stacked vertex indices.
        threshold : float
            Relative eigenvalue threshold of :func:`feature_matrix`.
        """
        ids, vertices, weights = _points(keys, FEATURE_POINTS if feature_points is None else feature_points)
        neutral = (weights @ keys.neutral[vertices]).reshape(-1)
        vectors = np.einsum("mc,ncx->nmx", weights, keys.displacements[:, vertices]).reshape(len(keys), -1)
        matrix, ev = feature_matrix(np.vstack([np.zeros(vectors.shape[1]), vectors]), threshold)
        return cls(ids, vertices, weights, neutral, matrix, ev)

    @property
    def dimension(self) -> int:
        return len(self.matrix)

    def displacements(self, frames: np.ndarray) -> np.ndarray:
        """(F, 3 m) feature-point displacements of (F, V, 3) stacked vertex frames."""
        pts = np.einsum("mc,fcx->fmx", self.weights, frames[:, self.vertices])
        return pts.reshape(len(frames), -1) - self.neutral

    def __call__(self, frames: np.ndarray) -> np.ndarray:
        """(F, d) parameters of (F, V, 3) stacked vertex frames."""
        return self.displacements(frames) @ self.matrix.T


def _points(keys: KeyModels, feature_points) -> tuple[list, np.ndarray, np.ndarray]:
    """Ids, the stacked vertices used and the (m, c) affine weights of the points."""
    rows = []
    ids = []
    for fp in feature_points:
        if isinstance(fp, (int, np.integer)):
            if not 0 <= fp < keys.n_vertices:
                raise InputError(f"feature vertex {fp} is outside 0..{keys.n_vertices - 1}")
            rows.append(((int(fp),), (1.0,)))
            ids.append(f"#{fp}")
            continue
        if keys.head is None:
            raise InputError(f"feature point {fp} needs a head to be found on",
                             fix="give the key-models a head, or the feature points as vertex indices")
        if fp not in keys.head.feature_points:
            raise InputError(f"the source base model has no feature point {fp}",
                             fix="place it (recon annotate, or in the head's fdp.json) or choose other points")
        b = keys.head.feature_points[fp]
        base = _offsets(keys.head)[b.part]
        rows.append((tuple(base + v for v in b.vertices), b.weights))
        ids.append(fp)
    if len(rows) < 2:
        raise InputError(f"the parameterisation needs at least two feature points, got {len(rows)}")
    vertices = np.unique(np.concatenate([r[0] for r in rows])).astype(np.int64)
    weights = np.zeros((len(rows), len(vertices)))
    for k, (v, w) in enumerate(rows):
        np.add.at(weights[k], np.searchsorted(vertices, v), w)
    return ids, vertices, weights
