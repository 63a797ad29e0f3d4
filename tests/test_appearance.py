"""Shading after visibility: textures, Gouraud, fog, transparency. Expected colours come from
the brute-force ray reference (tests/reference.py: its own barycentrics and hit points) and
formulas written out here, not from hsr's shading code."""

import numpy as np
import pytest

import hsr
from hsr.appearance.fog import Fog, parse_fog
from hsr.appearance.texture import sample
from hsr.scene.images import checkerboard, load_texture
from reference import reference_render

W, H = 120, 90


def slanted_plane(uv_scale=1.0):
    """A 4 x 4 quad in the y = 0 plane, uv (0..1) x uv_scale, seen at a grazing slant."""
    pos = np.array([[-2, 0, 2], [2, 0, 2], [2, 0, -2], [-2, 0, -2]], dtype=float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float) * uv_scale
    mesh = hsr.Mesh(pos, faces, corner_uv=uv[faces], texture=checkerboard(8, 8))
    camera = hsr.Camera.look_at((0, 1.2, 3.2), (0, 0, -0.5), (0, 1, 0), 50, 0.5, 20)
    return mesh, camera


def checker_dark(uv):
    """Expected square of an 8 x 8 checkerboard with 8 texels per square (nearest): the
    image's row 0 is the top, v = 0 the bottom."""
    texel_i = np.floor(uv[:, 0] * 64).astype(int) % 64
    texel_j = 63 - np.floor(uv[:, 1] * 64).astype(int) % 64  # image row
    return ((texel_i // 8 + texel_j // 8) % 2) == 1


def reference_uv(mesh, camera, jitter=(0.0, 0.0)):
    """(H, W, 2) uv seen at each pixel centre by the reference ray caster (NaN = none)."""
    face, _, bary = reference_render(mesh, camera, W, H, with_barycentrics=True, jitter=jitter)
    uv = np.full((H, W, 2), np.nan)
    covered = face >= 0
    uv[covered] = np.einsum("ij,ijk->ik", bary[covered], mesh.corner_uv[face[covered]])
    return uv


def test_checkerboard_is_perspective_correct():
    mesh, camera = slanted_plane()
    frame = hsr.render(mesh, camera, W, H, texture_filter="nearest")
    uv = reference_uv(mesh, camera)
    covered = ~np.isnan(uv[..., 0])
    expected = checker_dark(uv[covered])
    # Pixels whose centre is within a hair of a texel boundary (or of the quad's outline)
    # may go either way.
    unsure = np.zeros(covered.sum(), bool)
    for j in ((0.02, 0.02), (-0.02, 0.02), (0.02, -0.02), (-0.02, -0.02)):
        uv_j = reference_uv(mesh, camera, j)[covered]
        unsure |= np.isnan(uv_j[:, 0])
        unsure |= checker_dark(np.nan_to_num(uv_j)) != expected
    gray = frame.color[covered].astype(float).mean(axis=1)
    dark_seen = gray < gray.max() * 0.5
    wrong = (dark_seen != expected) & ~unsure
    assert covered.sum() > 2000 and unsure.mean() < 0.2
    assert wrong.sum() == 0, f"{wrong.sum()} pixels show the wrong checker square"

    # Affine (screen-linear) uv, the classic mistake, disagrees on many pixels: the
    # comparison above can fail.
    rows, cols = np.nonzero(covered)
    xy = _project(mesh.positions, camera)
    affine = np.empty((len(rows), 2))
    for f in range(2):
        tri = xy[mesh.faces[f]]
        b = _screen_barycentrics(tri, cols + 0.5, rows + 0.5)
        inside = (b >= -1e-9).all(axis=1)
        affine[inside] = b[inside] @ mesh.corner_uv[f]
    assert ((checker_dark(affine) != expected) & ~unsure).sum() > 100


def _project(points, camera):
    clip = np.c_[points, np.ones(len(points))] @ (
        camera.projection_matrix(W / H) @ camera.view_matrix).T
    ndc = clip[:, :2] / clip[:, 3:]
    return np.c_[(ndc[:, 0] + 1) * W / 2, (1 - ndc[:, 1]) * H / 2]  # image coordinates


def _screen_barycentrics(tri, x, y):
    (x0, y0), (x1, y1), (x2, y2) = tri
    det = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    b1 = ((x - x0) * (y2 - y0) - (x2 - x0) * (y - y0)) / det
    b2 = ((x1 - x0) * (y - y0) - (x - x0) * (y1 - y0)) / det
    return np.stack([1 - b1 - b2, b1, b2], axis=1)


def test_sampling_by_hand():
    # 2 x 2 texture; image row 0 (top) = v in [0.5, 1).
    image = np.array([[[0, 0, 0], [100, 100, 100]],
                      [[200, 200, 200], [40, 40, 40]]], dtype=np.uint8)
    tex = load_texture(image)
    assert sample(tex, np.array([[0.25, 0.25]]), "nearest")[0, 0] == 200  # bottom-left
    assert sample(tex, np.array([[0.75, 0.75]]), "nearest")[0, 0] == 100  # top-right
    # Texel centres give the texel; halfway between four centres gives their mean.
    assert sample(tex, np.array([[0.25, 0.75]]), "bilinear")[0, 0] == pytest.approx(0)
    assert sample(tex, np.array([[0.5, 0.5]]), "bilinear")[0, 0] == pytest.approx(85)
    # At u = 0, GL_REPEAT mixes the last and first columns half and half; clamp does not.
    assert sample(tex, np.array([[0.0, 0.25]]), "bilinear", "repeat")[0, 0] == pytest.approx(120)
    assert sample(tex, np.array([[0.0, 0.25]]), "bilinear", "clamp")[0, 0] == pytest.approx(200)
    assert sample(tex, np.array([[1.25, -0.75]]), "nearest", "repeat")[0, 0] == 200
    assert sample(tex, np.array([[1.25, -0.75]]), "nearest", "clamp")[0, 0] == 40  # bottom-right
    assert sample(tex, np.array([[1.25, 1.75]]), "nearest", "clamp")[0, 0] == 100


def test_texture_from_an_mtl_file_repeats(tmp_path):
    from PIL import Image

    stripes = np.zeros((4, 8, 3), np.uint8)
    stripes[:, :4] = (200, 40, 10)
    stripes[:, 4:] = (10, 40, 200)
    Image.fromarray(stripes).save(tmp_path / "stripes.png")
    (tmp_path / "quad.mtl").write_text("newmtl m\nKd 1 1 1\nmap_Kd stripes.png\n")
    (tmp_path / "quad.obj").write_text(
        "mtllib quad.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n"
        "vt 0 0\nvt 3 0\nvt 3 3\nvt 0 3\nusemtl m\nf 1/1 2/2 3/3 4/4\n")
    mesh = hsr.load(str(tmp_path / "quad.obj"))
    camera = hsr.Camera.look_at((0, 0, 3), (0, 0, 0), (0, 1, 0), 60, 0.1, 10)
    frame = hsr.render(mesh, camera, 120, 90, texture_filter="nearest")
    row = frame.color[45][frame.face_id[45] >= 0].astype(int)
    red = row[:, 0] > row[:, 2]
    # u runs 0..3 across the quad: six stripes, five changes, texel colours exactly
    # (the quad faces the light: intensity 1).
    assert np.count_nonzero(red[1:] != red[:-1]) == 5
    assert {tuple(c) for c in row} == {(200, 40, 10), (10, 40, 200)}
    off = hsr.render(mesh, camera, 120, 90, textures=False)
    assert off.color[45, 60].tolist() == [255, 255, 255]  # Kd 1 1 1, no texture


def test_texture_without_uv_is_an_error():
    mesh = hsr.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], texture=checkerboard())
    camera = hsr.Camera.look_at((0, 0, 3), (0, 0, 0), (0, 1, 0), 60, 0.1, 10)
    with pytest.raises(hsr.RenderError, match="texture coordinates"):
        hsr.render(mesh, camera, 20, 20)


