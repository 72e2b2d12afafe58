"""The statistical identity model shipped beside the generic head.

A head is the generic head plus a weighted sum of identity modes, each one standard
deviation of a principal component of the ICT FaceKit's scanned identities: a head
``generic + sum_k c_k mode_k`` with ``c ~ N(0, I)`` is a plausible person. The model is
the ICT FaceKit's first 50 modes on the generic head's vertices
(``scripts/build_identity_model.py``), stored as int8 with one scale per mode in
``data/generic_head/identity_model.npz`` (2.3 MB; at most 0.05 mm from the full-precision
mode per vertex and mode).

:func:`recon.shape.from_front.fit_front` fits it to the points of a front photo,
:func:`fit_to_points` to 3D points (those the two-photo calibration gives): either way the
DFFD then starts from the model's head, which is already near the person, instead of the
generic head.
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mpeg4.errors import InputError
from mpeg4.head import Head

__all__ = ["POINT_SD_MM", "IdentityModel", "fit_to_points", "build_identity_model", "write_identity_model", "load_identity_model",
           "identity_model_path"]


#: Expected distance (mm) between a marked point and where the model can put it: the
#: marking's spread and what 50 modes cannot express of a face.
POINT_SD_MM = 2.0


def identity_model_path() -> Path:
    """``identity_model.npz`` beside the generic head in use."""
    from mpeg4.generic_head import generic_head_path

    return generic_head_path().with_name("identity_model.npz")


@dataclass
class IdentityModel:
    """Identity modes on a head's vertices.

    Attributes
    ----------
    modes : dict of str to (K, n, 3) float64
        Per part of the head (its order), each mode's displacement of the part's vertices,
        metres, one standard deviation.
    """

    modes: dict[str, np.ndarray]

    @property
    def n_modes(self) -> int:
        return next(iter(self.modes.values())).shape[0]

    @property
    def n_vertices(self) -> int:
        return sum(m.shape[1] for m in self.modes.values())

    def check(self, head: Head, where: str = "identity model") -> None:
        """Refuse a head whose parts do not match the model's."""
        for name, part in head.parts.items():
            m = self.modes.get(name)
            if m is None or m.shape[1] != part.n_vertices:
                raise InputError(f"the identity model does not fit the head's part {name!r} "
                                 f"({part.n_vertices} vertices, the model has "
                                 f"{'none' if m is None else m.shape[1]})", where=where,
                                 fix="use the generic head the model was built for "
                                     "(scripts/build_identity_model.py rebuilds it)")

    def head(self, generic: Head, coefficients: np.ndarray) -> Head:
        """``generic`` reshaped by ``coefficients`` (K,) (standard deviations of each mode)."""
        c = np.asarray(coefficients, dtype=np.float64)
        moves = {name: np.tensordot(c, self.modes[name], 1) for name in generic.parts}
        out = generic.with_vertices({name: part.vertices + moves[name] for name, part in generic.parts.items()})
        for name, part in out.parts.items():
            if part.centre is not None:  # an eyeball's centre goes with the eyeball
                part.centre = part.centre + moves[name].mean(axis=0)
        return out

    def point_basis(self, head: Head, ids) -> np.ndarray:
        """(len(ids), 3, K): how each feature point of ``head`` moves per unit of each mode."""
        out = np.empty((len(ids), 3, self.n_modes))
        for n, i in enumerate(ids):
            b = head.feature_points[i]
            m = self.modes[b.part][:, list(b.vertices)]  # (K, k, 3)
            out[n] = np.einsum("kvj,v->jk", m, np.asarray(b.weights, dtype=np.float64))
        return out


