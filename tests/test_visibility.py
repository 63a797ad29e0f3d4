"""Per-face visibility and pruning (issue #16): known answers from scenes built so the
visible faces are known by construction, counts against the brute-force ray reference,
and every written format read back and rendered."""

import json
import os

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

import hsr
from hsr.cli import main
from hsr.visibility import (
    VisibilityError,
    auto_size,
    decide,
    face_visibility,
    grow_rings,
    keep_faces,
    object_visibility,
    prune,
    verify,
)
from hsr.visibility.prune import MAX_RINGS
from reference import ambiguous_pixels, reference_render


def _box(center, size, subdivisions=0, name="box"):
    m = trimesh.creation.box(extents=size)
    for _ in range(subdivisions):
        m = m.subdivide()
    return hsr.Mesh(m.vertices + center, m.faces, name=name)


def _ball(center, radius, subdivisions=2, name="ball", inward=False):
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    faces = m.faces[:, ::-1] if inward else m.faces
    return hsr.Mesh(m.vertices + center, faces, name=name)


def box_with_parts():
    """A closed 4 x 4 x 4 box (subdivided: 192 faces) holding three parts entirely inside:
    whatever the viewpoint outside, only the box's outer faces can show."""
    scene = hsr.Scene()
    scene.add(_box((0, 0, 0), (4, 4, 4), 2), name="housing")
    scene.add(_ball((-1, 0, 0), 0.8), name="ball")
    scene.add(_box((1.0, 1.0, 1.0), (1, 0.5, 0.7)), name="block")
    scene.add(_ball((1, -1, -0.5), 0.6, 1), name="small ball")
    return scene


def test_a_closed_box_hides_everything_inside():
    scene = box_with_parts()
    pruned, kept = prune(scene, "sphere:48", 96)
    housing = scene.instances[0].mesh.n_faces
    assert np.array_equal(kept, np.arange(housing))  # every box face, nothing else
    assert [i.name for i in pruned.instances] == ["housing"]
    counts = object_visibility(scene, "sphere:48", 96)
    assert counts[0] > 0 and not counts[1:].any()
    # Objects level: the same here, whole instances.
    by_object, kept_objects = prune(scene, "sphere:48", 96, level="objects")
    assert np.array_equal(kept_objects, kept) and len(by_object) == 1
    report = verify(scene, pruned, kept, 12, 96, seed=5)
    assert report["changed"] == 0 and report["covered"] > 0


def test_verify_counts_what_a_wrong_removal_changes():
    """The check must be able to fail: remove one visible face of the box by hand."""
    scene = box_with_parts()
    keep = np.zeros(scene.n_faces, bool)
    keep[:scene.instances[0].mesh.n_faces] = True
    keep[5] = False  # a face of the housing, visible from outside
    wrong = hsr.visibility.subset_scene(scene, keep)
    report = verify(scene, wrong, np.flatnonzero(keep), 40, 96, seed=1)
    assert report["changed"] > 0


def test_nested_spheres_outside_and_inside_views(tmp_path):
    """A hollow sphere in a hollow sphere: from outside only the outer one shows; with
    cameras inside the inner one too (a transforms.json, as a user gives them) both stay."""
    scene = hsr.Scene([_ball((0, 0, 0), 2.0, 2, "outer"), _ball((0, 0, 0), 1.0, 2, "inner")])
    n_outer = scene.instances[0].mesh.n_faces
    _, kept = prune(scene, "sphere:64", 96)
    assert np.array_equal(kept, np.arange(n_outer))
    inside = [hsr.Camera.look_at((0, 0, 0), d, up, fov_y=100, near=0.05, far=10)
              for d, up in (((1, 0, 0), (0, 1, 0)), ((-1, 0, 0), (0, 1, 0)),
                            ((0, 0, 1), (0, 1, 0)), ((0, 0, -1), (0, 1, 0)),
                            ((0, 1, 0), (0, 0, 1)), ((0, -1, 0), (0, 0, 1)))]
    hsr.write_transforms(tmp_path / "inside.json", inside, 96, 96)
    _, kept = prune(scene, ["sphere:64", str(tmp_path / "inside.json")], 96)
    assert np.array_equal(kept, np.arange(scene.n_faces))


