"""The renderer draws points where the camera model says, textures the right way up, and
returns depth consistent with Camera.depth."""

import numpy as np
import pytest

from mpeg4.render import Camera, RenderMesh, look_rotation, render


def _marker_meshes(cam, points, size_px=3.0):
    """A small camera-facing square centred on each point, size_px pixels across."""
    meshes = []
    right, up = cam.rotation[0], cam.rotation[1]
    for p in points:
        px_m = cam.depth(p[None])[0] / cam.focal_px if cam.perspective else 1.0 / cam.scale_px
        a = 0.5 * size_px * px_m
        v = np.array([p - a * right - a * up, p + a * right - a * up, p + a * right + a * up, p - a * right + a * up])
        meshes.append(RenderMesh(v, [[0, 1, 2], [0, 2, 3]], colour=(0.0, 0.0, 0.0)))
    return meshes


def _centroids(image, guesses, radius=6):
    dark = 255.0 - image.astype(float).mean(axis=2)
    out = []
    for gx, gy in guesses:
        x0, y0 = int(round(gx)), int(round(gy))
        win = dark[y0 - radius:y0 + radius + 1, x0 - radius:x0 + radius + 1]
        ys, xs = np.mgrid[y0 - radius:y0 + radius + 1, x0 - radius:x0 + radius + 1]
        out.append([(win * xs).sum() / win.sum(), (win * ys).sum() / win.sum()])
    return np.array(out)


@pytest.mark.parametrize("focal", [None, 900.0])
@pytest.mark.parametrize("yaw, pitch", [(0, 0), (90, 0), (35, 10)])
def test_projected_points_land_on_the_rendered_pixels(focal, yaw, pitch):
    rng = np.random.default_rng(int(yaw) + (0 if focal is None else 1))
    pts = rng.uniform(-0.08, 0.08, (12, 3))
    cam = Camera.fit(pts, 333, 411, yaw_deg=yaw, pitch_deg=pitch, margin=0.1, focal_px=focal)
    cam.principal = (cam.principal[0] + 7.3, cam.principal[1] - 4.6)  # off-centre principal point
    # Fixed markers must not overlap: render one point at a time in a few batches.
    err = []
    for batch in np.array_split(np.arange(len(pts)), 3):
        image = render(_marker_meshes(cam, pts[batch]), cam)
        expected = cam.project(pts[batch])
        err.append(np.linalg.norm(_centroids(image, expected) - expected, axis=1))
    assert np.concatenate(err).max() < 0.5


def test_camera_fit_keeps_points_inside_with_the_margin():
    pts = np.random.default_rng(3).normal(0, 0.1, (500, 3))
    for focal in (None, 1200.0):
        cam = Camera.fit(pts, 640, 480, yaw_deg=20, focal_px=focal, margin=0.1)
        uv = cam.project(pts)
        assert uv.min() >= 0.1 * 480 * 0.49
        assert (uv.max(axis=0) <= [640 * 0.91, 480 * 0.91]).all()


def test_front_view_shows_the_faces_left_on_the_right_and_up_up():
    rot = look_rotation(0, 0)
    cam = Camera(100, 100, rot, [0, 0, 2], scale_px=100.0)
    (xl, yl), (xu, yu) = cam.project(np.array([[0.1, 0, 0], [0, 0.1, 0]]))
    assert xl > 49.5 and yu < 49.5
    side = Camera(100, 100, look_rotation(90, 0), [2, 0, 0], scale_px=100.0)
    assert side.project(np.array([[0, 0, 0.1]]))[0, 0] < 49.5  # the nose points left


def test_texture_is_upright_and_depth_matches_the_camera():
    tex = np.zeros((8, 8, 3), np.uint8)
    tex[:4] = (255, 0, 0)  # top rows red
    tex[4:] = (0, 0, 255)
    quad = np.array([[-0.1, -0.1, 0], [0.1, -0.1, 0], [0.1, 0.1, 0], [-0.1, 0.1, 0]], float)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)  # t = 1 at the top
    cam = Camera.fit(quad, 200, 200, margin=0.2, focal_px=300.0)
    image, depth = render([RenderMesh(quad, [[0, 1, 2], [0, 2, 3]], uv=uv, texture=tex, colour=(1, 1, 1))], cam,
                          return_depth=True, ambient=1.0)
    top, bottom = image[70, 100].astype(int), image[130, 100].astype(int)
    assert top[0] > 200 and top[2] < 50 and bottom[2] > 200 and bottom[0] < 50
    # Depth at pixel centres inside the quad equals the camera's depth of the plane there.
    assert np.isinf(depth[2, 2])
    assert abs(depth[100, 100] - cam.depth(np.zeros((1, 3)))[0]) < 1e-4


def test_flat_lit_plane_has_its_colour_and_repeated_renders_keep_working():
    quad = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    cam = Camera(32, 32, look_rotation(0, 0), [0, 0, 3], scale_px=5.0)
    colour = (0.2, 0.6, 0.4)
    for _ in range(40):
        image = render([RenderMesh(quad, [[0, 1, 2], [0, 2, 3]], colour=colour)], cam, light=(0, 0, 1))
    np.testing.assert_allclose(image[16, 16] / 255.0, colour, atol=2 / 255)


def test_vertex_colours_multiply_the_base_colour():
    quad = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    cam = Camera(32, 32, look_rotation(0, 0), [0, 0, 3], scale_px=14.0)
    vc = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])  # red bottom, blue top
    image = render([RenderMesh(quad, [[0, 1, 2], [0, 2, 3]], colour=(1, 1, 1), vertex_colours=vc)], cam,
                   light=(0, 0, 1))
    assert image[27, 16, 0] > 200 and image[27, 16, 2] < 60  # bottom rows red
    assert image[4, 16, 2] > 200 and image[4, 16, 0] < 60  # top rows blue
