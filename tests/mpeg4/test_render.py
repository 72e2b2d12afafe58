"""The renderer draws points where the camera model says, textures the right way up, shades
predictably, returns depth consistent with Camera.depth, and keeps working without leaking."""

import numpy as np
import pytest

from mpeg4.camera import Camera, look_rotation
from mpeg4.errors import InputError
from mpeg4.render import (
    RendererUnavailable,
    RenderMesh,
    render,
    vertex_normals,
)

QUAD_TRIS = [[0, 1, 2], [0, 2, 3]]


def _marker_meshes(cam, points, size_px=3.0):
    """A dark camera-facing square centred on each point, size_px pixels across."""
    meshes = []
    right, up = cam.rotation[0], cam.rotation[1]
    for p in points:
        px_m = cam.depth(p[None])[0] / cam.focal_px if cam.perspective else 1.0 / cam.scale_px
        a = 0.5 * size_px * px_m
        v = np.array([p - a * right - a * up, p + a * right - a * up, p + a * right + a * up, p - a * right + a * up])
        meshes.append(RenderMesh(v, QUAD_TRIS, colour=(0.0, 0.0, 0.0)))
    return meshes


def _separated_batches(pixels, apart=16.0):
    """Split point indices into batches whose markers are `apart` pixels from each other."""
    batches = []
    for i, p in enumerate(pixels):
        for b in batches:
            if np.abs(pixels[b] - p).max(axis=1).min() > apart:
                b.append(i)
                break
        else:
            batches.append([i])
    return batches


def _centroids(image, guesses, radius=6):
    """Darkness-weighted centroid (x, y) in a window around each guess."""
    dark = 255.0 - image.astype(float).mean(axis=2)
    out = []
    for gx, gy in guesses:
        x0, y0 = round(gx), round(gy)
        win = dark[y0 - radius:y0 + radius + 1, x0 - radius:x0 + radius + 1]
        ys, xs = np.mgrid[y0 - radius:y0 + radius + 1, x0 - radius:x0 + radius + 1]
        out.append([(win * xs).sum() / win.sum(), (win * ys).sum() / win.sum()])
    return np.array(out)


@pytest.mark.parametrize("focal", [None, 900.0])
@pytest.mark.parametrize("yaw, pitch, size", [(0, 0, (333, 411)), (0, 10, (421, 287)),
                                              (90, 10, (333, 411)), (35, 10, (421, 287))])
def test_projected_points_land_on_the_rendered_pixels(focal, yaw, pitch, size):
    rng = np.random.default_rng(int(yaw) + int(pitch) + (0 if focal is None else 1))
    pts = rng.uniform(-0.08, 0.08, (12, 3))
    cam = Camera.fit(pts, *size, yaw_deg=yaw, pitch_deg=pitch, margin=0.1, focal_px=focal)
    cam.principal = (cam.principal[0] + 7.3, cam.principal[1] - 4.6)  # off-centre principal point
    err = []
    for batch in _separated_batches(cam.project(pts)):
        image = render(_marker_meshes(cam, pts[batch]), cam)
        expected = cam.project(pts[batch])
        err.append(np.linalg.norm(_centroids(image, expected) - expected, axis=1))
    # Multisampled edges put the centroid within ~0.15 px; a half-pixel slip would exceed 0.35.
    assert np.concatenate(err).max() < 0.3


def test_markers_land_without_multisampling_too():
    pts = np.random.default_rng(7).uniform(-0.08, 0.08, (12, 3))
    cam = Camera.fit(pts, 200, 150, yaw_deg=-30, pitch_deg=-5, margin=0.2, focal_px=400.0)
    for batch in _separated_batches(cam.project(pts)):
        image = render(_marker_meshes(cam, pts[batch], size_px=4.0), cam, samples=1)
        expected = cam.project(pts[batch])
        # Without antialiasing a 4-pixel square covers exactly the 4x4 pixel centres inside it,
        # so its centroid is within half a pixel of the point on each axis, never more.
        assert np.abs(_centroids(image, expected) - expected).max() <= 0.5 + 1e-9


