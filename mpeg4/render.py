"""Offscreen rendering of head meshes with OpenGL (moderngl on EGL; no display needed).

The camera model is explicit so that renders double as synthetic photos whose feature
point pixels are known: :meth:`Camera.project` gives the pixel at which :func:`render`
draws a 3D point, in OpenCV's convention (x right, y down, the centre of the top-left pixel
at (0, 0)).

Camera frame: the camera looks along its −z axis with +y up and +x right (OpenGL's eye
space). ``Camera.rotation`` takes world directions into that frame. Orthographic cameras
have a scale in pixels per metre; perspective ones a focal length in pixels.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["Camera", "RenderMesh", "render", "look_rotation"]


def look_rotation(yaw_deg: float = 0.0, pitch_deg: float = 0.0) -> np.ndarray:
    """(3, 3) world → camera rotation for a camera orbiting the origin.

    Yaw 0 puts the camera on +z looking along −z (a front view: the face's left, +x, is on
    the image's right). Yaw 90 puts it on +x (it sees the face's left side; the nose points
    to the image's left). Positive pitch raises the camera so it looks down.
    """
    y, p = np.radians(yaw_deg), np.radians(pitch_deg)
    # Camera position direction (unit vector from origin to camera).
    back = np.array([np.sin(y) * np.cos(p), np.sin(p), np.cos(y) * np.cos(p)])
    right = np.array([np.cos(y), 0.0, -np.sin(y)])
    up = np.cross(back, right)
    return np.stack([right, up, back])


@dataclass
class Camera:
    """A pinhole or orthographic camera.

    Attributes
    ----------
    width, height : int
        Image size, pixels.
    rotation : (3, 3) float64
        World → camera rotation (rows: camera right, up, backwards, in world coordinates).
    centre : (3,) float64
        Camera position, metres.
    focal_px : float or None
        Perspective focal length in pixels; None for orthographic.
    scale_px : float or None
        Orthographic scale, pixels per metre.
    principal : (cx, cy) or None
        Principal point in pixels; the image centre ``((W-1)/2, (H-1)/2)`` by default.
    near, far : float
        Clipping distances along the viewing axis, metres.
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
            raise ValueError("give exactly one of focal_px (perspective) and scale_px (orthographic)")
        if self.principal is None:
            self.principal = ((self.width - 1) / 2.0, (self.height - 1) / 2.0)

    @property
    def perspective(self) -> bool:
        return self.focal_px is not None

    @classmethod
    def fit(cls, points, width: int, height: int, yaw_deg: float = 0.0, pitch_deg: float = 0.0,
            margin: float = 0.1, focal_px: float | None = None) -> Camera:
        """A camera looking at ``points`` from direction (yaw, pitch) that frames them.

        Parameters
        ----------
        points : (K, 3) float array
            What must be in view, metres.
        width, height : int
            Image size.
        yaw_deg, pitch_deg : float
            Viewing direction (see :func:`look_rotation`).
        margin : float
            Free border on each side, as a fraction of the image size.
        focal_px : float, optional
            Perspective focal length in pixels; orthographic when None.
        """
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        rot = look_rotation(yaw_deg, pitch_deg)
        local = points @ rot.T
        lo, hi = local.min(axis=0), local.max(axis=0)
        mid = 0.5 * (lo + hi)
        extent = np.maximum(hi - lo, 1e-9)
        usable = np.array([width, height]) * (1 - 2 * margin)
        if focal_px is None:
            scale = float(min(usable / extent[:2]))
            depth = extent[2] + 1.0
            centre = rot.T @ np.array([mid[0], mid[1], hi[2] + depth])
            return cls(width, height, rot, centre, scale_px=scale)
        # Distance so that the nearest face of the box still fits the usable area.
        dist = float(max(focal_px * extent[:2] / usable)) + extent[2] / 2
        centre = rot.T @ np.array([mid[0], mid[1], mid[2] + dist])
        cam = cls(width, height, rot, centre, focal_px=focal_px, near=max(1e-3, 0.05 * dist),
                  far=dist + 10 * extent[2] + 1.0)
        # Shrink-wrap: if projected points still overflow (perspective growth), back off.
        for _ in range(20):
            uv = cam.project(points)
            over = max((-uv.min(axis=0) / np.array([width, height])).max(),
                       ((uv.max(axis=0) - [width - 1, height - 1]) / np.array([width, height])).max())
            if over <= -margin * 0.5:
                break
            dist *= 1.1
            cam.centre = rot.T @ np.array([mid[0], mid[1], mid[2] + dist])
            cam.far = dist + 10 * extent[2] + 1.0
        return cam

    def to_camera(self, points) -> np.ndarray:
        """(K, 3) points in the camera frame (metres)."""
        return (np.asarray(points, dtype=np.float64).reshape(-1, 3) - self.centre) @ self.rotation.T

    def depth(self, points) -> np.ndarray:
        """(K,) distance in front of the camera along its viewing axis, metres."""
        return -self.to_camera(points)[:, 2]

    def project(self, points) -> np.ndarray:
        """(K, 2) float pixel positions (x right, y down, top-left pixel centre at (0, 0))."""
        c = self.to_camera(points)
        cx, cy = self.principal
        if self.perspective:
            s = self.focal_px / -c[:, 2]
            return np.c_[cx + c[:, 0] * s, cy - c[:, 1] * s]
        return np.c_[cx + c[:, 0] * self.scale_px, cy - c[:, 1] * self.scale_px]

    def gl_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """(4, 4) view and projection matrices (row-major) matching :meth:`project`.

        Pixel x (OpenCV) and normalised device x relate by ``ndc = (2 x + 1) / W − 1``
        (pixel centres), and y is flipped.
        """
        view = np.eye(4)
        view[:3, :3] = self.rotation
        view[:3, 3] = -self.rotation @ self.centre
        w, h = self.width, self.height
        cx, cy = self.principal
        n, f = self.near, self.far
        proj = np.zeros((4, 4))
        if self.perspective:
            fx = fy = self.focal_px
            proj[0, 0] = 2 * fx / w
            proj[0, 2] = 1 - (2 * cx + 1) / w  # times -z_c: ndc_x = 2 fx x/(-z w) + (2cx+1)/w - 1
            proj[1, 1] = 2 * fy / h
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
        Metres.
    triangles : (M, 3) int
    normals : (N, 3) float or None
        Computed (area-weighted) when None.
    uv : (N, 2) float or None
        Texture coordinates, t = 0 at the bottom row of ``texture``.
    texture : (H, W, 3) uint8 or None
        Row 0 at the top.
    colour : (3,) float
        Base colour in [0, 1], multiplied with the texture.
    vertex_colours : (N, 3) float or None
        Per-vertex colours in [0, 1], multiplied with the rest (heat maps).
    """

    vertices: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray | None = None
    uv: np.ndarray | None = None
    texture: np.ndarray | None = None
    colour: tuple = (0.8, 0.8, 0.8)
    vertex_colours: np.ndarray | None = None


def vertex_normals(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(N, 3) unit area-weighted vertex normals; (0, 0, 1) where undefined."""
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    n = np.zeros_like(v)
    if len(t):
        fn = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
        for k in range(3):
            np.add.at(n, t[:, k], fn)
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    out = np.where(norm > 0, n / np.where(norm > 0, norm, 1), [0.0, 0.0, 1.0])
    return out


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
    v_colour = in_colour;
    vec4 eye = view * vec4(in_pos, 1.0);
    v_depth = -eye.z;
    v_normal = mat3(view) * in_normal;
    v_uv = in_uv;
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
uniform bool perspective;
in vec3 v_normal;
in vec2 v_uv;
in vec3 v_colour;
in float v_depth;
layout(location = 0) out vec4 f_colour;
layout(location = 1) out float f_depth;
void main() {
    vec3 n = normalize(v_normal);
    // Two-sided: light the side that faces the viewer.
    if (!gl_FrontFacing) n = -n;
    float diffuse = max(dot(n, light_dir), 0.0);
    vec3 base = colour * v_colour;
    if (textured) base *= texture(tex, v_uv).rgb;
    f_colour = vec4(base * (ambient + (1.0 - ambient) * diffuse), 1.0);
    f_depth = v_depth;
}
"""


class _GL:
    """One EGL context per process, with the shader program compiled once."""

    def __init__(self):
        import moderngl

        try:
            self.ctx = moderngl.create_standalone_context(backend="egl")
        except Exception as e:  # the message names what is missing
            raise RuntimeError("cannot create an offscreen OpenGL context (EGL): "
                               f"{e}. Install the Debian packages libegl1 libgl1-mesa-dri libgbm1 "
                               "(bash install.sh does).") from e
        self.prog = self.ctx.program(vertex_shader=_VERTEX, fragment_shader=_FRAGMENT)


@functools.lru_cache(maxsize=1)
def _gl() -> _GL:
    return _GL()


def render(meshes: Sequence[RenderMesh], camera: Camera, background=(1.0, 1.0, 1.0),
           return_depth: bool = False, samples: int = 4, light=None, ambient: float = 0.35):
    """Draw meshes with Lambert shading from a headlight-like key light.

    Parameters
    ----------
    meshes : sequence of RenderMesh
    camera : Camera
    background : (3,) float
        RGB in [0, 1].
    return_depth : bool
        Also return the depth image.
    samples : int
        Multisampling (antialiasing) samples for the colour image.
    light : (3,) float, optional
        Direction *towards* the light in the camera frame; by default from the upper left
        behind the viewer.
    ambient : float
        Share of unshadowed ambient light.

    Returns
    -------
    image : (H, W, 3) uint8
        Row 0 at the top.
    depth : (H, W) float64, only with ``return_depth``
        Distance along the viewing axis at each pixel centre (metres); inf where empty.
    """
    import moderngl

    gl = _gl()
    ctx, prog = gl.ctx, gl.prog
    w, h = int(camera.width), int(camera.height)
    view, proj = camera.gl_matrices()
    mvp = proj @ view
    light = np.array([-0.3, 0.4, 1.0] if light is None else light, dtype=np.float64)
    light /= np.linalg.norm(light)
    prog["mvp"].write(mvp.T.astype("f4").tobytes())  # GL is column-major
    prog["view"].write(view.T.astype("f4").tobytes())
    prog["light_dir"].value = tuple(light)
    prog["ambient"].value = float(ambient)
    prog["tex"].value = 0

    resources = []
    vaos = []
    try:
        for m in meshes:
            v = np.asarray(m.vertices, dtype=np.float64).reshape(-1, 3)
            t = np.asarray(m.triangles, dtype=np.int64).reshape(-1, 3)
            if not len(t):
                continue
            n = vertex_normals(v, t) if m.normals is None else np.asarray(m.normals, dtype=np.float64)
            textured = m.texture is not None and m.uv is not None
            uv = np.asarray(m.uv, dtype=np.float64) if textured else np.zeros((len(v), 2))
            vc = np.ones((len(v), 3)) if m.vertex_colours is None else np.asarray(m.vertex_colours, dtype=np.float64)
            data = np.c_[v, n, uv, vc].astype("f4")
            vbo = ctx.buffer(data.tobytes())
            ibo = ctx.buffer(t.astype("u4").tobytes())
            resources += [vbo, ibo]
            vao = ctx.vertex_array(prog, [(vbo, "3f 3f 2f 3f", "in_pos", "in_normal", "in_uv", "in_colour")],
                                   index_buffer=ibo,
                                   index_element_size=4)
            resources.append(vao)
            tex = None
            if textured:
                img = np.ascontiguousarray(np.asarray(m.texture, dtype=np.uint8)[::-1, :, :3])  # GL rows bottom-up
                tex = ctx.texture((img.shape[1], img.shape[0]), 3, img.tobytes(), alignment=1)
                tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
                tex.build_mipmaps()
                tex.repeat_x = tex.repeat_y = False
                resources.append(tex)
            vaos.append((vao, tex, tuple(float(c) for c in m.colour)))

        def draw(fbo):
            fbo.use()
            ctx.viewport = (0, 0, w, h)
            fbo.clear(*background, 1.0)
            ctx.enable(moderngl.DEPTH_TEST)
            ctx.disable(moderngl.CULL_FACE)
            for vao, tex, colour in vaos:
                prog["colour"].value = colour
                prog["textured"].value = tex is not None
                if tex is not None:
                    tex.use(0)
                vao.render(moderngl.TRIANGLES)

        # Colour, multisampled, resolved into a plain framebuffer.
        ms_col = ctx.renderbuffer((w, h), 4, samples=samples)
        ms_dep_tex = ctx.renderbuffer((w, h), 1, samples=samples, dtype="f4")
        ms_depth = ctx.depth_renderbuffer((w, h), samples=samples)
        ms = ctx.framebuffer([ms_col, ms_dep_tex], ms_depth)
        resources += [ms_col, ms_dep_tex, ms_depth, ms]
        draw(ms)
        col = ctx.renderbuffer((w, h), 4)
        col2 = ctx.renderbuffer((w, h), 1, dtype="f4")
        out = ctx.framebuffer([col, col2])
        resources += [col, col2, out]
        ctx.copy_framebuffer(out, ms)
        image = np.frombuffer(out.read(components=3, alignment=1), np.uint8).reshape(h, w, 3)[::-1].copy()
        if not return_depth:
            return image
        # Depth from a single-sample pass, so each pixel is one surface, not a blend.
        dcol = ctx.renderbuffer((w, h), 4)
        dval = ctx.renderbuffer((w, h), 1, dtype="f4")
        ddep = ctx.depth_renderbuffer((w, h))
        dfbo = ctx.framebuffer([dcol, dval], ddep)
        resources += [dcol, dval, ddep, dfbo]
        draw(dfbo)
        cleared = np.frombuffer(dfbo.read(components=1, attachment=1, dtype="f4"), np.float32)
        depth_buf = np.frombuffer(dfbo.read(components=1, attachment=-1, dtype="f4"), np.float32).reshape(h, w)[::-1]
        depth = cleared.reshape(h, w)[::-1].astype(np.float64)
        depth[depth_buf >= 1.0] = np.inf
        return image, depth
    finally:
        for r in resources:
            r.release()
