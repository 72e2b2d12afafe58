"""Build the generic head (``data/generic_head/generic_head.glb``) from the ICT FaceKit.

Usage::

    python3 scripts/build_generic_head.py [--npz ../shared/data/ict_facekit/ict_facekit.npz]
                                          [-o data/generic_head/generic_head.glb]

What it does (see ``data/generic_head/README.md`` for the why):

- centimetres → metres, the full 26,719-vertex resolution in ICT's vertex order within each
  part (``metadata["ict_vertex_ids"]`` maps every part's vertices back to ICT's);
- parts: ``skin`` (ICT face, head and neck, mouth socket, eye sockets), ``eye_l``/``eye_r``
  (rotation centre = least-squares sphere through the sclera; a texture made here — sclera,
  iris, pupil — projected along the gaze), ``teeth_upper``/``teeth_lower``,
  ``gums_upper``/``gums_lower``/``tongue`` (the gums-and-tongue mesh split along its UV
  islands: islands the jaw does not move are the upper gums and palate, moving islands
  narrower than 2.2 cm are the tongue, the rest the lower gums; lit as the open mouth lets
  light in, through ramp textures: :func:`lit_mouth`); the eyelash cards and the
  lacrimal fluid, eye blend and eye occlusion overlays are dropped (they need textures with
  alpha; drawn opaque they hide the eyes);
- the 53 ARKit-named expressions and ICT's two pupil-dilation shapes as sparse morph targets
  (displacements over 1e-7 m);
- all 84 MPEG-4 feature points by the rules in :data:`RULES`, placed on the face's left and
  mirrored to the right through the mesh's own symmetry, midline points on vertices with
  x = 0 exactly.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mpeg4.catalogue import FEATURE_POINTS, FP_IDS  # noqa: E402
from mpeg4.head import FeaturePointBinding, Head, Part, SparseDisplacement  # noqa: E402
from mpeg4.render import vertex_normals  # noqa: E402
from recon.texture.materials import eye_texture, eye_uv  # noqa: E402
from recon.texture.mouth import OPEN_JAW, bared_pose, brightest_light, lit_in_place  # noqa: E402

DEFAULT_NPZ = ROOT.parent / "shared" / "data" / "ict_facekit" / "ict_facekit.npz"
DEFAULT_OUT = ROOT / "data" / "generic_head" / "generic_head.glb"
ICT_COMMIT = "da5f95a607f5e6b37755b38d3385d7f2853732e5"

#: Flat colours of the parts without a texture (the others are white under theirs: the eyes,
#: the mouth's parts).
COLOURS = {"skin": (0.87, 0.70, 0.60)}

#: ICT meshes left out: the eyelash cards need their alpha texture (opaque they hide the
#: eyes); the lacrimal fluid, eye blend and eye occlusion overlays are never split off.
DROPPED = ("eyelashes_l", "eyelashes_r")

#: FP id → how it is placed (left and midline points; right points mirror their partners).
#: "lm k" is ICT's Multi-PIE landmark k (0-based); "front(x, y)" is the frontmost skin
#: vertex at that (x, y) (a ray from the front), distances in metres.
RULES = {
    "2.1": "lm 8 (lowest point of the chin)",
    "2.2": "lm 62 (inner upper lip centre)", "2.3": "lm 66 (inner lower lip centre)",
    "2.4": "lm 64 (left inner lip corner)", "2.6": "lm 63", "2.8": "lm 65",
    "2.10": "chin boss: on the midline profile from 8.2 down to 2.1, the frontmost vertex below the mentolabial "
            "sulcus (the profile's point furthest behind the line from 8.2 to 2.1) and above 2.1",
    "2.11": "lm 10 (left chin corner)",
    "2.13": "gonion (angle of the jaw): the hindmost skin vertex of the jaw's underside (facing down by 30 "
            "degrees or more: vertex normal's y under -0.5) lateral of half 10.5's x, in front of 10.7, from 5 mm "
            "below 10.5 down to 10 mm below 2.1",
    "3.1": "upper lid margin at the pupil: the lowest skin vertex above 3.5 within 1.2 mm of its x and at most "
           "3 mm behind it",
    "3.3": "lower lid margin at the pupil: the highest such skin vertex below 3.5",
    "3.5": "eye_l vertex furthest along the gaze (centre of the iris)",
    "3.7": "lm 45 (outer corner)", "3.11": "lm 42 (inner corner)",
    "3.9": "front(x of 3.3, y of 3.3 - 4 mm) (lower lid fold)",
    "3.13": "front(x of 3.1, y of 3.1 + 5 mm) (upper lid fold)",
    "4.1": "lm 22", "4.3": "lm 24", "4.5": "lm 26",
    "5.1": "front(0.9 x of 3.7, halfway between 9.15 and 8.1) (soft cheek)",
    "5.3": "front(x of 3.7, 40 % up from 9.15 to 3.7) (cheekbone)",
    "6.1": "frontmost tongue vertex near the midline (tip), averaged with its mirror vertex",
    "6.2": "highest tongue vertex near the midline, halfway back (body centre), averaged with its mirror",
    "6.3": "tongue vertex furthest left at the depth of 6.2",
    "7.1": "inside the neck: 0.35 of each ear lobe (10.5, 10.6) and 0.3 of the back of the neck on the "
           "midline at the lobes' height",
    "8.1": "lm 51", "8.2": "lm 57", "8.3": "lm 54", "8.5": "midpoint of lm 52 and 53", "8.7": "midpoint of lm 55 and 56",
    "8.10": "lm 52 (left peak of the Cupid's bow)",
    "9.1": "front(1.25 x of 9.5, y of 9.5 + 4 mm) (outer edge of the ala)",
    "9.3": "frontmost skin vertex (tip of the nose)", "9.5": "lm 35 (alar base)",
    "9.7": "front(0.45 x of 3.11, y of 3.11) (upper edge of the nasal bone)",
    "9.8": "top of the upper central incisors (both sides' highest vertices averaged)",
    "9.9": "bottom of the lower central incisors", "9.10": "cutting edge of the upper central incisors",
    "9.11": "cutting edge of the lower central incisors",
    "9.12": "lm 28 (nose bump)", "9.13": "front(0.35 x of 3.11, y of 9.12)", "9.15": "lm 33 (subnasale)",
    "10.1": "top of the left ear's rim (the rim: the connected patch around the ear's outermost point of "
            "vertices from which a ray towards the midline meets skin again 2-40 mm on)",
    "10.3": "rear rim of the ear at mid height (between the lobe and the rim's top)",
    "10.5": "lowest point of the lobe (the ear: the connected skin patch within 2 cm of its outermost point, "
            "up to 1 cm above the pupils)",
    "10.7": "frontmost ear vertex in its lowest 8 mm (lobe joins the face)",
    "10.9": "highest skin vertex beside the rim, in front of the ear's middle (the ear joins the head)",
    "11.1": "front midline vertex as far above the glabella (midway between 4.1 and lm 27) as the glabella is "
            "above 9.15 (facial thirds; the head has no hair)",
    "11.3": "front(x of 4.5, y of 11.1 - 10 mm) (end of the hairline)",
    "11.4": "highest skin vertex (top of the skull)",
    "11.5": "the same vertex as 11.4 (the generic head has no hair)",
    "11.6": "backmost midline skin vertex above 9.15 (back of the skull)",
}


def split_parts(data) -> dict[str, np.ndarray]:
    """Part name → ICT triangle indices (rows of ``faces``)."""
    faces = data["faces"]
    tri_part = data["faces_part"].astype(int)
    names = [str(n) for n in data["part_names"]]
    pid = {n: k for k, n in enumerate(names)}
    v_ranges = {str(n): r for n, r in zip(data["detail_part_names"], data["detail_part_vertex_ranges"])}
    out = {"skin": np.flatnonzero(np.isin(tri_part, [pid["Face"], pid["Head and Neck"], pid["Mouth socket"],
                                                     pid["Eye socket left"], pid["Eye socket right"]]))}
    for name, ict in (("eye_l", "Eyeball left"), ("eye_r", "Eyeball right"),
                      ("eyelashes_l", "Eyelashes left"), ("eyelashes_r", "Eyelashes right")):
        out[name] = np.flatnonzero(tri_part == pid[ict])
    teeth = np.flatnonzero(tri_part == pid["Teeth"])
    upper_end = max(r[1] for n, r in v_ranges.items() if "upper" in n and ("olar" in n or "cuspid" in n
                                                                             or "anine" in n or "ncisor" in n))
    upper = faces[teeth].max(axis=1) < upper_end
    out["teeth_upper"], out["teeth_lower"] = teeth[upper], teeth[~upper]
    # Gums and tongue: one connected mesh; its UV islands separate palate/gums/tongue.
    gt = np.flatnonzero(tri_part == pid["Gums and tongue"])
    uvf = data["faces_uv_idx"][gt]
    uniq, inv = np.unique(uvf, return_inverse=True)
    inv = inv.reshape(-1, 3)
    n = len(uniq)
    adj = sp.coo_matrix((np.ones(3 * len(inv)), (inv.ravel(), np.roll(inv, 1, axis=1).ravel())), shape=(n, n))
    _, label = connected_components(adj, directed=False)
    island = label[inv[:, 0]]
    names_e = [str(x) for x in data["expression_names"]]
    jaw = np.linalg.norm(data["expression_deltas"][names_e.index("jawOpen")], axis=1)
    verts = data["vertices"]
    groups = {"gums_upper": [], "gums_lower": [], "tongue": []}
    for k in np.unique(island):
        tris = gt[island == k]
        vid = np.unique(faces[tris])
        if np.median(jaw[vid]) < 0.1:  # cm: the jaw leaves it still
            groups["gums_upper"].append(tris)
        elif np.abs(verts[vid, 0]).max() < 2.2:
            groups["tongue"].append(tris)
        else:
            groups["gums_lower"].append(tris)
    for name, tris in groups.items():
        out[name] = np.sort(np.concatenate(tris))
    return out


def sphere_fit(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares sphere (centre, radius) through (K, 3) points."""
    a = np.c_[2 * points, np.ones(len(points))]
    b = (points ** 2).sum(axis=1)
    sol, *_ = np.linalg.lstsq(a, b, rcond=None)
    centre = sol[:3]
    return centre, float(np.sqrt(sol[3] + centre @ centre))