def test_views_are_oriented_as_documented():
    front = Camera(100, 100, look_rotation(0, 0), [0, 0, 2], scale_px=100.0)
    (xl, yl), (xu, yu) = front.project(np.array([[0.1, 0, 0], [0, 0.1, 0]]))
    assert xl == pytest.approx(59.5) and yl == pytest.approx(49.5)  # the face's left on the right
    assert xu == pytest.approx(49.5) and yu == pytest.approx(39.5)  # world up is image up
    side = Camera(100, 100, look_rotation(90, 0), [2, 0, 0], scale_px=100.0)
    assert side.project(np.array([[0, 0, 0.1]]))[0, 0] == pytest.approx(39.5)  # the nose points left
    above = look_rotation(0, 30)
    assert above[2] @ [0, 1, 0] == pytest.approx(0.5)  # the camera sits above, looking down
    np.testing.assert_allclose(above @ above.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(above) == pytest.approx(1.0)


@pytest.mark.parametrize("focal", [None, 1200.0])
def test_camera_fit_frames_the_points_tightly_within_the_margin(focal):
    pts = np.random.default_rng(3).normal(0, 0.1, (500, 3))
    w, h, m = 640, 480, 0.1
    cam = Camera.fit(pts, w, h, yaw_deg=20, pitch_deg=10, focal_px=focal, margin=m)
    uv = cam.project(pts)
    lo = np.array([-0.5 + m * w, -0.5 + m * h])
    hi = np.array([w - 0.5 - m * w, h - 0.5 - m * h])
    slack = np.r_[uv.min(axis=0) - lo, hi - uv.max(axis=0)]  # left, top, right, bottom
    assert slack.min() > -1e-6  # every point inside the margin
    assert slack.min() < 1e-6  # and touching it: as large as the margin allows
    assert (cam.depth(pts) > cam.near).all() and (cam.depth(pts) < cam.far).all()


def _plane_depth(cam, p0, normal):
    """Depth at every pixel centre of the plane through p0 with the given normal."""
    ys, xs = np.mgrid[0:cam.height, 0:cam.width].astype(float)
    cx, cy = cam.principal
    if cam.perspective:
        d_cam = np.stack([(xs - cx) / cam.focal_px, -(ys - cy) / cam.focal_px, -np.ones_like(xs)], -1)
        origin = np.broadcast_to(cam.centre, d_cam.shape)
    else:
        off = np.stack([(xs - cx) / cam.scale_px, -(ys - cy) / cam.scale_px, np.zeros_like(xs)], -1)
        origin = cam.centre + off @ cam.rotation
        d_cam = np.broadcast_to([0.0, 0.0, -1.0], off.shape)
    d = d_cam @ cam.rotation  # world directions whose depth grows by 1 per unit step
    t = ((p0 - origin) @ normal) / (d @ normal)
    return t


def _inset(poly, width, height):
    """(H, W) signed distance of each pixel centre inside a convex polygon, pixels."""
    ys, xs = np.mgrid[0:height, 0:width].astype(float)
    (ax, ay), (bx, by) = poly[1] - poly[0], poly[2] - poly[0]
    orient = np.sign(ax * by - ay * bx)
    dist = np.full(xs.shape, np.inf)
    for a, b in zip(poly, np.roll(poly, -1, axis=0)):
        e = b - a
        dist = np.minimum(dist, orient * (e[0] * (ys - a[1]) - e[1] * (xs - a[0])) / np.linalg.norm(e))
    return dist


@pytest.mark.parametrize("focal", [None, 500.0])
def test_depth_matches_camera_depth_on_a_tilted_plane(focal):
    # A quad tilted 40 degrees about a slanted axis, seen from the three-quarter view.
    tilt = np.radians(40)
    axis_u = np.array([1.0, 0.3, 0.0]) / np.linalg.norm([1.0, 0.3, 0.0])
    normal = np.array([0.0, 0.0, 1.0]) * np.cos(tilt) + np.cross(axis_u, [0, 0, 1.0]) * np.sin(tilt)
    axis_v = np.cross(normal, axis_u)
    p0 = np.array([0.01, -0.02, 0.03])
    quad = p0 + 0.1 * np.array([-axis_u - axis_v, axis_u - axis_v, axis_u + axis_v, -axis_u + axis_v])
    cam = Camera.fit(quad, 240, 200, yaw_deg=35, pitch_deg=10, margin=0.15, focal_px=focal)
    image, depth = render([RenderMesh(quad, QUAD_TRIS)], cam, return_depth=True)
    truth = _plane_depth(cam, p0, normal)
    inset = _inset(cam.project(quad), cam.width, cam.height)
    inside = inset > 1.0  # pixel centres more than a pixel inside the projected quad
    assert inside.sum() > 5000
    assert np.abs(depth[inside] - truth[inside]).max() < 1e-4
    # Each pixel's depth gives back a point of the plane.
    ys, xs = np.nonzero(inside)
    on = cam.unproject(np.c_[xs, ys], depth[ys, xs])
    assert np.abs((on - p0) @ normal).max() < 1e-4
    # Nothing drawn beyond the antialiased rim: depth inf, background white.
    outer = inset < -1.0
    assert outer.sum() > 5000
    assert np.isinf(depth[outer]).all() and (image[outer] == 255).all()


@pytest.mark.parametrize("focal", [None, 500.0])
def test_unproject_inverts_project_and_depth(focal):
    rng = np.random.default_rng(4)
    points = rng.normal(0, 0.05, (50, 3))
    cam = Camera.fit(points, 320, 240, yaw_deg=-60, pitch_deg=-15, focal_px=focal)
    back = cam.unproject(cam.project(points), cam.depth(points))
    np.testing.assert_allclose(back, points, atol=1e-12)


def test_nearer_surface_wins_whatever_the_drawing_order():
    quad = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    cam = Camera(40, 30, look_rotation(0, 0), [0, 0, 3], focal_px=30.0)
    near = RenderMesh(quad + [0, 0, 0.5], QUAD_TRIS, colour=(1, 0, 0))
    far = RenderMesh(quad, QUAD_TRIS, colour=(0, 0, 1))
    for order in ([near, far], [far, near]):
        image, depth = render(order, cam, return_depth=True, light=(0, 0, 1))
        assert tuple(image[15, 20]) == (255, 0, 0)
        assert depth[15, 20] == pytest.approx(2.5, abs=1e-5)


@pytest.mark.parametrize("focal", [None, 300.0])
def test_texture_is_upright_and_not_mirrored(focal):
    tex = np.zeros((8, 8, 3), np.uint8)
    tex[:4] = (255, 0, 0)  # top rows red
    tex[4:] = (0, 0, 255)  # bottom rows blue
    tex[:, :2] = (0, 255, 0)  # left columns green
    quad = np.array([[-0.1, -0.1, 0], [0.1, -0.1, 0], [0.1, 0.1, 0], [-0.1, 0.1, 0]], float)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)  # t = 1 at the top, s = 0 at the face's right
    cam = Camera.fit(quad, 200, 160, margin=0.2, focal_px=focal)
    image = render([RenderMesh(quad, QUAD_TRIS, uv=uv, texture=tex, colour=(1, 1, 1))], cam, ambient=1.0)
    (x0, y0), (x1, y1) = cam.project(quad[[0, 2]])  # bottom-left and top-right corners in the image
    assert x0 < x1 and y0 > y1

    def at(fx, fy):  # the pixel at fractions (fx, fy) of the quad from its top-left corner
        return image[round(y1 + fy * (y0 - y1)), round(x0 + fx * (x1 - x0))].astype(int)

    assert tuple(at(0.6, 0.25)) == (255, 0, 0)  # red above
    assert tuple(at(0.6, 0.75)) == (0, 0, 255)  # blue below
    assert tuple(at(0.1, 0.5)) == (0, 255, 0)  # column 0 of the texture on the image's left


