"""Loading meshes: face order kept, n-gons fanned, attributes kept, bad input refused."""

import os

import numpy as np
import pytest
import trimesh

import hsr
from hsr.errors import MeshError
from reference import ambiguous_pixels, compare, reference_render


def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def parse_obj_positions(path):
    """Independent OBJ reading (positions only) to check face order: (F, 3, 3)."""
    verts, tris = [], []
    for line in open(path):
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            verts.append([float(x) for x in parts[1:4]])
        elif parts[0] == "f":
            idx = [int(t.split("/")[0]) for t in parts[1:]]
            idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
            for k in range(1, len(idx) - 1):
                tris.append([verts[idx[0]], verts[idx[k]], verts[idx[k + 1]]])
    return np.array(tris)


def test_shared_models_keep_file_order(models_dir):
    for name in sorted(os.listdir(models_dir)):
        if not name.endswith(".obj"):
            continue
        path = os.path.join(models_dir, name)
        mesh = hsr.load(path)
        expected = parse_obj_positions(path)
        assert np.array_equal(mesh.positions[mesh.faces], expected), name


def test_ngons_fan_in_file_order_with_negative_indices(tmp_path):
    path = write(tmp_path, "ngon.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv -1 0.5 0\n"
                 "f 1 2 3 4 5\nf -1 -3 -4\n")
    mesh = hsr.load(path)
    assert mesh.faces.tolist() == [[0, 1, 2], [0, 2, 3], [0, 3, 4], [4, 2, 1]]


def test_uv_normals_and_materials_kept_in_order(tmp_path):
    write(tmp_path, "m.mtl", "newmtl red\nKd 1 0 0\nnewmtl green\nKd 0 1 0\n")
    path = write(tmp_path, "m.obj", "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                 "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
                 "usemtl red\nf 1/1/1 2/2/1 3/3/1\nusemtl green\nf 1/1/1 3/3/1 4/4/1\n"
                 "usemtl red\nf 2/2/1 3/3/1 4/4/1\n")
    mesh = hsr.load(path)
    assert mesh.faces.tolist() == [[0, 1, 2], [0, 2, 3], [1, 2, 3]]
    assert mesh.corner_uv[1].tolist() == [[0, 0], [1, 1], [0, 1]]
    assert np.allclose(mesh.corner_normals, [0, 0, 1])
    assert mesh.face_colors.tolist() == [[255, 0, 0], [0, 255, 0], [255, 0, 0]]


def test_mixed_face_token_forms(tmp_path):
    path = write(tmp_path, "mix.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n"
                 "f 1 2 3\nf 1/1 2/1 3/1\nf 1//1 2//1 3//1\nf 1/1/1 2/1/1 3/1/1\n")
    assert hsr.load(path).faces.tolist() == [[0, 1, 2]] * 4


@pytest.mark.parametrize("ext", ["ply", "stl", "off", "glb"])
def test_trimesh_formats_keep_face_order(tmp_path, ext):
    sphere = trimesh.creation.icosphere(subdivisions=2)
    rng = np.random.default_rng(0)
    order = rng.permutation(len(sphere.faces))
    mesh_in = trimesh.Trimesh(sphere.vertices, sphere.faces[order], process=False)
    path = str(tmp_path / f"s.{ext}")
    mesh_in.export(path)
    mesh = hsr.load(path)
    assert np.allclose(mesh.positions[mesh.faces], mesh_in.vertices[mesh_in.faces], atol=1e-6)


def test_arrays_and_trimesh_objects():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    f = np.array([[0, 1, 2]])
    assert hsr.load((v, f)).faces.tolist() == [[0, 1, 2]]
    assert hsr.load(trimesh.Trimesh(v, f, process=False)).n_faces == 1