def test_gouraud_interpolates_vertex_lighting():
    pos = np.array([[-1, -1, 0], [1, -1, -0.5], [0, 1, 0.2]], dtype=float)
    normals = np.array([[0, 0, 1], [0.6, 0, 0.8], [0, -0.8, 0.6]], dtype=float)
    mesh = hsr.Mesh(pos, [[0, 1, 2]], corner_normals=normals[None])
    camera = hsr.Camera.look_at((0.3, 0.2, 3), (0, 0, 0), (0, 1, 0), 60, 0.1, 10)
    frame = hsr.render(mesh, camera, W, H, shading="gouraud")
    face, _, bary = reference_render(mesh, camera, W, H, with_barycentrics=True)
    covered = face >= 0
    forward = np.asarray(camera.target, float) - camera.eye
    forward /= np.linalg.norm(forward)
    unit = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    corner = np.maximum(0, -(unit @ forward))
    expected = 230 * (bary[covered] @ corner)
    got = frame.color[covered][:, 0].astype(float)
    assert covered.sum() > 500
    assert np.abs(got - expected).max() <= 1.01
    # and it is not flat shading
    assert np.ptp(got) > 20


def test_gouraud_computes_smooth_normals_when_the_file_has_none():
    sphere = hsr.scenes.uv_sphere(1.0, 24, 48)
    sphere.corner_normals = None
    camera = hsr.Camera.look_at((0, 0, 4), (0, 0, 0), (0, 1, 0), 40, 0.1, 10)
    flat = hsr.render(sphere, camera, W, H).color[..., 1].astype(int)
    smooth = hsr.render(sphere, camera, W, H, shading="gouraud").color[..., 1].astype(int)
    # Neighbouring pixels change far less across face boundaries with Gouraud shading.
    jumps_flat = np.abs(np.diff(flat, axis=1))[:, 30:90].max()
    jumps_smooth = np.abs(np.diff(smooth, axis=1))[:, 30:90].max()
    assert jumps_smooth < jumps_flat


