"""``hsr.batch.render_views`` (issue #32): job specs of every odd kind are refused before
any work with an HsrError (views, sizes, outputs, formats, task sizes, render options,
camera files), and ``resume`` over outputs corrupted every way a killed process or a
full disk leaves them (cut PNG and NPY files, the wrong shape or dtype, garbage, empty
files, a Zarr chunk cut short or removed, a broken array header) renders every
corrupted view again and never counts it as done: the outputs end equal to those of an
uninterrupted run, which are compared with ``hsr.render`` directly."""

from __future__ import annotations

import glob
import json
import os
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from PIL import Image

import hsr
from conftest import require
from hsr.batch import render_views

from . import scaled
from .guards import time_limit

distributed = require("distributed")
require("zarr")

SIZE = (24, 18)
VIEWS = "orbit:3"


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                       dashboard_address=None, silence_logs=40)
    with distributed.Client(cluster) as c:
        yield c
    cluster.close()


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    path = tmp_path_factory.mktemp("model") / "box.obj"
    cube = hsr.scenes.cube()
    lines = [f"v {x} {y} {z}" for x, y, z in cube.positions]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in cube.faces]
    path.write_text("\n".join(lines) + "\n")
    return str(path)


_spec_values = {
    "views": st.sampled_from(["orbit:2", "orbit:0", "orbit:-1", "orbit:x", "orbit:2:95",
                              "orbit:2:nan", "sphere:1", "sphere:1000001", "hemisphere:",
                              "per-model:missing.json", "per-model:", "nope:3", "", "/dev/zero",
                              "/etc", "missing.json", 7, None, [], [None], {"x": []}]),
    "size": st.sampled_from([(8, 6), (0, 6), (-1, 5), (40000, 4), (8,), "8x6", None, (1.5, 2),
                             (float("nan"), 2), 16]),
    "outputs": st.sampled_from([("color",), ("ids", "eye_depth"), (), ("colour",), "color",
                                "color,ids", ("color", "color"), None, 3]),
    "format": st.sampled_from(["files", "zarr", "hdf5", None, 1]),
    "views_per_task": st.sampled_from([None, 1, 0, -3, 100001, 2.5, True, "4"]),
    "options": st.sampled_from([{}, {"algorithm": "painter"}, {"algorithm": "nope"},
                                {"cull": "sideways"}, {"threads": 2}, {"shading": "toon"},
                                {"workspace": 1}, {"into": None}, {"nonsense": 1},
                                {"background": (300, 0, 0)}, {"depth_func": "greater"}]),
    "near_far": st.sampled_from([(0.1, 100.0), (0.0, 1.0), (1.0, 0.5), (float("nan"), 1.0),
                                 (-1.0, 1.0)]),
}


