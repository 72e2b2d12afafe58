"""The lean renderers return render's depth image, and its unlit image of vertex-coloured
meshes, to the bit, whatever the camera."""

import numpy as np
import pytest

from mpeg4.camera import Camera
from mpeg4.unlit import render_depth, render_unlit
from mpeg4.errors import InputError
from mpeg4.render import RenderMesh, render


def _sphere_and_plane():
    """A sphere in front of a tilted plane (open, overlapping, one mesh with no triangles)."""
    u, v = np.meshgrid(np.linspace(0, np.pi, 24), np.linspace(0, 2 * np.pi, 48), indexing="ij")
    pts = 0.05 * np.stack([np.sin(u) * np.cos(v), np.sin(u) * np.sin(v), np.cos(u)], axis=-1).reshape(-1, 3)
    k = np.arange(24 * 48).reshape(24, 48)
    a, b, c, d = k[:-1, :-1], k[:-1, 1:], k[1:, :-1], k[1:, 1:]
    tris = np.r_[np.c_[a.ravel(), b.ravel(), c.ravel()], np.c_[b.ravel(), d.ravel(), c.ravel()]]
    plane = np.array([[-0.2, -0.2, -0.1], [0.2, -0.2, -0.05], [0.2, 0.2, -0.02], [-0.2, 0.2, -0.08]])
    return [RenderMesh(pts + [0.01, 0.0, 0.03], tris), RenderMesh(plane, [[0, 1, 2], [0, 2, 3]], colour=(1, 0, 0)),
            RenderMesh(plane, np.zeros((0, 3), int))]


@pytest.mark.parametrize("focal,yaw,pitch", [(None, 0.0, 0.0), (300.0, 35.0, 10.0), (500.0, 180.0, -20.0)])
def test_render_depth_is_renders_depth(focal, yaw, pitch):
    meshes = _sphere_and_plane()
    cam = Camera.fit(np.concatenate([m.vertices for m in meshes]), 160, 120, yaw_deg=yaw, pitch_deg=pitch,
                     margin=0.1, focal_px=focal)
    _, depth = render(meshes, cam, return_depth=True, samples=0)
    ours = render_depth(meshes, cam)
    assert ours.dtype == np.float64 and ours.shape == (120, 160)
    assert np.isfinite(depth).mean() > 0.2 and np.isinf(depth).any()
    np.testing.assert_array_equal(ours, depth)


def test_render_depth_refuses_what_render_refuses():
    cam = Camera(40, 30, np.eye(3), [0, 0, 3], focal_px=30.0)
    with pytest.raises(InputError, match="triangle indices"):
        render_depth([RenderMesh(np.zeros((3, 3)), [[0, 1, 5]])], cam)


@pytest.mark.parametrize("focal,yaw", [(None, 20.0), (400.0, -150.0)])
def test_render_unlit_is_renders_unlit_image(focal, yaw):
    meshes = _sphere_and_plane()
    rng = np.random.default_rng(0)
    for m in meshes:
        m.vertex_colours = rng.random((len(m.vertices), 3))
    meshes[1].colour = (0.5, 0.8, 1.0)
    cam = Camera.fit(np.concatenate([m.vertices for m in meshes]), 150, 130, yaw_deg=yaw, margin=0.1, focal_px=focal)
    for background in ((0.0, 0.0, 0.0), (0.5, 0.5, 0.5)):
        image, depth = render(meshes, cam, background=background, return_depth=True, samples=0, ambient=1.0)
        ours, our_depth = render_unlit(meshes, cam, background=background, return_depth=True)
        np.testing.assert_array_equal(ours, image)
        np.testing.assert_array_equal(our_depth, depth)
        np.testing.assert_array_equal(render_unlit(meshes, cam, background=background), image)