@pytest.mark.parametrize("fog", [Fog("linear", 2.0, 9.0), Fog("exp", density=0.2),
                                 Fog("exp2", density=0.15),
                                 Fog("linear", 2.0, 9.0, distance="plane")])
def test_fog_follows_the_gl_formulas(fog):
    fog = Fog(fog.mode, fog.start, fog.end, fog.density, (20, 60, 200), fog.distance)
    wall = hsr.Mesh([[-6, -6, -5], [6, -6, -5], [6, 6, -5], [-6, 6, -5]], [[0, 1, 2], [0, 2, 3]])
    camera = hsr.Camera.look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 90, 0.5, 20)
    frame = hsr.render(wall, camera, W, H, fog=fog)
    face, _, bary = reference_render(wall, camera, W, H, with_barycentrics=True)
    tri = wall.positions[wall.faces[face[face >= 0]]]
    hit = np.einsum("ij,ijk->ik", bary[face >= 0], tri)
    c = np.linalg.norm(hit, axis=1) if fog.distance == "radial" else np.abs(hit[:, 2])
    if fog.mode == "linear":
        f = (fog.end - c) / (fog.end - fog.start)
    elif fog.mode == "exp":
        f = np.exp(-fog.density * c)
    else:
        f = np.exp(-(fog.density * c) ** 2)
    f = np.clip(f, 0, 1)[:, None]
    expected = f * 230 + (1 - f) * np.array([20, 60, 200])
    got = frame.color[face >= 0].astype(float)
    assert np.abs(got - expected).max() <= 1.01
    if fog.distance == "radial":
        assert np.ptp(got[:, 0]) > 5  # the corners are farther than the centre


def test_fog_parsing_and_errors():
    assert parse_fog("linear:1,5") == Fog("linear", 1.0, 5.0)
    assert parse_fog("exp2:0.3").density == 0.3
    for bad in ("linear:1", "exp:a", "cloud:1", "linear:3,3", "exp:-1"):
        with pytest.raises(hsr.RenderError):
            parse_fog(bad)


