"""glTF / GLB scenes and materials (issue #14, "Scenes and materials"). Files are built here
with trimesh's exporter (and their JSON edited where trimesh cannot write what glTF allows:
shared meshes, several primitives, a node tree); every loaded scene is compared with the
same scene assembled by hand with ``Scene.add``, and colours with values computed here."""

import json
import struct

import numpy as np
import pytest
import trimesh
from PIL import Image

import hsr
from hsr.cli import main

T = trimesh.transformations
W, H = 120, 90


def glb_bytes(scene: trimesh.Scene) -> bytes:
    return scene.export(file_type="glb")


def rewrite_glb(data: bytes, edit) -> bytes:
    """The GLB with its JSON chunk passed through ``edit`` (binary chunk unchanged)."""
    length, = struct.unpack_from("<I", data, 12)
    header = json.loads(data[20:20 + length])
    edit(header)
    text = json.dumps(header).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<I4s", len(text), b"JSON") + text + data[20 + length:]
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def three_nodes():
    """Two instances of a box and an icosphere, with transforms (as trimesh writes them)."""
    box = trimesh.creation.box(extents=(1.0, 0.6, 0.8))
    ball = trimesh.creation.icosphere(subdivisions=1, radius=0.5)
    moves = {"left": T.compose_matrix(translate=(-1.2, 0, 0), angles=(0, 0.4, 0)),
             "ball": T.translation_matrix((0, 0.2, -0.5)),
             "right": T.compose_matrix(translate=(1.3, 0.1, 0.2), angles=(0.3, 0, 0),
                                       scale=(1.2, 1.2, 1.2))}
    scene = trimesh.Scene()
    scene.add_geometry(box, node_name="left", geom_name="box", transform=moves["left"])
    scene.add_geometry(ball, node_name="ball", geom_name="ball", transform=moves["ball"])
    scene.add_geometry(box, node_name="right", geom_name="box", transform=moves["right"])
    return scene, {"box": box, "ball": ball}, moves


def f32(values):
    """What a glTF file stores for positions: float32."""
    return np.asarray(values, dtype=np.float32).astype(np.float64)


def by_hand(parts, order, stored=f32):
    """The scene assembled with Scene.add: (geometry, node, world matrix) in order, from
    the numbers the file stores (float32 positions; node matrices are JSON numbers)."""
    scene = hsr.Scene()
    for geom, name, matrix in order:
        scene.add(hsr.Mesh(stored(parts[geom].vertices), parts[geom].faces), matrix, name=name)
    return scene


def same_render(a, b):
    cam = hsr.views.default(b.bounds(), W / H)
    fa, fb = hsr.render(a, cam, W, H), hsr.render(b, cam, W, H)
    assert (fb.face_id >= 0).sum() > 1000
    assert np.array_equal(fa.face_id, fb.face_id)
    assert np.array_equal(fa.depth, fb.depth)
    assert np.array_equal(fa.object_id, fb.object_id)


def test_nodes_become_instances_in_file_order(tmp_path):
    scene, parts, moves = three_nodes()
    path = tmp_path / "three.glb"
    path.write_bytes(glb_bytes(scene))
    loaded = hsr.load_scene(str(path))
    assert [i.name for i in loaded.instances] == ["left", "ball", "right"]
    expected = by_hand(parts, [("box", "left", moves["left"]),
                               ("ball", "ball", moves["ball"]),
                               ("box", "right", moves["right"])])
    for got, want in zip(loaded.instances, expected.instances):
        assert np.allclose(got.model, want.model, atol=1e-6)
    same_render(loaded, expected)
    # hsr.load refuses several nodes and says what to use; a trimesh.Scene works too.
    with pytest.raises(hsr.MeshError, match="load_scene"):
        hsr.load(str(path))
    with pytest.raises(hsr.MeshError, match="load_scene"):
        hsr.render(scene, hsr.views.default(expected.bounds()), W, H)
    in_memory = hsr.load_scene(scene)  # a trimesh.Scene: float64 positions, insertion order
    assert [i.name for i in in_memory.instances] == ["left", "ball", "right"]
    same_render(in_memory, by_hand(parts, [("box", "left", moves["left"]),
                                           ("ball", "ball", moves["ball"]),
                                           ("box", "right", moves["right"])], np.asarray))


def shared_tree(h):
    """three_nodes' JSON edited: both boxes use one glTF mesh; the roots are listed
    right-then-left and the ball is a child of the left box."""
    names = [n["name"] for n in h["nodes"]]
    left, ball, right = (names.index(k) for k in ("left", "ball", "right"))
    h["nodes"][right]["mesh"] = h["nodes"][left]["mesh"]
    h["nodes"][left]["children"] = [ball]
    h["scenes"][h.get("scene", 0)]["nodes"] = [right, left]


