"""Offscreen rendering of head meshes with OpenGL (moderngl on EGL; no display needed).

:func:`render` draws a 3D point at the pixel :meth:`mpeg4.camera.Camera.project` gives and
returns there the depth :meth:`mpeg4.camera.Camera.depth` gives, so that renders double as
synthetic photos whose feature point pixels are known (the conventions: :mod:`mpeg4.camera`).

Shading is Lambert from one directional key light plus ambient, lit on both sides of every
triangle (meshes may be open or inconsistently wound), in linear RGB written straight to
8-bit: a plane facing a frontal light with colour ``c`` comes out as ``round(255 c)``.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .camera import Camera
from .errors import InputError

__all__ = ["RenderMesh", "RendererUnavailable", "render", "vertex_normals"]

_EGL_PACKAGES = "libegl1 libgl1-mesa-dri libgbm1"


class RendererUnavailable(RuntimeError):
    """No offscreen OpenGL context could be made (EGL or Mesa missing)."""


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