class _Placer:
    """Feature point placement on the ICT mesh, in ICT vertex indices (metres)."""

    def __init__(self, data, part_vertices: dict[str, np.ndarray]):
        self.v = data["vertices"].astype(np.float64) * 0.01
        self.lm = data["landmarks_multipie68"].astype(int)
        self.parts = part_vertices
        self.skin = part_vertices["skin"]
        self.tree = cKDTree(self.v)
        self.midline = self.skin[self.v[self.skin, 0] == 0.0]
        self.skin_triangles = data["faces"][split_parts(data)["skin"]].astype(np.int64)

    def vertex_of(self, k: int) -> np.ndarray:
        return self.v[k]

    def front(self, x: float, y: float, radius: float = 0.002, candidates=None) -> int:
        """Frontmost skin vertex near the ray through (x, y) along −z."""
        c = self.skin if candidates is None else candidates
        for r in (radius, 2 * radius, 4 * radius):
            near = c[(np.abs(self.v[c, 0] - x) < r) & (np.abs(self.v[c, 1] - y) < r)]
            if len(near):
                return int(near[np.argmax(self.v[near, 2])])
        raise RuntimeError(f"no skin vertex near x={x:.4f}, y={y:.4f}")

    def midline_path(self, a: int, b: int) -> np.ndarray:
        """Skin vertex ids from ``a`` to ``b`` (both on the midline) along the shortest chain
        of skin edges between midline vertices: the outer profile between them, where the
        midline's other vertices (the mouth socket's) lie behind it, off that chain."""
        from scipy.sparse.csgraph import shortest_path

        on = np.zeros(len(self.v), bool)
        on[self.midline] = True
        e = self.skin_triangles
        e = np.concatenate([e[:, [0, 1]], e[:, [1, 2]], e[:, [2, 0]]])
        e = e[on[e].all(axis=1)]
        w = np.linalg.norm(self.v[e[:, 0]] - self.v[e[:, 1]], axis=1)
        graph = sp.coo_matrix((w, (e[:, 0], e[:, 1])), shape=(len(self.v), len(self.v))).tocsr()
        _, prev = shortest_path(graph, directed=False, indices=a, return_predecessors=True)
        assert prev[b] >= 0, f"no midline path from {a} to {b}"
        path = [b]
        while path[-1] != a:
            path.append(int(prev[path[-1]]))
        return np.array(path[::-1])

    def mirror(self, k: int) -> int:
        p = self.v[k] * [-1, 1, 1]
        part = next(n for n, ids in self.parts.items() if k in set(ids.tolist()))
        other = {"eye_l": "eye_r", "eye_r": "eye_l", "eyelashes_l": "eyelashes_r",
                 "eyelashes_r": "eyelashes_l"}.get(part, part)
        ids = self.parts[other]
        d = np.linalg.norm(self.v[ids] - p, axis=1)
        return int(ids[np.argmin(d)])