@pytest.mark.parametrize("text,message", [
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "vertex index 4 outside 1..3"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "vertex index 0"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", "bad face vertex 'x'"),
    ("v 0 0 0\nv 1 a 0\nv 0 1 0\nf 1 2 3\n", ":2: bad vertex"),
    ("v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n", "NaN or infinite"),
    ("v 0 0 0\nv 1 inf 0\nv 0 1 0\nf 1 2 3\n", "NaN or infinite"),
    ("v 0 0 0\nv 1 0 0\n", "empty"),
    ("", "empty"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", "at least 3 vertices"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/2 2/1 3/1\n", "texture index 2 outside 1..1"),
])
def test_malformed_obj(tmp_path, text, message):
    path = write(tmp_path, "bad.obj", text)
    with pytest.raises(MeshError, match=message.replace("(", r"\(").replace(".", r"\.")):
        hsr.load(path)


def test_missing_and_unreadable_files(tmp_path):
    with pytest.raises(MeshError, match="file not found"):
        hsr.load(str(tmp_path / "nope.obj"))
    with pytest.raises(MeshError, match="directory"):
        hsr.load(str(tmp_path))
    junk = tmp_path / "junk.ply"
    junk.write_bytes(b"\x00\x01garbage" * 20)
    with pytest.raises(MeshError):
        hsr.load(str(junk))


@pytest.mark.parametrize("faces,message", [
    (np.array([[0, 1, 3]]), "outside 0..2"),
    (np.array([[0, -1, 2]]), "outside 0..2"),
    (np.zeros((0, 3), int), "empty"),
    (np.array([[0, 1]]), "shape"),
    (np.array([[0.5, 1, 2]]), "integers"),
])
def test_bad_arrays(faces, message):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    with pytest.raises(MeshError, match=message):
        hsr.Mesh(v, faces)


def test_unused_nan_vertex_is_allowed_used_one_is_not():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [np.nan, 0, 0]], float)
    hsr.Mesh(v, np.array([[0, 1, 2]]))
    with pytest.raises(MeshError, match="vertex 3"):
        hsr.Mesh(v, np.array([[0, 1, 3]]))


def test_a_used_huge_vertex_is_refused_by_name_and_unused_ones_do_not_count(tmp_path):
    """The validation's one flat pass (all used vertices within bounds) and its search for
    the culprit (one is not) give the same answers as a vertex-by-vertex check."""
    v = np.array([[0, 0, 0], [2, 0, 0], [0, -3, 0], [1e101, 0, 0], [np.inf, 0, 0]], float)
    assert hsr.Mesh(v, np.array([[0, 1, 2]])).extent() == 3.0  # the unused ones ignored
    with pytest.raises(MeshError, match=r"vertex 3 has a coordinate beyond \+-1e\+100"):
        hsr.Mesh(v, np.array([[0, 1, 3]]))
    with pytest.raises(MeshError, match="vertex 4 has a NaN or infinite coordinate"):
        hsr.Mesh(v, np.array([[0, 4, 3]]))  # the non-finite one named first
    obj = tmp_path / "huge.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1e101 0\nf 1 2 3\n")
    with pytest.raises(MeshError, match="vertex 2 has a coordinate beyond"):
        hsr.load(str(obj))


def test_unused_nan_and_huge_vertices_render_like_the_reference():
    # Unused vertices may hold anything (Mesh accepts them); placing the mesh in a scene
    # once measured its reach over every vertex, NaN included, and refused to render.
    v = np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0], [np.nan, 0, 0], [1e300, 0, 0],
                  [-1, 1, -0.5], [0.5, -1, 0.5], [1, 1, -0.5]], float)
    mesh = hsr.Mesh(v, np.array([[0, 1, 2], [5, 6, 7]]))
    camera = hsr.Camera(eye=(0.3, 0.2, 4.0), target=(0, 0, 0), up=(0, 1, 0), fov_y=45)
    frame = hsr.render(mesh, camera, 48, 40)
    ref_face, ref_depth = reference_render(mesh, camera, 48, 40)
    amb = ambiguous_pixels(mesh, camera, 48, 40)
    face_bad, depth_bad, compared = compare(frame.face_id, frame.depth, ref_face, ref_depth,
                                            amb)
    assert (face_bad, depth_bad) == (0, 0) and compared > 1500
    assert set(np.unique(frame.face_id)) == {-1, 0, 1}
    assert mesh.extent() == 1.0


