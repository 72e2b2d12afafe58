"""The muscles placed on a head: the placement file and Waters' linear muscles and sphincter.

:func:`load_placement` reads ``fmc/data/muscles.toml``; :func:`place_muscles` puts each muscle
on the head by its feature points (:class:`Muscle`).
"""

from __future__ import annotations

import functools
import tomllib
from dataclasses import dataclass
from importlib import resources

import numpy as np

from mpeg4.catalogue import FEATURE_POINTS
from mpeg4.errors import InputError
from mpeg4.head import Head

__all__ = ["GROUPS", "load_placement", "Muscle", "place_muscles"]

#: The combination groups of [1]: direction of the sum, largest single magnitude.
GROUPS = ("forehead_l", "forehead_r", "mouth_up", "mouth_down")


@functools.lru_cache(maxsize=1)
def _placement_text() -> str:
    return resources.files("fmc").joinpath("data/muscles.toml").read_text()


def load_placement() -> dict:
    """The model's placement (``fmc/data/muscles.toml``) as a fresh dict."""
    return tomllib.loads(_placement_text())


def _point(head: Head, spec, es0: float, mirrored: bool, where: str) -> np.ndarray:
    """(3,) position of a placement point: Σ w·FP + offset·ES0 (mirrored for the right side)."""
    if not isinstance(spec, dict) or "at" not in spec:
        raise InputError("a placement point needs 'at' (feature point weights)", where=where,
                         fix='write it as { at = { "4.1" = 1.0 }, off = [0, 0, 0] }')
    at = spec["at"]
    off = np.asarray(spec.get("off", [0.0, 0.0, 0.0]), dtype=np.float64)
    total = sum(float(w) for w in at.values())
    if not at or abs(total - 1.0) > 1e-6:
        raise InputError(f"feature point weights sum to {total:g}, expected 1", where=where)
    if off.shape != (3,) or not np.isfinite(off).all():
        raise InputError(f"offset {spec.get('off')} is not three finite numbers", where=where)
    p = np.zeros(3)
    for fp_id, w in at.items():
        if fp_id not in FEATURE_POINTS:
            raise InputError(f"unknown feature point {fp_id!r}", where=where)
        i = FEATURE_POINTS[fp_id].mirror if mirrored and FEATURE_POINTS[fp_id].mirror else fp_id
        if i not in head.feature_points:
            raise InputError(f"{where.split(',')[0]} needs feature point {i}, which the head lacks",
                             fix="place the point (recon annotate / the fdp.json) before authoring")
        p += float(w) * head.fp_position(i)
    if mirrored:
        off = off * np.array([-1.0, 1.0, 1.0])
    return p + off * es0


@dataclass(frozen=True)
class Muscle:
    """One Waters muscle placed on a head.

    Attributes
    ----------
    name : str
    kind : {"linear", "sphincter"}
    head : (3,) float64
        Linear: the bone attachment the skin is pulled towards. Sphincter: the pull centre.
    tail : (3,) float64 or None
        Linear: the skin insertion.
    zone : float
        Half-angle of the cone of influence, radians (linear).
    fall_start, fall_end : float
        Radii (metres from the head) where the radial fall-off peaks and ends (linear).
    semi_axes : (3,) float64 or None
        Sphincter: semi-axes of its ellipsoid of influence, metres (the third, depth, is
        the first).
    midline : float
        Sphincter quadrant: half-width of the fade across the midline, metres (0: none).
    elasticity : float
        Waters's skin constant k.
    side : {"L", "R", "C"}
    group : str or None
        One of :data:`GROUPS`, or None (displacements add up).
    acts_on : {"all", "upper", "lower"}
    """

    name: str
    kind: str
    head: np.ndarray
    tail: np.ndarray | None
    zone: float
    fall_start: float
    fall_end: float
    semi_axes: np.ndarray | None
    midline: float
    elasticity: float
    side: str
    group: str | None
    acts_on: str
    midline_x: float = 0.0

    @property
    def length(self) -> float:
        return float(np.linalg.norm(self.tail - self.head)) if self.kind == "linear" else 0.0

    def displacement(self, vertices: np.ndarray) -> np.ndarray:
        """(N, 3) displacement of ``vertices`` (metres) at contraction 1.

        Linear: ``k · L · A(μ) · R(D) · (head − p)/|head − p|`` with ``A = cos(μ/zone · π/2)``
        inside the cone (μ the angle between head→p and head→tail) and the radial fall-off
        ``R = cos((1 − D/Rs) π/2)`` for ``D < Rs``, ``cos((D − Rs)/(Rf − Rs) π/2)`` up to Rf [2]_.
        Sphincter: ``k · (1 − ρ) · P(centre − p)``, ρ the ellipsoidal radius and P the
        projection on the frontal plane.
        """
        v = np.asarray(vertices, dtype=np.float64)
        if self.kind == "sphincter":
            q = v - self.head
            rho = np.sqrt(((q / self.semi_axes) ** 2).sum(axis=1))
            f = np.clip(1.0 - rho, 0.0, None)
            if self.midline > 0:
                s = 1.0 if self.side == "L" else -1.0
                f = f * np.clip(0.5 + s * (v[:, 0] - self.midline_x) / (2 * self.midline), 0.0, 1.0)
            out = -self.elasticity * f[:, None] * q
            out[:, 2] = 0.0  # the ring contracts in its own (frontal) plane
            return out
        d = v - self.head
        dist = np.linalg.norm(d, axis=1)
        axis = (self.tail - self.head) / self.length
        with np.errstate(invalid="ignore", divide="ignore"):
            mu = np.arccos(np.clip(d @ axis / dist, -1.0, 1.0))
            a = np.where(mu < self.zone, np.cos(mu / self.zone * np.pi / 2), 0.0)
            rs, rf = self.fall_start, self.fall_end
            r = np.where(dist < rs, np.cos((1.0 - dist / rs) * np.pi / 2),
                         np.where(dist < rf, np.cos((dist - rs) / (rf - rs) * np.pi / 2), 0.0))
            w = np.where(dist > 0, self.elasticity * self.length * a * r / dist, 0.0)
        return -w[:, None] * d


