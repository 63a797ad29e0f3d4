"""Partitioned stores damaged in every array and in their metadata, each case read by
every command that reads a store (batch, prune, render, visibility) and by the library:
one line and exit 2 (a PartitionError), never a hang, a traceback, memory exhausted, or
exit 0 with a picture made of fill values; no output is left behind (issue #61).

Before the checks: a deleted chunk read as zeros (369 pixels differed, prune wrote 3,489
of 5,199 faces); a FIFO chunk or zarr.json blocked every command; zarr.json linked to
/dev/zero read until memory ran out; a missing name was a KeyError."""

from __future__ import annotations

import json
import os
import shutil

import numpy as np
import pytest

import hsr
from conftest import require, run_cli
from fuzz.guards import time_limit

require("zarr")

ARRAYS = ("positions", "faces", "face_id", "vertex_start", "vertex_id", "face_colors",
          "corner_uv")


@pytest.fixture(scope="module")
def good_store(tmp_path_factory):
    """Three parts of equal size of a two-instance scene with face colours, texture
    coordinates and a texture given as an array (every kind of array a store holds)."""
    folder = tmp_path_factory.mktemp("stores")
    mesh = hsr.scenes.cube()
    n = mesh.n_faces
    uv = np.tile(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]), (n, 1, 1))
    colored = hsr.Mesh(mesh.positions, mesh.faces, corner_uv=uv,
                       face_colors=np.full((n, 3), 90, np.uint8),
                       texture=np.full((4, 4, 3), 200, np.uint8), name="painted")
    scene = hsr.Scene()
    scene.add(colored, name="a")
    scene.add(colored, np.array([[1, 0, 0, 3], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]],
                                float), name="b")
    store = hsr.partition(scene, 3, folder / "good.zarr")
    assert len(set(store.part_faces)) == 1  # equal parts: a face_id array can be swapped
    return folder / "good.zarr"


def _chunk(folder):
    for root, _, files in os.walk(folder / "c"):
        for name in files:
            return os.path.join(root, name)
    raise AssertionError(f"no chunk in {folder}")


def _meta(folder, change):
    doc = json.loads((folder / "zarr.json").read_text())
    change(doc)
    (folder / "zarr.json").write_text(json.dumps(doc))


def _fifo(path):
    os.remove(path)
    os.mkfifo(path)


def _link(path, target):
    os.remove(path)
    os.symlink(target, path)


# Damage to one array's folder: (name, function of the array folder, words of the error).
ARRAY_DAMAGE = [
    ("chunk deleted", lambda a: os.remove(_chunk(a)), "missing"),
    ("chunk a FIFO", lambda a: _fifo(_chunk(a)), "not a regular file"),
    ("chunk a link", lambda a: _link(_chunk(a), "/etc/hostname"), "not a regular file"),
    ("chunk cut short", lambda a: open(_chunk(a), "r+b").truncate(3), "cannot be read"),
    ("zarr.json a FIFO", lambda a: _fifo(a / "zarr.json"), "not a regular file"),
    ("zarr.json to /dev/zero", lambda a: _link(a / "zarr.json", "/dev/zero"),
     "not a regular file"),
    ("zarr.json deleted", lambda a: os.remove(a / "zarr.json"), "not found"),
    ("zarr.json not JSON", lambda a: (a / "zarr.json").write_text("{"), "not JSON"),
    ("shape grown", lambda a: _meta(a, lambda d: d.update(shape=[d["shape"][0] + 1]
                                                           + d["shape"][1:])), ""),
    ("shape 10^12 rows", lambda a: _meta(a, lambda d: d.update(shape=[10 ** 12]
                                                                + d["shape"][1:])), ""),
    ("dtype changed", lambda a: _meta(a, lambda d: d.update(data_type="float32")), "dtype"),
    ("chunk size 0", lambda a: _meta(a, lambda d: d["chunk_grid"]["configuration"].update(
        chunk_shape=[0] * len(d["shape"]))), "chunk grid"),
    ("sharded", lambda a: _meta(a, lambda d: d.update(codecs=[{"name": "sharding_indexed"}])),
     "codecs"),
    ("keys with dots", lambda a: _meta(a, lambda d: d.update(chunk_key_encoding={
        "name": "default", "configuration": {"separator": "."}})), "chunk keys"),
]


def _root(change):
    def damage(store):
        _meta(store, lambda d: change(d["attributes"]["hsr"]))
    return damage


def _swap_face_ids(store):
    shutil.rmtree(store / "part_0001" / "face_id")
    shutil.copytree(store / "part_0000" / "face_id", store / "part_0001" / "face_id")


