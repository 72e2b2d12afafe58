"""A painted skin for a synthetic person: tone, blotches and blush, lips, brows, lashes, hair, iris.

:func:`make_person` lays the paint out on the neutral head so that it follows the anatomy of
every identity; :func:`skin_albedo` gives the paint at the skin's vertices (the true albedo).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from mpeg4.head import Head
from mpeg4.render import RenderMesh, vertex_normals
from recon.texture.bake import fill_empty, interpolate, rasterize_uv
from recon.texture.materials import eye_texture

from .ict import _SKIN_PARTS, identity_head, load_ict

__all__ = ["Person", "make_person", "skin_albedo", "value_noise", "smoothstep", "hairline_height", "ear_distance"]

_SKIN_TONES = np.array([(238, 200, 178), (224, 176, 150), (198, 150, 118), (170, 118, 88), (128, 86, 62),
                        (232, 190, 160), (210, 164, 132)], float)
_HAIR = np.array([(40, 28, 22), (70, 46, 30), (110, 78, 48), (25, 22, 22), (150, 112, 70), (92, 60, 42)], float)
_IRIS = np.array([(92, 64, 40), (60, 92, 120), (80, 104, 70), (120, 86, 50), (50, 38, 30)], float)


@dataclass
class Person:
    """A synthetic person: an identity head and how it is painted.

    Attributes
    ----------
    seed : int
    head : Head
        The identity on the generic head's topology, metres.
    skin_meshes : list of RenderMesh
        The skin as ICT lays out its texture (one mesh per UV tile), painted.
    iris_rgb, hair_rgb, skin_rgb : (3,) float
        The colours drawn for this person.
    eye_texture : (S, S, 3) uint8
    dress : list of (str, RenderMesh)
        What the person wears over the head (:mod:`recon.evaluate.dressing`), each with
        its kind: ``"hair"``, ``"clothes"`` or ``"glasses"``. Empty for the clean set.
    """

    seed: int
    head: Head
    skin_meshes: list[RenderMesh]
    iris_rgb: np.ndarray
    hair_rgb: np.ndarray
    skin_rgb: np.ndarray
    eye_texture: np.ndarray = field(repr=False, default=None)
    dress: list[tuple[str, RenderMesh]] = field(repr=False, default_factory=list)

    @property
    def ipd_mm(self) -> float:
        """Distance between the pupils (3.5, 3.6), millimetres."""
        return float(np.linalg.norm(self.head.fp_position("3.5") - self.head.fp_position("3.6")) * 1000)

    def meshes(self) -> list[RenderMesh]:
        """Everything to draw: the painted skin, textured eyes, teeth, gums and tongue."""
        out = list(self.skin_meshes)
        for name, part in self.head.parts.items():
            if name == "skin":
                continue
            tex = self.eye_texture if name.startswith("eye_") else part.texture
            out.append(RenderMesh(part.vertices, part.triangles, uv=part.uv, texture=tex, colour=part.colour))
        return out + [mesh for _, mesh in self.dress]


def value_noise(points: np.ndarray, spacing: float, seed: int, where: np.ndarray | None = None) -> np.ndarray:
    """Smooth noise in [-1, 1] at (K, 3) points (metres): random values on a lattice
    ``spacing`` apart (hashed through a permutation drawn from ``seed``, so it needs no
    stored grid and is the same wherever it is evaluated), blended with smoothstep weights.
    With ``where`` (K,) bool, only those points are evaluated (0 elsewhere)."""
    n = 1024
    rng = np.random.default_rng(seed)
    perm = rng.permutation(n)
    values = rng.uniform(-1, 1, n)
    out = np.zeros(len(points))
    sel = slice(None) if where is None else np.flatnonzero(where)
    g = np.asarray(points, float)[sel] / spacing
    base = np.floor(g).astype(np.int64)
    f = g - base
    w1 = f * f * (3 - 2 * f)
    w0 = 1 - w1
    i0, i1 = base % n, (base + 1) % n
    acc = np.zeros(len(g))
    for ox in (0, 1):
        hx = perm[(i1 if ox else i0)[:, 0]]
        wx = (w1 if ox else w0)[:, 0]
        for oy in (0, 1):
            hy = perm[(hx + (i1 if oy else i0)[:, 1]) % n]
            wxy = wx * (w1 if oy else w0)[:, 1]
            for oz in (0, 1):
                h = perm[(hy + (i1 if oz else i0)[:, 2]) % n]
                acc += wxy * (w1 if oz else w0)[:, 2] * values[h]
    out[sel] = acc
    return out


def _polyline_distance(p: np.ndarray, line: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance (K,) from 2D points (K, 2) to a polyline (L, 2), and the arc-length share
    (0 at the first point, 1 at the last) of the nearest place."""
    seg0, seg1 = line[:-1], line[1:]
    d = seg1 - seg0
    lengths = np.linalg.norm(d, axis=1)
    cum = np.r_[0.0, np.cumsum(lengths)]
    best = np.full(len(p), np.inf)
    share = np.zeros(len(p))
    for k in range(len(d)):
        t = np.clip(((p - seg0[k]) @ d[k]) / max(lengths[k] ** 2, 1e-18), 0, 1)
        dist = np.linalg.norm(p - (seg0[k] + t[:, None] * d[k]), axis=1)
        better = dist < best
        best[better] = dist[better]
        share[better] = (cum[k] + t[better] * lengths[k]) / cum[-1]
    return best, share


def smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3 - 2 * t)


def _paint(pos: np.ndarray, part: np.ndarray, fp: dict[str, np.ndarray], ring_upper: np.ndarray,
           ring_lower: np.ndarray, seed: int, skin: np.ndarray, hair: np.ndarray) -> np.ndarray:
    """RGB in [0, 255] at (K, 3) neutral-head points of the ICT skin parts ``part`` (K,)."""
    from scipy.spatial import cKDTree

    x, y, z = pos.T
    ax = np.abs(x)
    col = np.broadcast_to(skin, pos.shape).copy()
    # Blotches and fine grain.
    col *= (1 + 0.035 * value_noise(pos, 0.012, seed + 1))[:, None]
    col *= (1 + 0.02 * value_noise(pos, 0.003, seed + 2))[:, None]
    # Blush on the cheeks and the tip of the nose, redder ears.
    red = np.array([1.0, -0.45, -0.35])
    cheek = np.exp(-((ax - fp["5.3"][0]) ** 2 + (y - fp["5.1"][1] * 0.5 - fp["5.3"][1] * 0.5) ** 2) / 0.018 ** 2)
    cheek *= z > fp["5.3"][2] - 0.03
    nose = np.exp(-np.sum((pos - fp["9.3"]) ** 2, axis=1) / 0.012 ** 2)
    ear_c = np.mean([fp[i] for i in ("10.1", "10.3", "10.5", "10.7", "10.9")], axis=0)
    ear = np.exp(-np.sum((np.c_[ax, y, z] - ear_c) ** 2, axis=1) / 0.02 ** 2)
    col += (18 * cheek + 14 * nose + 12 * ear)[:, None] * red
    # Slightly darker upper lids and under the eyes.
    for c in ("3.5",):
        e = fp[c]
        d2 = ((ax - e[0]) ** 2) / 0.02 ** 2 + ((y - e[1]) ** 2) / 0.012 ** 2
        col *= (1 - 0.07 * np.exp(-d2) * (z > e[2] - 0.02))[:, None]
    # Lips: inside the outer lip contour seen from the front.
    upper = np.array([fp[i][:2] for i in ("8.4", "8.6", "8.9", "8.1", "8.10", "8.5", "8.3")])
    lower = np.array([fp[i][:2] for i in ("8.3", "8.7", "8.2", "8.8", "8.4")])
    contour = np.r_[upper, lower[1:-1]]
    lip = _soft_polygon(pos[:, :2], contour, 0.0008) * (z > fp["8.3"][2] - 0.012)
    lip_rgb = np.array([176, 86, 88]) * (0.75 + 0.25 * skin / 230)
    col = col * (1 - lip[:, None]) + lip[:, None] * lip_rgb * (1 + 0.05 * value_noise(pos, 0.0015, seed + 3, lip > 0))[:, None]
    # Eyebrows: a tapering band along 4.1 → 4.3 → 4.5 (and its mirror), with hair strokes.
    brow_line = np.array([fp["4.1"][:2] + [0.0, -0.002], fp["4.3"][:2] + [0.0, -0.003],
                          fp["4.5"][:2] + [0.0, -0.001]])
    dist, share = _polyline_distance(np.c_[ax, y], brow_line)
    half = 0.0055 * (1 - share) + 0.0025 * share
    near = dist < half
    strokes = 0.6 + 0.4 * value_noise(pos * [1.0, 3.0, 1.0], 0.0012, seed + 8, near)
    brow = (1 - smoothstep(half * 0.6, half, dist)) * (z > fp["4.5"][2] - 0.02) * np.clip(strokes, 0, 1)
    col = col * (1 - 0.9 * brow[:, None]) + 0.9 * brow[:, None] * hair * 0.7
    # Lash line along the lid margins (the rim of the eye opening).
    tree_u, tree_l = cKDTree(ring_upper), cKDTree(ring_lower)
    du, _ = tree_u.query(pos)
    dl, _ = tree_l.query(pos)
    lash = 0.85 * (1 - smoothstep(0.0004, 0.0016, du)) + 0.35 * (1 - smoothstep(0.0002, 0.0009, dl))
    lash *= part == 0
    col = col * (1 - lash[:, None]) + lash[:, None] * np.array([30.0, 22, 20])
    # Scalp hair above the hairline.
    line = hairline_height(pos, fp, seed)
    scalp = smoothstep(line - 0.0015, line + 0.0025, y) * (part <= 1)
    scalp *= smoothstep(0.022, 0.03, ear_distance(pos, fp))  # not on the ear itself
    hairy = scalp > 0
    grain = 1 + 0.18 * value_noise(pos, 0.0009, seed + 5, hairy) + 0.1 * value_noise(pos, 0.004, seed + 6, hairy)
    col = col * (1 - scalp[:, None]) + scalp[:, None] * hair * grain[:, None]
    # Inside the mouth and behind the eyes.
    mouth = part == 2
    col[mouth] = np.array([120.0, 52, 56]) * (1 + 0.05 * value_noise(pos, 0.004, seed + 7, mouth)[mouth])[:, None]
    col[(part == 3) | (part == 4)] = (90.0, 60, 60)
    return np.clip(col, 0, 255)


