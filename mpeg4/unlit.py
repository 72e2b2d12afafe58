"""Unlit renders: :func:`mpeg4.render.render`'s depth image alone, or its image of meshes
that carry their colour per vertex and are not lit, from lean programs.

The software rasteriser (Mesa's llvmpipe) is bound by its per-triangle set-up, which grows
with the values it interpolates across each triangle: the full program interpolates nine
(normal, texture coordinates, colour, depth); :func:`render_depth` interpolates the depth
alone and :func:`render_unlit` the colour and the depth, with the same arithmetic, so
their images are the same to the bit for a third less of the work. What the texture's
visibility and de-lighting steps (:mod:`recon.texture`) render needs nothing else.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np

from .camera import Camera
from .errors import InputError
from .render import RenderMesh, _gl, _mesh_arrays, _read_depth

__all__ = ["render_depth", "render_unlit"]

_VERTEX = """
#version 330
uniform mat4 mvp;
uniform mat4 view;
in vec3 in_pos;
out float v_depth;
void main() {
    vec4 eye = view * vec4(in_pos, 1.0);
    v_depth = -eye.z;
    gl_Position = mvp * vec4(in_pos, 1.0);
}
"""

_FRAGMENT = """
#version 330
in float v_depth;
layout(location = 0) out float f_depth;
void main() {
    f_depth = v_depth;
}
"""


# Colour and depth: render's programs with ambient 1 draw colour x vertex colour exactly.
_COLOUR_VERTEX = """
#version 330
uniform mat4 mvp;
uniform mat4 view;
in vec3 in_pos;
in vec3 in_colour;
out vec3 v_colour;
out float v_depth;
void main() {
    vec4 eye = view * vec4(in_pos, 1.0);
    v_depth = -eye.z;
    v_colour = in_colour;
    gl_Position = mvp * vec4(in_pos, 1.0);
}
"""

_COLOUR_FRAGMENT = """
#version 330
uniform vec3 colour;
in vec3 v_colour;
in float v_depth;
layout(location = 0) out vec4 f_colour;
layout(location = 1) out float f_depth;
void main() {
    f_colour = vec4(colour * v_colour, 1.0);
    f_depth = v_depth;
}
"""


@functools.lru_cache(maxsize=2)
def _program(ctx, colour: bool):
    """The depth (or colour and depth) program, compiled once for the process's GL context."""
    if colour:
        return ctx.program(vertex_shader=_COLOUR_VERTEX, fragment_shader=_COLOUR_FRAGMENT)
    return ctx.program(vertex_shader=_VERTEX, fragment_shader=_FRAGMENT)


def render_depth(meshes: Sequence[RenderMesh], camera: Camera) -> np.ndarray:
    """Depth of the nearest surface at each pixel centre.

    Parameters
    ----------
    meshes : sequence of RenderMesh
        Only their vertices and triangles are used.
    camera : Camera

    Returns
    -------
    (H, W) float64
        Metres (:meth:`Camera.depth`), ``inf`` where nothing was drawn: what
        ``render(meshes, camera, return_depth=True)`` returns as its depth.
    """
    return _draw(meshes, camera, None, True)


def render_unlit(meshes: Sequence[RenderMesh], camera: Camera, background=(0.0, 0.0, 0.0),
                 return_depth: bool = False):
    """Meshes drawn in their colour times their vertex colours, unlit, without textures or
    multisampling: ``render(meshes, camera, background, return_depth, samples=0,
    ambient=1.0)`` for untextured meshes whose normals (ignored here) are never zero.

    Returns
    -------
    image : (H, W, 3) uint8
    depth : (H, W) float64, only with ``return_depth``
    """
    return _draw(meshes, camera, background, return_depth)


def _draw(meshes, camera: Camera, background, return_depth: bool):
    """Draw with the depth program (``background`` None) or the colour one."""
    import moderngl

    gl = _gl()
    colour = background is not None
    ctx, prog = gl.ctx, _program(gl.ctx, colour)
    w, h = int(camera.width), int(camera.height)
    if w > gl.max_size or h > gl.max_size:
        raise InputError(f"image size {w}x{h} exceeds the renderer's limit of {gl.max_size} pixels",
                         where="render", fix="render a smaller image")
    view, proj = camera.gl_matrices()
    prog["mvp"].write((proj @ view).T.astype("f4").tobytes())  # GL wants column-major
    prog["view"].write(view.T.astype("f4").tobytes())
    checked = [(a, m) for k, m in enumerate(meshes) if (a := _mesh_arrays(m, k)) is not None]
    targets = [ctx.renderbuffer((w, h), 4)] if colour else []
    resources = targets + [ctx.renderbuffer((w, h), 1, dtype="f4"), ctx.depth_renderbuffer((w, h))]
    try:
        fbo = ctx.framebuffer(resources[:-1], resources[-1])
        resources.append(fbo)
        fbo.use()
        ctx.viewport = (0, 0, w, h)
        fbo.clear(*(background or (0.0, 0.0, 0.0)), 1.0, depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)  # both sides of every triangle, as render draws them
        for (data, tri, _), m in checked:
            # render's interleaved layout (position, normal, uv, colour): only what is used.
            columns = [0, 1, 2, 8, 9, 10] if colour else [0, 1, 2]
            vbo, ibo = ctx.buffer(np.ascontiguousarray(data[:, columns]).tobytes()), ctx.buffer(tri.tobytes())
            attributes = ("in_pos", "in_colour") if colour else ("in_pos",)
            vao = ctx.vertex_array(prog, [(vbo, " ".join(["3f"] * len(attributes)), *attributes)], index_buffer=ibo,
                                   index_element_size=4)
            resources += [vbo, ibo, vao]
            if colour:
                prog["colour"].value = tuple(float(c) for c in m.colour)
            vao.render(moderngl.TRIANGLES)
        if not colour:
            return _read_depth(fbo, 0, w, h)
        image = np.frombuffer(fbo.read(components=3, alignment=1), np.uint8).reshape(h, w, 3)[::-1].copy()
        return (image, _read_depth(fbo, 1, w, h)) if return_depth else image
    finally:
        for r in resources:
            r.release()
