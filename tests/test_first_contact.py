"""First contact, round two (issue #62): real files look as their authors meant them.
Each case failed before its fix."""

from __future__ import annotations

import json
import os
import struct

import numpy as np

import hsr


def _glb_materials(path) -> list:
    data = open(path, "rb").read()
    (length,) = struct.unpack_from("<I", data, 12)
    return json.loads(data[20:20 + length]).get("materials", [])


def test_a_gltf_texture_without_a_factor_is_drawn_as_it_is(tmp_path):
    """A material with no baseColorFactor means 1 (glTF 2.0, 3.9.2); the loader took
    trimesh's grey main colour (102) as the factor, drawing the Duck at 40% brightness,
    and hsr prune wrote baseColorFactor 0.4 into its output."""
    import trimesh
    from PIL import Image

    texel = np.array([234, 193, 16], np.uint8)
    box = trimesh.creation.box()
    uv = np.random.default_rng(0).random((len(box.vertices), 2))
    material = trimesh.visual.material.PBRMaterial(
        baseColorTexture=Image.fromarray(np.tile(texel, (8, 8, 1))))
    box.visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    path = tmp_path / "duck.glb"
    box.export(path)
    assert "baseColorFactor" not in _glb_materials(path)[0]["pbrMetallicRoughness"]
    mesh = hsr.load(path)
    assert mesh.face_colors is None
    # Seen square on under the headlight, a texel is drawn as the texture holds it.
    cam = hsr.Camera.look_at((0, 0, 5), (0, 0, 0), (0, 1, 0), 30, 1, 10)
    frame = hsr.render(mesh, cam, 32, 32, light="headlight")
    assert np.abs(frame.color[16, 16].astype(int) - texel).max() <= 1
    hsr.write_mesh(mesh, tmp_path / "out.glb")
    factor = _glb_materials(tmp_path / "out.glb")[0]["pbrMetallicRoughness"].get(
        "baseColorFactor", [1, 1, 1, 1])
    assert factor == [1.0, 1.0, 1.0, 1.0]


def _textured_obj(folder, map_line, texel=(10, 200, 30)):
    from PIL import Image

    Image.fromarray(np.tile(np.array(texel, np.uint8), (4, 4, 1))).save(
        os.path.join(folder, "fuze uv.png"))
    with open(os.path.join(folder, "m.mtl"), "w") as fh:
        fh.write(f"newmtl skin\nKd 1 1 1\n{map_line}\n")
    with open(os.path.join(folder, "m.obj"), "w") as fh:
        fh.write("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.1 0.2\nvt 0.3 0.2\n"
                 "vt 0.1 0.4\nusemtl skin\nf 1/1 2/2 3/3\n")
    return os.path.join(folder, "m.obj")


def test_mtl_texture_names_with_spaces_and_options(tmp_path):
    """map_Kd took the last word of 'fuze uv.png' (no texture at all) and ignored the
    -s / -o options; the MTL grammar: options first, then the file name to the end of
    the line."""
    from hsr.scene.obj import map_statement

    assert map_statement("fuze uv.png") == ("fuze uv.png", {})
    assert map_statement("-s 2 3 1 -o 0.5 -clamp on  my tex.jpg") == (
        "my tex.jpg", {"-s": ["2", "3", "1"], "-o": ["0.5"], "-clamp": ["on"]})
    assert map_statement("-bm 0.5 sub/dir/a.png")[0] == "sub/dir/a.png"
    mesh = hsr.load(_textured_obj(tmp_path, "map_Kd fuze uv.png"))
    assert os.path.basename(mesh.texture) == "fuze uv.png"
    np.testing.assert_allclose(mesh.corner_uv[0], [[0.1, 0.2], [0.3, 0.2], [0.1, 0.4]])
    scaled = hsr.load(_textured_obj(tmp_path, "map_Kd -s 2 3 -o 0.5 0.25 fuze uv.png"))
    np.testing.assert_allclose(scaled.corner_uv[0], [[0.7, 0.85], [1.1, 0.85],
                                                      [0.7, 1.45]])


def test_a_missing_texture_is_one_warning_naming_it(tmp_path):
    import contextlib
    import io
    import warnings

    from hsr.cli import main

    path = _textured_obj(tmp_path, "map_Kd gone.png")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mesh = hsr.load(path)
    assert mesh.texture is None
    assert [str(w.message) for w in caught if issubclass(w.category, hsr.HsrWarning)] == [
        "m.mtl:3: map_Kd names 'gone.png', which is not a file beside the model; drawn "
        "without it"]
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        assert main(["render", path, "--size", "16x16", "-o",
                     str(tmp_path / "o.png")]) == 0
    assert err.getvalue().strip().splitlines() == [
        "hsr: warning: m.mtl:3: map_Kd names 'gone.png', which is not a file beside the "
        "model; drawn without it"]