def two_primitives(h):
    """three_nodes' JSON edited: the ball's primitive added to the box's mesh, the left
    box the only root."""
    names = [n["name"] for n in h["nodes"]]
    left, ball = names.index("left"), names.index("ball")
    box_mesh, ball_mesh = h["nodes"][left]["mesh"], h["nodes"][ball]["mesh"]
    h["meshes"][box_mesh]["primitives"] += h["meshes"][ball_mesh]["primitives"]
    h["scenes"][h.get("scene", 0)]["nodes"] = [left]


def test_shared_meshes_trees_and_primitives(tmp_path):
    """Edited JSON: both boxes use one glTF mesh (one hsr Mesh, shared); the roots are
    listed right-then-left and the ball is a child of the left box (its transform composed
    with its parent's); a mesh with two primitives gives NODE/1, NODE/2."""
    scene, parts, moves = three_nodes()
    path = tmp_path / "tree.glb"
    path.write_bytes(rewrite_glb(glb_bytes(scene), shared_tree))
    loaded = hsr.load_scene(str(path))
    assert [i.name for i in loaded.instances] == ["right", "left", "ball"]
    assert loaded.instances[0].mesh is loaded.instances[1].mesh
    expected = by_hand(parts, [("box", "right", moves["right"]),
                               ("box", "left", moves["left"]),
                               ("ball", "ball", moves["left"] @ moves["ball"])])
    same_render(loaded, expected)
    path = tmp_path / "prims.glb"
    path.write_bytes(rewrite_glb(glb_bytes(scene), two_primitives))
    loaded = hsr.load_scene(str(path))
    assert [i.name for i in loaded.instances] == ["left/1", "left/2"]
    same_render(loaded, by_hand(parts, [("box", "a", moves["left"]),
                                        ("ball", "b", moves["left"])]))


def facing_quad(visual=None):
    """A unit quad in the z = 0 plane facing +Z (the camera below looks at it head on)."""
    return trimesh.Trimesh([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]],
                           [[0, 1, 2], [0, 2, 3]], process=False, visual=visual)


CAM = hsr.Camera.look_at((0, 0, 3), (0, 0, 0), fov_y=30, near=1, far=10)


def load_back(tmp_path, mesh, name="m.glb"):
    scene = trimesh.Scene()
    scene.add_geometry(mesh, node_name="only", geom_name="geom")
    path = tmp_path / name
    path.write_bytes(glb_bytes(scene))
    return hsr.load_scene(str(path))


def test_embedded_texture_is_used_the_right_way_up(tmp_path):
    """A texture red in its top half, blue in its bottom half (image rows), mapped with
    v = 1 at the top of the quad: the top of the picture is red, the bottom blue, as the
    same quad assembled by hand with OBJ's texture convention."""
    image = np.zeros((8, 8, 3), np.uint8)
    image[:4] = (255, 0, 0)
    image[4:] = (0, 0, 255)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
    material = trimesh.visual.material.PBRMaterial(baseColorTexture=Image.fromarray(image),
                                                   baseColorFactor=[255, 255, 255, 255])
    loaded = load_back(tmp_path, facing_quad(trimesh.visual.TextureVisuals(
        uv=uv, material=material)))
    mesh = loaded.instances[0].mesh
    assert mesh.texture is not None and mesh.face_colors is None
    frame = hsr.render(loaded, CAM, W, H, texture_filter="nearest")
    covered = frame.face_id >= 0
    rows = np.nonzero(covered.any(axis=1))[0]
    top, bottom = frame.color[rows[2]][covered[rows[2]]], frame.color[rows[-3]][covered[rows[-3]]]
    assert (top == (255, 0, 0)).all() and (bottom == (0, 0, 255)).all()
    quad = facing_quad()
    hand = hsr.Mesh(quad.vertices, quad.faces, corner_uv=uv[quad.faces], texture=image)
    assert np.array_equal(frame.color,
                          hsr.render(hand, CAM, W, H, texture_filter="nearest").color)
    # The same as a .gltf with its buffer and image in separate files beside it.
    parts = trimesh.Scene()
    parts.add_geometry(facing_quad(trimesh.visual.TextureVisuals(uv=uv, material=material)),
                       node_name="only", geom_name="geom")
    folder = tmp_path / "external"
    folder.mkdir()
    for name, data in parts.export(file_type="gltf").items():
        (folder / name).write_bytes(data)
    # trimesh puts the image in a buffer: point the glTF at a PNG file instead.
    doc = json.loads((folder / "model.gltf").read_text())
    doc["images"] = [{"uri": "texture.png", "mimeType": "image/png"}]
    (folder / "model.gltf").write_text(json.dumps(doc))
    Image.fromarray(image).save(folder / "texture.png")
    external = hsr.load_scene(str(folder / "model.gltf"))
    assert np.array_equal(hsr.render(external, CAM, W, H, texture_filter="nearest").color,
                          frame.color)


