"""The first look (hsr.first_look, hsr.best_view, ``hsr render MODEL``): the default view
shows the side of a model with the most shape, judged by facts computed here from the
geometry alone (where the detail is, where spot's head is, how much of fandisk's image is
one flat face), not by the score the chooser maximises."""

import math
import os

import numpy as np
import pytest

import hsr
from conftest import run_cli
from hsr.appearance import viewpoint
from hsr.errors import CameraError


def corrugated_box(ridges: int = 12) -> hsr.Mesh:
    """A unit cube whose +X side is a sawtooth relief of ``ridges`` vertical ridges, the
    other five sides flat: the detail is on +X."""
    verts, faces = [], []

    def quad(a, b, c, d):
        base = len(verts)
        verts.extend([a, b, c, d])
        faces.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]])

    lo, hi = -0.5, 0.5
    quad((lo, lo, hi), (lo, hi, hi), (lo, hi, lo), (lo, lo, lo))            # -X
    quad((lo, lo, lo), (hi, lo, lo), (hi, lo, hi), (lo, lo, hi))            # -Y
    quad((lo, hi, lo), (lo, hi, hi), (hi, hi, hi), (hi, hi, lo))            # +Y
    quad((lo, lo, lo), (lo, hi, lo), (hi, hi, lo), (hi, lo, lo))            # -Z
    quad((lo, lo, hi), (hi, lo, hi), (hi, hi, hi), (lo, hi, hi))            # +Z
    zs = np.linspace(hi, lo, 2 * ridges + 1)
    for k in range(2 * ridges):  # +X: strips alternating in and out by 0.08
        x0 = hi + (0.08 if k % 2 else 0.0)
        x1 = hi + (0.0 if k % 2 else 0.08)
        quad((x0, lo, zs[k]), (x1, lo, zs[k + 1]), (x1, hi, zs[k + 1]), (x0, hi, zs[k]))
    return hsr.Mesh(np.array(verts, dtype=np.float64), np.array(faces))


def turned(mesh: hsr.Mesh, degrees: float) -> tuple:
    """The mesh turned about +Y, and the rotation."""
    a = math.radians(degrees)
    rot = np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])
    return hsr.Mesh(mesh.positions @ rot.T, mesh.faces), rot


@pytest.mark.parametrize("degrees", [0, 90, 180, 270, 30])
def test_the_detailed_side_is_seen_however_the_model_is_turned(degrees):
    mesh, rot = turned(corrugated_box(), degrees)
    az, el = hsr.best_view(mesh)
    toward = hsr.views.direction(az, el)
    detail = rot @ np.array([1.0, 0.0, 0.0])  # where the relief faces now
    assert toward @ detail > 0.3, (degrees, az, el)
    assert 0 < el < 90  # from above, +Y up


def test_spot_is_seen_from_the_front(models_dir):
    """Spot's head is the end with its highest vertices (the horns); the first look must
    see it, where the old fixed view (35, 25) saw its back."""
    mesh = hsr.load(os.path.join(models_dir, "spot.obj"))
    points = mesh.used_positions()
    top = points[points[:, 1] >= np.quantile(points[:, 1], 0.98)]
    head = (top.mean(axis=0) - points.mean(axis=0))[[0, 2]]
    old = hsr.views.direction(*hsr.views.DEFAULT_VIEW)[[0, 2]]
    assert old @ head < 0  # what the issue saw: spot's back
    new = hsr.views.direction(*hsr.best_view(mesh))[[0, 2]]
    # Within 60 degrees of head-on, seen from above: the face in a three-quarter view.
    assert new @ head > 0.5 * np.linalg.norm(new) * np.linalg.norm(head)


def flat_share_and_creases(mesh, camera):
    """(the largest share of the model's pixels whose faces are within 5 degrees of one
    normal, neighbouring pixel pairs across a crease of > 30 degrees, and how many of
    those differ by >= 10 grey levels under the studio light)."""
    frame = hsr.render(mesh, camera, 320, 240, light="studio")
    covered = frame.face_id >= 0
    normals = mesh.face_normals()[np.maximum(frame.face_id, 0)]
    seen = normals[covered]
    share = max(float(((seen @ seen[k]) > math.cos(math.radians(5))).mean())
                for k in range(0, len(seen), 53))
    grey = frame.color[..., 0].astype(int)
    creases, separated = 0, 0
    for a, b in (((slice(None), slice(1, None)), (slice(None), slice(None, -1))),
                 ((slice(1, None),), (slice(None, -1),))):
        both = covered[a] & covered[b]
        crease = both & ((normals[a] * normals[b]).sum(-1) < math.cos(math.radians(30)))
        creases += int(crease.sum())
        separated += int((np.abs(grey[a] - grey[b])[crease] >= 10).sum())
    return share, creases, separated


def test_fandisk_shows_its_feature_edges_and_the_light_separates_its_faces(models_dir):
    mesh = hsr.load(os.path.join(models_dir, "fandisk.obj"))
    old_share, old_creases, _ = flat_share_and_creases(mesh, hsr.views.default(mesh, 4 / 3))
    share, creases, separated = flat_share_and_creases(mesh, hsr.first_look(mesh, 4 / 3))
    assert old_share > 0.8  # the "flat grey shape"
    assert share < 0.5 and creases > 2 * old_creases
    assert separated >= 0.95 * creases


def test_render_without_a_camera_and_the_cli_use_the_first_look(models_dir, tmp_path):
    path = os.path.join(models_dir, "spot.obj")
    mesh = hsr.load(path)
    plain = hsr.render(mesh, width=160, height=120)
    chosen = hsr.render(mesh, hsr.first_look(mesh, 160 / 120), 160, 120, light="studio")
    assert np.array_equal(plain.face_id, chosen.face_id)
    az, el = hsr.best_view(mesh)
    for args, same in (([], True), (["--view", f"{az:g},{el:g}"], True),
                       (["--view", "35,25"], False)):
        out = tmp_path / f"spot{len(args)}{same}.npy"
        code, err = run_cli(["render", path, "--size", "160x120", "-o",
                                str(tmp_path / "spot.png"), "--ids-out", str(out), *args])
        assert code == 0, err
        assert np.array_equal(np.load(out), plain.face_id) == same, args


def test_large_models_try_fewer_views():
    budget = viewpoint.FACE_BUDGET
    assert len(viewpoint.candidates(budget)) == 16
    assert len(viewpoint.candidates(budget + 1)) == 8
    assert viewpoint.candidates(8 * budget + 1) == [hsr.views.DEFAULT_VIEW]


@pytest.mark.parametrize("view", ["35", (1, 2, 3), (float("nan"), 0), None])
def test_a_bad_view_is_refused(view):
    mesh = corrugated_box()
    with pytest.raises(CameraError, match="view"):
        hsr.views.default(mesh, view=view)


def test_not_a_mesh_is_refused():
    with pytest.raises(hsr.HsrError):
        hsr.best_view("not a mesh")


def test_a_model_too_large_to_frame_is_refused_without_warnings():
    """Its face normals overflow float64 (9e99 squared): the choice must not warn, and the
    framing refuses the model as hsr.views.default does."""
    import warnings

    mesh = hsr.Mesh(np.array([[0, 0, 0], [9e99, 0, 0], [0, 9e99, 0.0]]), np.array([[0, 1, 2]]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(CameraError):
            hsr.first_look(mesh)