def _ear_rim(v: np.ndarray, data, tip: int) -> np.ndarray:
    """Skin vertex ids of the left ear's rim — the connected patch around the outermost point
    ``tip`` of vertices from which a ray towards the midline meets skin again 2–40 mm on —
    and of the vertices beside it."""
    import trimesh

    skin_parts = [i for i, n in enumerate(data["part_names"]) if str(n) in
                  ("Face", "Head and Neck", "Mouth socket", "Eye socket left", "Eye socket right")]
    tris = data["faces"][np.isin(data["faces_part"], skin_parts)]
    mesh = trimesh.Trimesh(v, tris, process=False)
    near = np.flatnonzero(np.linalg.norm(v[:, [1, 2]] - v[tip, [1, 2]], axis=1) < 0.045)
    near = near[np.isin(near, tris) & (v[near, 0] > v[tip, 0] - 0.03)]
    origins = v[near] - [1e-4, 0.0, 0.0]
    hits, ray, _ = mesh.ray.intersects_location(origins, np.tile([-1.0, 0.0, 0.0], (len(near), 1)),
                                                multiple_hits=False)
    dist = np.full(len(near), np.inf)
    dist[ray] = np.linalg.norm(hits - origins[ray], axis=1)
    rim = np.zeros(len(v), bool)
    rim[near[(dist > 0.002) & (dist < 0.04)]] = True
    t = tris[np.all(rim[tris], axis=1)]
    graph = sp.coo_matrix((np.ones(3 * len(t)), (t.ravel(), np.roll(t, 1, axis=1).ravel())), shape=(len(v), len(v)))
    _, comp = connected_components(graph, directed=False)
    ear = rim & (comp == comp[tip])
    # Skin vertices that share a triangle with the rim but are not on it: its border with
    # the head (and with the hollow inside the ear).
    touch = tris[ear[tris].any(axis=1) & ~ear[tris].all(axis=1)]
    beside = np.setdiff1d(np.unique(touch), np.flatnonzero(ear))
    return np.flatnonzero(ear), beside


