"""Offscreen rendering of head meshes with OpenGL (moderngl on EGL; no display needed).

The camera model is explicit so that renders double as synthetic photos whose feature
point pixels are known: :meth:`Camera.project` gives the pixel at which :func:`render`
draws a 3D point, and :meth:`Camera.depth` the depth :func:`render` returns there.

Conventions
-----------
World
    Metres, MPEG-4 neutral frame: +x the face's own left, +y up, +z towards the viewer.
Camera frame
    The camera looks along its own −z axis with +x right and +y up (OpenGL's eye space).
    ``Camera.rotation`` takes world directions into that frame; its rows are the camera's
    right, up and backward directions written in world coordinates.
Pixels
    OpenCV's: x right, y down, the centre of the top-left pixel at (0, 0), so the image
    centre is ``((W - 1) / 2, (H - 1) / 2)``. World +y appears up in the image; seen from
    the front the face's left (+x) is on the image's right.
Depth
    Distance in front of the camera along its viewing axis (−z in the camera frame), in
    metres; not the Euclidean distance to the camera centre.

Shading is Lambert from one directional key light plus ambient, lit on both sides of every
triangle (meshes may be open or inconsistently wound), in linear RGB written straight to
8-bit: a plane facing a frontal light with colour ``c`` comes out as ``round(255 c)``.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .errors import InputError

__all__ = ["Camera", "RenderMesh", "RendererUnavailable", "look_rotation", "render", "vertex_normals"]

_EGL_PACKAGES = "libegl1 libgl1-mesa-dri libgbm1"


class RendererUnavailable(RuntimeError):
    """No offscreen OpenGL context could be made (EGL or Mesa missing)."""


def look_rotation(yaw_deg: float = 0.0, pitch_deg: float = 0.0) -> np.ndarray:
    """World → camera rotation for a camera looking at the origin from (yaw, pitch).

    Parameters
    ----------
    yaw_deg : float
        Rotation of the camera about world +y, degrees. 0 puts the camera on +z looking
        along −z (front view: the face's left, +x, on the image's right); 90 puts it on +x,
        where it sees the face's left side and the nose (+z) points to the image's left.
    pitch_deg : float
        Elevation, degrees; positive raises the camera so that it looks down.

    Returns
    -------
    (3, 3) float64
        Rows: camera right, up and backward (from the origin towards the camera) in world
        coordinates. Image "up" stays in the plane of world +y and the viewing direction.
    """
    y, p = np.radians(yaw_deg), np.radians(pitch_deg)
    back = np.array([np.sin(y) * np.cos(p), np.sin(p), np.cos(y) * np.cos(p)])
    right = np.array([np.cos(y), 0.0, -np.sin(y)])
    up = np.cross(back, right)
    return np.stack([right, up, back])


@dataclass
class Camera:
    """A pinhole (perspective) or orthographic camera.

    A world point ``X`` has camera coordinates ``c = rotation @ (X - centre)`` and depth
    ``-c_z``. Perspective: pixel ``(cx + f c_x / depth, cy - f c_y / depth)``.
    Orthographic: pixel ``(cx + s c_x, cy - s c_y)``. ``(cx, cy)`` is ``principal``.

    Attributes
    ----------
    width, height : int
        Image size, pixels.
    rotation : (3, 3) float64
        World → camera rotation (rows: camera right, up, backward, in world coordinates).
    centre : (3,) float64
        Camera position, metres, world frame.
    focal_px : float or None
        Perspective focal length in pixels (square pixels); None for orthographic.
    scale_px : float or None
        Orthographic scale, pixels per metre.
    principal : (cx, cy) or None
        Principal point in pixels (OpenCV convention); the image centre
        ``((W - 1) / 2, (H - 1) / 2)`` when None.
    near, far : float
        Clipping depths, metres. Orthographic cameras draw between them too, so the
        centre must stand in front of what is drawn.
    """

    width: int
    height: int
    rotation: np.ndarray
    centre: np.ndarray
    focal_px: float | None = None
    scale_px: float | None = None
    principal: tuple[float, float] | None = None
    near: float = 0.01
    far: float = 100.0

    def __post_init__(self):
        self.rotation = np.asarray(self.rotation, dtype=np.float64).reshape(3, 3)
        self.centre = np.asarray(self.centre, dtype=np.float64).reshape(3)
        if (self.focal_px is None) == (self.scale_px is None):
            raise InputError("a camera needs exactly one of focal_px and scale_px", where="Camera",
                             fix="give focal_px for a perspective camera or scale_px for an orthographic one")
        if int(self.width) < 1 or int(self.height) < 1:
            raise InputError(f"image size {self.width}x{self.height} is empty", where="Camera",
                             fix="give a width and height of at least one pixel")
        if self.principal is None:
            self.principal = ((self.width - 1) / 2.0, (self.height - 1) / 2.0)

    @property
    def perspective(self) -> bool:
        """True for a pinhole camera, False for an orthographic one."""
        return self.focal_px is not None

    @classmethod
    def fit(cls, points, width: int, height: int, yaw_deg: float = 0.0, pitch_deg: float = 0.0,
            margin: float = 0.1, focal_px: float | None = None) -> Camera:
        """A camera looking from direction (yaw, pitch) that frames ``points`` tightly.

        Every point projects inside the image less a border of ``margin`` times the image
        width (left and right) and height (top and bottom), and the framing is as tight as
        that allows: the points reach the border on at least one side.

        Parameters
        ----------
        points : (K, 3) float array
            What must be in view, metres.
        width, height : int
            Image size, pixels.
        yaw_deg, pitch_deg : float
            Viewing direction, degrees (see :func:`look_rotation`): yaw 0 is the front view,
            yaw 90 shows the face's left side with the nose pointing to the image's left,
            pitch > 0 looks down from above.
        margin : float
            Free border on each side as a fraction of the image size, in [0, 0.5).
        focal_px : float, optional
            Perspective focal length in pixels, the camera distance then chosen so that the
            points fit; orthographic when None, the scale chosen so that they fit.

        Returns
        -------
        Camera
            With the principal point at the image centre.
        """
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if not len(points) or not np.isfinite(points).all():
            raise InputError("no finite points to frame", where="Camera.fit",
                             fix="pass the (K, 3) vertices or feature points to keep in view")
        if not 0 <= margin < 0.5:
            raise InputError(f"margin {margin} is outside [0, 0.5)", where="Camera.fit",
                             fix="give the free border as a fraction of the image, e.g. 0.1")
        rot = look_rotation(yaw_deg, pitch_deg)
        local = points @ rot.T  # camera-aligned axes, origin unchanged
        lo, hi = local.min(axis=0), local.max(axis=0)
        size = max(float((hi - lo).max()), 1e-6)
        # Half the usable span around the image centre: pixel centres run from 0 to W-1,
        # but pixels cover [-0.5, W-0.5], and the border is taken from that.
        half = 0.5 * np.array([width, height], dtype=np.float64) * (1 - 2 * margin)
        if focal_px is None:
            scale = float(min(half / np.maximum(0.5 * (hi - lo)[:2], 1e-9)))
            mid = 0.5 * (lo + hi)
            stand = hi[2] + size + 1.0  # in front of everything, so nothing is clipped
            centre = rot.T @ np.array([mid[0], mid[1], stand])
            return cls(width, height, rot, centre, scale_px=scale, near=0.01,
                       far=stand - lo[2] + 10 * size + 1.0)
        f = float(focal_px)
        # Camera at (tx, ty, d) in the aligned frame. Point i fits horizontally when
        # |f (X_i - tx)| <= half_x (d - Z_i); a tx exists for every pair (i, j) iff
        # d >= f (X_i - X_j) / (2 half_x) + (Z_i + Z_j) / 2, whose maximum separates.
        ds = []
        for axis in (0, 1):
            a = f * local[:, axis] / (2 * half[axis])
            ds.append(float((a + local[:, 2] / 2).max() + (-a + local[:, 2] / 2).max()))
        d = max(ds + [hi[2] + 1e-3 * size])
        t = []
        for axis in (0, 1):
            reach = half[axis] * (d - local[:, 2]) / f
            t.append(0.5 * ((local[:, axis] - reach).max() + (local[:, axis] + reach).min()))
        centre = rot.T @ np.array([t[0], t[1], d])
        nearest, farthest = d - hi[2], d - lo[2]
        return cls(width, height, rot, centre, focal_px=f, near=max(1e-4, 0.25 * nearest),
                   far=2.0 * farthest + 10 * size + 1.0)

    def to_camera(self, points) -> np.ndarray:
        """(K, 3) float64 camera-frame coordinates (metres) of (K, 3) world points."""
        return (np.asarray(points, dtype=np.float64).reshape(-1, 3) - self.centre) @ self.rotation.T

    def towards(self, points) -> np.ndarray:
        """(K, 3) float64 unit directions from (K, 3) world points towards the camera: to
        its centre for a perspective camera, along its backward axis (the same for every
        point) for an orthographic one."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if not self.perspective:
            return np.tile(self.rotation[2], (len(p), 1))
        d = self.centre - p
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    def depth(self, points) -> np.ndarray:
        """(K,) float64 depth of (K, 3) world points along the viewing axis, metres.

        The quantity :func:`render` returns as depth; negative behind the camera.
        """
        return -self.to_camera(points)[:, 2]

    def project(self, points) -> np.ndarray:
        """(K, 2) float64 pixel positions (x right, y down, top-left pixel centre at (0, 0))
        of (K, 3) world points, metres."""
        c = self.to_camera(points)
        cx, cy = self.principal
        if self.perspective:
            s = self.focal_px / -c[:, 2]
            return np.stack([cx + c[:, 0] * s, cy - c[:, 1] * s], axis=1)
        return np.stack([cx + c[:, 0] * self.scale_px, cy - c[:, 1] * self.scale_px], axis=1)

    def unproject(self, pixels, depth) -> np.ndarray:
        """(K, 3) float64 world points (metres) at (K, 2) pixel positions and (K,) depths
        along the viewing axis: the inverse of :meth:`project` and :meth:`depth` (a depth
        render's pixels give the surface they show)."""
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        d = np.asarray(depth, dtype=np.float64).reshape(-1)
        cx, cy = self.principal
        s = d / self.focal_px if self.perspective else np.full_like(d, 1.0 / self.scale_px)
        r = self.rotation  # rows: the camera's axes in the world; summed by hand, as a (K, 3)
        # by (3, 3) product through matmul is several times slower for large K
        return (((px[:, 0] - cx) * s)[:, None] * r[0] - ((px[:, 1] - cy) * s)[:, None] * r[1]
                - d[:, None] * r[2] + self.centre)

    def gl_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """(4, 4) float64 view and projection matrices (row-major) matching :meth:`project`.

        GL rasterises pixel centres at normalised device x = (2 x + 1) / W − 1 with rows
        counted from the bottom, so pixel x maps to that and pixel y to
        1 − (2 y + 1) / H; the image is flipped to put row 0 on top afterwards.
        """
        view = np.eye(4)
        view[:3, :3] = self.rotation
        view[:3, 3] = -self.rotation @ self.centre
        w, h = self.width, self.height
        cx, cy = self.principal
        n, f = float(self.near), float(self.far)
        proj = np.zeros((4, 4))
        if self.perspective:
            fp = self.focal_px
            # clip w = -z_c; ndc_x = 2 fp x_c / (w_img -z_c) + (2 cx + 1) / w_img - 1.
            proj[0, 0] = 2 * fp / w
            proj[0, 2] = 1 - (2 * cx + 1) / w
            proj[1, 1] = 2 * fp / h
            proj[1, 2] = (2 * cy + 1) / h - 1
            proj[2, 2] = -(f + n) / (f - n)
            proj[2, 3] = -2 * f * n / (f - n)
            proj[3, 2] = -1.0
        else:
            s = self.scale_px
            proj[0, 0] = 2 * s / w
            proj[0, 3] = (2 * cx + 1) / w - 1
            proj[1, 1] = 2 * s / h
            proj[1, 3] = 1 - (2 * cy + 1) / h
            proj[2, 2] = -2 / (f - n)
            proj[2, 3] = -(f + n) / (f - n)
            proj[3, 3] = 1.0
        return view, proj


