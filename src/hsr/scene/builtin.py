"""Built-in procedural scenes, so a new user (and every test) has something to render
with no files. Each entry of :data:`SCENES` builds ``(Scene, Camera)``.

- ``cubes``: cube instances overlapping on screen (Gambetta ch. 12's figure).
- ``cyclic``: three triangles overlapping in a visibility cycle (seed 004, fig. 11.1):
  no back-to-front order of whole triangles exists, painter's algorithm must fail.
- ``penetration``: two triangles piercing each other (seed 001's hard case).
- ``spheres``: intersecting spheres (curved, closed, many small triangles).
- ``terrain``: a displaced grid of 1M triangles (``terrain(n)`` for other sizes).
- ``city``: 256 buildings of 3072 triangles seen from street level (occlusion culling).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import HsrError, check_choice
from .camera import Camera
from .mesh import Mesh, Scene

__all__ = ["SCENES", "get", "cube", "uv_sphere", "cubes", "cyclic", "penetration", "spheres",
           "glass", "checker",
           "translate", "rotate_y", "scale"]

# Gambetta's cube colours: red, green, blue, yellow, purple, cyan (one per side).
_SIDE_COLORS = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 0], [128, 0, 255],
                         [0, 255, 255]], dtype=np.uint8)


def translate(x: float, y: float, z: float) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def scale(s: float) -> np.ndarray:
    m = np.eye(4)
    m[0, 0] = m[1, 1] = m[2, 2] = s
    return m


def rotate_y(degrees: float) -> np.ndarray:
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    m = np.eye(4)
    m[0, 0], m[0, 2], m[2, 0], m[2, 2] = c, s, -s, c
    return m


def cube(colored: bool = True) -> Mesh:
    """The cube [-1, 1]^3 as 12 triangles, counter-clockwise seen from outside."""
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    idx = {tuple(p): i for i, p in enumerate(v.astype(int))}
    faces = []
    for axis in range(3):
        for sign in (1, -1):
            u_axis, w_axis = (axis + 1) % 3, (axis + 2) % 3
            corners = []
            for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = [0, 0, 0]
                p[axis], p[u_axis], p[w_axis] = sign, a, b
                corners.append(idx[tuple(p)])
            if sign < 0:
                corners = corners[::-1]
            faces += [[corners[0], corners[1], corners[2]], [corners[0], corners[2], corners[3]]]
    colors = np.repeat(_SIDE_COLORS, 2, axis=0) if colored else None
    return Mesh(v, np.array(faces), face_colors=colors, name="cube")


def uv_sphere(radius: float = 1.0, n_lat: int = 16, n_lon: int = 32,
              color: tuple | None = None) -> Mesh:
    """A latitude-longitude sphere, counter-clockwise seen from outside, closed."""
    verts = [[0.0, radius, 0.0]]
    for i in range(1, n_lat):
        theta = math.pi * i / n_lat
        for j in range(n_lon):
            phi = 2 * math.pi * j / n_lon
            verts.append([radius * math.sin(theta) * math.cos(phi), radius * math.cos(theta),
                          -radius * math.sin(theta) * math.sin(phi)])
    verts.append([0.0, -radius, 0.0])
    bottom = len(verts) - 1

    def ring(i, j):
        return 1 + (i - 1) * n_lon + (j % n_lon)

    faces = []
    for j in range(n_lon):
        faces.append([0, ring(1, j), ring(1, j + 1)])
    for i in range(1, n_lat - 1):
        for j in range(n_lon):
            a, b, c, d = ring(i, j), ring(i + 1, j), ring(i + 1, j + 1), ring(i, j + 1)
            faces += [[a, b, c], [a, c, d]]
    for j in range(n_lon):
        faces.append([bottom, ring(n_lat - 1, j + 1), ring(n_lat - 1, j)])
    colors = None if color is None else np.tile(np.asarray(color, np.uint8), (len(faces), 1))
    return Mesh(np.array(verts), np.array(faces), face_colors=colors, name="sphere")


def cubes() -> tuple:
    """Four coloured cubes at different depths, overlapping on screen."""
    scene = Scene()
    box = cube()
    scene.add(box, translate(-1.5, 0.0, -7.0) @ scale(0.75))
    scene.add(box, translate(1.25, 1.5, -9.5) @ rotate_y(195))
    scene.add(box, translate(0.3, -0.6, -5.2) @ rotate_y(35) @ scale(0.6))
    scene.add(box, translate(-0.2, 1.2, -12.0) @ rotate_y(-20) @ scale(1.4))
    camera = Camera.look_at(eye=(-1.0, 2.2, 1.0), target=(0.0, 0.3, -8.0), fov_y=50.0,
                            near=0.5, far=40.0)
    return scene, camera


def cyclic() -> tuple:
    """Three long triangles in a visibility cycle: A over B, B over C, C over A.

    Stick i runs along the edge V_i -> V_(i+1) of an equilateral triangle, from a narrow
    far tail behind V_i to a wide near head beyond V_(i+1); at V_(i+1) its head lies over
    the tail of stick i+1, so each stick is in front of the next one (seed 004, 11.1).
    """
    faces: list = []
    verts: list = []
    colors: list = []
    palette = [[230, 60, 60], [60, 200, 60], [70, 110, 240]]
    corners = [np.array([math.cos(a), math.sin(a)]) * 1.2
               for a in (math.pi / 2 + 2 * math.pi * i / 3 for i in range(3))]
    for i in range(3):
        v0, v1 = corners[i], corners[(i + 1) % 3]
        length = float(np.linalg.norm(v1 - v0))
        d = (v1 - v0) / length
        n = np.array([-d[1], d[0]])
        tail = v0 - 0.6 * length * d
        head = v1 + 0.3 * length * d
        base = len(verts)
        # Depth rises from the tail (far) to the head (near).
        verts += [[tail[0], tail[1], -5.6], [head[0] - 0.25 * n[0], head[1] - 0.25 * n[1], -4.4],
                  [head[0] + 0.25 * n[0], head[1] + 0.25 * n[1], -4.4]]
        faces.append([base, base + 1, base + 2])
        colors.append(palette[i])
    mesh = Mesh(np.array(verts), np.array(faces), face_colors=np.array(colors), name="cyclic")
    camera = Camera.look_at(eye=(0.0, 0.0, 0.0), target=(0.0, 0.0, -5.0), fov_y=60.0,
                            near=0.5, far=20.0)
    return Scene([mesh]), camera


def penetration() -> tuple:
    """Two triangles that pierce each other: each is in front over part of the other."""
    verts = np.array([
        [-1.6, -1.0, -5.5], [1.6, -1.0, -5.5], [0.0, 1.4, -3.5],  # leans towards the eye
        [-1.4, 1.1, -5.2], [0.1, -1.4, -4.0], [1.5, 0.9, -4.6],   # crosses it
    ])
    faces = np.array([[0, 1, 2], [3, 4, 5]])
    mesh = Mesh(verts, faces, face_colors=np.array([[235, 150, 40], [40, 150, 235]]),
                name="penetration")
    camera = Camera.look_at(eye=(0.0, 0.0, 0.0), target=(0.0, 0.0, -5.0), fov_y=50.0,
                            near=0.5, far=20.0)
    return Scene([mesh]), camera


def spheres(detail: int = 24) -> tuple:
    """Three intersecting spheres, ``detail`` latitude bands each."""
    scene = Scene()
    lon = 2 * detail
    scene.add(uv_sphere(1.0, detail, lon, (220, 80, 80)), translate(-0.7, 0.0, -6.0))
    scene.add(uv_sphere(0.9, detail, lon, (80, 200, 90)), translate(0.6, 0.3, -6.4))
    scene.add(uv_sphere(0.7, detail, lon, (90, 120, 230)), translate(0.0, -0.5, -5.3))
    camera = Camera.look_at(eye=(0.0, 0.5, 0.0), target=(0.0, 0.0, -6.0), fov_y=40.0,
                            near=1.0, far=20.0)
    return scene, camera


def terrain_mesh(n_triangles: int = 1_000_000, name: str = "terrain") -> Mesh:
    """A displaced grid of about ``n_triangles`` triangles over [-1, 1]^2 (for scaling
    benchmarks: 1M, 10M ...). Heights are a few sine waves, so it has hills that hide
    each other."""
    n = max(2, int(round(math.sqrt(n_triangles / 2.0))) + 1)
    u = np.linspace(-1.0, 1.0, n)
    gx, gz = np.meshgrid(u, u)
    height = (0.12 * np.sin(5.0 * gx) * np.cos(4.0 * gz) + 0.05 * np.sin(17.0 * gx + 3.0 * gz)
              + 0.02 * np.cos(31.0 * gz - 7.0 * gx))
    positions = np.stack([gx.ravel(), height.ravel(), gz.ravel()], axis=1)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="xy")
    a = (j * n + i).ravel()
    quads = np.stack([a, a + n, a + n + 1, a + 1], axis=1)
    # Two counter-clockwise triangles per cell, seen from above (+y).
    faces = np.empty((2 * len(quads), 3), dtype=np.int64)
    faces[0::2] = quads[:, [0, 1, 2]]
    faces[1::2] = quads[:, [0, 2, 3]]
    return Mesh(positions, faces, name=name)


def terrain(n_triangles: int = 1_000_000):
    """The terrain mesh seen from a low oblique angle."""
    camera = Camera.look_at(eye=(0.0, 0.9, 2.2), target=(0.0, -0.1, 0.0), fov_y=50.0,
                            near=0.3, far=6.0)
    return Scene([terrain_mesh(n_triangles)]), camera


def tessellated_cube(segments: int = 8) -> Mesh:
    """The cube [-1, 1]^3 with every side cut into segments x segments quads (closed,
    counter-clockwise from outside): a cheap way to give an object many triangles."""
    u = np.linspace(-1.0, 1.0, segments + 1)
    ga, gb = np.meshgrid(u, u, indexing="ij")
    positions: list[np.ndarray] = []
    faces: list[np.ndarray] = []
    for axis in range(3):
        for sign in (1.0, -1.0):
            p = np.zeros((segments + 1, segments + 1, 3))
            p[..., axis] = sign
            p[..., (axis + 1) % 3] = ga
            p[..., (axis + 2) % 3] = gb
            base = sum(len(x) for x in positions)
            positions.append(p.reshape(-1, 3))
            i, j = np.meshgrid(np.arange(segments), np.arange(segments), indexing="ij")
            a = (base + i * (segments + 1) + j).ravel()
            quad = np.stack([a, a + segments + 1, a + segments + 2, a + 1], axis=1)
            if sign < 0:
                quad = quad[:, ::-1]
            faces += [quad[:, [0, 1, 2]], quad[:, [0, 2, 3]]]
    return Mesh(np.concatenate(positions), np.concatenate(faces), name="tessellated cube")


def city(blocks: int = 16, segments: int = 16, seed: int = 7):
    """A grid of ``blocks`` x ``blocks`` buildings (tessellated boxes of random heights) on
    a ground plane, seen from street level: the first rows hide most of the city, which
    is where occlusion culling pays."""
    rng = np.random.default_rng(seed)
    scene = Scene()
    ground = Mesh(np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], float) * 60.0,
                  np.array([[0, 2, 1], [0, 3, 2]]), face_colors=np.full((2, 3), 90), name="ground")
    scene.add(ground)
    box = tessellated_cube(segments)
    spacing = 6.0
    for bx in range(blocks):
        for bz in range(blocks):
            h = rng.uniform(2.0, 9.0)
            model = translate((bx - blocks / 2) * spacing, h, -(bz + 1) * spacing) @ np.diag(
                [2.0, h, 2.0, 1.0])
            scene.add(box, model)
    camera = Camera.look_at(eye=(-1.0, 1.7, 4.0), target=(2.0, 3.0, -20.0), fov_y=60.0,
                            near=0.5, far=200.0)
    return scene, camera


def glass() -> tuple:
    """Transparency (seed 003): an opaque floor and cube; a transparent sphere beside them,
    and two transparent slabs that pass through each other, where sorting whole objects
    back to front cannot be right (compare with ``transparency="exact"``)."""
    scene = Scene()
    floor = Mesh(np.array([[-4.0, 0, -4], [4, 0, -4], [4, 0, 4], [-4, 0, 4]]),
                 np.array([[0, 2, 1], [0, 3, 2]]), face_colors=np.array([[190, 190, 180]] * 2),
                 name="floor")
    scene.add(floor, translate(0, -1.0, -8))
    scene.add(cube(), translate(1.6, -0.4, -9.5) @ rotate_y(30) @ scale(0.6))
    scene.add(uv_sphere(0.8, 16, 32, color=(60, 200, 90)), translate(-1.8, -0.2, -7.5),
              opacity=0.45)
    slab = tessellated_cube(1)
    slab.face_colors = np.tile(np.array([[230, 40, 40]], np.uint8), (slab.n_faces, 1))
    scene.add(slab, translate(0.2, 0.3, -8) @ rotate_y(35) @ _scale3(1.3, 0.7, 0.15),
              opacity=0.5)
    slab_b = tessellated_cube(1)
    slab_b.face_colors = np.tile(np.array([[40, 80, 230]], np.uint8), (slab_b.n_faces, 1))
    scene.add(slab_b, translate(0.0, 0.2, -8.2) @ rotate_y(-35) @ _scale3(1.3, 0.7, 0.15),
              opacity=0.5)
    camera = Camera.look_at(eye=(0.0, 3.2, -2.5), target=(0.0, -0.3, -8.2), fov_y=45.0,
                            near=0.5, far=30.0)
    return scene, camera


def _scale3(x, y, z) -> np.ndarray:
    return np.diag([x, y, z, 1.0])


def checker() -> tuple:
    """A textured plane at a grazing angle (seed 002's homework): perspective-correct
    texture coordinates keep the squares straight and shrinking with distance."""
    from .images import checkerboard

    pos = np.array([[-3, 0, 3], [3, 0, 3], [3, 0, -3], [-3, 0, -3]], dtype=float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    plane = Mesh(pos, faces, corner_uv=uv[faces], texture=checkerboard(8, 16), name="checker")
    scene = Scene().add(plane)
    camera = Camera.look_at(eye=(0, 1.8, 3.5), target=(0, 0, -1.0), fov_y=55.0, near=0.3,
                            far=20.0)
    return scene, camera


SCENES = {"cubes": cubes, "cyclic": cyclic, "penetration": penetration, "spheres": spheres,
          "terrain": terrain, "city": city, "glass": glass, "checker": checker}


def get(name: str) -> tuple:
    """``(Scene, Camera)`` of the built-in scene ``name``.

    Raises :class:`~hsr.errors.HsrError` for an unknown name.
    """
    check_choice(name, tuple(SCENES), "scene", HsrError)
    return SCENES[name]()