def slotted_block():
    """A 4 x 2 x 4 block with a 1-wide, 1-deep slot open at the top (+y), built from three
    boxes that touch: the faces where boxes meet are inside the solid. (Each box face is
    8 triangles that split at the face's mid-lines, so the slot floor's level y = 0 cuts
    no triangle.)"""
    parts = [((-1.25, 0, 0), (1.5, 2, 4)), ((1.25, 0, 0), (1.5, 2, 4)),
             ((0, -0.5, 0), (1, 1, 4))]
    scene = hsr.Scene()
    for k, (c, s) in enumerate(parts):
        scene.add(_box(c, s, 1), name=f"part{k}")
    return scene


def test_a_slot_keeps_the_walls_seen_through_its_opening():
    scene = slotted_block()
    counts = face_visibility(scene, "sphere:128", 128)
    keep = keep_faces(scene, counts)
    tri = scene.world_triangles()
    centre = tri.mean(axis=1)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    # The slot's walls (x = +-0.5 facing into the slot) and floor (y = 0, facing up).
    wall = (np.abs(np.abs(centre[:, 0]) - 0.5) < 1e-9) & (centre[:, 1] > 0) & (
        normal[:, 0] * np.sign(centre[:, 0]) < -0.99)
    floor = (np.abs(centre[:, 1]) < 1e-9) & (np.abs(centre[:, 0]) < 0.5) & (
        normal[:, 1] > 0.99)
    assert wall.sum() == 8 and floor.sum() == 8
    assert keep[wall].all() and keep[floor].all()
    # Every outer face shows. Where two parts touch (the floor block's sides against the
    # side blocks: 8 + 8, and the side blocks' lower walls: 4 + 4) faces are sandwiched;
    # most never show, but one whose edge lies on the outer surface ties in depth with it
    # along that seam and may win a pixel there (float32 depth, the depth test's rule),
    # so it is visible in the renderer's output and stays: removing it would change that
    # pixel, which verify would count.
    touching = (np.abs(np.abs(centre[:, 0]) - 0.5) < 1e-9) & (centre[:, 1] < 0)
    assert touching.sum() == 24
    assert keep[~touching].all()
    assert keep[touching].sum() <= 6 and counts[touching].max() <= 2
    pruned, kept = prune(scene, "sphere:128", 128, counts=counts)
    assert verify(scene, pruned, kept, 20, 128)["changed"] == 0


@pytest.mark.parametrize("depth_func, winner", [("less", 0), ("lequal", 1)])
def test_coplanar_duplicates_follow_the_depth_test(depth_func, winner):
    """Two copies of a quad, one after the other: the tie goes as the renderer decides it,
    the earlier with less, the later with lequal; the loser is never visible."""
    quad = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    scene = hsr.Scene([hsr.Mesh(quad, faces, name="a"), hsr.Mesh(quad, faces, name="b")])
    counts = face_visibility(scene, "orbit:8", 64, depth_func=depth_func)
    assert counts[2 * winner:2 * winner + 2].all()
    assert not counts[2 * (1 - winner):2 * (1 - winner) + 2].any()


def test_a_face_seen_on_one_pixel_of_one_view_is_kept():
    """A tiny triangle in front of a wall covers the centre of exactly one pixel of one
    view: it has a count of 1 and stays (with the default --min-pixels 1)."""
    cam = hsr.Camera.look_at((0, 0, 5), (0, 0, 0), fov_y=40, near=1, far=20)
    wall = _box((0, 0, -1), (6, 6, 0.2))
    # Pixel (20, 12) of a 40 x 30 image: its centre's ray, 3 units from the eye.
    x_ndc, y_ndc = (20.5 / 40) * 2 - 1, 1 - (12.5 / 30) * 2
    t = np.tan(np.radians(20))
    p = np.array([x_ndc * t * 40 / 30, y_ndc * t, -1.0]) * 3 + np.array([0, 0, 5])
    s = 0.01  # far smaller than a pixel (about 0.07 units there)
    tiny = hsr.Mesh(p + np.array([[-s, -s, 0], [s, -s, 0], [0, s, 0]]), [[0, 1, 2]],
                    name="tiny")
    scene = hsr.Scene([wall, tiny])
    counts = face_visibility(scene, [cam], (40, 30))
    assert counts[-1] == 1
    ref, _ = reference_render(scene, cam, 40, 30)
    assert np.count_nonzero(ref == scene.n_faces - 1) == 1
    _, kept = prune(scene, [cam], (40, 30))
    assert kept[-1] == scene.n_faces - 1
    _, kept = prune(scene, [cam], (40, 30), min_pixels=2)
    assert scene.n_faces - 1 not in kept


