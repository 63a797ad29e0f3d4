"""Trust, round four (issue #61): no command writes over one of its inputs or over another
of its outputs, a store is written only where nothing, an empty folder or a store of its
own kind is, and every output appears whole or not at all. Each case failed before the
shared output guard (hsr.scene.outputs); every refusal is one line, exit 2, and leaves
every file as it was."""

from __future__ import annotations

import hashlib
import os

import numpy as np
import pytest

import hsr
from conftest import require, run_cli

TRIANGLES = """mtllib look.mtl
v 0 0 0
v 1 0 0
v 0 1 0
v 1 1 -1
vt 0 0
vt 1 0
vt 0 1
usemtl skin
f 1/1 2/2 3/3
f 2/2 4/3 3/1
"""


@pytest.fixture
def textured(tmp_path):
    """A folder with an OBJ, the .mtl it names and the texture the .mtl names, and a
    fingerprint of every file in it (to show nothing changed)."""
    from PIL import Image

    (tmp_path / "m.obj").write_text(TRIANGLES)
    (tmp_path / "look.mtl").write_text("newmtl skin\nKd 1 1 1\nmap_Kd tex.png\n")
    Image.fromarray(np.full((4, 4, 3), 200, np.uint8)).save(tmp_path / "tex.png")
    (tmp_path / "notes.txt").write_text("a user's notes")
    return tmp_path


def fingerprint(folder) -> dict:
    out = {}
    for root, _, files in os.walk(folder):
        for name in files:
            path = os.path.join(root, name)
            with open(path, "rb") as fh:
                out[os.path.relpath(path, folder)] = hashlib.sha256(fh.read()).hexdigest()
    return out


def refused(args, message):
    code, err = run_cli(args)
    assert code == 2 and len(err) == 1 and err[0].startswith("hsr: error: "), (args, err)
    assert message in err[0], err[0]


def test_the_loader_records_what_it_read(textured):
    mesh = hsr.load(textured / "m.obj")
    assert mesh.texture and os.path.samefile(mesh.texture, textured / "tex.png")
    names = sorted(os.path.basename(p) for p in mesh.sources)
    assert names == ["look.mtl", "m.obj", "tex.png"]
    assert sorted(os.path.basename(p) for p in hsr.Scene([mesh]).sources()) == names


@pytest.mark.parametrize("args, message", [
    (["-o", "tex.png"], "-o tex.png is a file the model is read from"),  # overwrote it
    (["-o", "a.png", "--depth-out", "a.png"], "are the same file"),
    (["-o", "a.png", "--normals-out", "./a.png"], "are the same file"),
    (["-o", "x.png", "--error-map", "x.png"], "are the same file"),
    (["-o", "v.png", "--orbit", "2", "--depth-out", "v.png"], "are the same file"),
    (["-o", "tex.png", "--orbit", "2", "--ids-out", "tex.npy"], None),  # tex_000.png
])
def test_render_never_writes_over_an_input_or_another_output(textured, monkeypatch, args,
                                                             message):
    monkeypatch.chdir(textured)
    before = fingerprint(textured)
    if message is None:
        code, err = run_cli(["render", "m.obj", "--size", "16x16", "--quiet", *args])
        assert code == 0, err
        after = fingerprint(textured)
        assert {k: v for k, v in after.items() if k in before} == before
        return
    refused(["render", "m.obj", "--size", "16x16", *args], message)
    assert fingerprint(textured) == before


def test_a_hard_link_or_a_texture_option_is_an_input_too(textured, monkeypatch):
    monkeypatch.chdir(textured)
    os.link("tex.png", "alias.png")
    before = fingerprint(textured)
    refused(["render", "m.obj", "--size", "16x16", "-o", "alias.png"], "an input")
    refused(["render", "m.obj", "--size", "16x16", "--texture", "notes.txt", "-o",
             "notes.txt"], "notes.txt")
    refused(["explain", "depth", "m.obj", "--size", "32x32", "-o", "tex.png"], "an input")
    refused(["compare", "m.obj", "--size", "32x32", "--montage", "tex.png"], "an input")
    assert fingerprint(textured) == before


def test_partition_never_deletes_a_model_or_an_ordinary_file(textured, monkeypatch):
    """--out MODEL --force deleted the model; --out notes.txt --force any file."""
    require("zarr")
    monkeypatch.chdir(textured)
    before = fingerprint(textured)
    refused(["partition", "m.obj", "--parts", "1", "--out", "m.obj", "--force"],
            "would replace the model")
    refused(["partition", "m.obj", "--parts", "1", "--out", "notes.txt", "--force"],
            "not a folder")
    os.mkdir("mine")
    (textured / "mine" / "keep.txt").write_text("mine")
    refused(["partition", "m.obj", "--parts", "1", "--out", "mine", "--force"],
            "not a store hsr wrote")
    refused(["partition", "m.obj", "--parts", "1", "--out", ".", "--force"],
            "would replace the model")
    assert fingerprint(textured) == dict(before, **{"mine/keep.txt": fingerprint(
        textured / "mine")["keep.txt"]})
    code, err = run_cli(["partition", "m.obj", "--parts", "2", "--out", "s.zarr", "--quiet"])
    assert code == 0, err
    refused(["partition", "m.obj", "--parts", "2", "--out", "s.zarr"], "--force")
    code, err = run_cli(["partition", "m.obj", "--parts", "1", "--out", "s.zarr", "--force",
                         "--quiet"])
    assert code == 0 and hsr.load_scene("s.zarr").parts == 1