def ear_distance(pos: np.ndarray, fp: dict[str, np.ndarray]) -> np.ndarray:
    """(K,) distance in metres from neutral-head points (K, 3) to the middle of the nearer ear."""
    ear_c = np.mean([fp[i] for i in ("10.1", "10.3", "10.5", "10.7", "10.9")], axis=0)
    return np.linalg.norm(np.c_[np.abs(pos[:, 0]), pos[:, 1:]] - ear_c, axis=1)


def hairline_height(pos: np.ndarray, fp: dict[str, np.ndarray], seed: int) -> np.ndarray:
    """(K,) height (y, metres) of the hairline at neutral-head points (K, 3): the line runs
    11.1 → 11.3 → over the ear → down to the nape, by the angle round the head's vertical
    axis, with a few millimetres of seeded waviness. Hair grows above it."""
    x, y, z = pos.T
    theta = np.degrees(np.arctan2(np.abs(x), z - fp["10.9"][2] * 0.5))
    th = [0.0, np.degrees(np.arctan2(fp["11.3"][0], fp["11.3"][2] - fp["10.9"][2] * 0.5)), 70.0, 100.0, 130.0, 180.0]
    hy = [fp["11.1"][1], fp["11.3"][1] - 0.004, fp["10.9"][1] + 0.015, fp["10.1"][1] + 0.008, fp["10.5"][1] - 0.005,
          fp["10.5"][1] - 0.015]
    return np.interp(theta, th, hy) + 0.003 * value_noise(pos, 0.006, seed + 4, y > fp["10.5"][1] - 0.03)