def place_feature_points(data, part_vertices) -> dict[str, tuple[str, tuple[int, ...], tuple[float, ...]]]:
    """FP id → (part, ICT vertex ids, weights) for all 84 points (rules: :data:`RULES`)."""
    P = _Placer(data, part_vertices)
    v, lm = P.v, P.lm
    fp: dict[str, tuple[str, tuple[int, ...], tuple[float, ...]]] = {}

    def at(i, k, part="skin"):
        fp[i] = (part, (int(k),), (1.0,))

    def mid(i, a, b, part="skin"):
        fp[i] = (part, (int(a), int(b)), (0.5, 0.5))

    def pos(i):
        part, ks, ws = fp[i]
        return np.asarray(ws) @ v[list(ks)]

    for i, k in {"2.1": 8, "2.2": 62, "2.3": 66, "2.4": 64, "2.6": 63, "2.8": 65, "2.11": 10,
                 "3.7": 45, "3.11": 42, "4.1": 22, "4.3": 24, "4.5": 26, "8.1": 51, "8.2": 57, "8.3": 54,
                 "8.10": 52, "9.5": 35, "9.12": 28, "9.15": 33}.items():
        at(i, lm[k])
    mid("8.5", lm[52], lm[53])
    mid("8.7", lm[55], lm[56])
    mids = P.midline
    # Chin boss: the chin's most prominent point (the reference: "above 2.1"), not the lower
    # lip's bulge, which is the frontmost point right under 8.2. Along the outer profile the
    # skin goes back from the lip into the mentolabial sulcus, then forward onto the chin.
    # The sulcus is the profile's point furthest behind the chord from 8.2 to 2.1 (the lowest
    # z overall would be under the chin, which curves back to 2.1).
    profile = P.midline_path(lm[57], lm[8])[1:-1]
    a, b = v[lm[57], 1:], v[lm[8], 1:]
    t = (b - a) / np.linalg.norm(b - a)
    d = v[profile, 1:] - a
    depth = t[0] * d[:, 1] - t[1] * d[:, 0]  # > 0 behind the chord (y up, z to the viewer)
    chin = profile[int(np.argmax(depth)) + 1:]
    at("2.10", chin[np.argmax(v[chin, 2])])
    # Pupil: the eye vertex furthest along the gaze (from the centre through the iris).
    eye = part_vertices["eye_l"]
    v_ranges = {str(n): r for n, r in zip(data["detail_part_names"], data["detail_part_vertex_ranges"])}
    iris = np.arange(*v_ranges["Iris left"])
    sclera = np.arange(*v_ranges["Sclera left"])
    centre, _ = sphere_fit(v[sclera])
    gaze = v[iris].mean(axis=0) - centre
    at("3.5", eye[np.argmax((v[eye] - centre) @ gaze)], "eye_l")
    # Lid margins at the pupil's x: the skin vertices that bound the visible eye there.
    near = P.skin[(np.abs(v[P.skin, 0] - pos("3.5")[0]) < 0.0012) & (v[P.skin, 2] > pos("3.5")[2] - 0.003)]
    above, below = near[v[near, 1] > pos("3.5")[1]], near[v[near, 1] < pos("3.5")[1]]
    at("3.1", above[np.argmin(v[above, 1])])
    at("3.3", below[np.argmax(v[below, 1])])
    at("3.9", P.front(pos("3.3")[0], pos("3.3")[1] - 0.004))
    at("3.13", P.front(pos("3.1")[0], pos("3.1")[1] + 0.005))
    y_cheek = 0.5 * (pos("9.15")[1] + pos("8.1")[1])
    at("5.1", P.front(0.9 * pos("3.7")[0], y_cheek))
    at("5.3", P.front(pos("3.7")[0], pos("9.15")[1] + 0.4 * (pos("3.7")[1] - pos("9.15")[1])))
    at("9.1", P.front(1.25 * pos("9.5")[0], pos("9.5")[1] + 0.004))
    at("9.3", P.skin[np.argmax(v[P.skin, 2])])
    at("9.7", P.front(0.45 * pos("3.11")[0], pos("3.11")[1]))
    at("9.13", P.front(0.35 * pos("3.11")[0], pos("9.12")[1]))
    # Tongue.
    tongue = part_vertices["tongue"]
    near_mid = tongue[np.abs(v[tongue, 0]) < 0.002]
    k = near_mid[np.argmax(v[near_mid, 2])]
    mid("6.1", k, P.mirror(k), "tongue")
    z_half = 0.5 * (v[tongue, 2].min() + v[tongue, 2].max())
    band = near_mid[np.abs(v[near_mid, 2] - z_half) < 0.004]
    k = band[np.argmax(v[band, 1])]
    mid("6.2", k, P.mirror(k), "tongue")
    band = tongue[np.abs(v[tongue, 2] - pos("6.2")[2]) < 0.003]
    at("6.3", band[np.argmax(v[band, 0])], "tongue")
    # Teeth: central incisors (left ones; midline points average a vertex and its mirror).
    for i, name, part, pick in (("9.8", "Central incisor upper left", "teeth_upper", np.argmax),
                                ("9.10", "Central incisor upper left", "teeth_upper", np.argmin),
                                ("9.9", "Central incisor lower left", "teeth_lower", np.argmin),
                                ("9.11", "Central incisor lower left", "teeth_lower", np.argmax)):
        ids = np.arange(*v_ranges[name])
        k = ids[pick(v[ids, 1])]
        mid(i, k, P.mirror(k), part)
    # Ears: the connected patch of skin around the outermost point of the ear (the helix),
    # within 2 cm of it sideways and at most 1 cm above the pupils (higher up the skull is
    # as wide as the ear and the patch would run onto it).
    low_face = P.skin[(v[P.skin, 1] < pos("3.5")[1] + 0.01) & (v[P.skin, 1] > pos("2.1")[1])]
    tip = low_face[np.argmax(v[low_face, 0])]
    mask = np.zeros(len(v), bool)
    mask[low_face[v[low_face, 0] > v[tip, 0] - 0.02]] = True
    tris = data["faces"][np.all(mask[data["faces"]], axis=1)]
    graph = sp.coo_matrix((np.ones(3 * len(tris)), (tris.ravel(), np.roll(tris, 1, axis=1).ravel())),
                          shape=(len(v), len(v)))
    _, comp = connected_components(graph, directed=False)
    ear = np.flatnonzero(mask & (comp == comp[tip]))
    ear_y = v[ear, 1]
    at("10.5", ear[np.argmin(ear_y)])
    low = ear[ear_y < ear_y.min() + 0.008]
    at("10.7", low[np.argmax(v[low, 2])])
    # Gonion (the reference's 2.13: the angle of the jaw bone), where the jaw's lower border
    # turns up towards the ear: the hindmost point of the jaw's underside. ICT's outline
    # landmark 13 is not it: it lies mid-cheek at the lobe's height, 5 cm in front of the ear.
    # The underside: skin facing down by 30 degrees or more (the cheek and the neck face
    # sideways or forward), lateral of half the lobe's x (not the mouth socket's roof nor the
    # right side), 5 mm or more below the lobe (the lobe and where it joins the face face down
    # too); in front of 10.7 and at most 1 cm under the chin are guards against the skin
    # behind the ear and the neck (neither decides on this head).
    normals = vertex_normals(v, P.skin_triangles)
    s = P.skin
    jaw = s[(normals[s, 1] < -0.5) & (v[s, 0] > 0.5 * pos("10.5")[0]) & (v[s, 2] > pos("10.7")[2])
            & (v[s, 1] < pos("10.5")[1] - 0.005) & (v[s, 1] > pos("2.1")[1] - 0.010)]
    at("2.13", jaw[np.argmin(v[jaw, 2])])
    # The top of that patch runs onto the temple; the ear's own rim is told from it by what
    # lies behind: a ray into the head from a rim vertex meets skin again within a few
    # centimetres (the side of the head behind the ear), from the temple it does not.
    helix, joins = _ear_rim(v, data, tip)
    hy = v[helix, 1]
    at("10.1", helix[np.argmax(hy)])
    # Where the rim's front meets the head: the highest skin vertex beside the rim (not on
    # it) in front of the ear's middle.
    front = joins[v[joins, 2] > v[helix, 2].mean()]
    at("10.9", front[np.argmax(v[front, 1])])
    y_mid = 0.5 * (ear_y.min() + hy.max())
    band = ear[np.abs(ear_y - y_mid) < 0.004]
    at("10.3", band[np.argmin(v[band, 2])])
    # Hairline and skull.
    glabella_y = 0.5 * (pos("4.1")[1] + v[lm[27], 1])
    y_hair = glabella_y + (glabella_y - pos("9.15")[1])
    front_mid = mids[v[mids, 2] > 0]
    at("11.1", front_mid[np.argmin(np.abs(v[front_mid, 1] - y_hair))])
    at("11.3", P.front(pos("4.5")[0], pos("11.1")[1] - 0.010))
    top = mids[np.argmax(v[mids, 1])]
    at("11.4", top)
    at("11.5", top)
    above = mids[v[mids, 1] > pos("9.15")[1]]
    at("11.6", above[np.argmin(v[above, 2])])
    # 7.1 inside the neck at the lobes' height: between the two lobes and the back of the
    # neck (the mirror pair keeps it on the midline).
    neck = mids[np.abs(v[mids, 1] - pos("10.5")[1]) < 0.006]
    back = neck[np.argmin(v[neck, 2])]
    lobe = fp["10.5"][1][0]
    fp["7.1"] = ("skin", (int(lobe), P.mirror(lobe), int(back)), (0.35, 0.35, 0.3))
    # Right side: the mirror images of the left points.
    for i in FP_IDS:
        f = FEATURE_POINTS[i]
        if f.side == "R":
            part, ks, ws = fp[f.mirror]
            mpart = {"eye_l": "eye_r", "eyelashes_l": "eyelashes_r"}.get(part, part)
            fp[i] = (mpart, tuple(P.mirror(k) for k in ks), ws)
    missing = [i for i in FP_IDS if i not in fp]
    assert not missing, missing
    return fp


