"""What makes real photos hard, put on a synthetic person: hair with volume, skin tones
across the Fitzpatrick range, clothes with a collar, glasses, and busy backgrounds.

The clean synthetic set (:mod:`recon.evaluate.synthetic`) paints short hair flat on the
skull, in front of a plain studio wall: nothing hides the skull's outline, the ears or the
neck. Real photos fail where that is not so. A :class:`Look` says how a person is dressed;
:func:`dress` builds the meshes, and :func:`background_image` the wall behind. Everything is
drawn from a seed and laid out on the neutral head, so it follows every identity's anatomy.

Hair is an offset of the scalp (the skin above the painted hairline) along its normals,
thickening from nothing at the hairline to the style's thickness a couple of centimetres
above it, with seeded curls; a ponytail is a tube hanging from the back of the head. The
skull's own feature points (11.4, 11.6) stay on the skin, under the hair; 11.5, the top of
the hair, moves to the hair's surface (:func:`hair_top`).

Skin types I–VI are placed by their individual typology angle, ITA° = atan((L* − 50) / b*),
the colorimetric scale that tracks the Fitzpatrick types (very light > 55°, light 41–55°,
intermediate 28–41°, tan 10–28°, brown −30–10°, dark < −30°): one CIELAB colour inside each
band, turned to sRGB by scikit-image.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mpeg4.head import Head
from mpeg4.render import RenderMesh, vertex_normals

from .paint import Person, ear_distance, hairline_height, smoothstep, value_noise

__all__ = ["HAIR_STYLES", "BACKGROUNDS", "FITZPATRICK_LAB", "Look", "hard_look", "fitzpatrick_rgb", "dress",
           "hair_top", "background_image", "ita_degrees"]

#: Hair styles: ``"painted"`` (the clean set: colour on the skin only), ``"short"`` (a few
#: millimetres of volume), ``"bushy"`` (curly, several centimetres) and ``"ponytail"`` (long
#: hair drawn back flat and tied behind the head).
HAIR_STYLES = ("painted", "short", "bushy", "ponytail")
#: Backgrounds: the clean set's plain wall, a mottled wall, and a cluttered room.
BACKGROUNDS = ("plain", "textured", "cluttered")
#: CIELAB (L*, a*, b*) of the skin for Fitzpatrick types I–VI, one in each ITA° band.
FITZPATRICK_LAB = {1: (71.0, 8.0, 12.5), 2: (65.0, 10.0, 15.5), 3: (60.0, 11.5, 17.0), 4: (54.0, 13.0, 18.5),
                   5: (44.0, 13.0, 17.0), 6: (32.0, 10.0, 11.5)}
_SHIRTS = np.array([(236, 236, 232), (52, 70, 120), (30, 30, 34), (150, 40, 42), (120, 124, 128), (196, 170, 120)],
                   float)
_FRAMES = np.array([(28, 28, 32), (92, 58, 36), (150, 150, 156)], float)


def ita_degrees(lab) -> np.ndarray:
    """Individual typology angle (degrees) of CIELAB colours (..., 3)."""
    lab = np.asarray(lab, float)
    return np.degrees(np.arctan2(lab[..., 0] - 50.0, lab[..., 2]))


def fitzpatrick_rgb(skin_type: int) -> np.ndarray:
    """(3,) float sRGB in 0–255 of a Fitzpatrick skin type (1–6) as this module paints it."""
    from skimage.color import lab2rgb

    if skin_type not in FITZPATRICK_LAB:
        raise ValueError(f"Fitzpatrick skin type must be 1–6 (I–VI), got {skin_type!r}")
    return lab2rgb(np.array(FITZPATRICK_LAB[skin_type], float)[None, None])[0, 0] * 255.0


@dataclass(frozen=True)
class Look:
    """How a synthetic person is dressed and photographed.

    Attributes
    ----------
    hair : str
        One of :data:`HAIR_STYLES`.
    skin_type : int or None
        Fitzpatrick type 1–6 (I–VI); None keeps the clean set's drawn tone.
    clothes : bool
        A shirt over the shoulders and neck, with a collar.
    glasses : bool
        A pair of glasses (frames only: the renderer draws no transparent lenses).
    background : str
        One of :data:`BACKGROUNDS`.
    """

    hair: str = "painted"
    skin_type: int | None = None
    clothes: bool = False
    glasses: bool = False
    background: str = "plain"

    def __post_init__(self):
        if self.hair not in HAIR_STYLES:
            raise ValueError(f"hair style must be one of {', '.join(HAIR_STYLES)}, got {self.hair!r}")
        if self.background not in BACKGROUNDS:
            raise ValueError(f"background must be one of {', '.join(BACKGROUNDS)}, got {self.background!r}")
        if self.skin_type is not None and self.skin_type not in FITZPATRICK_LAB:
            raise ValueError(f"skin type must be 1–6 (Fitzpatrick I–VI) or None, got {self.skin_type!r}")

    @property
    def name(self) -> str:
        parts = [f"hair {self.hair}"]
        if self.skin_type:
            parts.append(f"type {'I II III IV V VI'.split()[self.skin_type - 1]}")
        parts += ["clothes"] * self.clothes + ["glasses"] * self.glasses + [f"{self.background} background"]
        return ", ".join(parts)


def hard_look(seed: int) -> Look:
    """The harder set's look for a seed: the three hair volumes, the six skin types and the
    two busy backgrounds in turn (so that any six consecutive seeds hold every type and
    every style twice), always clothes, glasses on every third person."""
    return Look(hair=("short", "bushy", "ponytail")[seed % 3], skin_type=seed % 6 + 1, clothes=True,
                glasses=seed % 3 == 1, background=("textured", "cluttered")[seed % 2])


def _scalp(person: Person, neutral: Head, seed: int):
    """Skin triangles of the scalp and, per skin vertex, the neutral position and the height
    above the hairline (metres, negative below)."""
    fp = neutral.fp_positions()
    p0 = neutral.skin.vertices
    above = p0[:, 1] - hairline_height(p0, fp, 100 * seed)
    tri = person.head.skin.triangles
    keep = np.all(above[tri] > -0.002, axis=1)
    return tri[keep], above, fp


def _hair_mesh(person: Person, neutral: Head, style: str, seed: int) -> RenderMesh:
    """The hair's outer surface: the scalp moved out along its normals."""
    import trimesh

    rng = np.random.default_rng(20_000 + seed)
    tri, above, fp = _scalp(person, neutral, seed)
    skin = person.head.skin
    normals = vertex_normals(skin.vertices, skin.triangles)
    attrs = np.c_[neutral.skin.vertices, above, normals]
    used, local = np.unique(tri, return_inverse=True)
    v, t = skin.vertices[used], local.reshape(-1, 3)
    a = attrs[used]
    for _ in range(2):  # about 2 mm edges, fine enough for the curls
        v, t, extra = trimesh.remesh.subdivide(v, t, vertex_attributes={"a": a})
        a = extra["a"]
    p0, above, n = a[:, :3], a[:, 3], a[:, 4:]
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    thick = {"short": 0.006, "bushy": 0.032, "ponytail": 0.005}[style] * rng.uniform(0.85, 1.15)
    # From nothing at the hairline to full thickness 2 cm above it, thinner over the ears.
    ramp = smoothstep(-0.001, 0.02, above) * smoothstep(0.012 if style == "bushy" else 0.02, 0.045,
                                                        ear_distance(p0, fp))
    curls = 0.0
    if style == "bushy":
        curls = 0.25 * value_noise(p0, 0.018, seed + 31) + 0.15 * value_noise(p0, 0.006, seed + 32)
    elif style == "short":
        curls = 0.15 * value_noise(p0, 0.01, seed + 33)
    offset = 0.0008 + thick * ramp * (1 + curls)
    v = v + n * offset[:, None]
    grain = 1 + 0.2 * value_noise(p0, 0.0015, seed + 34) + 0.12 * value_noise(p0, 0.006, seed + 35)
    if style == "ponytail":  # combed back: streaks along the head's length
        grain += 0.15 * value_noise(p0 * [1.0, 1.0, 0.15], 0.0015, seed + 36)
    colours = np.clip(person.hair_rgb[None] * grain[:, None], 0, 255) / 255.0
    return RenderMesh(v, t, colour=(1.0, 1.0, 1.0), vertex_colours=colours)