def _soft_polygon(p: np.ndarray, poly: np.ndarray, soft: float) -> np.ndarray:
    """1 inside a 2D polygon, 0 outside, a smooth step ``soft`` metres wide across its edge."""
    closed = np.r_[poly, poly[:1]]
    dist, _ = _polyline_distance(p, closed)
    # Even-odd rule, vectorised over the edges.
    inside = np.zeros(len(p), dtype=bool)
    for a, b in zip(closed[:-1], closed[1:]):
        cross = ((a[1] > p[:, 1]) != (b[1] > p[:, 1]))
        xint = a[0] + (p[:, 1] - a[1]) * (b[0] - a[0]) / np.where(b[1] == a[1], 1e-18, b[1] - a[1])
        inside ^= cross & (p[:, 0] < xint)
    signed = np.where(inside, dist, -dist)
    return smoothstep(-soft, soft, signed)


def _lid_rings(data: dict) -> tuple[np.ndarray, np.ndarray]:
    """Neutral positions (metres) of the face vertices on the rim of each eye opening,
    split into the upper and lower lid."""
    faces, fpart = data["faces"], data["faces_part"]
    names = [str(n) for n in data["part_names"]]
    face_end = data["part_vertex_ranges"][names.index("Face")][1]
    v = data["vertices"].astype(np.float64) * 0.01
    upper, lower = [], []
    for socket in ("Eye socket left", "Eye socket right"):
        ring = np.unique(faces[fpart == names.index(socket)])
        ring = ring[ring < face_end]
        centre = v[ring].mean(axis=0)
        upper.append(v[ring][v[ring][:, 1] >= centre[1]])
        lower.append(v[ring][v[ring][:, 1] < centre[1]])
    return np.concatenate(upper), np.concatenate(lower)


def _skin_layout(data: dict):
    """The ICT skin triangles (in generic skin vertex indices) with their corner UVs."""
    names = [str(n) for n in data["part_names"]]
    ids = [names.index(n) for n in _SKIN_PARTS]
    sel = np.flatnonzero(np.isin(data["faces_part"], ids))
    tris = data["faces"][sel].astype(np.int64)  # the generic skin keeps ICT's first 14,062 vertex ids
    uv = data["uv"][data["faces_uv_idx"][sel]].astype(np.float64)  # (M, 3, 2)
    part = data["faces_part"][sel].astype(int)
    return tris, uv, part


@functools.lru_cache(maxsize=4)
def _texel_positions(npz: str | None, size: int):
    """Per UV tile (0: face, 1: head, neck and sockets): the neutral 3D position and ICT part
    of every texel, and which texels the skin covers."""
    data = load_ict(npz)
    tris, uv, part = _skin_layout(data)
    v0 = data["vertices"].astype(np.float64) * 0.01
    tiles = []
    tile_of = np.floor(uv[:, :, 0].mean(axis=1)).astype(int)
    for t in (0, 1):
        sel = np.flatnonzero(tile_of == t)
        corner_uv = uv[sel].reshape(-1, 2) - [t, 0.0]
        corner_tri = np.arange(3 * len(sel)).reshape(-1, 3)
        ids, bary = rasterize_uv(corner_uv, corner_tri, (size, size))
        pos = interpolate(v0[tris[sel]].reshape(-1, 3), corner_tri, ids, bary)
        tpart = np.where(ids >= 0, part[sel][np.maximum(ids, 0)], -1)
        tiles.append((sel, ids >= 0, pos, tpart))
    return tiles