def test_base_colour_factor_face_and_vertex_colours(tmp_path):
    # Factor alone: a face looking straight at the headlight shows the factor itself.
    material = trimesh.visual.material.PBRMaterial(baseColorFactor=[255, 128, 0, 255])
    loaded = load_back(tmp_path, facing_quad(trimesh.visual.TextureVisuals(material=material)))
    frame = hsr.render(loaded, CAM, W, H)
    assert (frame.color[frame.face_id >= 0] == (255, 128, 0)).all()
    # Face colours through hsr.load of a trimesh object.
    quad = facing_quad()
    quad.visual.face_colors = [[200, 0, 0, 255], [0, 0, 200, 255]]
    frame = hsr.render(hsr.load(quad), CAM, W, H)
    for f, rgb in ((0, (200, 0, 0)), (1, (0, 0, 200))):
        assert (frame.color[frame.face_id == f] == rgb).all()


def test_vertex_colours_are_interpolated(tmp_path):
    """Red, green and blue corners on a triangle facing the camera (constant depth, so
    perspective-correct interpolation is linear in the image): every covered pixel has
    the barycentric mix computed here from OpenCV's pinhole projection, within 1."""
    tri = trimesh.Trimesh([[-1, -1, 0], [1, -1, 0], [0, 1, 0]], [[0, 1, 2]], process=False)
    tri.visual.vertex_colors = [[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255]]
    loaded = load_back(tmp_path, tri)
    assert loaded.instances[0].mesh.corner_colors is not None
    frame = hsr.render(loaded, CAM, W, H)
    K, R, t = CAM.to_opencv(W, H)
    cam_pts = tri.vertices @ R.T + t
    uv = cam_pts[:, :2] / cam_pts[:, 2:] * [K[0, 0], K[1, 1]] + K[:2, 2]
    rows, cols = np.nonzero(frame.face_id == 0)
    assert len(rows) > 500
    m = np.array([[uv[0, 0] - uv[2, 0], uv[1, 0] - uv[2, 0]],
                  [uv[0, 1] - uv[2, 1], uv[1, 1] - uv[2, 1]]])
    l01 = np.linalg.solve(m, np.stack([cols - uv[2, 0], rows - uv[2, 1]]))
    bary = np.vstack([l01, 1 - l01.sum(axis=0)]).T
    expected = bary @ np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255.0]])
    assert np.abs(frame.color[rows, cols] - expected).max() <= 1.01


def test_cli_renders_a_glb_and_checks_textures(tmp_path, capsys):
    scene, _, _ = three_nodes()
    glb = tmp_path / "three.glb"
    glb.write_bytes(glb_bytes(scene))
    out, ids = tmp_path / "out.png", tmp_path / "ids.npy"
    assert main(["render", str(glb), "-o", str(out), "--ids-out", str(ids), "--size", "160x120",
                 "--quiet"]) == 0
    face_id = np.load(ids)
    offsets = hsr.load_scene(str(glb)).face_offsets()
    owners = set(np.searchsorted(offsets, face_id[face_id >= 0], side="right") - 1)
    assert owners == {0, 1, 2}  # every node is drawn
    # --texture: conflicts and unused arguments are errors, never a silent choice.
    quad = tmp_path / "quad.obj"
    quad.write_text("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                    "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    img = tmp_path / "img.png"
    Image.fromarray(np.full((4, 4, 3), 90, np.uint8)).save(img)
    cases = [
        ([str(quad), str(glb), "--texture", str(img)], "say which"),
        ([str(quad), "--texture", str(img), "--texture", str(img)], "two textures"),
        ([str(quad), "--texture", f"nothere.obj={img}"], "not one of the MODELs"),
        ([str(quad), str(glb), "--texture", f"three.glb={img}"], "no texture coordinates"),
    ]
    for args, message in cases:
        capsys.readouterr()
        assert main(["render", *args, "-o", str(out)]) == 2
        assert message in capsys.readouterr().err
    assert main(["render", str(quad), str(glb), "--texture", f"quad.obj={img}", "-o", str(out),
                 "--quiet"]) == 0