def build_generic_head(npz_path=DEFAULT_NPZ) -> Head:
    """The generic head as a :class:`mpeg4.Head` (pure: reads the npz, writes nothing)."""
    data = dict(np.load(npz_path))
    verts = data["vertices"].astype(np.float64) * 0.01
    faces = data["faces"].astype(np.int64)
    tri_sets = split_parts(data)
    tri_sets = {k: t for k, t in tri_sets.items() if k not in DROPPED}
    part_vertices = {name: np.unique(faces[t]) for name, t in tri_sets.items()}
    order = ["skin", "eye_l", "eye_r", "teeth_upper", "teeth_lower", "gums_upper", "gums_lower", "tongue"]
    v_ranges = {str(n): r for n, r in zip(data["detail_part_names"], data["detail_part_vertex_ranges"])}
    parts = {}
    for name in order:
        ids = part_vertices[name]
        tris = np.searchsorted(ids, faces[tri_sets[name]])
        centre = None
        if name in ("eye_l", "eye_r"):
            sclera = np.arange(*v_ranges["Sclera left" if name == "eye_l" else "Sclera right"])
            centre, _ = sphere_fit(verts[sclera])
        uv = texture = None
        if centre is not None:
            iris = np.arange(*v_ranges["Iris left" if name == "eye_l" else "Iris right"])
            uv = eye_uv(verts[ids], centre, verts[iris].mean(axis=0) - centre)
            texture = eye_texture()
        parts[name] = Part(name, verts[ids], tris, uv=uv, texture=texture,
                           colour=COLOURS.get(name, (1.0, 1.0, 1.0)), centre=centre)
    names = [str(x) for x in data["expression_names"]] + [str(x) for x in data["extra_expression_names"]]
    deltas = np.concatenate([data["expression_deltas"], data["extra_expression_deltas"]])
    targets = {}
    for k, name in enumerate(names):
        target = {}
        for part, ids in part_vertices.items():
            d = SparseDisplacement.from_dense(deltas[k][ids].astype(np.float64) * 0.01, tol=1e-7)
            if len(d.indices):
                target[part] = d
        targets[name] = target
    fps = {}
    for i, (part, ks, ws) in place_feature_points(data, part_vertices).items():
        local = np.searchsorted(part_vertices[part], ks)
        assert (part_vertices[part][local] == ks).all(), (i, part)
        fps[i] = FeaturePointBinding(part, tuple(int(x) for x in local), ws)
    metadata = {
        "name": "generic head",
        "source": {"data": "ICT-FaceKit (ICT Face Model Light), USC Institute for Creative Technologies, "
                           "Vision and Graphics Lab", "commit": ICT_COMMIT, "license": "MIT"},
        "units": "m",
        "ict_vertex_ids": {name: (ids.tolist() if not (np.diff(ids) == 1).all()
                                  else [int(ids[0]), int(ids[-1]) + 1]) for name, ids in part_vertices.items()},
        "morph_targets": "ICT-FaceKit expression blendshapes (ARKit names) and PupilDilate_L/R",
    }
    return lit_mouth(Head(parts, fps, targets, metadata=metadata))