def _muscle(head: Head, name: str, spec: dict, es0: float, mirrored: bool, midline_x: float) -> Muscle:
    where = f"muscle {name}, fmc/data/muscles.toml"
    kind = spec.get("kind", "linear")
    side = "C" if not (name.endswith("_l") or name.endswith("_r")) else name[-1].upper()
    group = spec.get("group")
    if group is not None and mirrored:
        group = group[:-2] + "_r" if group.endswith("_l") else group
    if group is not None and group not in GROUPS:
        raise InputError(f"unknown combination group {group!r}", where=where, fix=f"use one of {', '.join(GROUPS)}")
    acts_on = spec.get("acts_on", "all")
    if acts_on not in ("all", "upper", "lower"):
        raise InputError(f"acts_on is {acts_on!r}", where=where, fix="use all, upper or lower")
    k = float(spec.get("elasticity", 0.0))
    if not np.isfinite(k) or k <= 0:
        raise InputError(f"elasticity is {k:g}; the skin must give (k > 0)", where=where)
    if kind == "sphincter":
        centre = _point(head, spec.get("centre"), es0, mirrored, where + ", centre")
        axes = np.asarray(spec.get("semi_axes", [0.0, 0.0]), dtype=np.float64) * es0
        if axes.shape != (2,) or not (axes > 1e-6).all():
            raise InputError(f"sphincter semi-axes {spec.get('semi_axes')} must be two positive lengths (ES0)",
                             where=where)
        return Muscle(name, kind, centre, None, 0.0, 0.0, 0.0, np.array([axes[0], axes[1], axes[0]]),
                      float(spec.get("midline", 0.0)) * es0, k, side, group, acts_on, midline_x)
    if kind != "linear":
        raise InputError(f"unknown muscle kind {kind!r}", where=where, fix="use linear or sphincter")
    h = _point(head, spec.get("head"), es0, mirrored, where + ", head")
    t = _point(head, spec.get("tail"), es0, mirrored, where + ", tail")
    length = float(np.linalg.norm(t - h))
    if length < 1e-3 * es0:
        raise InputError(f"head and tail coincide ({length * 1000:.3f} mm apart): the muscle has no direction",
                         where=where, fix="move the head (bone attachment) away from the tail (skin insertion)")
    zone = np.radians(float(spec.get("zone", 0.0)))
    if not 0 < zone < np.pi:
        raise InputError(f"zone half-angle {spec.get('zone')} degrees is outside (0, 180)", where=where)
    fs, fe = float(spec.get("fall_start", 1.0)), float(spec.get("fall_end", 0.0))
    if not 0 < fs < fe:
        raise InputError(f"fall-off radii start {fs:g} and end {fe:g} (muscle lengths) must satisfy 0 < start < end",
                         where=where)
    return Muscle(name, kind, h, t, float(zone), fs * length, fe * length, None, 0.0, k, side, group, acts_on,
                  midline_x)


def place_muscles(head: Head, placement: dict | None = None) -> list[Muscle]:
    """The muscles of ``placement`` (default ``fmc/data/muscles.toml``) placed on ``head``.

    Muscles named ``*_l`` are mirrored to ``*_r``. Raises :class:`InputError` naming the
    muscle and the feature point when a point is missing, and for degenerate placements
    (head and tail together, an empty cone, fall-off radii out of order, a muscle whose
    zone holds no skin vertex).
    """
    placement = load_placement() if placement is None else placement
    es0 = head.fapu.ES0
    midline_x = float(np.mean([head.fp_position(i)[0] for i in ("2.2", "8.1") if i in head.feature_points]
                              or [0.0]))
    out = []
    for name, spec in placement.get("muscles", {}).items():
        out.append(_muscle(head, name, spec, es0, False, midline_x))
        if name.endswith("_l"):
            out.append(_muscle(head, name[:-2] + "_r", spec, es0, True, midline_x))
    skin = head.skin.vertices
    for m in out:
        if not np.abs(m.displacement(skin)).max(initial=0.0) > 0:
            raise InputError(f"muscle {m.name} moves no skin vertex: its zone of influence misses the face",
                             where="fmc/data/muscles.toml",
                             fix="place its tail (insertion) on the skin and its head within reach of it")
    return out