@settings(max_examples=8, deadline=None)
@given(st.integers(0, 10_000))
def test_counts_match_the_ray_reference(seed):
    """Random soups from three random outside viewpoints: the counts are the reference's
    per-pixel face ids counted, except at pixels whose centre lies on an edge."""
    rng = np.random.default_rng(seed)
    n = 12
    corners = rng.uniform(-1, 1, (n, 3, 3))
    mesh = hsr.Mesh(corners.reshape(-1, 3), np.arange(3 * n).reshape(-1, 3))
    scene = hsr.Scene([mesh])
    cams = [hsr.views.framed(scene.bounds(), d / np.linalg.norm(d), 40 / 32)
            for d in rng.normal(size=(3, 3))]
    counts = face_visibility(scene, cams, (40, 32))
    expected = np.zeros(n, np.int64)
    slack = 0
    for cam in cams:
        ids, _ = reference_render(scene, cam, 40, 32)
        amb = ambiguous_pixels(scene, cam, 40, 32)
        expected += np.bincount(ids[ids >= 0], minlength=n)
        slack += 2 * int(amb.sum())
    assert np.abs(counts - expected).sum() <= slack


def test_rings_reach_faces_sharing_an_edge():
    """On a grid, one ring from a face adds exactly the faces sharing one of its edges
    (by position: the grid is split into per-face vertices, as texture seams split it);
    the reference finds them by comparing corner positions directly."""
    grid = trimesh.creation.box(extents=(4, 4, 1)).subdivide().subdivide()
    tri = grid.vertices[grid.faces]
    mesh = hsr.Mesh(tri.reshape(-1, 3), np.arange(tri.shape[0] * 3).reshape(-1, 3))
    keep = np.zeros(mesh.n_faces, bool)
    keep[7] = True
    one = grow_rings(mesh, keep, 1)

    def shares_edge(f, g):
        same = sum(any(np.array_equal(a, b) for b in tri[g]) for a in tri[f])
        return same >= 2

    expected = np.array([f == 7 or shares_edge(7, f) for f in range(mesh.n_faces)])
    assert np.array_equal(one, expected) and 2 <= expected.sum() - 1 <= 3
    two = grow_rings(mesh, keep, 2)
    ring2 = np.array([two_f for two_f in range(mesh.n_faces)
                      if any(shares_edge(g, two_f) or g == two_f
                             for g in np.flatnonzero(one))])
    assert np.array_equal(np.flatnonzero(two), ring2)


@pytest.mark.parametrize("depth_func", ["less", "lequal"])
def test_skipping_hidden_objects_changes_no_count(depth_func):
    """Objects a view cannot show are skipped (the ones earlier views saw are drawn
    first; an unseen object whose box lies behind them wherever it could show is left
    out): the counts equal the full draws', on the box of parts and on the touching,
    coplanar slot parts (ties)."""
    from hsr.visibility.count import count_view, count_view_culled

    for scene in (box_with_parts(), slotted_block()):
        full = face_visibility(scene, "sphere:24", 96, cull_objects=False,
                               depth_func=depth_func)
        culled = face_visibility(scene, "sphere:24", 96, depth_func=depth_func,
                                 cull_objects="always")
        assert np.array_equal(full, culled)
    # The skipping happens: from outside, the three parts inside the housing.
    scene = box_with_parts()
    boxes = [i.mesh.bounds() for i in scene.instances]
    options = {"algorithm": "zbuffer", "depth_func": depth_func}
    seen = np.array([True, False, False, False])
    for cam in hsr.views.sphere(scene.bounds(), 4):
        a, b = np.zeros(scene.n_faces, np.int64), np.zeros(scene.n_faces, np.int64)
        assert count_view_culled(scene, cam, 96, 96, None, options, a, seen, boxes,
                                 always=True) == 3
        count_view(scene, cam, 96, 96, None, options, b)
        assert np.array_equal(a, b)