def test_batch_zarr_never_wipes_a_folder_it_did_not_write(textured, monkeypatch):
    """--format zarr --out O wiped O/<stem>.zarr holding the user's files; an ordinary
    file there ended in a traceback."""
    require("zarr")
    require("distributed")
    from hsr.batch import render_views

    monkeypatch.chdir(textured)
    os.makedirs("O/m.zarr")
    (textured / "O" / "m.zarr" / "thesis.tex").write_text("years of work")
    args = ["batch", "m.obj", "--views", "orbit:2", "--size", "16x16", "--out", "O",
            "--format", "zarr", "--workers", "1", "--quiet"]
    refused(args, "not a store hsr wrote")
    refused(args + ["--force"], "not a store hsr wrote")
    assert (textured / "O" / "m.zarr" / "thesis.tex").read_text() == "years of work"
    os.makedirs("P")
    (textured / "P" / "m.zarr").write_text("a file")
    refused(["batch", "m.obj", "--views", "orbit:2", "--out", "P", "--format", "zarr"],
            "not a folder")
    # Its own store: replaced with --force, continued with --resume, else refused.
    first = render_views(["m.obj"], "orbit:2", (16, 16), ("ids",), "Q", format="zarr",
                         workers=1)
    assert first.rendered == 2
    with pytest.raises(hsr.HsrError, match="--force"):
        render_views(["m.obj"], "orbit:2", (16, 16), ("ids",), "Q", format="zarr", workers=1)
    assert render_views(["m.obj"], "orbit:2", (16, 16), ("ids",), "Q", format="zarr",
                        workers=1, resume=True).skipped == 2
    assert render_views(["m.obj"], "orbit:2", (16, 16), ("ids",), "Q", format="zarr",
                        workers=1, force=True).rendered == 2


def test_batch_refuses_inputs_inside_what_it_writes(textured, monkeypatch):
    require("distributed")
    from hsr.batch import render_views

    monkeypatch.chdir(textured)
    os.makedirs("out/m")
    os.replace("m.obj", "out/m/m.obj")
    for name in ("look.mtl", "tex.png"):
        os.replace(name, f"out/m/{name}")
    with pytest.raises(hsr.HsrError, match="holds the input"):
        render_views(["out/m/m.obj"], "orbit:2", (16, 16), ("color",), "out", workers=1)
    # The model's texture inside what the job writes, seen once the worker loads it.
    os.makedirs("elsewhere/m")
    (textured / "elsewhere" / "m.obj").write_text(TRIANGLES.replace("look.mtl",
                                                                    "m/look.mtl"))
    (textured / "elsewhere" / "m" / "look.mtl").write_text(
        "newmtl skin\nKd 1 1 1\nmap_Kd tex.png\n")
    os.replace("out/m/tex.png", "elsewhere/tex.png")
    result = render_views(["elsewhere/m.obj"], "orbit:2", (16, 16), ("color",), "elsewhere",
                          workers=1)
    assert result.failed == 2 and "holds the input" in result.rows[0]["error"]


def test_prune_never_writes_a_companion_over_an_input(textured, monkeypatch):
    """An OBJ's .mtl beside the pruned model replaced the input's .mtl of that name."""
    monkeypatch.chdir(textured)
    before = fingerprint(textured)
    refused(["prune", "m.obj", "-o", "look.obj", "--force", "--views", "sphere:4",
             "--size", "16"], "look.mtl is a file the model is read from")
    mesh = hsr.load("m.obj")  # the library's writer too, even when told to overwrite
    for target in ("m.obj", "look.obj"):
        with pytest.raises(hsr.OutputError, match="read from"):
            hsr.write_mesh(mesh, target, overwrite=True)
    assert fingerprint(textured) == before


def test_visibility_writes_the_sparse_convention_and_square_sizes(textured, monkeypatch):
    import scipy.sparse

    monkeypatch.chdir(textured)
    code, err = run_cli(["visibility", "m.obj", "--views", "sphere:3", "--size", "24",
                         "-o", "f.npz", "--quiet"])
    assert code == 0, err
    matrix = scipy.sparse.load_npz("f.npz")
    scene = hsr.load_scene("m.obj")
    want = hsr.visibility_matrix(scene, hsr.views.sphere(scene.bounds(), 3, 1.0), 24)
    assert matrix.shape == (2, 3)
    assert (matrix.toarray() == want.counts.toarray()).all()
    np.save("pts.npy", np.array([[0.2, 0.2, 0.0], [9.0, 9.0, 9.0]]))
    code, err = run_cli(["visibility", "m.obj", "--views", "sphere:3", "--what",
                         "points:pts.npy", "-o", "p.npz", "--quiet"])
    assert code == 0, err
    seen = scipy.sparse.load_npz("p.npz")
    assert seen.shape == (2, 3) and (seen.toarray() == np.load("p.npz")["visible"]).all()
    for flag in (["--algorithm", "painter"], ["--cull", "back"], ["--depth-func", "lequal"]):
        refused(["visibility", "m.obj", "--views", "sphere:2", "--what", "vertices", "-o",
                 "v.npz", *flag], f"{flag[0]} goes with --what faces")