def quads(z_near=-3.0, z_far=-5.0, crossing=False):
    """Two overlapping square quads facing the camera (or crossing each other)."""
    scene = hsr.Scene()
    red = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    faces = [[0, 1, 2], [0, 2, 3]]
    if crossing:  # two quads through the same centre, tilted opposite ways about y
        a = red.copy()
        a[:, 2] = -4 + 0.8 * a[:, 0]
        b = red.copy() + [0.3, 0.2, 0]
        b[:, 2] = -4 - 0.8 * (b[:, 0] - 0.3)
        scene.add(hsr.Mesh(a, faces, face_colors=[[255, 0, 0]] * 2), opacity=0.5)
        scene.add(hsr.Mesh(b, faces, face_colors=[[0, 0, 255]] * 2), opacity=0.5)
    else:
        scene.add(hsr.Mesh(red + [0, 0, z_near], faces, face_colors=[[255, 0, 0]] * 2),
                  opacity=0.5)
        scene.add(hsr.Mesh(red + [0.5, 0.5, z_far], faces, face_colors=[[0, 0, 255]] * 2),
                  opacity=0.5)
    camera = hsr.Camera.look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60, 0.5, 20)
    return scene, camera


def blend(dst, src, a):
    return np.floor(a * np.asarray(src, float) + (1 - a) * np.asarray(dst, float) + 0.5)


def test_transparent_objects_blend_back_to_front_whatever_the_submission_order():
    scene, camera = quads()
    frame = hsr.render(scene, camera, W, H, shading="flat", textures=False)
    # pixels covered by both quads: shoot the reference at each quad alone
    only_near, _ = reference_render(hsr.Scene([scene.instances[0]]), camera, W, H)
    only_far, _ = reference_render(hsr.Scene([scene.instances[1]]), camera, W, H)
    both = (only_near >= 0) & (only_far >= 0)
    assert both.sum() > 100
    expected = blend(blend([0, 0, 0], [0, 0, 255], 0.5), [255, 0, 0], 0.5)
    assert (frame.color[both] == expected).all()
    near_only = (only_near >= 0) & (only_far < 0)
    assert (frame.color[near_only] == blend([0, 0, 0], [255, 0, 0], 0.5)).all()
    # Transparent surfaces do not write depth or ids (depth mask off).
    assert (frame.face_id == -1).all() and (frame.depth == 1.0).all()
    assert frame.stats["transparent_objects"] == 2


def test_opaque_objects_hide_transparent_ones_behind_them():
    scene, camera = quads()
    wall = hsr.Mesh([[-0.2, -0.2, -4], [0.2, -0.2, -4], [0.2, 0.2, -4], [-0.2, 0.2, -4]],
                    [[0, 1, 2], [0, 2, 3]], face_colors=[[0, 255, 0]] * 2)
    scene.add(wall)  # opaque, between the two transparent quads, drawn last
    frame = hsr.render(scene, camera, W, H)
    wall_px = frame.face_id >= 0
    assert wall_px.sum() > 20
    # Over the wall: only the near red quad blended on green (the blue one is hidden).
    expected = blend([0, 255, 0], [255, 0, 0], 0.5)
    assert (frame.color[wall_px] == expected).all()


def test_per_object_sorting_fails_on_interpenetrating_objects_and_exact_does_not():
    scene, camera = quads(crossing=True)
    by_object = hsr.render(scene, camera, W, H)
    exact = hsr.render(scene, camera, W, H, transparency="exact")
    # Expected per pixel: the two surfaces blended far to near, by the reference's depths.
    f_red, d_red = reference_render(hsr.Scene([scene.instances[0]]), camera, W, H)
    f_blue, d_blue = reference_render(hsr.Scene([scene.instances[1]]), camera, W, H)
    both = (f_red >= 0) & (f_blue >= 0)
    red_far = d_red > d_blue
    lit = 255 / np.sqrt(1 + 0.8 ** 2)  # flat Lambert of the tilted quads
    far_col = np.where(red_far[..., None], [lit, 0, 0], [0, 0, lit])
    near_col = np.where(red_far[..., None], [0, 0, lit], [lit, 0, 0])
    expected = blend(blend(np.zeros(3), far_col, 0.5), near_col, 0.5)
    sure = both & (np.abs(d_red - d_blue) > 1e-4)
    assert (exact.color[sure] == expected[sure]).all()
    wrong = (by_object.color != expected).any(axis=2) & sure
    assert wrong.sum() > 50, "per-object order should get part of the overlap wrong"
    assert (~wrong & sure).sum() > 50, "... and the other part right"


