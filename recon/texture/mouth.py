"""The inside of the mouth: teeth, gums and tongue lit by what the open lips let in.

A viewer lights every surface alike, so an open mouth drawn with flat tongue and gum
colours reads as a pink slab: nothing says it is a cavity. What tells a mouth from a
slab is how little light reaches in — the tongue's tip and the front teeth see the room
through the opening, the back of the tongue and the palate almost nothing. That light
does not depend on the viewer and moves little as the mouth talks, so it is baked into
the parts' textures, where every renderer (ours, three.js, Blender) shows it:

1. :func:`open_pose`: the head with its jaw open (FAP 3, :data:`OPEN_JAW`) by the generic
   head's animation tables, the mouth as it is seen when it shows its inside; and
   :func:`bared_pose`: the lips drawn back from the closed teeth (:data:`BARED`), as a
   smile or a snarl shows their fronts, which the upper lip shades when the jaw drops;
2. :func:`cavity_light`: for each vertex of the mouth's parts, the share of the light
   from a uniform sky that reaches it (cosine-weighted ambient occlusion), found by
   depth renders of the whole head from many directions; each vertex keeps the most it
   gets over the poses (:func:`brightest_light`: a texture holds one light, and a
   surface is seen when the pose shows it);
3. :func:`mouth_textures`: each part unwrapped by xatlas (every triangle its own texels),
   its material (:mod:`recon.texture.materials`: enamel, gum, tongue) times that light
   baked into its texture.

A head whose vertices must keep their order and number — the generic head, whose
identities, expressions and tables apply by ICT's vertex order — cannot be unwrapped
(an atlas splits vertices along its seams). :func:`lit_in_place` shows the same light
there through a *ramp*: each vertex's texture coordinate is its light (and its height on
the part), the texture holds the material shaded by every light. Texture coordinates
interpolate across a triangle as the light would, so renderers draw the baked shading;
the materials' mottle and the gaps between the teeth are what it gives up.

References
----------
M. Pharr and S. Green, "Ambient occlusion", GPU Gems, chapter 17, 2004 (the quantity
baked); the depth-map visibility test is the one :mod:`recon.texture.regions` uses.
"""

from __future__ import annotations

import numpy as np

from mpeg4.camera import Camera
from mpeg4.errors import InputError
from mpeg4.head import Head
from mpeg4.render import RenderMesh, vertex_normals
from mpeg4.unlit import render_depth

__all__ = ["MOUTH_PARTS", "OPEN_JAW", "BARED", "BOUNCE", "RAMP", "sky_directions", "open_pose", "bared_pose",
           "cavity_light", "brightest_light", "shaded", "mouth_textures", "lit_in_place"]

#: The parts whose textures are made here.
MOUTH_PARTS = ("teeth_upper", "teeth_lower", "gums_upper", "gums_lower", "tongue")
#: FAP 3 (open_jaw, MNS) at which the light is found: a mouth open as in a broad vowel
#: (about 15 mm between the incisors on the generic head).
OPEN_JAW = 400.0
#: The morph targets (ICT's, ARKit's names) that draw the lips back from the teeth, and
#: their weights: the upper lip raised, the lower one lowered, the jaw closed.
BARED = {"mouthUpperUp_L": 1.0, "mouthUpperUp_R": 1.0, "mouthLowerDown_L": 1.0, "mouthLowerDown_R": 1.0}
#: Light that reaches even the deepest point (the room's light bounced off the cheeks
#: and teeth): the floor of the baked shading, so no part is drawn pure black.
BOUNCE = 0.06
#: Texels of a ramp (:func:`lit_in_place`) along its light axis: steps of 1/255 of the
#: light, under one grey level of the 8-bit texture.
RAMP = 256