def test_subset_scenes_reuse_a_scene_per_set_and_keep_few():
    # The culled draws render subsets of the instances; the same set gets the same Scene
    # (which keeps its joined arrays), and only the most recent few are held.
    from hsr.visibility.count import SubsetScenes

    scene = box_with_parts()
    subsets = SubsetScenes(scene, keep=2)
    first = subsets.get(np.array([0, 2]))
    assert [i is j for i, j in zip(first.instances, [scene.instances[0],
                                                     scene.instances[2]])] == [True, True]
    assert subsets.get(np.array([0, 2])) is first
    second = subsets.get(np.array([1]))
    assert subsets.get(np.array([0, 2])) is first  # used last: kept
    subsets.get(np.array([3]))  # evicts [1], the least recently used
    assert subsets.get(np.array([0, 2])) is first
    assert subsets.get(np.array([1])) is not second


@settings(max_examples=12, deadline=None)
@given(st.integers(0, 100_000))
def test_skipping_hidden_objects_on_random_assemblies(seed):
    """Random assemblies: boxes and balls inside, across and outside a housing, some
    touching, one an exact duplicate of another (ties): the same counts with and without
    skipping hidden objects, for less and lequal, one view at a time or two at once."""
    rng = np.random.default_rng(seed)
    scene = hsr.Scene()
    scene.add(_box((0, 0, 0), (3, 3, 3), 1), name="housing")
    parts = []
    for k in range(int(rng.integers(3, 9))):
        centre = rng.uniform(-2.2, 2.2, 3).round(1)
        size = rng.uniform(0.2, 1.2, 3).round(1)
        mesh = _box(centre, size, name=f"b{k}") if rng.random() < 0.6 else _ball(
            centre, float(size[0]), 1, f"s{k}")
        parts.append(mesh)
        scene.add(mesh, name=mesh.name)
    scene.add(parts[0], name="duplicate")
    for func in ("less", "lequal"):
        # One view at a time against two at once (each lane its own counts, the objects
        # seen so far read across lanes while they change).
        full = face_visibility(scene, "sphere:6", 64, cull_objects=False, depth_func=func,
                               threads=1)
        assert np.array_equal(full, face_visibility(scene, "sphere:6", 64, depth_func=func,
                                                    cull_objects="always", threads=2))


def test_keep_neighbors_keeps_faces_next_to_visible_ones():
    scene = box_with_parts()
    counts = face_visibility(scene, "sphere:32", 64)
    plain = keep_faces(scene, counts)
    grown = keep_faces(scene, counts, keep_neighbors=1)
    assert (grown >= plain).all()
    # The inside parts touch no visible face: growing along edges never reaches them.
    assert np.array_equal(grown, plain)


def test_dask_client_gives_the_same_counts(tmp_path):
    distributed = pytest.importorskip("distributed")
    scene = box_with_parts()
    local = face_visibility(scene, "sphere:12", 64)
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       host="127.0.0.1", dashboard_address="127.0.0.1:0",
                                       silence_logs=50)
    with distributed.Client(cluster) as client:
        remote = face_visibility(scene, "sphere:12", 64, client=client)
        remote_auto = decide(scene, "auto", 64, client=client)
        # The command, connected to the same scheduler by its address.
        src, out = tmp_path / "assembly.glb", tmp_path / "pruned.glb"
        hsr.write_mesh(scene, src)
        assert main(["prune", str(src), "-o", str(out), "--views", "sphere:12", "--size",
                     "64", "--scheduler", cluster.scheduler_address, "--quiet"]) == 0
    cluster.close()
    assert np.array_equal(local, remote)
    # The automatic rounds run there too, and decide as they do here.
    local_auto = decide(scene, "auto", 64)
    assert remote_auto.views == local_auto.views
    assert np.array_equal(remote_auto.counts, local_auto.counts)
    pruned, _ = prune(scene, "sphere:12", 64, counts=local)
    back = hsr.load_scene(out)
    assert [i.name for i in back.instances] == [i.name for i in pruned.instances]
    assert back.n_faces == pruned.n_faces