def make_person(seed: int, data: dict | None = None, generic: Head | None = None, texture_size: int = 1024,
                spread: float = 1.0, skin_rgb=None, expression: Mapping[str, float] | None = None) -> Person:
    """A painted ICT identity, everything drawn from ``seed``; ``skin_rgb`` (3,) in 0–255
    overrides the drawn skin tone (the rest of the drawing is unchanged); ``expression``
    (ICT expression name → weight) poses it, the paint staying on the skin it was laid on."""
    data = load_ict() if data is None else data
    head = identity_head(data, seed, generic, spread, expression)
    rng = np.random.default_rng(10_000 + seed)
    drawn = _SKIN_TONES[rng.integers(len(_SKIN_TONES))] * rng.uniform(0.95, 1.05, 3)
    skin_rgb = drawn if skin_rgb is None else np.asarray(skin_rgb, float)
    hair_rgb = _HAIR[rng.integers(len(_HAIR))] * rng.uniform(0.9, 1.1)
    iris_rgb = _IRIS[rng.integers(len(_IRIS))] * rng.uniform(0.9, 1.1, 3)
    from mpeg4.generic_head import load_generic_head

    neutral = load_generic_head() if generic is None else generic
    fp = neutral.fp_positions()
    ring_u, ring_l = _lid_rings(data)
    tris, uv, part = _skin_layout(data)
    skin = head.parts["skin"]
    normals = vertex_normals(skin.vertices, skin.triangles)
    meshes = []
    for t, (sel, covered, pos, tpart) in enumerate(_texel_positions(None, texture_size)):
        ys, xs = np.nonzero(covered)
        img = np.zeros((texture_size, texture_size, 3))
        img[ys, xs] = _paint(pos[ys, xs], tpart[ys, xs], fp, ring_u, ring_l, 100 * seed, skin_rgb, hair_rgb)
        img = fill_empty(np.clip(img, 0, 255).astype(np.uint8), covered)
        corner = tris[sel].reshape(-1)
        meshes.append(RenderMesh(skin.vertices[corner], np.arange(len(corner)).reshape(-1, 3),
                                 normals=normals[corner], uv=uv[sel].reshape(-1, 2) - [t, 0.0], texture=img,
                                 colour=(1.0, 1.0, 1.0)))
    return Person(seed, head, meshes, iris_rgb, hair_rgb, skin_rgb, eye_texture(256, tuple(iris_rgb)))


def skin_albedo(person: Person, data: dict | None = None, blur_px: float = 2.0) -> np.ndarray:
    """(N, 3) float64: the painted colour (RGB, 0–255, no light) at each skin vertex of the
    person's head — the albedo a de-lit texture should give back.

    Sampled from the painted tiles at each vertex's ICT texture coordinate (a vertex on a
    tile's border takes the last tile that has it), after a Gaussian blur of ``blur_px``
    texels, so that a texel's misregistration does not count as colour error.
    """
    import cv2
    from scipy.ndimage import map_coordinates

    data = load_ict() if data is None else data
    tris, uv, _ = _skin_layout(data)
    n = person.head.parts["skin"].n_vertices
    out = np.full((n, 3), np.nan)
    tile_of = np.floor(uv[:, :, 0].mean(axis=1)).astype(int)
    for t, mesh in enumerate(person.skin_meshes):
        sel = np.flatnonzero(tile_of == t)
        img = cv2.GaussianBlur(mesh.texture.astype(np.float32), (0, 0), blur_px) if blur_px else \
            mesh.texture.astype(np.float32)
        s = img.shape[0]
        corner_uv = uv[sel].reshape(-1, 2) - [t, 0.0]
        x = (corner_uv[:, 0] * s - 0.5).astype(np.float32)
        y = ((1.0 - corner_uv[:, 1]) * s - 0.5).astype(np.float32)
        rgb = np.stack([map_coordinates(img[..., c], [y, x], order=1, mode="nearest") for c in range(3)], axis=1)
        out[tris[sel].reshape(-1)] = rgb
    return out