def fit_to_points(model: IdentityModel, head: Head, points, point_sd_mm: float = POINT_SD_MM,
                  rounds: int = 6) -> np.ndarray:
    """Coefficients (K,) of the identity whose feature points best match 3D ``points``.

    Maximum a posteriori: the squared distances of the head's feature points (after the
    similarity that best aligns them, which the photos leave free) over ``point_sd_mm``
    squared, plus the squared coefficients; alternating the similarity and the
    coefficients' linear solution. A point far off (a detection gone astray) weighs less
    each round (Cauchy weights at three spreads), so it cannot bend the whole head.

    Parameters
    ----------
    model : IdentityModel
    head : Head
        The head the modes displace.
    points : mapping of str to (3,) float
        FP id → position, metres, any frame.
    point_sd_mm : float
        The points' expected spread about what the model can express, mm.
    """
    from .deform import fit_similarity

    ids = [i for i in points if i in head.feature_points]
    if len(ids) < 4:
        raise InputError(f"only {len(ids)} feature points to fit the identity model to", where="identity model",
                         fix="give at least 4, spread over the face")
    X0 = np.array([head.fp_position(i) for i in ids])
    Y = np.array([np.asarray(points[i], dtype=np.float64) for i in ids])
    B = model.point_basis(head, ids).reshape(-1, model.n_modes)
    sd = point_sd_mm * 1e-3
    c = np.zeros(model.n_modes)
    w = np.ones(len(ids))
    for _ in range(rounds):
        sim = fit_similarity(X0 + (B @ c).reshape(-1, 3), Y, w)
        inside = (Y - sim.translation) @ sim.rotation / sim.scale  # the points in the head's frame
        wk = np.repeat(w, 3) / sd ** 2
        c = np.linalg.solve((B * wk[:, None]).T @ B + np.eye(model.n_modes), B.T @ (wk * (inside - X0).reshape(-1)))
        miss = np.linalg.norm(inside - X0 - (B @ c).reshape(-1, 3), axis=1)
        w = 1.0 / (1.0 + (miss / (3 * sd)) ** 2)
    return c


def build_identity_model(deltas_cm: np.ndarray, generic: Head) -> IdentityModel:
    """The model from ICT FaceKit identity deltas (K, N, 3), centimetres, on ICT's vertex
    numbering, taken at the vertices each part of ``generic`` came from
    (``metadata["ict_vertex_ids"]``)."""
    from mpeg4.generic_head import ict_vertex_ids

    ids = ict_vertex_ids(generic)
    return IdentityModel({name: deltas_cm[:, ids[name]].astype(np.float64) * 0.01 for name in generic.parts})


def write_identity_model(model: IdentityModel, path: str | os.PathLike) -> float:
    """Write the model (int8, one scale per mode); returns the largest quantisation error, metres."""
    names = list(model.modes)
    sizes = [model.modes[n].shape[1] for n in names]
    allm = np.concatenate([model.modes[n] for n in names], axis=1)
    scale = np.abs(allm).max(axis=(1, 2)) / 127.0
    q = np.round(allm / scale[:, None, None]).astype(np.int8)
    error = float(np.abs(q * scale[:, None, None] - allm).max())
    np.savez_compressed(path, modes=q, scale=scale, parts=np.array(names), part_sizes=np.array(sizes))
    return error


@functools.lru_cache(maxsize=2)
def _read(path: str) -> IdentityModel:
    with np.load(path) as d:
        q, scale = d["modes"], d["scale"]
        names, sizes = [str(n) for n in d["parts"]], d["part_sizes"]
    allm = q.astype(np.float64) * scale[:, None, None]
    bounds = np.r_[0, np.cumsum(sizes)]
    return IdentityModel({n: allm[:, a:b] for n, a, b in zip(names, bounds[:-1], bounds[1:])})


def load_identity_model(path: str | os.PathLike | None = None) -> IdentityModel:
    """The shipped model (read once per process), or the one at ``path``."""
    path = Path(path) if path is not None else identity_model_path()
    if not path.exists():
        raise InputError("the identity model is missing", where=str(path),
                         fix="rebuild it with python3 scripts/build_identity_model.py")
    return _read(os.fspath(path))
