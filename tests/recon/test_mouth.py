"""The inside of the mouth: the light baked into teeth, gums and tongue (recon.texture.mouth)."""

import numpy as np
import pytest
import trimesh

from mpeg4.errors import InputError
from recon.texture.mouth import (BOUNCE, MOUTH_PARTS, RAMP, bared_pose, brightest_light, cavity_light, lit_in_place,
                                 mouth_textures, open_pose, shaded, sky_directions)


def _disc(z: float, radius: float, n: int = 12):
    """A small flat disc facing +z (a fan round its centre, vertex 0)."""
    a = np.linspace(0, 2 * np.pi, n + 1)[:-1]
    v = np.r_[[[0.0, 0.0, z]], np.c_[radius * np.cos(a), radius * np.sin(a), np.full(n, z)]]
    f = np.c_[np.zeros(n, int), 1 + np.arange(n), 1 + (np.arange(n) + 1) % n]
    return v, f


def _well(radius: float, depth: float):
    """An open-top cylinder (its mouth facing +z) with a small disc on its floor."""
    wall = trimesh.creation.cylinder(radius=radius, height=depth, sections=96)
    wall.apply_translation([0, 0, depth / 2])
    wall.update_faces(~(np.abs(wall.vertices[wall.faces][:, :, 2] - depth) < 1e-9).all(axis=1))
    floor_v, floor_f = _disc(1e-4, 0.02 * radius)
    return {"wall": wall.vertices, "floor": floor_v}, {"wall": wall.faces, "floor": floor_f}


def test_sky_directions_are_unit_and_even():
    d = sky_directions(500)
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0)
    assert np.linalg.norm(d.mean(axis=0)) < 0.01
    # Over any hemisphere the cosines sum to a quarter of the directions.
    for n in ([0, 0, 1], [1, 0, 0], [0.6, -0.8, 0]):
        assert abs(np.clip(d @ n, 0, None).sum() / 500 - 0.25) < 0.005


@pytest.mark.parametrize("depth", [0.005, 0.01, 0.02])
def test_light_at_the_bottom_of_a_well(depth):
    # The floor's centre sees the sky through a cone of half-angle atan(r / h): its
    # cosine-weighted share is sin² of that angle, r² / (r² + h²).
    r = 0.01
    v, f = _well(r, depth)
    light = cavity_light(v, f, parts=("floor",), n_directions=256, size=96)["floor"][0]
    assert abs(light - r * r / (r * r + depth * depth)) < 0.04


def test_a_surface_open_to_the_sky_gets_all_of_it():
    v, f = _disc(0.0, 0.01)
    assert cavity_light({"p": v}, {"p": f}, parts=("p",), size=64)["p"][0] == pytest.approx(1.0, abs=1e-9)


def test_shading_in_linear_light():
    albedo = np.array([[200, 120, 90]], np.uint8)
    assert np.abs(shaded(albedo, np.ones(1)).astype(int) - albedo).max() <= 1
    dark = shaded(albedo, np.zeros(1)).astype(float) / 255
    lin = lambda c: np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    assert np.allclose(lin(dark), BOUNCE * lin(albedo / 255.0), atol=0.004)
    steps = shaded(np.repeat(albedo, 5, axis=0), np.linspace(0, 1, 5)).astype(int)
    assert (np.diff(steps, axis=0) > 0).all()


@pytest.fixture(scope="module")
def generic_light():
    from mpeg4.generic_head import load_generic_head

    head = load_generic_head()
    posed = open_pose(head)
    return head, posed, cavity_light(posed, {n: p.triangles for n, p in head.parts.items()})


def test_the_jaw_opens(generic_light):
    head, posed, _ = generic_light
    gap = lambda v: np.linalg.norm(head.fp_position("2.2", v) - head.fp_position("2.3", v))
    assert gap(posed) > gap({n: p.vertices for n, p in head.parts.items()}) + 0.008  # metres


def test_the_light_falls_off_into_the_mouth(generic_light):
    head, _, light = generic_light
    assert set(light) == set(MOUTH_PARTS)
    for name, values in light.items():
        assert len(values) == head.parts[name].n_vertices
        assert values.max() < 0.9  # nothing inside the mouth is open to the whole sky
    # The tongue's tip sees the room through the lips; its back and the throat do not.
    z = head.parts["tongue"].vertices[:, 2]
    tip, back = light["tongue"][z >= np.quantile(z, 0.8)], light["tongue"][z <= np.quantile(z, 0.5)]
    assert tip.max() > 0.05 and back.max() < 0.2 * tip.max()
    # The upper incisors' fronts are lit better than the molars.
    t = head.parts["teeth_upper"].vertices
    front, molars = t[:, 2] >= np.quantile(t[:, 2], 0.9), t[:, 2] <= np.quantile(t[:, 2], 0.3)
    assert light["teeth_upper"][front].mean() > 5 * light["teeth_upper"][molars].mean()


def test_the_bared_teeth_keep_the_light_their_fronts_get(generic_light):
    # With the jaw dropped the upper lip shades the incisors' fronts; drawn back from the
    # closed teeth, it does not: the baked light keeps the brighter of the two, so teeth a
    # smile shows are not drawn in the open mouth's shadow.
    head, posed, light = generic_light
    tris = {n: p.triangles for n, p in head.parts.items()}
    bared = bared_pose(head)
    assert bared is not None
    both = brightest_light([posed, None, bared], tris)
    alone = cavity_light(bared, tris)
    for name in MOUTH_PARTS:
        assert np.array_equal(both[name], np.maximum(light[name], alone[name])), name
    t = head.parts["teeth_upper"].vertices
    fronts = t[:, 2] >= np.quantile(t[:, 2], 0.9)
    assert both["teeth_upper"][fronts].mean() > 1.2 * light["teeth_upper"][fronts].mean()
    # A head without those morph targets has no bared pose.
    from mpeg4.head import Head

    assert bared_pose(Head(head.parts, head.feature_points)) is None