@pytest.mark.parametrize("views, message", [
    ("cube:8", "views"), ([], "no views"), ("per-model:x.json", "per-model"),
])
def test_bad_views_are_refused(views, message):
    with pytest.raises(VisibilityError, match=message):
        face_visibility(box_with_parts(), views, 32)


def test_a_workspace_is_not_an_option_of_face_visibility():
    """Each lane of views keeps a workspace of its own; one passed in would be shared."""
    with pytest.raises(VisibilityError, match="workspace is not an option"):
        face_visibility(box_with_parts(), "sphere:4", 32, workspace=hsr.Workspace(1))


def test_bad_arguments_are_refused():
    scene = box_with_parts()
    counts = np.ones(scene.n_faces, np.int64)
    for kwargs, message in (({"level": "parts"}, "level"), ({"min_pixels": 0}, "min_pixels"),
                            ({"keep_neighbors": -1}, "keep_neighbors")):
        with pytest.raises(VisibilityError, match=message):
            prune(scene, "sphere:4", 32, counts=counts, **kwargs)
    # decide refuses a bad rule before any view is rendered or sent: this client would
    # fail at its first use.
    for kwargs, message in (({"min_pixels": 0}, "min_pixels"), ({"level": "parts"}, "level"),
                            ({"keep_neighbors": MAX_RINGS + 1}, "keep_neighbors")):
        with pytest.raises(VisibilityError, match=message):
            decide(scene, "auto", 32, client=object(), **kwargs)
    with pytest.raises(VisibilityError, match="nothing would be left"):
        prune(scene, "sphere:4", 32, counts=np.zeros(scene.n_faces, np.int64))
    with pytest.raises(VisibilityError, match="size"):
        face_visibility(scene, "sphere:4", "big")
    with pytest.raises(VisibilityError, match="cull_objects"):
        face_visibility(scene, "sphere:4", 32, cull_objects="sometimes")
    see_through = hsr.Scene([hsr.Instance(_box((0, 0, 0), (1, 1, 1)), opacity=0.5)])
    with pytest.raises(VisibilityError, match="opacity"):
        face_visibility(see_through, "sphere:4", 32)
    with pytest.raises(hsr.RenderError):
        face_visibility(scene, "sphere:4", 32, cull="sideways")


def _textured_scene():
    """Two instances of one textured mesh (uv, normals, face colours) and a plain one."""
    m = trimesh.creation.box(extents=(1, 1, 1))
    tri = m.vertices[m.faces]
    uv = (tri[..., :2] + 0.5) * 0.9
    normals = np.repeat(m.face_normals[:, None, :], 3, axis=1)
    texture = np.zeros((8, 8, 3), np.uint8)
    texture[:4] = (250, 20, 20)
    texture[4:] = (20, 20, 250)
    colors = np.tile(np.array([[200, 180, 160]], np.uint8), (12, 1))
    textured = hsr.Mesh(m.vertices, m.faces, uv, normals, colors, texture, "crate")
    scene = hsr.Scene()
    scene.add(textured, np.eye(4), name="crate A")
    moved = np.eye(4)
    moved[:3, 3] = (2, 0, 0)
    scene.add(textured, moved, name="crate B")
    scene.add(_box((-2, 0, 0), (1, 2, 1)), name="pillar")
    return scene