def sky_directions(n: int) -> np.ndarray:
    """(n, 3) unit vectors spread evenly over the sphere (a Fibonacci lattice)."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = np.pi * (1.0 + 5.0 ** 0.5) * k
    r = np.sqrt(1.0 - z * z)
    return np.c_[r * np.cos(phi), r * np.sin(phi), z]


def open_pose(head: Head, fat=None, value: float = OPEN_JAW) -> dict[str, np.ndarray]:
    """Part name → (N, 3) vertices (metres) of the head with its jaw open by ``value``.

    Parameters
    ----------
    head : Head
        A head with tables, or of the generic head's topology (a built head; the copies
        its texture's seams added follow their originals).
    fat : FAT, optional
        The tables to open it with: the head's own, else the generic head's (moved in
        the head's own FAPU).
    value : float
        FAP 3 (open_jaw), MNS.
    """
    from mpeg4.fat import apply_fat
    from mpeg4.generic_head import load_generic_head

    if head.fapu is None:
        raise InputError("the head has no FAPU to open its jaw by", where="mouth",
                         fix="give the head its feature points (its FAPU follow from them)")
    if fat is None and head.fat is not None and len(head.fat):
        fat = head.fat
    if fat is not None:
        return apply_fat(fat, {name: p.vertices for name, p in head.parts.items()}, {3: value}, head.fapu)
    # The generic head's tables, on the head's original vertices; the copies a texture's
    # seams added (mpeg4.seams.split_vertices) follow their originals.
    generic = load_generic_head(with_fat=True)
    copies = head.metadata.get("duplicated_vertices", {})
    originals = {}
    for name, p in generic.parts.items():
        own = head.parts.get(name)
        extra = np.asarray(copies.get(name, []), dtype=np.int64)
        if own is None or own.n_vertices != p.n_vertices + len(extra):
            raise InputError(f"the head has no animation tables and its part '{name}' is not the generic head's",
                             where="mouth", fix="open the mouth of a head built from the generic head, or give "
                                                "the head its tables (fmc clone)")
        originals[name] = np.r_[np.arange(p.n_vertices), extra]
    posed = apply_fat(generic.fat, {name: head.parts[name].vertices[:p.n_vertices]
                                    for name, p in generic.parts.items()}, {3: value}, head.fapu)
    out = {name: posed[name][index] for name, index in originals.items()}
    out.update({name: p.vertices.copy() for name, p in head.parts.items() if name not in out})
    return out


def bared_pose(head: Head) -> dict[str, np.ndarray] | None:
    """Part name → (N, 3) vertices (metres) of the head with its lips drawn back from the
    teeth by its morph targets :data:`BARED`; None when it lacks them."""
    if not all(name in head.morph_targets for name in BARED):
        return None
    return head.morphed(BARED)


def cavity_light(vertices: dict[str, np.ndarray], triangles: dict[str, np.ndarray],
                 parts=MOUTH_PARTS, n_directions: int = 64, size: int = 256) -> dict[str, np.ndarray]:
    """Part name → (N,) share of a uniform sky's light reaching each vertex of ``parts``.

    Each direction's orthographic depth render of the whole head tells which vertices it
    sees (:func:`mpeg4.unlit.render_depth`; the camera framed on ``parts`` only, since a
    vertex and whatever hides it project to the same pixel); a vertex's light is the
    cosine-weighted share of the directions that see it, over its hemisphere.

    Parameters
    ----------
    vertices, triangles : mapping of str to arrays
        Every part of the head (all of them hide light), posed (:func:`open_pose`).
    parts : sequence of str
        The parts to light.
    n_directions : int
        Directions over the sphere (:func:`sky_directions`); the ones behind the face
        (which see nothing of the mouth) are skipped.
    size : int
        Side of each depth render, pixels.

    Returns
    -------
    dict of str to (N,) float64
        In [0, 1]: 1 for a vertex open to the whole hemisphere over it.
    """
    names = [p for p in parts if p in vertices]
    if not names:
        return {}
    meshes = [RenderMesh(np.asarray(v, float), np.asarray(triangles[k])) for k, v in vertices.items()]
    points = np.concatenate([vertices[k] for k in names])
    normals = np.concatenate([vertex_normals(vertices[k], triangles[k]) for k in names])
    all_dirs = sky_directions(n_directions)
    # A vertex open to the whole hemisphere over it gets exactly 1 (the directions' own sum).
    full = np.clip(normals @ all_dirs.T, 0.0, None).sum(axis=1)
    # The mouth opens forward: directions from behind the face see none of it.
    dirs = all_dirs[all_dirs[:, 2] > -0.2]
    lit = np.zeros(len(points))
    # Each vertex is tested a hair above its surface, and a hair's depth is allowed, so
    # that the surface it lies on does not hide it at grazing angles (metres).
    lifted = points + 0.0002 * normals
    tol = 0.0002
    for d in dirs:
        yaw = np.degrees(np.arctan2(d[0], d[2]))
        pitch = np.degrees(np.arcsin(np.clip(d[1], -1, 1)))
        cam = Camera.fit(points, size, size, yaw_deg=yaw, pitch_deg=pitch, margin=0.02)
        depth = render_depth(meshes, cam)
        px = np.round(cam.project(lifted)).astype(np.int64)
        inside = (px[:, 0] >= 0) & (px[:, 0] < size) & (px[:, 1] >= 0) & (px[:, 1] < size)
        seen = np.zeros(len(points), bool)
        seen[inside] = cam.depth(lifted[inside]) <= depth[px[inside, 1], px[inside, 0]] + tol
        # The camera looks along -view; light from the camera's side reaches normals facing it.
        toward = cam.rotation[2]  # unit vector from the scene towards the camera
        lit += np.clip(normals @ toward, 0.0, None) * seen
    share = np.clip(lit / np.maximum(full, 1e-12), 0.0, 1.0)
    out, start = {}, 0
    for k in names:
        n = len(vertices[k])
        out[k] = share[start:start + n]
        start += n
    return out


def brightest_light(poses, triangles: dict[str, np.ndarray], parts=MOUTH_PARTS) -> dict[str, np.ndarray]:
    """Part name → (N,) the most light (:func:`cavity_light`) each vertex of ``parts`` gets
    over the ``poses`` (a sequence of part name → vertices; None entries skipped)."""
    out = {}
    for posed in poses:
        if posed is None:
            continue
        for name, values in cavity_light(posed, triangles, parts).items():
            out[name] = np.maximum(out[name], values) if name in out else values
    return out


def _to_linear(srgb: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] to linear light."""
    return np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)