def test_flat_lit_plane_has_its_colour_on_both_sides():
    quad = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    cam = Camera(32, 32, look_rotation(0, 0), [0, 0, 3], scale_px=5.0)
    c = np.array([0.2, 0.6, 0.4])
    for tris in (QUAD_TRIS, [[0, 2, 1], [0, 3, 2]]):  # both windings: lighting is two-sided
        image = render([RenderMesh(quad, tris, colour=tuple(c))], cam, light=(0, 0, 1))
        np.testing.assert_allclose(image[16, 16] / 255.0, c, atol=1 / 255)
    # Lambert: the default light is off-axis, so a facing plane gets ambient + (1 - a) cos.
    image = render([RenderMesh(quad, QUAD_TRIS, colour=tuple(c))], cam, ambient=0.35)
    cos = 1 / np.linalg.norm([-0.3, 0.4, 1.0])
    np.testing.assert_allclose(image[16, 16] / 255.0, c * (0.35 + 0.65 * cos), atol=1 / 255)
    # A plane turned 60 degrees away from a frontal light gets half the diffuse share.
    r = np.radians(60)
    turned = quad @ np.array([[np.cos(r), 0, -np.sin(r)], [0, 1, 0], [np.sin(r), 0, np.cos(r)]]).T
    image = render([RenderMesh(turned, QUAD_TRIS, colour=tuple(c))], cam, light=(0, 0, 1), ambient=0.2)
    np.testing.assert_allclose(image[16, 16] / 255.0, c * (0.2 + 0.8 * 0.5), atol=1 / 255)