@settings(max_examples=scaled(80), suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(job=st.fixed_dictionaries({}, optional=_spec_values))
def test_job_specs_run_or_are_refused(client, model, tmp_path, job):
    out = tmp_path / f"out{abs(hash(repr(job))) % 10**8}"
    near, far = job.get("near_far", (0.1, 100.0))
    with warnings.catch_warnings(), time_limit(120):
        warnings.simplefilter("error")
        try:
            result = render_views([model], job.get("views", "orbit:2"), job.get("size", (8, 6)),
                                  job.get("outputs", ("color",)), str(out), client,
                                  format=job.get("format", "files"),
                                  views_per_task=job.get("views_per_task"), near=near,
                                  far=far, progress=False, **job.get("options", {}))
        except hsr.HsrError as exc:
            event(f"refused: {type(exc).__name__}")
            assert not os.path.exists(out / "manifest.json")
            return
    event("ran")
    assert result.failed == 0, result.rows
    assert json.loads((out / "manifest.json").read_text())["summary"]["rendered"] >= 1


def _first_run(client, model, out, fmt, outputs):
    result = render_views([model], VIEWS, SIZE, outputs, str(out), client, format=fmt,
                          progress=False)
    assert result.failed == 0
    return result


def _reference(model, outputs):
    scene = hsr.load_scene(model)
    cams = hsr.views.orbit(scene.bounds(), 3, 20.0, SIZE[0] / SIZE[1])
    frames = [hsr.render(scene, cam, *SIZE) for cam in cams]
    return [{"color": f.color, "ids": f.face_id, "eye_depth": f.eye_depth}
            for f in frames]


_DAMAGE = ["cut", "cut", "empty", "garbage", "delete", "wrong_shape", "wrong_dtype",
           "wrong_size_png", "gray_png"]


def _damage_file(path, how, rng):
    data = open(path, "rb").read() if os.path.exists(path) else b""
    if how == "cut":
        open(path, "wb").write(data[:int(rng.integers(0, max(1, len(data) - 1)))])
    elif how == "empty":
        open(path, "wb").close()
    elif how == "garbage":
        open(path, "wb").write(rng.bytes(len(data) or 64))
    elif how == "delete":
        os.remove(path)
    elif path.endswith(".npy"):
        array = np.load(path)
        bad = {"wrong_shape": lambda: array[:-1], "wrong_dtype": lambda: array.astype(
            np.float64), "wrong_size_png": lambda: array.T, "gray_png": lambda: array[..., None]}
        np.save(path, bad[how]())
    else:
        image = np.asarray(Image.open(path))
        bad = {"wrong_shape": lambda: image[:-1], "wrong_dtype": lambda: image[..., 0],
               "wrong_size_png": lambda: image[:, :-2], "gray_png": lambda: image[..., 0]}
        Image.fromarray(bad[how]()).save(path, format="PNG")


def _damage_zarr(store, name, view, how, rng):
    chunk = os.path.join(store, name, "c", str(view), "0", "0")
    if name == "color":
        chunk = os.path.join(chunk, "0")
    if how in ("wrong_shape", "wrong_dtype", "wrong_size_png", "gray_png"):
        how = "cut"
    _damage_file(chunk, how, rng)


@settings(max_examples=scaled(30), suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(fmt=st.sampled_from(["files", "zarr"]),
       damage=st.lists(st.tuples(st.sampled_from(["color", "ids", "eye_depth"]),
                                 st.integers(0, 2), st.sampled_from(_DAMAGE)),
                       min_size=1, max_size=4, unique_by=lambda d: d[:2]),
       seed=st.integers(0, 2 ** 32 - 1))
def test_resume_renders_every_corrupted_view_again(client, model, tmp_path_factory, fmt,
                                                   damage, seed):
    outputs = ("color", "ids", "eye_depth")
    out = tmp_path_factory.mktemp("resume")
    _first_run(client, model, out, fmt, outputs)
    rng = np.random.default_rng(seed)
    stem = "box"
    for name, view, how in damage:
        if fmt == "files":
            ext = ".png" if name == "color" else ".npy"
            _damage_file(str(out / stem / name / f"{view:04d}{ext}"), how, rng)
        else:
            _damage_zarr(str(out / f"{stem}.zarr"), name, view, how, rng)
    with warnings.catch_warnings(), time_limit(120):
        warnings.simplefilter("error")
        result = render_views([model], VIEWS, SIZE, outputs, str(out), client, format=fmt,
                              resume=True, progress=False)
    damaged = {view for _, view, _ in damage}
    done = {r["view"] for r in result.rows if r["status"] == "ok"}
    assert damaged <= done, (damage, result.rows)
    assert result.failed == 0
    event(f"{fmt}: {len(damaged)} views damaged")
    want = _reference(model, outputs)
    for view in range(3):
        for name in outputs:
            if fmt == "files":
                path = out / stem / name / f"{view:04d}{'.png' if name == 'color' else '.npy'}"
                got = np.asarray(Image.open(path)) if name == "color" else np.load(path)
            else:
                import zarr

                got = zarr.open_group(str(out / f"{stem}.zarr"), mode="r")[name][view]
            np.testing.assert_array_equal(got, want[view][name], err_msg=f"{name} {view}")
    assert not glob.glob(str(out / "**" / "*.tmp"), recursive=True)