def test_extent_follows_replaced_positions():
    mesh = hsr.Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0], [9, 9, 9]], float),
                    np.array([[0, 1, 2]]))
    assert mesh.extent() == 2.0
    mesh.positions = mesh.positions * 3
    assert mesh.extent() == 6.0


def test_degenerate_mask_follows_replaced_arrays_and_the_render_with_it():
    # The mask is judged once per positions/faces array (a render asks every view); a
    # mesh given new positions must not keep skipping a face that is no longer flat.
    flat = np.array([[-1, -1, 0], [1, -1, 0], [0, -1, 0], [-1, 1, 0]], float)
    mesh = hsr.Mesh(flat, np.array([[0, 1, 2], [0, 1, 3]]))
    camera = hsr.Camera(eye=(0, 0, 4.0), target=(0, 0, 0), up=(0, 1, 0), fov_y=45)
    assert mesh.degenerate_mask().tolist() == [True, False]
    assert set(np.unique(hsr.render(mesh, camera, 40, 40).face_id)) == {-1, 1}
    mesh.positions = np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0.5], [-1, 1, 0]], float)
    assert mesh.degenerate_mask().tolist() == [False, False]
    frame = hsr.render(mesh, camera, 40, 40)
    ref_face, ref_depth = reference_render(mesh, camera, 40, 40)
    amb = ambiguous_pixels(mesh, camera, 40, 40)
    assert compare(frame.face_id, frame.depth, ref_face, ref_depth, amb)[:2] == (0, 0)
    assert 0 in frame.face_id
    with pytest.raises(ValueError):
        mesh.degenerate_mask()[0] = True  # read-only: callers cannot corrupt it


def _two_part_scene():
    a = hsr.Mesh(np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0]], float), np.array([[0, 1, 2]]))
    b = hsr.Mesh(np.array([[-1, 1, -0.5], [0.5, -1, 0.5], [1, 1, -0.5], [5, 5, 5]], float),
                 np.array([[0, 1, 2], [0, 0, 1]]))
    return hsr.Scene([a, b]), a, b


def test_assembled_joins_the_instances_in_submission_order():
    scene, a, b = _two_part_scene()
    positions, faces, degenerate, owner = scene.assembled()
    assert np.array_equal(positions, np.vstack([a.positions, b.positions]))
    assert np.array_equal(faces, np.vstack([a.faces, b.faces + 3]))
    assert degenerate.tolist() == [False, False, True]
    assert owner.tolist() == [0, 0, 0, 1, 1, 1, 1]
    assert scene.assembled()[1] is faces  # kept between calls


def test_renders_follow_a_scene_whose_parts_change():
    # The joined arrays are kept on the scene between renders; a render after an
    # instance is added or a mesh gets new positions must not draw the old geometry.
    scene, a, b = _two_part_scene()
    camera = hsr.Camera(eye=(0.2, 0.1, 4.0), target=(0, 0, 0), up=(0, 1, 0), fov_y=45)

    def matches_reference():
        frame = hsr.render(scene, camera, 40, 36)
        ref_face, ref_depth = reference_render(scene, camera, 40, 36)
        amb = ambiguous_pixels(scene, camera, 40, 36)
        return compare(frame.face_id, frame.depth, ref_face, ref_depth, amb)[:2] == (0, 0)

    assert matches_reference()
    b.positions = b.positions + np.array([0.3, 0.0, 0.4])
    assert matches_reference()
    scene.add(hsr.Mesh(np.array([[-2, -2, 0.2], [0, -2, 0.2], [-1, 0.5, 0.2]], float),
                       np.array([[0, 1, 2]])))
    assert matches_reference()
    assert 3 in hsr.render(scene, camera, 40, 36).face_id


def test_a_pickled_scene_leaves_its_joined_arrays_behind():
    import pickle

    scene, _, _ = _two_part_scene()
    scene.assembled()
    copy = pickle.loads(pickle.dumps(scene))
    assert not hasattr(copy, "_assembled")
    assert np.array_equal(copy.assembled()[1], scene.assembled()[1])