def test_mouth_textures_bake_the_light(generic_light):
    head, _, light = generic_light
    out = mouth_textures(head, light)
    copies = out.metadata["duplicated_vertices"]
    for name in MOUTH_PARTS:
        before, part = head.parts[name], out.parts[name]
        n = before.n_vertices
        source = np.r_[np.arange(n), copies[name]]
        assert part.n_vertices == len(source)
        assert np.array_equal(part.vertices, before.vertices[source])
        assert part.texture.shape == (256, 256, 3) and part.texture.dtype == np.uint8
        assert part.uv.min() >= 0 and part.uv.max() <= 1
        # The triangles are the same, corner by corner, over the copies.
        assert np.array_equal(source[part.triangles], before.triangles)
        # The texture under each vertex follows its light: the vertices lit by half the
        # part's most or more read lighter (in linear light) than the unlit, by at least
        # half what the light alone implies (the rest: the materials' mottle and gradient,
        # and texels at a vertex that belong to the triangle beside it).
        h, w = part.texture.shape[:2]
        px = np.clip(np.round(np.c_[part.uv[:, 0] * w - 0.5, (1 - part.uv[:, 1]) * h - 0.5]).astype(int), 0, w - 1)
        c = part.texture[px[:, 1], px[:, 0]].astype(float) / 255
        lum = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).mean(axis=1)
        lit = light[name][source]
        most = lit >= 0.5 * lit.max()
        assert lit.max() > 0.02 and (lit == 0).sum() > 10, name
        implied = (BOUNCE + (1 - BOUNCE) * lit[most].mean()) / BOUNCE
        assert lum[most].mean() / lum[lit == 0].mean() > 1 + 0.5 * (implied - 1), name
    # Opening the textured head again moves each copy with its original.
    posed = open_pose(out)
    for name in MOUTH_PARTS:
        n = head.parts[name].n_vertices
        assert np.allclose(posed[name][n:], posed[name][copies[name]])


def test_light_values_must_match_the_part(generic_light):
    head, _, light = generic_light
    with pytest.raises(InputError, match="light values"):
        mouth_textures(head, {"tongue": light["tongue"][:-3]})


def _flat(head):
    """The head with its mouth's parts in flat colours (as the generic head had them)."""
    from recon.texture.materials import GUM_RGB, TONGUE_RGB

    out = head.copy()
    for name in MOUTH_PARTS:
        p = out.parts[name]
        p.uv = p.texture = None
        p.colour = (0.96, 0.94, 0.86) if name.startswith("teeth") else TONGUE_RGB if name == "tongue" else GUM_RGB
    return out


@pytest.mark.parametrize("bake", ["atlas", "ramp"])
def test_an_open_mouth_reads_as_a_mouth(generic_light, bake):
    # The generic head with its mouth textured, from the front: the opening reads far
    # darker than the lips (0.77 of them with flat colours, 0.26 lit either way), the
    # teeth lighter than the tongue behind them (1.6 flat, 2.6-2.7 lit).
    from recon.evaluate.mouth import opening_figures

    head, _, light = generic_light
    flat = opening_figures(_flat(head))
    lit = opening_figures(mouth_textures(head, light) if bake == "atlas" else lit_in_place(head, light))
    assert lit.opening_over_lips < 0.5 * flat.opening_over_lips
    assert lit.teeth_over_tongue > 1.3 * flat.teeth_over_tongue
    # The same pixels: the light changed, not what shows.
    assert lit.teeth_share == pytest.approx(flat.teeth_share, abs=0.01) and lit.tongue_share > 0.3


def test_a_ramp_shows_each_vertex_its_light_in_place(generic_light):
    from recon.texture.materials import mouth_albedo

    head, _, light = generic_light
    out = lit_in_place(head, light)
    for name in MOUTH_PARTS:
        before, part = head.parts[name], out.parts[name]
        # Nothing split or moved: the generic head's vertex order is what its tables use.
        assert np.array_equal(part.vertices, before.vertices) and np.array_equal(part.triangles, before.triangles)
        assert part.texture.shape[1] == RAMP and part.colour == (1.0, 1.0, 1.0)
        # The texel under each vertex is its material's colour at its height, shaded by its
        # light to within the ramp's step (1/255 of the light) and 8-bit rounding.
        h, w = part.texture.shape[:2]
        px = np.c_[part.uv[:, 0] * w - 0.5, (1 - part.uv[:, 1]) * h - 0.5]
        col, row = np.round(px).astype(int).T
        assert np.abs(px[:, 0] - col).max() < 0.5 + 1e-9
        want = shaded(mouth_albedo(name).mean(axis=1).round().astype(np.uint8)[row],
                      np.clip(light[name], 0, 1)).astype(int)
        assert np.abs(part.texture[row, col].astype(int) - want).max() <= 2, name
    with pytest.raises(InputError, match="light values"):
        lit_in_place(head, {"tongue": light["tongue"][:-3]})


def test_the_generic_head_ships_its_mouth_lit():
    from mpeg4.generic_head import load_generic_head
    from recon.evaluate.mouth import opening_figures

    head = load_generic_head()
    for name in MOUTH_PARTS:
        assert head.parts[name].texture is not None and head.parts[name].uv is not None, name
    assert opening_figures(head).opening_over_lips < 0.5 * opening_figures(_flat(head)).opening_over_lips