@pytest.mark.parametrize("ext", [".obj", ".ply", ".glb"])
def test_written_models_read_back_to_the_same_faces(ext, tmp_path):
    scene = _textured_scene()
    path = tmp_path / f"out{ext}"
    written = hsr.write_mesh(scene, path)
    assert all(os.path.isfile(p) for p in written)
    back = hsr.load_scene(path) if ext == ".glb" else hsr.Scene([hsr.load(path)])
    assert back.n_faces == scene.n_faces
    assert np.allclose(back.world_triangles(), scene.world_triangles(), atol=1e-6)
    cam = hsr.views.default(scene, 4 / 3)
    # One OBJ read by hsr is one mesh with one texture: the pillar has no texture
    # coordinates, so compare the faces without textures there.
    a = hsr.render(scene, cam, 160, 120, textures=ext != ".obj")
    b = hsr.render(back, cam, 160, 120, textures=ext != ".obj")
    assert (a.face_id == b.face_id).mean() > 0.999
    if ext == ".glb":
        assert [i.name for i in back.instances] == [i.name for i in scene.instances]
        assert back.instances[0].mesh is back.instances[1].mesh
        assert np.abs(a.color.astype(int) - b.color.astype(int)).max() <= 2
    if ext == ".obj":  # attributes: uv on every face (else hsr's reader drops them)
        crates = hsr.Scene(scene.instances[:2])
        hsr.write_mesh(crates, tmp_path / "crates.obj")
        mesh = hsr.load(tmp_path / "crates.obj")
        assert np.allclose(mesh.corner_uv[:12], scene.instances[0].mesh.corner_uv)
        assert np.array_equal(mesh.face_colors[:12], scene.instances[0].mesh.face_colors)
        assert mesh.texture is not None and os.path.isfile(mesh.texture)


def test_write_refuses_other_extensions(tmp_path):
    with pytest.raises(hsr.OutputError, match="extension"):
        hsr.write_mesh(_textured_scene(), tmp_path / "out.fbx")


def test_cli_prune_a_glb_assembly_by_objects(tmp_path, capsys):
    scene = box_with_parts()
    src = tmp_path / "assembly.glb"
    hsr.write_mesh(scene, src)
    out = tmp_path / "pruned.glb"
    assert main(["prune", str(src), "-o", str(out), "--views", "sphere:32", "--size", "64",
                 "--level", "objects", "--verify", "6"]) == 0
    text = capsys.readouterr().out
    assert "objects 4 -> 1" in text and "verify: 0 of" in text
    back = hsr.load_scene(out)
    assert [i.name for i in back.instances] == ["housing"]
    assert back.n_faces == scene.instances[0].mesh.n_faces


def test_cli_prune_faces_with_interior_cameras(tmp_path, capsys):
    scene = hsr.Scene([_ball((0, 0, 0), 2.0, 2, "outer"), _ball((0, 0, 0), 1.0, 2, "inner")])
    src = tmp_path / "nested.obj"
    hsr.write_mesh(scene, src)
    inside = [hsr.Camera.look_at((0, 0, 0), d, (0, 1, 0), fov_y=120, near=0.05, far=10)
              for d in ((1, 0, 0), (-1, 0, 0), (0, 0, 1), (0, 0, -1))]
    hsr.write_transforms(tmp_path / "inside.json", inside, 64, 64)
    out = tmp_path / "kept.ply"
    assert main(["prune", str(src), "-o", str(out), "--views", "sphere:32", "--views",
                 str(tmp_path / "inside.json"), "--size", "64", "--quiet"]) == 0
    assert capsys.readouterr().out == ""
    kept = hsr.load(out).n_faces
    assert scene.instances[0].mesh.n_faces < kept <= scene.n_faces


@pytest.mark.parametrize("args, message", [
    (["--views", "cube:3"], "views"),
    (["--min-pixels", "0"], "min_pixels"),
    (["--keep-neighbors", "-2"], "keep_neighbors"),
    (["--size", "0"], "width"),
    (["--size", "big"], "--size"),
    (["--max-views", "0"], "max_views"),
    (["-o", "out.fbx"], "extension"),
    (["--near", "-1"], "near must be > 0"),
    (["--far", "inf"], "far"),
])
def test_cli_prune_errors_are_one_line(args, message, tmp_path, capsys):
    src = tmp_path / "box.obj"
    hsr.write_mesh(box_with_parts(), src)
    argv = ["prune", str(src), "-o", str(tmp_path / "out.obj"), "--size", "32", "--views",
            "sphere:4"] + args
    if "-o" in args:
        argv = ["prune", str(src), "--size", "32"] + [a if a != "out.fbx" else str(
            tmp_path / a) for a in args]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("hsr: error:") and message in err and "\n" not in err


