"""Depth-only renders: :func:`mpeg4.render.render`'s depth image without its colours.

The software rasteriser (Mesa's llvmpipe) is bound by its per-triangle set-up, which grows
with the values it interpolates across each triangle: the full program interpolates nine
(normal, texture coordinates, colour, depth), this one the depth alone, with the same
arithmetic, so the depth images are the same (to the bit) for a third less of the work.
Visibility tests (:mod:`recon.texture.regions`) need nothing else.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np

from .errors import InputError
from .render import Camera, RenderMesh, _gl, _mesh_arrays, _read_depth

__all__ = ["render_depth"]

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


@functools.lru_cache(maxsize=1)
def _program(ctx):
    """The depth program, compiled once for the process's GL context."""
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
    import moderngl

    gl = _gl()
    ctx, prog = gl.ctx, _program(gl.ctx)
    w, h = int(camera.width), int(camera.height)
    if w > gl.max_size or h > gl.max_size:
        raise InputError(f"image size {w}x{h} exceeds the renderer's limit of {gl.max_size} pixels",
                         where="render_depth", fix="render a smaller image")
    view, proj = camera.gl_matrices()
    prog["mvp"].write((proj @ view).T.astype("f4").tobytes())  # GL wants column-major
    prog["view"].write(view.T.astype("f4").tobytes())
    checked = [a for k, m in enumerate(meshes) if (a := _mesh_arrays(m, k)) is not None]
    resources = [ctx.renderbuffer((w, h), 1, dtype="f4"), ctx.depth_renderbuffer((w, h))]
    try:
        fbo = ctx.framebuffer([resources[0]], resources[1])
        resources.append(fbo)
        fbo.use()
        ctx.viewport = (0, 0, w, h)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)  # both sides of every triangle, as render draws them
        for data, tri, _ in checked:
            vbo, ibo = ctx.buffer(np.ascontiguousarray(data[:, :3]).tobytes()), ctx.buffer(tri.tobytes())
            vao = ctx.vertex_array(prog, [(vbo, "3f", "in_pos")], index_buffer=ibo, index_element_size=4)
            resources += [vbo, ibo, vao]
            vao.render(moderngl.TRIANGLES)
        return _read_depth(fbo, 0, w, h)
    finally:
        for r in resources:
            r.release()
