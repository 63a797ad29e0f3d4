"""Real OpenGL (moderngl on Mesa llvmpipe, headless EGL) rendering the same scene, for
conformance tests and benchmarks. Writes gl_PrimitiveID + 1 to an integer attachment and
gl_FragCoord.z (the fragment's window depth, before any depth-buffer quantisation) to a
float attachment; the depth test itself runs on the framebuffer's depth attachment."""

from __future__ import annotations

import numpy as np

import hsr

_VS = """#version 330
uniform mat4 view_proj;
in vec3 pos_world;
void main() { gl_Position = view_proj * vec4(pos_world, 1.0); }
"""
_FS = """#version 330
layout(location = 0) out int face;
layout(location = 1) out float depth;
void main() { face = gl_PrimitiveID + 1; depth = gl_FragCoord.z; }
"""

_DEPTH_FUNCS = {"never": "0", "less": "<", "equal": "==", "lequal": "<=", "greater": ">",
                "notequal": "!=", "gequal": ">=", "always": "1"}


def create_context():
    import moderngl

    return moderngl.create_context(standalone=True, backend="egl")


class GLRenderer:
    """Draws world-space triangles with a view-projection matrix, as OpenGL does."""

    def __init__(self, ctx=None):
        self.ctx = ctx or create_context()
        self.prog = self.ctx.program(vertex_shader=_VS, fragment_shader=_FS)
        self._fbo = None
        self._size = None

    def _framebuffer(self, width, height):
        if self._size != (width, height):
            if self._fbo is not None:
                self._fbo.release()
            ctx = self.ctx
            self._face = ctx.renderbuffer((width, height), components=1, dtype="i4")
            self._depth_color = ctx.renderbuffer((width, height), components=1, dtype="f4")
            self._depth = ctx.depth_renderbuffer((width, height))
            self._fbo = ctx.framebuffer([self._face, self._depth_color], self._depth)
            self._size = (width, height)
        return self._fbo

    def upload(self, tri_world):
        """Upload (F, 3, 3) world-space triangles; returns a vertex array to draw."""
        data = np.ascontiguousarray(tri_world, dtype="f4").reshape(-1, 3)
        vbo = self.ctx.buffer(data.tobytes())
        return self.ctx.vertex_array(self.prog, [(vbo, "3f", "pos_world")]), vbo

    def render(self, tri_world, view_proj, width, height, cull="none", front_face="ccw",
               depth_func="less", depth_test=True, depth_mask=True, clear_depth=1.0, vao=None,
               polygon_offset=(0.0, 0.0), polygon_mode="fill"):
        """Returns (face_id (H, W) int32 with -1 background, depth (H, W) float32 with
        clear_depth where empty), row 0 = top. ``polygon_mode`` fill or line
        (glPolygonMode), ``polygon_offset`` (factor, units) as glPolygonOffset."""
        import moderngl

        ctx = self.ctx
        fbo = self._framebuffer(width, height)
        fbo.use()
        ctx.viewport = (0, 0, width, height)
        fbo.clear(0, 0, 0, 0, depth=clear_depth)
        ctx.disable(moderngl.BLEND)
        if depth_test:
            ctx.enable(moderngl.DEPTH_TEST)
            ctx.depth_func = _DEPTH_FUNCS[depth_func]
        else:
            ctx.disable(moderngl.DEPTH_TEST)
        fbo.depth_mask = depth_mask
        if cull == "none":
            ctx.disable(moderngl.CULL_FACE)
        else:
            ctx.enable(moderngl.CULL_FACE)
            ctx.cull_face = cull
        ctx.front_face = front_face
        self.prog["view_proj"].write(np.asarray(view_proj, dtype="f4").T.tobytes())
        own = vao is None
        if own:
            vao, vbo = self.upload(tri_world)
        ctx.polygon_offset = tuple(float(v) for v in polygon_offset)
        ctx.wireframe = polygon_mode == "line"
        vao.render(moderngl.TRIANGLES)
        ctx.finish()
        ctx.polygon_offset = (0.0, 0.0)
        ctx.wireframe = False
        face = np.frombuffer(fbo.read(components=1, dtype="i4", attachment=0), dtype="i4")
        depth = np.frombuffer(fbo.read(components=1, dtype="f4", attachment=1), dtype="f4")
        if own:
            vao.release()
            vbo.release()
        face = face.reshape(height, width)[::-1] - 1
        depth = depth.reshape(height, width)[::-1].copy()
        depth[face < 0] = clear_depth
        return face.astype(np.int32), depth


def cameras_for(mesh):
    """front (auto-framed), oblique from below-behind, inside the bounding box (near
    plane crossing), orthographic."""
    b = mesh.bounds()
    center = b.mean(axis=0)
    size = float(np.linalg.norm(b[1] - b[0]))
    front = hsr.Camera.frame(b, fov_y=45)
    oblique = hsr.Camera.frame(b, direction=(-0.8, -0.5, -1.0), fov_y=60)
    inside_eye = center + (b[1] - center) * np.array([0.35, 0.2, 0.3])
    inside = hsr.Camera.look_at(inside_eye, center - (b[1] - center) * 0.5, fov_y=75,
                                near=size * 0.02, far=size * 3)
    ortho = hsr.Camera.frame(b, direction=(1.0, 0.4, 0.2), ortho_height=size * 0.8)
    return {"front": front, "oblique": oblique, "inside": inside, "ortho": ortho}


def compare_gl(gl, mesh, cam, width, height, **state):
    frame = hsr.render(mesh, cam, width, height, **state)
    view_proj = cam.projection_matrix(width / height) @ cam.view_matrix
    gl_state = {k: v for k, v in state.items()}
    gl_face, gl_depth = gl.render(hsr.Scene([mesh]).world_triangles(), view_proj, width,
                                  height, **gl_state)
    covered = (gl_face >= 0) | (frame.face_id >= 0)
    agree = (gl_face == frame.face_id) & covered
    n_cov = int(covered.sum())
    share = agree.sum() / n_cov if n_cov else 1.0
    both = agree & (gl_face >= 0)
    diff = np.abs(gl_depth[both].astype(np.float64) - frame.depth[both])
    p99 = float(np.percentile(diff, 99)) if diff.size else 0.0
    worst = float(diff.max()) if diff.size else 0.0
    return share, p99, worst, n_cov, frame