def test_vertex_colours_multiply_the_base_colour():
    quad = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    cam = Camera(32, 32, look_rotation(0, 0), [0, 0, 3], scale_px=14.0)
    vc = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])  # red bottom, blue top
    image = render([RenderMesh(quad, QUAD_TRIS, colour=(1, 1, 1), vertex_colours=vc)], cam, light=(0, 0, 1))
    assert image[27, 16, 0] > 200 and image[27, 16, 2] < 60  # bottom rows red
    assert image[4, 16, 2] > 200 and image[4, 16, 0] < 60  # top rows blue


def test_vertex_normals_are_unit_and_area_weighted():
    # A tent: two faces meeting at a ridge; the ridge normal leans towards the larger face.
    v = np.array([[0, 0, 0], [0, 1, 0], [2, 0, 1], [-1, 0, 1.0]])
    n = vertex_normals(v, [[0, 1, 2], [1, 0, 3]])
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0)
    f1 = np.cross(v[1] - v[0], v[2] - v[0])
    f2 = np.cross(v[0] - v[1], v[3] - v[1])
    np.testing.assert_allclose(n[0], (f1 + f2) / np.linalg.norm(f1 + f2))


def _rss_mb():
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS")) / 1024


def test_repeated_renders_do_not_leak_and_stay_identical():
    # A textured wavy sheet of 2,000 triangles.
    gy, gx = np.mgrid[0:26, 0:41] / np.array([25.0, 40.0])[:, None, None]  # (26, 41) grid in [0, 1]
    v = np.c_[0.2 * gx.ravel() - 0.1, 0.16 * gy.ravel() - 0.08, 0.02 * np.sin(8 * gx.ravel()) * np.cos(6 * gy.ravel())]
    quads = (np.arange(25)[:, None] * 41 + np.arange(40)).ravel()
    tris = np.r_[np.c_[quads, quads + 1, quads + 42], np.c_[quads, quads + 42, quads + 41]]
    tex = np.random.default_rng(0).integers(0, 256, (64, 64, 3), dtype=np.uint8)
    mesh = RenderMesh(v, tris, uv=np.c_[gx.ravel(), gy.ravel()], texture=tex)
    cam = Camera.fit(v, 160, 200, yaw_deg=20, focal_px=300.0)
    first, first_depth = render([mesh], cam, return_depth=True)
    for _ in range(5):
        render([mesh], cam, return_depth=True)
    before = _rss_mb()
    for _ in range(50):
        image, depth = render([mesh], cam, return_depth=True)
    assert _rss_mb() - before < 4.0
    assert np.array_equal(image, first) and np.array_equal(depth, first_depth)


def test_bad_meshes_and_a_missing_egl_give_clear_errors(monkeypatch):
    cam = Camera(10, 10, np.eye(3), [0, 0, 1], scale_px=1.0)
    with pytest.raises(InputError, match="mesh 0: triangle indices run from 0 to 3 but there are 3"):
        render([RenderMesh(np.zeros((3, 3)), [[0, 1, 3]])], cam)
    with pytest.raises(InputError, match="uv have shape"):
        render([RenderMesh(np.zeros((3, 3)), [[0, 1, 2]], uv=np.zeros((2, 2)), texture=np.zeros((2, 2, 3), np.uint8))],
               cam)
    with pytest.raises(InputError, match="exactly one of focal_px and scale_px"):
        Camera(10, 10, np.eye(3), [0, 0, 1])
    import moderngl

    from mpeg4 import render as render_module

    def no_egl(**kwargs):
        raise moderngl.Error("eglGetDisplay failed")

    monkeypatch.setattr(moderngl, "create_standalone_context", no_egl)
    with pytest.raises(RendererUnavailable, match="libegl1 libgl1-mesa-dri libgbm1"):
        render_module._GL()
