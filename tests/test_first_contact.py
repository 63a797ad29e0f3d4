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
