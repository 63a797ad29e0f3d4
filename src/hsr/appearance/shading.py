"""The shading stage, shared by every algorithm: turns per-pixel visibility (face id,
depth) into colours. Nothing here decides visibility.

Modes: ``flat`` (Lambert per face, light along the view direction: tinyrenderer's look;
two-sided so back faces drawn with culling off are lit too), ``gouraud`` (Lambert at the
vertices with per-vertex normals from the file or averaged over the faces around each
vertex, the intensity interpolated perspective-correctly: Gouraud 1971), ``normal``
(world normal as RGB), ``random`` (a hashed colour per face: Gambetta's look), ``depth``
(linear eye depth, near = bright).

A mesh with texture coordinates and a texture (``Mesh.texture``, from an .mtl ``map_Kd`` or
given by the caller) is textured in ``flat`` and ``gouraud``: texel x Lambert intensity.
Fog (:mod:`hsr.appearance.fog`) is applied last. The per-face modes without texture or fog take a
fast path (a colour per visible face, painted by face id); everything else is computed
per fragment by :func:`shade_fragments`, which the transparency pass also uses."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numba import njit

from ..choices import Light, Shading, TextureFilter, TextureWrap
from ..errors import RenderError, check_choice
from ..geometry.weld import weld
from ..parallel import Workers
from ..scene.images import load_texture
from ..scene.mesh import instance_of, normal_matrix
from .fog import Fog
from .texture import FILTERS, WRAPS, sample

if TYPE_CHECKING:
    from ..geometry.stage import ScreenTriangles
    from ..scene.camera import Camera
    from ..scene.mesh import Mesh, Scene

__all__ = ["SHADING_MODES", "LIGHTS", "LightRig", "light_rig", "lambert", "Look", "ShadeContext",
           "shade_fragments", "face_colors", "paint_faces", "shade_depth", "face_random_colors",
           "linear_eye_depth", "vertex_normals", "as_look", "check_background", "shade_visible"]

# ``auto``: ``smooth`` on meshes whose file carries normals (as every glTF viewer draws
# them), ``flat`` on the others. ``smooth`` interpolates the normals and lights each pixel
# (Phong's normal interpolation, 1975); ``gouraud`` lights the corners and interpolates;
# ``unlit`` is the base colour alone (texture x factor x vertex colour, glTF's
# KHR_materials_unlit): the albedo.
SHADING_MODES = ("auto", "flat", "smooth", "gouraud", "unlit", "normal", "random", "depth")
# Computed normals average only the faces round a vertex within this many degrees of the
# corner's own face, so a cube keeps its edges (Blender's auto-smooth default).
CREASE_ANGLE = 30.0
LIGHTS = ("headlight", "studio")

# The studio rig, in eye space (x right, y up, z towards the viewer): directions towards
# each light and their strengths. A key light from above-left-front and a weaker fill from
# the right, plus a little ambient, so faces turned differently get different shades
# (the three-point lighting of photography, less the back light, which would only light
# silhouettes). Fixed to the camera, so every view of a model is lit alike.
_STUDIO_EYE = np.array([[-0.45, 0.6, 0.66], [0.7, 0.05, 0.71]])
_STUDIO_POWER = np.array([0.78, 0.3])
_STUDIO_AMBIENT = 0.12


@dataclass(frozen=True)
class LightRig:
    """World-space unit directions towards the lights (L, 3), their strengths (L,) and an
    ambient term: Lambert intensity ``ambient + sum_l power_l * max(0, n . dir_l)`` with the
    normal turned towards the eye (two-sided)."""

    directions: np.ndarray
    power: np.ndarray
    ambient: float


def light_rig(light: str, camera) -> LightRig:
    """The lights of ``light`` (one of :data:`LIGHTS`) for ``camera``: ``headlight`` is one
    light along the view direction (tinyrenderer's and the seeds' look: intensity
    ``|n . view|``); ``studio`` a key and a fill light fixed to the camera."""
    check_choice(light, LIGHTS, "light")
    forward = np.asarray(camera.forward, dtype=np.float64)
    if light == "headlight":
        return LightRig(-forward[None, :], np.ones(1), 0.0)
    eye_dirs = _STUDIO_EYE / np.linalg.norm(_STUDIO_EYE, axis=1, keepdims=True)
    # Eye -> world: the rows of the view rotation are the eye axes in world space.
    world = eye_dirs @ camera.view_matrix[:3, :3]
    return LightRig(np.ascontiguousarray(world), _STUDIO_POWER.copy(), _STUDIO_AMBIENT)


def lambert(rig: LightRig, normals, toward_eye) -> np.ndarray:
    """Two-sided Lambert intensity of ``normals`` (..., 3) under ``rig``; ``toward_eye``
    (broadcastable to normals[..., 0]) is +1 or -1, turning each normal towards the eye."""
    lit = np.maximum(0.0, (normals @ rig.directions.T) * np.asarray(toward_eye)[..., None])
    return rig.ambient + lit @ rig.power
_DEFAULT_BASE = np.array([230.0, 230.0, 230.0])
LIT = ("flat", "smooth", "gouraud", "unlit")  # the modes that colour by the base colour


# Faces per block of :func:`_face_rgb`: its per-face arrays stay in L1 (64 x 11 doubles).
_RGB_BLOCK = 64


@njit(cache=True, nogil=True, error_model="numpy")
def _face_rgb(lo, hi, positions, faces, linear, forward, light_dirs, light_power, ambient,
              base_rgb, mode, wanted, out):
    """(F, 3) uint8 colour per face from its normal after the linear map ``linear``.

    mode 0 (flat): ``base * (ambient + sum_l power_l * max(0, n' . dir_l))``, Lambert with
    directional lights, two-sided: ``n'`` is the normal turned towards the eye (against
    ``forward``). The headlight (one light along the view, no ambient) gives
    ``base * |n . forward|``. mode 1 (normal): ``(n * 0.5 + 0.5) * 255``. ``base_rgb`` is
    (F, 3) or (1, 3).
    Computes faces ``wanted[lo:hi]`` (the others are never looked up): a list rather
    than a mask over all faces, so that the threads get equal shares of the work and
    the loop has no branch on visibility, which is as good as random where hills hide
    each other (the 1M-face terrain at 1080p: its whole shading stage 13.5 -> 11.9 ms,
    median of 90 renders each).

    Blocks of faces in three passes: gather the edge vectors (indexed loads, one face at
    a time), then normals and Lambert for the whole block in loops without indexing or
    branches, which the compiler turns into SIMD (a square root and three divisions per
    face were most of the time: the 360k visible faces of the 1M terrain at 1080p, one
    thread, 8.5-11.9 -> 4.1-6.7 ms in three alternating runs), then scatter the colours.
    Every value comes from the same operations in the same order as one face at a time
    (IEEE division and square root round alike in SIMD lanes; ``error_model="numpy"``
    only drops the zero-divisor check, and the divisor is never zero), so the colours
    are bit for bit the same.
    """
    per_face = base_rgb.shape[0] == faces.shape[0]
    # The matrix and view direction read once, into locals: the stores into ``out`` below
    # could alias those arrays for all the compiler knows.
    l00, l01, l02 = linear[0, 0], linear[0, 1], linear[0, 2]
    l10, l11, l12 = linear[1, 0], linear[1, 1], linear[1, 2]
    l20, l21, l22 = linear[2, 0], linear[2, 1], linear[2, 2]
    fx, fy, fz = forward[0], forward[1], forward[2]
    edge = np.empty((6, _RGB_BLOCK))  # model-space edges c1 - c0, c2 - c0 of the block
    unit = np.empty((3, _RGB_BLOCK))  # unit normals
    shade = np.empty(_RGB_BLOCK)
    toward_eye = np.empty(_RGB_BLOCK)
    for start in range(lo, hi, _RGB_BLOCK):
        size = min(_RGB_BLOCK, hi - start)
        for j in range(size):
            f = wanted[start + j]
            a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
            ax, ay, az = positions[a, 0], positions[a, 1], positions[a, 2]
            edge[0, j], edge[1, j], edge[2, j] = (positions[b, 0] - ax, positions[b, 1] - ay,
                                                  positions[b, 2] - az)
            edge[3, j], edge[4, j], edge[5, j] = (positions[c, 0] - ax, positions[c, 1] - ay,
                                                  positions[c, 2] - az)
        for j in range(size):
            # Edges through ``linear`` (a linear map keeps differences), then their cross.
            d1x, d1y, d1z = edge[0, j], edge[1, j], edge[2, j]
            d2x, d2y, d2z = edge[3, j], edge[4, j], edge[5, j]
            e1x = l00 * d1x + l01 * d1y + l02 * d1z
            e1y = l10 * d1x + l11 * d1y + l12 * d1z
            e1z = l20 * d1x + l21 * d1y + l22 * d1z
            e2x = l00 * d2x + l01 * d2y + l02 * d2z
            e2y = l10 * d2x + l11 * d2y + l12 * d2z
            e2z = l20 * d2x + l21 * d2y + l22 * d2z
            nx, ny, nz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
            length = np.sqrt(nx * nx + ny * ny + nz * nz)
            # A zero normal stays zero: dividing by 1 leaves any value as it is.
            scale = length if length > 0.0 else 1.0
            unit[0, j], unit[1, j], unit[2, j] = nx / scale, ny / scale, nz / scale
        if mode == 0:
            for j in range(size):
                toward_eye[j] = (-1.0 if unit[0, j] * fx + unit[1, j] * fy + unit[2, j] * fz
                                 > 0.0 else 1.0)
                shade[j] = ambient
            for m in range(light_dirs.shape[0]):
                dx, dy, dz = light_dirs[m, 0], light_dirs[m, 1], light_dirs[m, 2]
                power = light_power[m]
                for j in range(size):
                    lit = toward_eye[j] * (unit[0, j] * dx + unit[1, j] * dy + unit[2, j] * dz)
                    shade[j] = shade[j] + power * lit if lit > 0.0 else shade[j]
            for j in range(size):
                f = wanted[start + j]
                b = f if per_face else 0
                for c in range(3):
                    out[f, c] = np.uint8(min(255.0, base_rgb[b, c] * shade[j]))
        else:
            for j in range(size):
                f = wanted[start + j]
                for c in range(3):
                    out[f, c] = np.uint8(min(255.0, (unit[c, j] * 0.5 + 0.5) * 255.0))


def _face_base(mesh) -> np.ndarray:
    """(F, 3) or (1, 3) float64 base colour per face for the per-face paths: the face
    colour times the mean of its vertex colours (vertex colours are interpolated only
    per fragment)."""
    if mesh.corner_colors is None:
        return (mesh.face_colors.astype(np.float64) if mesh.face_colors is not None
                else _DEFAULT_BASE[None, :])
    vertex = mesh.corner_colors.astype(np.float64).mean(axis=1)
    if mesh.face_colors is not None:
        vertex *= mesh.face_colors / 255.0
    return vertex


def paint_faces(workers, face_id, face_rgb, background, image):
    """``image = face_rgb[face_id]`` where a face is visible, else the background
    (``face_rgb`` may be empty: every pixel gets the background). Returns the number of
    covered pixels."""
    # Rows are the unit here: a few dozen rows of a large image are plenty of work.
    parts = workers.run_range(_scan_rows, face_id.shape[0], True, face_id, face_rgb,
                              background, image, _NO_SEEN, min_chunk=32)
    return sum(parts)


_NO_SEEN = np.zeros(0, dtype=np.bool_)


def visible_faces(face_id, n_faces, workers=None):
    """(F,) bool: faces that appear in the image (rows scanned in parallel, each chunk
    into its own mask)."""
    workers = workers or Workers(1)
    bounds = workers.split(face_id.shape[0], min_chunk=32)
    seen = np.zeros((len(bounds) - 1, n_faces), dtype=np.bool_)
    workers.run(_scan_rows, bounds, False, face_id, np.zeros((0, 3), np.uint8),
                np.zeros(3, np.uint8), np.zeros((1, 1, 3), np.uint8), each=seen)
    return np.logical_or.reduce(seen) if len(seen) > 1 else seen[0]


@njit(cache=True, nogil=True)
def _scan_rows(lo, hi, paint, face_id, face_rgb, background, image, seen):
    """One pass over image rows ``lo..hi``: with ``paint``, colour them from the per-face
    table (returns the covered count); without, mark the faces seen in ``seen`` (F,).
    One kernel for both halves of the per-face path, and no allocation inside it: one
    small compile on first use."""
    covered = 0
    if not paint:
        for r in range(lo, hi):
            for c in range(face_id.shape[1]):
                if face_id[r, c] >= 0:
                    seen[face_id[r, c]] = True
        return covered
    use_table = face_rgb.shape[0] > 0
    for r in range(lo, hi):
        for c in range(face_id.shape[1]):
            f = face_id[r, c]
            if f >= 0:
                covered += 1
            if f >= 0 and use_table:
                image[r, c, 0] = face_rgb[f, 0]
                image[r, c, 1] = face_rgb[f, 1]
                image[r, c, 2] = face_rgb[f, 2]
            else:
                image[r, c, 0] = background[0]
                image[r, c, 1] = background[1]
                image[r, c, 2] = background[2]
    return covered


def face_colors(mode: str, scene, camera, workers, face_id=None,
                light: str = "headlight") -> np.ndarray:
    """(F, 3) uint8 colour of the faces visible in ``face_id`` (all faces when None) for
    the per-face shading modes (other rows are left unset); (0, 3) for ``depth``, which
    is per pixel."""
    if mode not in SHADING_MODES:
        raise RenderError(f"shading must be one of {', '.join(SHADING_MODES)}; got {mode!r}")
    if mode == "depth":
        return np.zeros((0, 3), dtype=np.uint8)
    if mode in ("auto", "smooth", "gouraud"):  # per-face stand-in (lines, points, SVG)
        mode = "flat"
    if mode == "random":
        return face_random_colors(scene.n_faces)
    if mode == "unlit":
        return np.concatenate([np.broadcast_to(to_uint8(_face_base(inst.mesh)),
                                               (inst.mesh.n_faces, 3))
                               for inst in scene.instances])
    if face_id is None:
        visible = np.ones(scene.n_faces, dtype=np.bool_)
    else:
        visible = visible_faces(face_id, scene.n_faces, workers)
    out = np.empty((scene.n_faces, 3), dtype=np.uint8)
    rig = light_rig(light, camera)
    offsets = scene.face_offsets()
    for k, inst in enumerate(scene.instances):
        lo, hi = offsets[k], offsets[k + 1]
        wanted = np.flatnonzero(visible[lo:hi])
        if not len(wanted):
            continue
        mesh = inst.mesh
        base = _face_base(mesh)
        workers.run_range(_face_rgb, len(wanted), mesh.positions, mesh.faces,
                          np.ascontiguousarray(inst.model[:3, :3]), camera.forward,
                          rig.directions, rig.power, rig.ambient, base,
                          0 if mode == "flat" else 1, wanted, out[lo:hi])
    return out


def shade_depth(image, face_id, depth, camera, depth_range=(0.0, 1.0)) -> None:
    """Paint linear eye depth into ``image`` where a face is visible: near = bright (255),
    far = dark (40), scaled over the visible range."""
    covered = face_id >= 0
    if not covered.any():
        return
    eye_depth = linear_eye_depth(depth[covered], camera, depth_range)
    lo, hi = float(eye_depth.min()), float(eye_depth.max())
    scale = (eye_depth - lo) / (hi - lo) if hi > lo else np.zeros_like(eye_depth)
    gray = np.round(255.0 - 215.0 * scale).astype(np.uint8)
    image[covered] = gray[:, None]


def face_random_colors(n_faces: int) -> np.ndarray:
    """(F, 3) uint8 distinct-looking colours from a hash of the face index (deterministic,
    no global random state): Gambetta's one-colour-per-triangle look."""
    h = np.arange(n_faces, dtype=np.uint64) * np.uint64(0x9E3779B97F4A7C15)
    h ^= h >> np.uint64(29)
    h *= np.uint64(0xBF58476D1CE4E5B9)
    h ^= h >> np.uint64(32)
    rgb = np.stack([(h >> np.uint64(s)) & np.uint64(0xFF) for s in (0, 8, 16)], axis=1)
    return (64 + (rgb.astype(np.float64) * (191.0 / 255.0))).astype(np.uint8)


def linear_eye_depth(depth_window, camera, depth_range=(0.0, 1.0)) -> np.ndarray:
    """Distance along the view axis (positive, world units) from window depth."""
    near_d, far_d = depth_range
    z_ndc = (np.asarray(depth_window, dtype=np.float64) - 0.5 * (far_d + near_d)) * (
        2.0 / (far_d - near_d) if far_d != near_d else 0.0)
    n, f = camera.near, camera.far
    if camera.is_orthographic:
        return 0.5 * (z_ndc * (f - n) + (f + n))
    return 2.0 * f * n / ((f + n) - z_ndc * (f - n))


@dataclass(frozen=True)
class Look:
    """How visible surfaces are coloured (everything after visibility).

    shading : one of :data:`SHADING_MODES`: ``auto`` (the default) draws a mesh whose
        file carries normals ``smooth`` and the others ``flat``; ``smooth`` and ``gouraud``
        compute normals where a mesh has none, averaging the faces round each vertex that
        lie within ``crease_angle`` degrees of each other.
    textures : use the meshes' textures where they have one and texture coordinates.
    texture_filter : ``nearest`` or ``bilinear``; texture_wrap : ``repeat`` or ``clamp``.
    fog : a :class:`hsr.Fog` or None.
    light : ``headlight`` (one light along the view: the textbooks' look) or ``studio``
        (a key light from above-left-front and a fill, fixed to the camera: shapes read
        better; ``hsr render MODEL`` uses it). Both are two-sided.

    Raises :class:`~hsr.errors.RenderError` for an unknown shading mode, filter, wrap or
    light, or a fog that is not an :class:`hsr.Fog`.
    """

    shading: Shading = "auto"
    textures: bool = True
    texture_filter: TextureFilter = "bilinear"
    texture_wrap: TextureWrap = "repeat"
    fog: Fog | None = None
    light: Light = "headlight"
    crease_angle: float = CREASE_ANGLE

    def __post_init__(self):
        check_choice(self.shading, SHADING_MODES, "shading")
        check_choice(self.light, LIGHTS, "light")
        check_choice(self.texture_filter, FILTERS, "texture filter")
        check_choice(self.texture_wrap, WRAPS, "texture wrap")
        if not isinstance(self.textures, (bool, np.bool_)):
            raise RenderError(f"textures must be True or False, got {self.textures!r}")
        if self.fog is not None and not isinstance(self.fog, Fog):
            raise RenderError(f"fog must be an hsr.Fog, got {type(self.fog).__name__}")
        angle = self.crease_angle
        if (isinstance(angle, bool) or not isinstance(angle, (int, float, np.floating))
                or not 0.0 <= angle <= 180.0):
            raise RenderError(f"crease_angle must be a number in 0..180 degrees, got {angle!r}")

    def mode_of(self, mesh: Mesh) -> str:
        """The shading mode ``mesh`` is drawn with (``auto`` resolved for it)."""
        if self.shading == "auto":
            return "smooth" if mesh.corner_normals is not None else "flat"
        return self.shading


def as_look(look, shading, textures, texture_filter, texture_wrap, fog,
            light="headlight") -> Look:
    """The render's :class:`Look`: ``look`` if given, else one from the separate arguments."""
    if look is None:
        return Look(shading, textures, texture_filter, texture_wrap, fog, light)
    if not isinstance(look, Look):
        raise RenderError(f"look must be an hsr.Look, got {type(look).__name__}")
    return look


def check_background(background) -> np.ndarray:
    """(3,) uint8 background colour from three numbers in 0..255."""
    try:
        rgb = np.asarray(background, dtype=np.float64)
    except (TypeError, ValueError):
        rgb = np.zeros(0)
    if rgb.shape != (3,) or not np.all((rgb >= 0) & (rgb <= 255)):
        raise RenderError(f"background must be three numbers in 0..255, got {background!r}")
    return rgb.astype(np.uint8)


def _textured(look, mesh) -> bool:
    return look.textures and mesh.texture is not None and look.mode_of(mesh) in LIT


@dataclass
class ShadeContext:
    """Everything the per-fragment shading of one render needs; textures and normals are
    loaded or computed on first use and kept for the rest of this render only."""

    scene: Scene
    camera: Camera
    screen: ScreenTriangles  # clip-space corners of the source faces
    look: Look
    workers: Workers
    _textures: dict = field(default_factory=dict)
    _normals: dict = field(default_factory=dict)

    def __post_init__(self):
        for inst in self.scene.instances:
            if _textured(self.look, inst.mesh) and inst.mesh.corner_uv is None:
                raise RenderError(f"{inst.mesh.name}: has a texture but not every face has "
                                  f"texture coordinates (OBJ vt); use textures=False "
                                  f"(--no-texture)")

    @property
    def per_pixel(self) -> bool:
        """True when colours cannot be a plain per-face table."""
        look = self.look
        return look.fog is not None or any(
            look.mode_of(inst.mesh) in ("smooth", "gouraud") or _textured(look, inst.mesh)
            or (inst.mesh.corner_colors is not None
                and look.mode_of(inst.mesh) in ("flat", "unlit"))
            for inst in self.scene.instances)

    def texture(self, k):
        if k not in self._textures:
            self._textures[k] = load_texture(self.scene.instances[k].mesh.texture)
        return self._textures[k]

    def corner_normals(self, k):
        """(F, 3, 3) world-space unit normals at the corners of instance k's faces."""
        if k not in self._normals:
            inst = self.scene.instances[k]
            normals = (inst.mesh.corner_normals if inst.mesh.corner_normals is not None
                       else vertex_normals(inst.mesh, self.look.crease_angle))
            # Normals transform by the cofactor matrix (the inverse transpose up to scale,
            # and defined for singular model matrices too).
            world = normals @ normal_matrix(inst.model).T
            length = np.linalg.norm(world, axis=2, keepdims=True)
            self._normals[k] = np.divide(world, length, out=np.zeros_like(world),
                                         where=length > 0)
        return self._normals[k]


def vertex_normals(mesh, crease_angle: float = CREASE_ANGLE) -> np.ndarray:
    """(F, 3, 3) unit normals at face corners: at each corner, the area-weighted average of
    the normals of the faces round its vertex that lie within ``crease_angle`` degrees of
    the corner's own face (a crease stays sharp, as with Blender's auto smooth); vertices
    welded by exact position, so a mesh stored with split vertices is smoothed too."""
    corner_vertex = weld(mesh.positions)[1][mesh.faces]
    tri = mesh.positions[mesh.faces]
    area_normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # 2 x area
    length = np.linalg.norm(area_normal, axis=1, keepdims=True)
    unit = np.divide(area_normal, length, out=np.zeros_like(area_normal), where=length > 0)
    # The faces round each vertex, as compressed rows (vertex -> corners sorted by vertex).
    order = np.argsort(corner_vertex.reshape(-1), kind="stable")
    starts = np.searchsorted(corner_vertex.reshape(-1)[order],
                             np.arange(int(corner_vertex.max(initial=-1)) + 2))
    # A hair below the cosine, so faces exactly at the crease angle are smoothed.
    cos_crease = math.cos(math.radians(crease_angle)) - 1e-12
    out = np.zeros((len(mesh.faces), 3, 3))
    _corner_normals(corner_vertex, area_normal, unit, order // 3, starts, cos_crease, out)
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _corner_normals(corner_vertex, area_normal, unit, ring_face, starts, cos_crease, out):
    """Fill ``out`` (F, 3, 3) with the normalised sum of ``area_normal`` over the faces
    ``ring_face[starts[v]:starts[v + 1]]`` round each corner's vertex v whose ``unit``
    normal is within the crease of the corner's face (its own face always is, unless
    degenerate)."""
    for f in range(corner_vertex.shape[0]):
        for c in range(3):
            v = corner_vertex[f, c]
            sx = 0.0
            sy = 0.0
            sz = 0.0
            for i in range(starts[v], starts[v + 1]):
                g = ring_face[i]
                if (unit[f, 0] * unit[g, 0] + unit[f, 1] * unit[g, 1]
                        + unit[f, 2] * unit[g, 2]) >= cos_crease:
                    sx += area_normal[g, 0]
                    sy += area_normal[g, 1]
                    sz += area_normal[g, 2]
            norm = math.sqrt(sx * sx + sy * sy + sz * sz)
            if norm > 0.0:
                out[f, c, 0] = sx / norm
                out[f, c, 1] = sy / norm
                out[f, c, 2] = sz / norm


def _instance_groups(scene, faces):
    """(instance index, local face ids, positions in ``faces``) for each instance that
    owns some of the global ``faces``."""
    offsets = scene.face_offsets()
    owner = instance_of(offsets, faces)
    order = np.argsort(owner, kind="stable")
    bounds = np.searchsorted(owner[order], np.arange(len(offsets)))
    for k in range(len(offsets) - 1):
        idx = order[bounds[k]:bounds[k + 1]]
        if len(idx):
            yield k, faces[idx] - offsets[k], idx


def shade_fragments(ctx: ShadeContext, rows, cols, faces, depth_window) -> np.ndarray:
    """(K, 3) float64 colours (0..255) of K fragments: pixel centres (``rows``, ``cols``)
    on global ``faces`` at window depth ``depth_window``. Fog included."""
    from ..algorithms.fragments import barycentrics_at

    look, scene, camera = ctx.look, ctx.scene, ctx.camera
    k_count = len(faces)
    rgb = np.zeros((k_count, 3))
    if k_count == 0:
        return rgb
    faces = np.asarray(faces, dtype=np.int64)
    if look.shading == "depth":
        eye_depth = linear_eye_depth(depth_window, camera)
        lo, hi = float(eye_depth.min()), float(eye_depth.max())
        scale = (eye_depth - lo) / (hi - lo) if hi > lo else np.zeros_like(eye_depth)
        rgb[:] = (255.0 - 215.0 * scale)[:, None]
    elif look.shading in ("normal", "random"):
        table = face_colors(look.shading, scene, camera, ctx.workers,
                            _face_mask_image(faces, scene.n_faces))
        rgb[:] = table[faces]
    needs_bary = look.fog is not None or look.shading in ("auto",) + LIT
    bary = barycentrics_at(ctx.screen, rows, cols, faces) if needs_bary else None
    forward = np.asarray(camera.forward, dtype=np.float64)
    rig = light_rig(look.light, camera)
    view = camera.view_matrix
    for k, local, idx in _instance_groups(scene, faces):
        inst = scene.instances[k]
        mesh = inst.mesh
        mode = look.mode_of(mesh)
        b: Any = bary[idx] if bary is not None else None
        if needs_bary:
            world = (mesh.positions[mesh.faces[local]] @ inst.model[:3, :3].T
                     + inst.model[:3, 3])  # (K, 3 corners, 3)
        if mode in LIT:
            intensity = _intensity(mode, rig, world, forward, b,
                                   ctx.corner_normals(k)[local] if mode != "flat" else None)
            # glTF's base colour: texel x factor (face colour) x vertex colour, each
            # where given; hsr's light grey where none is.
            if _textured(look, mesh):
                uv = np.einsum("ij,ijk->ik", b, mesh.corner_uv[local])
                base = sample(ctx.texture(k), uv, look.texture_filter, look.texture_wrap)
                if mesh.face_colors is not None:
                    base *= mesh.face_colors[local] / 255.0
            elif mesh.face_colors is not None:
                base = mesh.face_colors[local].astype(np.float64)
            else:
                base = None
            if mesh.corner_colors is not None:
                vertex = np.einsum("ij,ijk->ik", b, mesh.corner_colors[local].astype(np.float64))
                base = vertex if base is None else base * (vertex / 255.0)
            if base is None:
                base = _DEFAULT_BASE[None, :]
            rgb[idx] = base * intensity[:, None]
        if look.fog is not None:
            eye = world @ view[:3, :3].T + view[:3, 3]
            pos_eye = np.einsum("ij,ijk->ik", b, eye)
            rgb[idx] = look.fog.apply(rgb[idx], pos_eye)
    return rgb


def _intensity(mode, rig, world, forward, bary, corner_normals) -> np.ndarray:
    """(K,) Lambert intensity of K fragments with barycentrics ``bary`` on triangles
    ``world`` (K, 3, 3): of the face normal (flat), of the interpolated corner normal
    (smooth, Phong 1975), or interpolated from the corners' (Gouraud 1971). Two-sided: a
    face looking away from the eye is lit as if turned round."""
    normal = np.cross(world[:, 1] - world[:, 0], world[:, 2] - world[:, 0])
    length = np.linalg.norm(normal, axis=1)
    normal /= np.where(length > 0, length, 1.0)[:, None]
    toward_eye = np.where(normal @ forward > 0.0, -1.0, 1.0)
    if mode == "unlit":
        return np.ones(len(world))
    if mode == "flat":
        return lambert(rig, normal, toward_eye)
    if mode == "gouraud":
        return np.einsum("ij,ij->i", bary, lambert(rig, corner_normals, toward_eye[:, None]))
    pixel = np.einsum("ij,ijk->ik", bary, corner_normals)
    length = np.linalg.norm(pixel, axis=1, keepdims=True)
    pixel = np.divide(pixel, length, out=normal.copy(), where=length > 0)
    return lambert(rig, pixel, toward_eye)


def _face_mask_image(faces, n_faces):
    """A one-row 'image' of the given face ids, for :func:`face_colors`' visible set."""
    return np.asarray(faces, dtype=np.int32).reshape(1, -1)


def to_uint8(rgb: np.ndarray) -> np.ndarray:
    """Round float colours to uint8 (GL's conversion: round to nearest, clamp)."""
    return np.clip(np.floor(rgb + 0.5), 0, 255).astype(np.uint8)


def shade_visible(ctx: ShadeContext, fragments, state, background):
    """Colour every pixel from its visible face (``fragments``): a colour per face where
    the look allows it, else per fragment. Returns ((H, W, 3) uint8, pixels covered)."""
    face_id = fragments.face_id
    height, width = face_id.shape
    color = ctx.workers.output((height, width, 3), np.uint8)
    look = ctx.look
    if state.polygon_mode != "fill" or not ctx.per_pixel:
        # Lines and points take a per-face colour (no fragment to shade between corners).
        mode = look.shading if state.polygon_mode == "fill" else (
            look.shading if look.shading in ("flat", "unlit", "normal", "random") else "flat")
        covered = paint_faces(ctx.workers, face_id,
                              face_colors(mode, ctx.scene, ctx.camera, ctx.workers, face_id,
                                          look.light),
                              background, color)
        if look.shading == "depth" and state.polygon_mode == "fill":
            shade_depth(color, face_id, fragments.depth, ctx.camera, state.depth_range)
        return color, covered
    covered = paint_faces(ctx.workers, face_id, np.zeros((0, 3), np.uint8), background, color)
    rows, cols = np.nonzero(face_id >= 0)
    if len(rows):
        color[rows, cols] = to_uint8(shade_fragments(
            ctx, rows, cols, face_id[rows, cols], fragments.depth[rows, cols]))
    return color, covered