@dataclass
class RenderMesh:
    """A triangle mesh to draw.

    Attributes
    ----------
    vertices : (N, 3) float
        Positions, metres.
    triangles : (M, 3) int
        Vertex indices; winding does not matter.
    normals : (N, 3) float or None
        Vertex normals; area-weighted ones are computed when None.
    uv : (N, 2) float or None
        Texture coordinates, t = 0 at the bottom row of ``texture``.
    texture : (H, W, 3) uint8 or None
        Row 0 at the top. (H, W) grey and (H, W, 4) RGBA (alpha ignored) are accepted.
    colour : (3,) float
        Base RGB in [0, 1], multiplied with the texture when there is one.
    vertex_colours : (N, 3) float or None
        Per-vertex RGB in [0, 1], multiplied with the rest (heat maps).
    """

    vertices: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray | None = None
    uv: np.ndarray | None = None
    texture: np.ndarray | None = None
    colour: tuple = (0.8, 0.8, 0.8)
    vertex_colours: np.ndarray | None = None


def vertex_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Unit area-weighted vertex normals.

    Parameters
    ----------
    vertices : (N, 3) float
        Metres.
    triangles : (M, 3) int

    Returns
    -------
    (N, 3) float64
        The normalised sum of the cross products of the incident triangles (each twice the
        triangle's area times its unit normal); (0, 0, 1) for vertices with none.
    """
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    n = np.zeros((3, len(v)))
    if len(t):
        # The cross products component by component on contiguous rows (np.cross's terms).
        a = v[t[:, 0]]
        e1, e2 = (v[t[:, 1]] - a).T, (v[t[:, 2]] - a).T
        fn = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0])
        idx = t.ravel()
        for k in range(3):  # bincount is far faster than np.add.at on large meshes
            n[k] = np.bincount(idx, weights=np.repeat(fn[k], 3), minlength=len(v))
    n = n.T
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(norm > 0, n / np.where(norm > 0, norm, 1.0), [0.0, 0.0, 1.0])


_VERTEX = """
#version 330
uniform mat4 mvp;
uniform mat4 view;
in vec3 in_pos;
in vec3 in_normal;
in vec2 in_uv;
in vec3 in_colour;
out vec3 v_normal;
out vec2 v_uv;
out vec3 v_colour;
out float v_depth;
void main() {
    vec4 eye = view * vec4(in_pos, 1.0);
    // Eye-space depth is affine in the vertex position, so GL's perspective-correct
    // interpolation gives the exact depth of the surface at each pixel centre.
    v_depth = -eye.z;
    v_normal = mat3(view) * in_normal;
    v_uv = in_uv;
    v_colour = in_colour;
    gl_Position = mvp * vec4(in_pos, 1.0);
}
"""

_FRAGMENT = """
#version 330
uniform vec3 colour;
uniform bool textured;
uniform sampler2D tex;
uniform vec3 light_dir;
uniform float ambient;
in vec3 v_normal;
in vec2 v_uv;
in vec3 v_colour;
in float v_depth;
layout(location = 0) out vec4 f_colour;
layout(location = 1) out float f_depth;
void main() {
    vec3 n = normalize(v_normal);
    // Two-sided lighting: light whichever side faces the viewer.
    if (!gl_FrontFacing) n = -n;
    float diffuse = max(dot(n, light_dir), 0.0);
    vec3 base = colour * v_colour;
    if (textured) base *= texture(tex, v_uv).rgb;
    f_colour = vec4(base * (ambient + (1.0 - ambient) * diffuse), 1.0);
    f_depth = v_depth;
}
"""

class _GL:
    """The process's EGL context with the shader program compiled once."""

    def __init__(self):
        try:
            import moderngl
        except ImportError as e:
            raise RendererUnavailable(f"the Python package moderngl is missing ({e}); "
                                      "install the project with: bash install.sh") from e
        try:
            self.ctx = moderngl.create_standalone_context(backend="egl")
        except Exception as e:
            raise RendererUnavailable(
                f"cannot create an offscreen OpenGL context with EGL ({e}); install the Debian "
                f"packages {_EGL_PACKAGES} (sudo apt-get install {_EGL_PACKAGES}, or bash install.sh)") from e
        self.prog = self.ctx.program(vertex_shader=_VERTEX, fragment_shader=_FRAGMENT)
        self.max_samples = int(self.ctx.max_samples)
        self.max_size = int(self.ctx.info["GL_MAX_VIEWPORT_DIMS"][0])
        self.max_texture = int(self.ctx.info["GL_MAX_TEXTURE_SIZE"])
        self.renderer = str(self.ctx.info["GL_RENDERER"])


@functools.lru_cache(maxsize=1)
def _gl() -> _GL:
    # Failures raise and are therefore not cached: a later call tries again.
    return _GL()


def _mesh_arrays(m: RenderMesh, k: int):
    """Checked float32 interleaved vertex data, uint32 indices and the texture of mesh k."""
    where = f"render, mesh {k}"
    v = np.asarray(m.vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3:
        raise InputError(f"vertices have shape {v.shape}, expected (N, 3)", where=where)
    t = np.asarray(m.triangles)
    if t.size == 0:
        return None
    if t.ndim != 2 or t.shape[1] != 3 or not np.issubdtype(t.dtype, np.integer):
        raise InputError(f"triangles have shape {t.shape} and dtype {t.dtype}, expected (M, 3) integers",
                         where=where)
    if t.min() < 0 or t.max() >= len(v):
        raise InputError(f"triangle indices run from {t.min()} to {t.max()} but there are {len(v)} vertices",
                         where=where, fix="index vertices from 0 to N-1")

    def per_vertex(a, name, dim):
        a = np.asarray(a, dtype=np.float64)
        if a.shape != (len(v), dim):
            raise InputError(f"{name} have shape {a.shape}, expected ({len(v)}, {dim})", where=where)
        return a

    n = vertex_normals(v, t) if m.normals is None else per_vertex(m.normals, "normals", 3)
    textured = m.texture is not None and m.uv is not None
    uv = per_vertex(m.uv, "uv", 2) if textured else np.zeros((len(v), 2))
    vc = np.ones((len(v), 3)) if m.vertex_colours is None else per_vertex(m.vertex_colours, "vertex_colours", 3)
    data = np.ascontiguousarray(np.c_[v, n, uv, vc], dtype="f4")
    tex = None
    if textured:
        tex = np.asarray(m.texture)
        if tex.ndim == 2:
            tex = tex[:, :, None]
        if tex.ndim != 3 or tex.shape[2] not in (1, 3, 4) or tex.dtype != np.uint8:
            raise InputError(f"texture has shape {tex.shape} and dtype {tex.dtype}, expected (H, W, 3) uint8",
                             where=where)
        tex = np.broadcast_to(tex[:, :, :3], tex.shape[:2] + (3,))
    return data, np.ascontiguousarray(t, dtype="u4"), tex


def render(meshes: Sequence[RenderMesh], camera: Camera, background=(1.0, 1.0, 1.0),
           return_depth: bool = False, samples: int = 4, light=None, ambient: float = 0.35):
    """Draw meshes with Lambert shading, depth test and multisample antialiasing.

    Parameters
    ----------
    meshes : sequence of RenderMesh
    camera : Camera
        Image size, pose and intrinsics; a mesh point ``X`` is drawn at
        ``camera.project(X)``.
    background : (3,) float
        RGB in [0, 1].
    return_depth : bool
        Also return the depth image.
    samples : int
        Multisample count for the colour image (clamped to what the driver offers;
        0 or 1 for none).
    light : (3,) float, optional
        Direction *towards* the key light in the camera frame (x right, y up, z towards
        the viewer); by default (-0.3, 0.4, 1): over the viewer's left shoulder.
    ambient : float
        Ambient share in [0, 1]: a surface at angle θ to the light gets
        ``colour * (ambient + (1 - ambient) * max(cos θ, 0))``.

    Returns
    -------
    image : (H, W, 3) uint8
        RGB, row 0 at the top.
    depth : (H, W) float64, only with ``return_depth``
        Depth (:meth:`Camera.depth`) of the nearest surface at each pixel centre, metres;
        ``inf`` where nothing was drawn. From a single-sample pass, so never a blend of two
        surfaces.
    """
    import moderngl

    gl = _gl()
    ctx, prog = gl.ctx, gl.prog
    w, h = int(camera.width), int(camera.height)
    if w > gl.max_size or h > gl.max_size:
        raise InputError(f"image size {w}x{h} exceeds the renderer's limit of {gl.max_size} pixels",
                         where="render", fix="render a smaller image")
    samples = 0 if samples <= 1 else min(int(samples), gl.max_samples)
    view, proj = camera.gl_matrices()
    light = np.array([-0.3, 0.4, 1.0] if light is None else light, dtype=np.float64).reshape(3)
    if not np.linalg.norm(light) > 0:
        raise InputError("light direction is zero", where="render", fix="give a direction towards the light")
    light = light / np.linalg.norm(light)
    prog["mvp"].write((proj @ view).T.astype("f4").tobytes())  # GL wants column-major
    prog["view"].write(view.T.astype("f4").tobytes())
    prog["light_dir"].value = tuple(light)
    prog["ambient"].value = float(ambient)
    prog["tex"].value = 0

    checked = [(a, m) for k, m in enumerate(meshes) if (a := _mesh_arrays(m, k)) is not None]
    resources = []  # every GL object made here, released in `finally`
    try:
        draws = []
        for (data, tri, tex_img), m in checked:
            vbo = ctx.buffer(data.tobytes())
            ibo = ctx.buffer(tri.tobytes())
            resources += [vbo, ibo]
            vao = ctx.vertex_array(prog, [(vbo, "3f 3f 2f 3f", "in_pos", "in_normal", "in_uv", "in_colour")],
                                   index_buffer=ibo, index_element_size=4)
            resources.append(vao)
            tex = None
            if tex_img is not None:
                if max(tex_img.shape[:2]) > gl.max_texture:
                    raise InputError(f"texture of {tex_img.shape[1]}x{tex_img.shape[0]} exceeds the limit of "
                                     f"{gl.max_texture} pixels", where="render", fix="downsample the texture")
                img = np.ascontiguousarray(tex_img[::-1])  # GL's first row is the bottom one
                tex = ctx.texture((img.shape[1], img.shape[0]), 3, img.tobytes(), alignment=1)
                resources.append(tex)
                tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
                tex.build_mipmaps()
                tex.repeat_x = tex.repeat_y = False
            draws.append((vao, tex, tuple(float(c) for c in m.colour)))

        def draw(fbo):
            fbo.use()
            ctx.viewport = (0, 0, w, h)
            fbo.clear(*background, 1.0, depth=1.0)
            ctx.enable(moderngl.DEPTH_TEST)
            ctx.disable(moderngl.CULL_FACE)  # open and inconsistently wound meshes show both sides
            for vao, tex, colour in draws:
                prog["colour"].value = colour
                prog["textured"].value = tex is not None
                if tex is not None:
                    tex.use(0)
                vao.render(moderngl.TRIANGLES)

        if samples:
            ms_col = ctx.renderbuffer((w, h), 4, samples=samples)
            ms_z = ctx.depth_renderbuffer((w, h), samples=samples)
            ms = ctx.framebuffer([ms_col], ms_z)
            resolved_col = ctx.renderbuffer((w, h), 4)
            resolved = ctx.framebuffer([resolved_col])
            resources += [ms_col, ms_z, ms, resolved_col, resolved]
            draw(ms)
            ctx.copy_framebuffer(resolved, ms)  # averages the samples
            image = resolved.read(components=3, alignment=1)
            if not return_depth:
                return np.frombuffer(image, np.uint8).reshape(h, w, 3)[::-1].copy()
        # Single-sample pass: the colour when not multisampling, and the depth, so that a
        # pixel's depth is that of one surface rather than a blend of two.
        col = ctx.renderbuffer((w, h), 4)
        dep = ctx.renderbuffer((w, h), 1, dtype="f4")
        zbuf = ctx.depth_renderbuffer((w, h))
        single = ctx.framebuffer([col, dep], zbuf)
        resources += [col, dep, zbuf, single]
        draw(single)
        if not samples:
            image = single.read(components=3, alignment=1)
        image = np.frombuffer(image, np.uint8).reshape(h, w, 3)[::-1].copy()
        if not return_depth:
            return image
        return image, _read_depth(single, 1, w, h)
    finally:
        for r in resources:
            r.release()


def _read_depth(fbo, attachment: int, w: int, h: int) -> np.ndarray:
    """(H, W) float64 depth from a framebuffer's float attachment, inf where its depth
    buffer was not touched by any triangle; row 0 at the top."""
    depth = np.frombuffer(fbo.read(components=1, attachment=attachment, dtype="f4"), np.float32)
    depth = depth.reshape(h, w)[::-1].astype(np.float64)
    z = np.frombuffer(fbo.read(components=1, attachment=-1, dtype="f4"), np.float32).reshape(h, w)[::-1]
    depth[z >= 1.0] = np.inf
    return depth