STORE_DAMAGE = [
    ("root zarr.json a FIFO", lambda s: _fifo(s / "zarr.json"), "not a partitioned scene"),
    ("root zarr.json to /dev/zero", lambda s: _link(s / "zarr.json", "/dev/zero"),
     "not a partitioned scene"),
    ("no name", _root(lambda m: m["instances"][0].pop("name")), "name"),
    ("no mesh_name", _root(lambda m: m["instances"][1].pop("mesh_name")), "mesh_name"),
    ("texture array missing", _root(lambda m: m["instances"][0].update(
        texture={"array": "texture_0042"})), "texture_0042"),
    ("texture a list", _root(lambda m: m["instances"][0].update(texture=[1])), "texture"),
    ("version 1", _root(lambda m: m.update(version=1)), "version"),
    ("10^12 faces", _root(lambda m: m.update(n_faces=10 ** 12, part_faces=[
        10 ** 12 - 2 * m["part_faces"][0]] + m["part_faces"][1:])), "hsr reads"),
    ("two parts share faces", _swap_face_ids, "earlier part"),
    ("a part folder a FIFO", lambda s: (shutil.rmtree(s / "part_0002"),
                                        os.mkfifo(s / "part_0002")), "not a regular file"),
]


def _every_reader(store, tmp_path, message, words=""):
    """Each command and the library refuse ``store`` in one line, quickly, writing
    nothing."""
    out = tmp_path / "out"
    out.mkdir()
    commands = [
        ["batch", str(store), "--views", "orbit:1", "--size", "16x16", "--out",
         str(out / "b"), "--quiet"],
        ["prune", str(store), "-o", str(out / "p.obj"), "--views", "sphere:2", "--size",
         "16", "--quiet"],
        ["render", str(store), "-o", str(out / "r.png"), "--size", "16x16"],
        ["visibility", str(store), "--views", "sphere:2", "-o", str(out / "v.npz")],
    ]
    for args in commands:
        with time_limit(60):
            code, err = run_cli(args)
        assert code == 2 and len(err) == 1 and err[0].startswith("hsr: error: "), (args, err)
        # render and visibility take mesh files: a store whose damage shows only when
        # its data is read is refused as a store (before any of it is read).
        assert (message in err[0] and words in err[0]) or (
            args[0] in ("render", "visibility")
            and "is a partitioned scene" in err[0]), (args, err[0])
        left = [f for root, _, files in os.walk(out) for f in files]
        assert not left, (args, left)
    with time_limit(60), pytest.raises(hsr.HsrError):
        hsr.batch.render_partitioned(str(store), [hsr.Camera.look_at((0, 0, 9), (0, 0, 0))],
                                     16, 16)


@pytest.mark.parametrize("array", ARRAYS)
@pytest.mark.parametrize("damage", ARRAY_DAMAGE, ids=[d[0] for d in ARRAY_DAMAGE])
def test_a_damaged_array_is_refused_by_every_reader(good_store, tmp_path, array, damage):
    store = tmp_path / "s.zarr"
    shutil.copytree(good_store, store, symlinks=True)
    _, change, words = damage
    change(store / "part_0001" / array)
    # The error names the store, the part and the array (a FIFO or link: its path).
    where = (f"part_0001/{array}/" if any(w in damage[0] for w in ("FIFO", "link", "/dev"))
             else f"part 1, array {array}")
    _every_reader(store, tmp_path, where, words)


@pytest.mark.parametrize("damage", STORE_DAMAGE, ids=[d[0] for d in STORE_DAMAGE])
def test_damaged_metadata_is_refused_by_every_reader(good_store, tmp_path, damage):
    store = tmp_path / "s.zarr"
    shutil.copytree(good_store, store, symlinks=True)
    _, change, words = damage
    change(store)
    _every_reader(store, tmp_path, words)


def test_a_damaged_texture_array_is_refused(good_store, tmp_path):
    store = tmp_path / "s.zarr"
    shutil.copytree(good_store, store)
    texture = next(p for p in store.iterdir() if p.name.startswith("texture_"))
    _meta(texture, lambda d: d.update(shape=[100000, 100000, 3]))
    _every_reader(store, tmp_path, "a texture must be")


def test_the_good_store_reads_as_written(good_store):
    """The cases above start from a store every reader takes."""
    store = hsr.load_scene(good_store)
    scene, face_id = store.part(1)
    assert len(face_id) == store.part_faces[1] and scene.n_faces == len(face_id)


def test_a_store_is_framed_by_its_box(good_store):
    """hsr.views.default(store) was an AttributeError (a store has no vertices in
    memory): it frames the box the metadata keeps, as for the scene it came from."""
    store = hsr.load_scene(good_store)
    cam = hsr.views.default(store, 1.0)
    box = hsr.views.default(store.bounds(), 1.0)
    assert np.allclose(cam.eye, box.eye) and np.allclose(cam.target, box.target)