def _tube(path: np.ndarray, radius: np.ndarray, sides: int = 20, closed: bool = False):
    """Vertices and triangles of a tube of ``radius`` (L,) metres round a path (L, 3);
    open paths get flat caps."""
    path = np.asarray(path, float)
    radius = np.broadcast_to(np.asarray(radius, float), (len(path),))
    tangent = np.gradient(path, axis=0) if not closed else np.roll(path, -1, 0) - np.roll(path, 1, 0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    # A frame carried along the path (no twist): project the previous normal off each tangent.
    ref = np.array([0.0, 0.0, 1.0]) if abs(tangent[0, 2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    normals = []
    nrm = np.cross(tangent[0], ref)
    for tg in tangent:
        nrm = nrm - tg * (nrm @ tg)
        nrm /= np.linalg.norm(nrm)
        normals.append(nrm)
    normals = np.array(normals)
    binormals = np.cross(tangent, normals)
    ang = np.linspace(0, 2 * np.pi, sides, endpoint=False)
    ring = (np.cos(ang)[None, :, None] * normals[:, None] + np.sin(ang)[None, :, None] * binormals[:, None])
    verts = (path[:, None] + radius[:, None, None] * ring).reshape(-1, 3)
    rows = len(path) if closed else len(path) - 1
    tris = []
    for i in range(rows):
        j = (i + 1) % len(path)
        for k in range(sides):
            a, b = i * sides + k, i * sides + (k + 1) % sides
            c, d = j * sides + k, j * sides + (k + 1) % sides
            tris += [(a, c, b), (b, c, d)]
    if not closed:
        for end, flip in ((0, True), (len(path) - 1, False)):
            centre = len(verts)
            verts = np.vstack([verts, path[end]])
            for k in range(sides):
                a, b = end * sides + k, end * sides + (k + 1) % sides
                tris.append((centre, b, a) if flip else (centre, a, b))
    return verts, np.array(tris, np.int64)


def _ponytail(person: Person, seed: int) -> RenderMesh:
    """A ponytail tied at the back of the head, hanging down behind the neck."""
    rng = np.random.default_rng(21_000 + seed)
    head = person.head
    back = head.fp_position("11.6")
    top_ear = head.fp_position("10.1")
    start = np.array([0.0, 0.5 * (back[1] + top_ear[1]), back[2] + 0.004])
    # The back of the skull at the tie's height.
    skin = head.skin.vertices
    near = np.abs(skin[:, 0]) < 0.01
    near &= np.abs(skin[:, 1] - start[1]) < 0.01
    if near.any():
        start[2] = skin[near, 2].min() - 0.004
    length = rng.uniform(0.14, 0.22)
    s = np.linspace(0, 1, 40)
    path = np.c_[0.004 * np.sin(3 * s), start[1] - length * s ** 1.4, start[2] - 0.035 * np.sin(np.pi * 0.5 * np.minimum(s * 2.5, 1))
                 - 0.012 * s]
    radius = np.where(s < 0.06, 0.007, 0.024 * np.sin(np.pi * np.clip((s - 0.04) / 1.0, 0, 1)) ** 0.6 + 0.004)
    v, t = _tube(path, radius, sides=24)
    grain = 1 + 0.22 * value_noise(v * [1.0, 0.2, 1.0], 0.0015, seed + 37)
    colours = np.clip(person.hair_rgb[None] * grain[:, None], 0, 255) / 255.0
    return RenderMesh(v, t, colour=(1.0, 1.0, 1.0), vertex_colours=colours)


def _clothes(person: Person, seed: int) -> RenderMesh:
    """A shirt over the neck's base and the shoulders, with a collar standing round the neck."""
    import trimesh

    rng = np.random.default_rng(22_000 + seed)
    head = person.head
    skin = head.skin
    v = skin.vertices
    chin = head.fp_position("2.1")
    back = head.fp_position("11.6")
    centre_z = 0.5 * (chin[2] + back[2]) - 0.01
    shirt_rgb = _SHIRTS[rng.integers(len(_SHIRTS))] * rng.uniform(0.9, 1.05)
    drop = rng.uniform(0.05, 0.075)
    striped = rng.uniform() < 0.5

    def collar_top(p):  # lowest at the front (an open neck), rising towards the back
        theta = np.degrees(np.arctan2(np.abs(p[:, 0]), p[:, 2] - centre_z))
        return chin[1] - drop + 0.035 * smoothstep(20, 150, theta)

    tri = skin.triangles
    keep = np.any(v[tri, 1] < collar_top(v)[tri] + 0.004, axis=1)
    used, local = np.unique(tri[keep], return_inverse=True)
    normals = vertex_normals(v, tri)
    pos, t, a = v[used], local.reshape(-1, 3), normals[used]
    for _ in range(3):  # fine enough (about 2 mm) for a clean edge
        pos, t, extra = trimesh.remesh.subdivide(pos, t, vertex_attributes={"n": a})
        a = extra["n"]
    n = a / np.linalg.norm(a, axis=1, keepdims=True)
    below = pos[:, 1] - collar_top(pos)  # negative inside the shirt
    t = t[np.any(below[t] < 0, axis=1)]
    # 4 mm of cloth over the body, the collar band standing off to 8 mm, nothing above its edge.
    out = 0.004 + 0.004 * smoothstep(-0.025, -0.01, below)
    out += 0.002 * value_noise(pos, 0.02, seed + 41)
    out *= smoothstep(0.001, -0.001, below)
    shade = 1 + 0.05 * value_noise(pos, 0.004, seed + 42)
    shade *= 1 - 0.08 * smoothstep(-0.026, -0.024, below) * smoothstep(-0.022, -0.024, below)  # the collar's seam
    if striped:
        shade *= 1 - 0.25 * (np.sin(pos[:, 1] * 2 * np.pi / 0.009) > 0.3) * (below < -0.025)
    colours = np.clip(shirt_rgb * shade[:, None], 0, 255) / 255.0
    used2, t2 = np.unique(t, return_inverse=True)
    return RenderMesh((pos + n * out[:, None])[used2], t2.reshape(-1, 3), colour=(1.0, 1.0, 1.0),
                      vertex_colours=colours[used2])


def _glasses(person: Person, seed: int) -> RenderMesh:
    """Frames in front of the eyes: two rims, a bridge, and the temples back to the ears."""
    rng = np.random.default_rng(23_000 + seed)
    head = person.head
    skin = head.skin.vertices
    pupils = {"l": head.fp_position("3.5"), "r": head.fp_position("3.6")}
    ipd = np.linalg.norm(pupils["l"] - pupils["r"])
    a, b = ipd * rng.uniform(0.36, 0.42), ipd * rng.uniform(0.24, 0.3)
    wire = rng.uniform(0.0010, 0.0018)
    nose_z = head.fp_position("9.3")[2]
    front_z = max(pupils["l"][2], pupils["r"][2]) + 0.014
    parts = []
    ang = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    rims = {}
    for side, p in pupils.items():
        c = np.array([p[0], p[1] - 0.002, front_z])
        rim = c + np.c_[a * np.cos(ang), b * np.sin(ang) * (1 - 0.15 * (np.sin(ang) < 0)), np.zeros_like(ang)]
        rim[:, 2] -= 0.004 * (np.abs(rim[:, 0] - c[0]) / a) ** 2 * np.sign(c[0]) * np.sign(rim[:, 0] - c[0])
        rims[side] = (c, rim)
        parts.append(_tube(rim, wire, sides=8, closed=True))
    cl, cr = rims["l"][0], rims["r"][0]
    s = np.linspace(0, 1, 12)
    bridge = np.c_[cl[0] - a + (cr[0] + a - cl[0] + a) * s, cl[1] + 0.3 * b + 0.004 * np.sin(np.pi * s),
                   np.full_like(s, min(front_z, nose_z - 0.006))]
    parts.append(_tube(bridge, wire, sides=8))
    for side, ear in (("l", "10.1"), ("r", "10.2")):
        c = rims[side][0]
        sign = np.sign(c[0])
        e = head.fp_position(ear)
        y = c[1] + 0.2 * b
        # Just outside the head between the rim and the ear.
        band = (np.abs(skin[:, 1] - y) < 0.012) & (skin[:, 2] > e[2] - 0.01) & (sign * skin[:, 0] > 0)
        half = np.abs(skin[band, 0]).max() + 0.003 if band.any() else abs(c[0]) + a
        x_out = sign * max(half, abs(c[0]) + a)
        temple = np.array([(c[0] + sign * a, y, c[2]), (x_out, y, c[2] - 0.012), (x_out, 0.5 * (y + e[1]), e[2]),
                           (x_out, e[1] - 0.012, e[2] - 0.02)])
        s = np.linspace(0, 1, 16)
        path = np.stack([np.interp(s * 3, np.arange(4), temple[:, k]) for k in range(3)], axis=1)
        parts.append(_tube(path, wire, sides=8))
    verts, tris, offset = [], [], 0
    for v, t in parts:
        verts.append(v)
        tris.append(t + offset)
        offset += len(v)
    colour = _FRAMES[rng.integers(len(_FRAMES))] / 255.0
    return RenderMesh(np.vstack(verts), np.vstack(tris), colour=tuple(colour))


def dress(person: Person, look: Look, neutral: Head | None = None) -> Person:
    """The person with the look's hair, clothes and glasses in ``person.dress`` (in place),
    and returned. Skin tone and background are chosen elsewhere (:func:`make_person`'s
    ``skin_rgb``, :func:`background_image`)."""
    from mpeg4.generic_head import load_generic_head

    neutral = load_generic_head() if neutral is None else neutral
    out = []
    if look.hair != "painted":
        out.append(("hair", _hair_mesh(person, neutral, look.hair, person.seed)))
        if look.hair == "ponytail":
            out.append(("hair", _ponytail(person, person.seed)))
    if look.clothes:
        out.append(("clothes", _clothes(person, person.seed)))
    if look.glasses:
        out.append(("glasses", _glasses(person, person.seed)))
    person.dress = out
    return person


def hair_top(person: Person) -> np.ndarray:
    """(3,) metres: the hair's surface straight above the top of the skull (11.4), which is
    where the standard puts 11.5; 11.4 itself when the person's hair has no volume. (Curls
    may rise higher elsewhere: the silhouette's top is not always 11.5.)"""
    top = person.head.fp_position("11.4")
    best = top.copy()
    for kind, mesh in person.dress:
        if kind != "hair":
            continue
        v = mesh.vertices
        near = np.linalg.norm(v[:, [0, 2]] - top[[0, 2]], axis=1) < 0.003  # the hair's edges are ~2 mm
        if near.any() and v[near, 1].max() > best[1]:
            best = np.array([top[0], v[near, 1].max(), top[2]])
    return best


def background_image(kind: str, width: int, height: int, seed: int, plain=(0.86, 0.87, 0.89)) -> np.ndarray:
    """(H, W, 3) uint8: the wall behind a synthetic person.

    ``"plain"``: the clean set's studio wall, darker towards the bottom. ``"textured"``: a
    painted wall mottled at several scales. ``"cluttered"``: a room — shelves, frames, a
    door, objects in strong and skin-like colours — slightly out of focus.
    """
    import cv2

    if kind not in BACKGROUNDS:
        raise ValueError(f"background must be one of {', '.join(BACKGROUNDS)}, got {kind!r}")
    rng = np.random.default_rng(30_000 + seed)
    shade = np.linspace(1.02, 0.9, height)[:, None, None]
    if kind == "plain":
        return np.clip(np.asarray(plain) * 255 * shade * np.ones((1, width, 1)), 0, 255).astype(np.uint8)

    def noise(cells: int) -> np.ndarray:
        grid = rng.uniform(-1, 1, (cells * height // width + 2, cells + 2)).astype(np.float32)
        return cv2.resize(grid, (width, height), interpolation=cv2.INTER_CUBIC)

    base = rng.uniform(90, 215, 3) * rng.uniform(0.8, 1.0, 3)
    img = np.ones((height, width, 3), np.float32) * base.astype(np.float32)
    mottle = 0.10 * noise(6) + 0.06 * noise(24) + 0.04 * noise(120)
    img *= (1 + mottle)[..., None] * shade.astype(np.float32)
    if kind == "cluttered":
        for _ in range(int(rng.integers(14, 24))):
            colour = (rng.uniform(20, 240, 3) if rng.uniform() < 0.6 else
                      np.array([rng.uniform(150, 235), rng.uniform(100, 180), rng.uniform(70, 150)]))  # skin-like
            x0, y0 = rng.uniform(-0.1, 1.0) * width, rng.uniform(-0.1, 1.0) * height
            w, h = rng.uniform(0.05, 0.4) * width, rng.uniform(0.03, 0.5) * height
            if rng.uniform() < 0.7:
                cv2.rectangle(img, (int(x0), int(y0)), (int(x0 + w), int(y0 + h)), tuple(float(c) for c in colour), -1)
            else:
                cv2.ellipse(img, (int(x0), int(y0)), (int(w / 2), int(h / 2)), float(rng.uniform(0, 180)), 0, 360,
                            tuple(float(c) for c in colour), -1)
        img = cv2.GaussianBlur(img, (0, 0), float(rng.uniform(1.5, 3.5)))
        img *= (1 + 0.03 * noise(200))[..., None]
    return np.clip(img, 0, 255).astype(np.uint8)