def lit_mouth(head: Head) -> Head:
    """The head with teeth, gums and tongue lit as the open mouth lets light in
    (:mod:`recon.texture.mouth`, through ramp textures: the vertices keep ICT's order),
    the light found with the jaw opened by ICT's ``jawOpen`` as far as FAP 3 at
    ``OPEN_JAW`` opens it (the chin, 2.1, down by that many MNS) and with the lips drawn
    back from the teeth (``bared_pose``), the brighter of the two kept."""
    drop = head.fp_position("2.1")[1] - head.fp_position("2.1", head.morphed({"jawOpen": 1.0}))[1]
    opened = head.morphed({"jawOpen": OPEN_JAW * head.fapu.MNS0 / 1024.0 / drop})
    light = brightest_light([opened, bared_pose(head)], {n: p.triangles for n, p in head.parts.items()})
    return lit_in_place(head, light)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="Build the generic head GLB from the ICT FaceKit.")
    ap.add_argument("--npz", type=Path, default=DEFAULT_NPZ)
    ap.add_argument("-o", "--out", type=Path, default=DEFAULT_OUT)
    args = ap.parse_args(argv)
    if not args.npz.exists():
        print(f"build_generic_head: {args.npz}: ICT FaceKit data not found (fix: put ict_facekit.npz there "
              f"or pass --npz)", file=sys.stderr)
        return 2
    from mpeg4.io import save_head

    t0 = time.perf_counter()
    head = build_generic_head(args.npz)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    save_head(head, args.out)
    dt = time.perf_counter() - t0
    print(head.summary())
    print(f"written: {args.out} ({args.out.stat().st_size / 1e6:.2f} MB) in {dt:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