def _to_srgb(linear: np.ndarray) -> np.ndarray:
    """Linear light in [0, 1] to sRGB-encoded values."""
    linear = np.clip(linear, 0.0, 1.0)
    return np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * linear ** (1 / 2.4) - 0.055)


def shaded(albedo: np.ndarray, light: np.ndarray) -> np.ndarray:
    """(..., 3) uint8: sRGB ``albedo`` (uint8) times ``light`` (..., share of the sky,
    :func:`cavity_light`), the product taken in linear light over a floor of
    :data:`BOUNCE`."""
    lin = _to_linear(np.asarray(albedo, np.float64) / 255.0)
    k = BOUNCE + (1.0 - BOUNCE) * np.clip(np.asarray(light, np.float64), 0.0, 1.0)
    return np.round(255.0 * _to_srgb(lin * k[..., None])).astype(np.uint8)


def _lit_parts(head: Head, light: dict[str, np.ndarray]):
    """(name, part, (N,) light) for each mouth part of ``head`` that ``light`` gives, its
    length checked against the part's vertices."""
    for name in MOUTH_PARTS:
        part = head.parts.get(name)
        if part is None or name not in light:
            continue
        lit = np.asarray(light[name], np.float64)
        if len(lit) != part.n_vertices:
            raise InputError(f"{len(lit)} light values for the {part.n_vertices} vertices of '{name}'",
                             where="mouth", fix="find the light on the same head (cavity_light)")
        yield name, part, lit


def mouth_textures(head: Head, light: dict[str, np.ndarray], seed: int = 0, size: int = 256) -> Head:
    """A copy of ``head`` whose mouth parts carry their own atlas and a texture with
    ``light`` baked in.

    Parameters
    ----------
    head : Head
    light : mapping of str to (N,) float
        Per part, each vertex's light (:func:`cavity_light`); parts not given keep theirs.
    seed : int
        For the materials' mottle.
    size : int
        Side of each part's texture, pixels.

    Returns
    -------
    Head
        Each lit part split along its atlas's seams (:func:`mpeg4.seams.split_vertices`:
        tables and morph targets move the copies with their originals).
    """
    import cv2

    from mpeg4.seams import split_vertices

    from . import materials
    from .atlas import unwrap
    from .bake import fill_empty, interpolate, rasterize_uv, uv_to_pixels

    out = head
    for name, part, lit in _lit_parts(head, light):
        base = materials.mouth_albedo(name, 128, seed)
        source, tris, uv = unwrap(part.vertices, part.triangles, size)
        ids, bary = rasterize_uv(uv, tris, (size, size))
        # The material as it lay over the part before (a front projection), per texel.
        planar = interpolate(materials.planar_uv(part.vertices)[source], tris, ids, bary)
        at = uv_to_pixels(planar, base.shape[:2]).astype(np.float32)
        albedo = cv2.remap(base, at[..., 0], at[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
        texel_light = interpolate(lit[source], tris, ids, bary)[..., 0]
        valid = ids >= 0
        texture = fill_empty(shaded(albedo, texel_light), valid)
        out = split_vertices(out, name, source, tris, uv=uv, texture=texture)
        out.parts[name].colour = (1.0, 1.0, 1.0)
    return out


def lit_in_place(head: Head, light: dict[str, np.ndarray], size: int = 128) -> Head:
    """A copy of ``head`` whose mouth parts show ``light`` through ramp textures, their
    vertices neither split nor reordered.

    Each lit part gets texture coordinates u = its light (texel centres: 0 at the first
    of :data:`RAMP` columns, 1 at the last), t = its height seen from the front
    (:func:`recon.texture.materials.planar_uv`), and a (size, RAMP) texture whose column
    for light l is the material (:func:`recon.texture.materials.mouth_albedo`, averaged
    across: the teeth's gradient from gum line to edge kept, the mottle and gaps not)
    :func:`shaded` by l.

    Parameters
    ----------
    head : Head
    light : mapping of str to (N,) float
        Per part, each vertex's light (:func:`cavity_light`); parts not given keep theirs.
    size : int
        Rows of each ramp (heights on the part).

    Returns
    -------
    Head
        The parts' colours set to white (the texture carries the material).
    """
    from . import materials

    out = head.copy()
    levels = np.linspace(0.0, 1.0, RAMP)
    for name, part, lit in _lit_parts(out, light):
        rows = materials.mouth_albedo(name, size).astype(np.float64).mean(axis=1)
        albedo = np.round(np.broadcast_to(rows[:, None], (size, RAMP, 3))).astype(np.uint8)
        part.texture = shaded(albedo, np.broadcast_to(levels, (size, RAMP)))
        u = (np.clip(lit, 0.0, 1.0) * (RAMP - 1) + 0.5) / RAMP
        part.uv = np.c_[u, materials.planar_uv(part.vertices)[:, 1]]
        part.colour = (1.0, 1.0, 1.0)
    return out