def test_cli_prune_refuses_a_folder_as_model(tmp_path, capsys):
    assert main(["prune", str(tmp_path), "-o", str(tmp_path / "o.obj")]) == 2
    assert "\n" not in capsys.readouterr().err.strip()


def test_transforms_of_interior_cameras_parse(tmp_path):
    """Camera files given as views are used as they are (their own intrinsics)."""
    cams = [hsr.Camera.look_at((0, 0, 0), (0, 0, -1), fov_y=60, near=0.1, far=10)]
    hsr.write_transforms(tmp_path / "t.json", cams, 32, 32)
    data = json.loads((tmp_path / "t.json").read_text())
    assert len(data["frames"]) == 1
    got = hsr.visibility.cameras_for(box_with_parts(), str(tmp_path / "t.json"), 1.0)
    assert len(got) == 1 and np.allclose(got[0].view_matrix, cams[0].view_matrix)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 1_000_000), st.integers(0, 3))
def test_rings_on_random_soups_match_a_set_reference(seed, rings):
    """Random soups on a coarse lattice (repeated positions, edges shared by several
    faces, collapsed edges and faces with a repeated index): each ring adds the faces
    that share an edge, as a set of two distinct positions, with a kept face."""
    rng = np.random.default_rng(seed)
    positions = rng.integers(0, 3, size=(rng.integers(3, 25), 3)).astype(float)
    faces = rng.integers(0, len(positions), size=(rng.integers(1, 50), 3))
    mesh = hsr.Mesh(positions, faces)
    keep = rng.random(len(faces)) < 0.2

    def edges(f):
        corners = [tuple(positions[v]) for v in faces[f]]
        return {frozenset((corners[k], corners[(k + 1) % 3])) for k in range(3)
                if corners[k] != corners[(k + 1) % 3]}

    expected = keep.copy()
    for _ in range(rings):
        reached = set().union(*(edges(f) for f in np.flatnonzero(expected)))
        expected = expected | np.array([bool(edges(f) & reached) for f in range(len(faces))])
    assert np.array_equal(grow_rings(mesh, keep, rings), expected)