def test_a_failed_write_leaves_the_old_file_and_no_scratch(tmp_path):
    from hsr.scene.outputs import staged

    target = tmp_path / "a.png"
    target.write_bytes(b"old")
    with pytest.raises(RuntimeError):
        with staged(target) as tmp:
            with open(tmp, "wb") as fh:
                fh.write(b"half")
            raise RuntimeError("the render failed")
    assert target.read_bytes() == b"old" and os.listdir(tmp_path) == ["a.png"]
    with staged(target) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(b"new")
    assert target.read_bytes() == b"new" and os.listdir(tmp_path) == ["a.png"]


def test_fog_of_huge_densities_gives_no_warning(textured, monkeypatch):
    """--fog exp:1e308 printed a NumPy overflow warning (run_cli makes it an error)."""
    monkeypatch.chdir(textured)
    for fog in ("exp:1e308", "exp2:1e200", "linear:-1e308,1e308"):
        code, err = run_cli(["render", "m.obj", "--size", "16x16", "--fog", fog, "-o",
                             "f.png", "--quiet"])
        assert code == 0, (fog, err)
    wide = hsr.Fog("linear", start=-1e308, end=1e308)
    assert wide.factor(np.array([0.0]))[0] == pytest.approx(0.5)


# --- things people already hold ------------------------------------------------------

def test_a_list_of_paths_and_meshes_is_one_scene(textured, models_dir):
    """hsr.load_scene([a, b]) and hsr.render([...]) take several models as the command
    line's MODELs do: the instances in order, face ids global in that order."""
    cube = hsr.scenes.cube()
    spot = os.path.join(models_dir, "spot.obj")
    scene = hsr.load_scene([str(textured / "m.obj"), cube, spot])
    parts = [hsr.load(textured / "m.obj"), cube, hsr.load(spot)]
    assert [i.mesh.n_faces for i in scene.instances] == [p.n_faces for p in parts]
    cam = hsr.views.default(scene, 1.0)
    together = hsr.render([str(textured / "m.obj"), cube, spot], cam, 48, 48)
    by_hand = hsr.render(hsr.Scene(parts), cam, 48, 48)
    assert np.array_equal(together.face_id, by_hand.face_id)
    assert (together.face_id >= parts[0].n_faces + cube.n_faces).any()  # spot is seen
    assert hsr.load_scene((cube.positions, cube.faces)).n_faces == cube.n_faces
    with pytest.raises(hsr.MeshError, match="empty list"):
        hsr.load_scene([])


def test_open3d_and_pyvista_meshes_are_taken_as_they_are(models_dir):
    """An Open3D TriangleMesh and a PyVista PolyData (quads triangulated by PyVista) are
    scenes; compared with the same mesh read by hsr.load."""
    import sys

    if sys.version_info >= (3, 13):
        pytest.skip("open3d-cpu has no wheel for Python 3.13 and later")
    o3d = require("open3d")
    pv = require("pyvista")

    path = os.path.join(models_dir, "spot.obj")
    mesh = hsr.load(path)
    tm = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(mesh.positions),
                                   o3d.utility.Vector3iVector(mesh.faces.astype(np.int32)))
    tm.vertex_colors = o3d.utility.Vector3dVector(np.full(mesh.positions.shape, 0.5))
    got = hsr.load_scene(tm).instances[0].mesh
    assert np.array_equal(got.positions, mesh.positions)
    assert np.array_equal(got.faces, mesh.faces)
    assert (got.corner_colors == 128).all()
    cam = hsr.views.default(mesh, 1.0)
    assert np.array_equal(hsr.render(tm, cam, 64, 64).face_id,
                          hsr.render(mesh, cam, 64, 64).face_id)
    flat = np.column_stack([np.full(mesh.n_faces, 3), mesh.faces]).ravel()
    poly = pv.PolyData(mesh.positions, flat)
    assert np.array_equal(hsr.load_scene(poly).instances[0].mesh.faces, mesh.faces)
    quad = pv.PolyData(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float),
                       np.array([4, 0, 1, 2, 3]))
    assert hsr.load_scene(quad).n_faces == 2
    assert hsr.load_scene([tm, poly]).n_faces == 2 * mesh.n_faces
    assert "open3d" in sys.modules and "pyvista" in sys.modules  # imported by the test


def test_a_scene_of_plain_meshes_imports_neither_open3d_nor_pyvista():
    import subprocess
    import sys

    code = ("import sys, hsr; hsr.render(hsr.scenes.cube(), hsr.views.default("
            "hsr.scenes.cube()), 16, 16); print('open3d' in sys.modules, "
            "'pyvista' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    assert out.stdout.split() == ["False", "False"], out.stderr