@pytest.mark.parametrize("algorithm", ["scanline", "raycast", "painter", "newell", "bsp"])
def test_every_algorithm_gets_textures_and_fog_for_free(algorithm):
    scene, camera = hsr.scenes.get("checker")
    look = dict(fog=Fog("linear", 2.0, 9.0, color=(90, 90, 120)), shading="gouraud")
    ref = hsr.render(scene, camera, W, H, **look)
    frame = hsr.render(scene, camera, W, H, algorithm=algorithm, **look)
    same_face = frame.face_id == ref.face_id
    assert same_face.mean() > 0.999
    assert (frame.color[same_face] == ref.color[same_face]).all()


# --------------------------------------------------------------------------- lights
def cube():
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return hsr.Mesh(v, [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])


@pytest.mark.parametrize("shading,path", [("flat", "per face"), ("flat", "per fragment"),
                                          ("gouraud", "per fragment")])
def test_studio_light_is_two_sided_lambert(shading, path):
    """Every covered pixel of a cube (seen three-quarter, so three faces show) has
    ``230 * (ambient + sum power * max(0, n . l))`` with n the face normal turned to the
    eye, for the rig's lights (their directions are inputs here; the sum is computed
    here). Gouraud on flat faces with face normals is the same. The per-fragment path is
    forced with a fog that changes nothing (density 0)."""
    from hsr.appearance.shading import light_rig

    mesh = cube()
    normals = mesh.face_normals()
    if shading == "gouraud":
        mesh = hsr.Mesh(mesh.positions, mesh.faces, corner_normals=np.repeat(
            normals[:, None, :], 3, axis=1))
    cam = hsr.views.default(mesh.bounds(), W / H)
    fog = hsr.Fog("exp", density=0.0) if path == "per fragment" else None
    frame = hsr.render(mesh, cam, W, H, shading=shading, light="studio", fog=fog)
    rig = light_rig("studio", cam)
    eye_space = rig.directions @ cam.view_matrix[:3, :3].T
    assert eye_space[0, 0] < 0 and eye_space[0, 1] > 0 and eye_space[0, 2] > 0  # key: up-left-front
    assert rig.power[0] > rig.power[1] > 0  # key brighter than fill
    covered = frame.face_id >= 0
    n = normals[frame.face_id[covered]]
    n *= np.where(n @ np.asarray(cam.forward) > 0, -1.0, 1.0)[:, None]
    expected = 230 * (rig.ambient + np.maximum(0, n @ rig.directions.T) @ rig.power)
    got = frame.color[covered][:, 0].astype(float)
    assert np.abs(got - np.minimum(expected, 255)).max() <= 1.01
    shades = {int(np.median(got[frame.face_id[covered] // 2 == q])) for q in range(6)
              if (frame.face_id[covered] // 2 == q).sum() > 50}
    assert len(shades) == 3  # three faces show, each with its own shade


def test_headlight_is_the_default_and_lights_are_checked():
    mesh = cube()
    cam = hsr.views.default(mesh.bounds(), W / H)
    frame = hsr.render(mesh, cam, W, H)
    covered = frame.face_id >= 0
    n = mesh.face_normals()[frame.face_id[covered]]
    expected = 230 * np.abs(n @ np.asarray(cam.forward))
    assert np.abs(frame.color[covered][:, 0] - expected).max() <= 1.01
    with pytest.raises(hsr.RenderError, match="light"):
        hsr.render(mesh, cam, W, H, light="sun")
    with pytest.raises(hsr.RenderError, match="light"):
        hsr.Look(light=None)


def test_flat_colours_of_transformed_instances_follow_their_world_normals():
    """Per-face colours are computed only for the faces that show, instance by instance
    (each through its own model matrix): every covered pixel of three cubes (rotated,
    sheared, scaled unevenly, one half hidden behind another) has ``230 |n . view|``
    with ``n`` the normal of its face's corners taken to world space here (no normal
    matrix: the cross product of the world edges)."""
    mesh = cube()

    def rotation(angle, axis):
        c, s = np.cos(angle), np.sin(angle)
        i, j = [k for k in range(3) if k != axis]
        m = np.eye(4)
        m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
        return m

    shear = np.eye(4)
    shear[0, 1] = 0.7
    models = [rotation(0.5, 1) @ np.diag([2.0, 0.5, 1.0, 1.0]),
              np.eye(4) + np.array([[0, 0, 0, 1.2], [0, 0, 0, 0.3], [0, 0, 0, -1.5], [0] * 4]),
              shear @ rotation(-0.8, 0) @ np.diag([0.6, 1.5, 0.8, 1.0])]
    models[2][:3, 3] = (-1.4, 0.2, 0.5)
    scene = hsr.Scene([hsr.Instance(mesh, m) for m in models])
    cam = hsr.Camera.look_at(eye=(1.0, 2.5, 6.0), target=(0.0, 0.0, -0.5), fov_y=50)
    frame = hsr.render(scene, cam, W, H)
    covered = frame.face_id >= 0
    corners = np.concatenate([(np.c_[mesh.positions, np.ones(len(mesh.positions))]
                               @ m.T)[:, :3][mesh.faces] for m in models])
    n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    expected = 230 * np.abs(n @ np.asarray(cam.forward))[frame.face_id[covered]]
    assert np.abs(frame.color[covered][:, 0] - expected).max() <= 1.01
    assert len(np.unique(frame.object_id[covered])) == 3
    assert len(np.unique(frame.face_id[covered])) < 3 * mesh.n_faces  # some faces hidden


@pytest.mark.parametrize("light", ["headlight", "studio"])
@pytest.mark.parametrize("threads", [1, 2])
def test_per_face_colours_of_many_faces_follow_lambert_face_by_face(light, threads):
    """The per-face colour kernel works on blocks of faces (gathered, then computed in
    SIMD lanes, then scattered): on a soup of 1000 faces (many blocks and a partial last
    one, split between threads) with per-face base colours, an instance matrix that
    shears and scales, and faces of zero area (zero normal), every face's flat and normal
    colour matches Lambert / the normal map written out here with NumPy, face by face,
    so a colour landing on another face or a lane left stale shows."""
    from hsr.appearance.shading import face_colors, light_rig

    rng = np.random.default_rng(7)
    positions = rng.normal(size=(600, 3))
    faces = rng.integers(0, 600, size=(1000, 3))
    faces[::37, 2] = faces[::37, 0]  # zero area: the normal stays zero
    base = rng.integers(0, 256, size=(1000, 3)).astype(np.uint8)
    model = np.eye(4)
    model[:3, :3] = [[1.5, 0.4, 0.0], [0.0, 0.7, 0.2], [0.3, 0.0, 1.1]]
    scene = hsr.Scene([hsr.Instance(hsr.Mesh(positions, faces, face_colors=base), model)])
    cam = hsr.Camera.look_at(eye=(0.5, 1.0, 6.0), target=(0.0, 0.0, 0.0), fov_y=50)
    world = (positions @ model[:3, :3].T)[faces]
    n = np.cross(world[:, 1] - world[:, 0], world[:, 2] - world[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(length > 0, n / np.where(length > 0, length, 1.0), 0.0)
    rig = light_rig(light, cam)
    toward_eye = np.where(n @ np.asarray(cam.forward) > 0, -1.0, 1.0)
    shade = rig.ambient + np.maximum(0, (n * toward_eye[:, None]) @ rig.directions.T) @ rig.power
    with hsr.parallel.Workers(threads) as workers:
        flat = face_colors("flat", scene, cam, workers, light=light).astype(float)
        normal = face_colors("normal", scene, cam, workers, light=light).astype(float)
    assert np.abs(flat - np.minimum(255, base * shade[:, None])).max() <= 1.01
    assert np.abs(normal - np.minimum(255, (n * 0.5 + 0.5) * 255)).max() <= 1.01
    flat_zero = flat[::37]
    assert np.abs(flat_zero - np.minimum(255, base[::37] * rig.ambient)).max() <= 1.01
    assert (normal[::37] == 127).all()