def test_auto_views_settle_on_the_closed_box():
    """The automatic decision: a Fibonacci sphere, then random rounds until one changes
    nothing. The box's faces are kept and nothing inside; the views it reports are
    the ones it rendered (recounting them gives its counts, and the views before the
    last round already give its decision); the last round holds at least half as many
    views as came before it; its random directions are not those verify draws from the
    same seed."""
    scene = box_with_parts()
    decision = decide(scene, "auto", 64, seed=3)
    housing = scene.instances[0].mesh.n_faces
    assert decision.converged and decision.size == (64, 64)
    assert np.array_equal(np.flatnonzero(decision.keep), np.arange(housing))
    n, last = decision.views, decision.last_round
    assert last >= max(16, -(-(n - last) // 2)) and n >= 32 + 16
    cameras = list(decision.cameras)
    assert np.array_equal(face_visibility(scene, cameras, 64), decision.counts)
    before = face_visibility(scene, cameras[:n - last], 64)
    assert np.array_equal(keep_faces(scene, before, keep_neighbors=2), decision.keep)
    drawn = np.array([c.eye for c in cameras[32:]]) - scene.bounds().mean(axis=0)
    drawn /= np.linalg.norm(drawn, axis=1, keepdims=True)
    rng = np.random.default_rng(3)  # what verify(seed=3) draws
    theirs = rng.normal(size=(len(drawn), 3))
    theirs /= np.linalg.norm(theirs, axis=1, keepdims=True)
    assert np.abs(drawn @ theirs.T).max() < 0.999999
    # The same seed decides the same way; and prune's default is this decision.
    again = decide(scene, "auto", 64, seed=3)
    assert again.views == n and np.array_equal(again.counts, decision.counts)
    pruned, kept = prune(scene, size=64, seed=3)
    assert np.array_equal(kept, np.flatnonzero(decision.keep))
    assert verify(scene, pruned, kept, 12, 64, seed=3)["changed"] == 0


def test_auto_views_go_on_while_rounds_find_faces():
    """A convex ball shows every face from outside, but at 48 x 48 without rings its
    5,120 small faces take several rounds to be found: each round holds half as many
    views as came before it (at least 16), and the decision ends with every face."""
    m = trimesh.creation.icosphere(subdivisions=4)
    scene = hsr.Scene().add(hsr.Mesh(m.vertices, m.faces))
    decision = decide(scene, "auto", 48, keep_neighbors=0)
    assert decision.converged and decision.keep.all()
    n, last = decision.views, decision.last_round
    assert n > 48 and last == max(16, -(-(n - last) // 2))


def test_auto_views_add_to_interior_cameras(tmp_path):
    """Given views stay in the first round of an automatic decision: cameras inside the
    inner of two nested spheres keep its faces, which no outside view sees."""
    scene = hsr.Scene([_ball((0, 0, 0), 2.0, 2, "outer"), _ball((0, 0, 0), 1.0, 2, "inner")])
    inside = [hsr.Camera.look_at((0, 0, 0), d, (0, 1, 0), fov_y=120, near=0.05, far=10)
              for d in ((1, 0, 0), (-1, 0, 0), (0, 0, 1), (0, 0, -1), (0, 1, 0.01),
                        (0, -1, 0.01))]
    outer = scene.instances[0].mesh.n_faces
    outside_only = decide(scene, "auto", 64)
    assert np.array_equal(np.flatnonzero(outside_only.keep), np.arange(outer))
    both = decide(scene, inside + ["auto"], 64)
    assert both.keep.all() and both.cameras[:len(inside)] == tuple(inside)


def test_auto_size_gives_about_a_pixel_per_face():
    def faces(n):
        tri = np.tile(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float), (n, 1))
        tri += np.repeat(np.arange(n), 3)[:, None] * np.array([0, 0, 1.0])
        return hsr.Scene().add(hsr.Mesh(tri, np.arange(3 * n).reshape(-1, 3)))

    assert auto_size(faces(12)) == 256  # the smallest
    assert auto_size(faces(200_000)) == 512  # sqrt: 447, up to a multiple of 128
    assert auto_size(faces(1_000_000)) == 1024
    assert auto_size(faces(5_000_000)) == 2048  # the largest
    assert decide(faces(12), "sphere:2").size == (256, 256)


def test_auto_stops_at_max_views_and_says_so(tmp_path, capsys):
    scene = box_with_parts()
    short = decide(scene, "auto", 32, max_views=40)
    assert not short.converged and short.views == 32 and short.last_round == 0
    with pytest.warns(hsr.visibility.VisibilityWarning, match="max_views"):
        prune(scene, "auto", 32, max_views=40)
    with pytest.raises(VisibilityError, match="max_views"):
        decide(scene, "auto", 32, max_views=0)
    with pytest.raises(VisibilityError, match="seed"):
        decide(scene, "auto", 32, seed=-1)
    src = tmp_path / "box.glb"
    hsr.write_mesh(scene, src)
    assert main(["prune", str(src), "-o", str(tmp_path / "o.glb"), "--size", "32",
                 "--max-views", "40"]) == 0
    captured = capsys.readouterr()
    assert captured.err.startswith("hsr: warning: no round") and "\n" not in \
        captured.err.strip()
    assert "still changing" in captured.out


def test_cli_prune_defaults_to_auto_views_and_size(tmp_path, capsys):
    scene = box_with_parts()
    src, out = tmp_path / "box.glb", tmp_path / "kept.obj"
    hsr.write_mesh(scene, src)
    assert main(["prune", str(src), "-o", str(out), "--verify", "8"]) == 0
    text = capsys.readouterr().out
    assert "views at 256x256 (auto: the last" in text and "verify: 0 of" in text
    assert hsr.load(out).n_faces == scene.instances[0].mesh.n_faces
