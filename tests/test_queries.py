"""Per-camera and many-camera visibility queries (issue #33) against independent
references: a brute-force segment test (Moller-Trumbore over every face, NumPy, written
here) for visible vertices and points of a shared model no other test uses, seen from
OpenCV cameras with off-centre principal points; ``cv2.projectPoints`` for the pixels;
``np.bincount`` of rendered face ids for the visibility matrix, on a real Dask
LocalCluster too; and bad input refused."""

from __future__ import annotations

import os

import numpy as np
import pytest

import hsr
from conftest import require
from hsr.visibility import face_visibility

cv2 = require("cv2")

W, H = 320, 240


@pytest.fixture(scope="module")
def diablo(models_dir):
    """A posed character (creases, thin limbs, self-occlusion), used by no other test."""
    return hsr.load(os.path.join(models_dir, "diablo3_pose.obj"))


def opencv_cameras(mesh, count=3, seed=4):
    """OpenCV cameras around the model, principal points well off the centre."""
    rng = np.random.default_rng(seed)
    lo, hi = mesh.bounds()
    centre, radius = (lo + hi) / 2, np.linalg.norm(hi - lo) / 2
    cams = []
    for k in range(count):
        direction = rng.normal(size=3)
        direction[1] = abs(direction[1]) * 0.5
        direction /= np.linalg.norm(direction)
        eye = centre + direction * radius * 2.6
        ref = hsr.Camera.look_at(eye, centre + rng.normal(scale=0.1 * radius, size=3))
        _, R, t = ref.to_opencv(W, H)
        K = np.array([[300.0, 0, W / 2 + 37.0 * (k + 1)], [0, 290.0, H / 2 - 23.0 * (k + 1)],
                      [0, 0, 1]])
        cams.append((hsr.Camera.from_opencv(K, R, t, W, H, near=0.01, far=100.0), K, R, t))
    return cams


def segments_blocked(tris, eye, points, tolerance):
    """(N,) bool: the segment eye -> point, cut ``tolerance`` of its length short of the
    point, meets a face (Moller-Trumbore in float64 over all faces; t in [0, 1 - tol])."""
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    e1, e2 = b - a, c - a
    s = eye - a
    q = np.cross(s, e1)
    blocked = np.zeros(len(points), dtype=bool)
    for i, point in enumerate(points):
        d = point - eye
        p = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, p)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            u = np.einsum("ij,ij->i", s, p) * inv
            v = (q @ d) * inv
            t = np.einsum("ij,ij->i", e2, q) * inv
        blocked[i] = np.any((det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0)
                            & (t <= 1 - tolerance))
    return blocked


def test_visible_vertices_equal_a_brute_force_segment_test(diablo):
    rays = hsr.RayScene(diablo)
    tris = diablo.positions[diablo.faces]
    for cam, K, R, t in opencv_cameras(diablo):
        visible = hsr.visible_vertices(rays, cam, W, H)
        assert visible.shape == (len(diablo.positions),)
        pixels, inside = hsr.visibility.project_points(cam, diablo.positions, W, H)
        assert 0.3 < inside.mean() <= 1.0
        # The projection is OpenCV's after the half-pixel shift.
        cv_pixels, _ = cv2.projectPoints(diablo.positions, cv2.Rodrigues(R)[0], t, K, None)
        np.testing.assert_allclose(pixels[inside] - 0.5, cv_pixels[inside, 0], atol=1e-6)
        assert not visible[~inside].any()
        # Brute force on every in-frustum vertex (every face per vertex).
        sample = np.flatnonzero(inside)
        blocked = segments_blocked(tris, np.asarray(cam.eye), diablo.positions[sample], 1e-4)
        agree = visible[sample] == ~blocked
        assert agree.mean() >= 0.995, agree.mean()
        # The rest lie within the tolerance band: a slightly longer or shorter segment
        # settles them.
        for k in np.flatnonzero(~agree):
            point = diablo.positions[sample[k]]
            assert segments_blocked(tris, np.asarray(cam.eye), point[None], 1e-3)[0] != \
                segments_blocked(tris, np.asarray(cam.eye), point[None], 1e-5)[0]
        assert 0.2 < visible[inside].mean() < 0.9  # a real mix of seen and hidden


def test_visible_points_and_the_opencv_convention(diablo):
    rng = np.random.default_rng(1)
    lo, hi = diablo.bounds()
    points = rng.uniform(lo, hi, (3000, 3))
    tris = diablo.positions[diablo.faces]
    (cam, K, R, t), = opencv_cameras(diablo, 1, seed=9)
    pixels, visible = hsr.visible_points(diablo, cam, points, W, H)
    cv_px, cv_vis = hsr.visible_points(diablo, cam, points, W, H, convention="opencv")
    np.testing.assert_array_equal(visible, cv_vis)
    np.testing.assert_allclose(cv_px, pixels - 0.5)
    ref, _ = cv2.projectPoints(points, cv2.Rodrigues(R)[0], t, K, None)
    _, inside = hsr.visibility.project_points(cam, points, W, H)
    np.testing.assert_allclose(cv_px[inside], ref[inside, 0], atol=1e-6)
    # Inside the image and depth range, exactly where OpenCV's pixel is in the image.
    in_image = ((ref[:, 0, 0] >= -0.5) & (ref[:, 0, 0] <= W - 0.5) & (ref[:, 0, 1] >= -0.5)
                & (ref[:, 0, 1] <= H - 0.5))
    assert (inside <= in_image).all()
    blocked = segments_blocked(tris, np.asarray(cam.eye), points[inside], 1e-4)
    assert (visible[inside] == ~blocked).mean() >= 0.995
    assert not visible[~inside].any()


def test_visible_faces_is_what_render_shows(diablo):
    (cam, *_), = opencv_cameras(diablo, 1, seed=5)
    faces, counts = hsr.visible_faces(diablo, cam, W, H, cull="back")
    ids = hsr.render(diablo, cam, W, H, cull="back").face_id
    ref = np.bincount(ids[ids >= 0], minlength=diablo.n_faces)
    np.testing.assert_array_equal(faces, np.flatnonzero(ref))
    np.testing.assert_array_equal(counts, ref[ref > 0])


def test_visibility_matrix_columns_rows_and_quality(diablo):
    views = "sphere:6"
    size = (96, 72)
    vm = hsr.visibility_matrix(diablo, views, size, quality=True)
    cams = vm.cameras
    assert vm.shape == (diablo.n_faces, 6)
    for j, cam in enumerate(cams):
        ids = hsr.render(diablo, cam, *size).face_id
        np.testing.assert_array_equal(vm.counts[:, j].toarray().ravel(),
                                      np.bincount(ids[ids >= 0], minlength=diablo.n_faces))
    np.testing.assert_array_equal(np.asarray(vm.counts.sum(axis=1)).ravel(),
                                  face_visibility(diablo, views, size))
    # Quality: the cosine between each face's normal and the direction to the eye, and
    # the distance, computed here per face from its centroid (a face's pixels spread
    # around it, so the means agree loosely, and tightly for faces far smaller than
    # their distance).
    tris = diablo.positions[diablo.faces]
    normal = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    centroid = tris.mean(axis=1)
    for j, cam in enumerate(cams):
        col = vm.counts[:, j].tocoo()
        faces = col.row
        to_eye = np.asarray(cam.eye) - centroid[faces]
        dist = np.linalg.norm(to_eye, axis=1)
        cosine = np.einsum("ij,ij->i", normal[faces], to_eye / dist[:, None])
        got_cos = vm.cosine[faces, j].toarray().ravel()
        got_dist = vm.distance[faces, j].toarray().ravel()
        assert np.median(np.abs(got_cos - cosine)) < 0.02
        assert np.median(np.abs(got_dist - dist) / dist) < 0.01
    best = vm.best_view()
    seen = np.asarray(vm.counts.sum(axis=1)).ravel() > 0
    assert (best[~seen] == -1).all() and (best[seen] >= 0).all()


def test_visibility_matrix_on_a_dask_cluster_equals_the_local_one(diablo):
    distributed = pytest.importorskip("distributed")
    local = hsr.visibility_matrix(diablo, "sphere:5", 64, quality=True)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address="127.0.0.1:0",
                                  silence_logs=40) as cluster, \
            distributed.Client(cluster) as client:
        remote = hsr.visibility_matrix(diablo, "sphere:5", 64, quality=True, client=client)
    for name in ("counts", "cosine", "distance"):
        a, b = getattr(local, name), getattr(remote, name)
        assert (a != b).nnz == 0, name


@pytest.mark.parametrize("call, message", [
    (lambda m, c: hsr.visible_points(m, c, np.zeros((0, 3)), W, H), "points is empty"),
    (lambda m, c: hsr.visible_points(m, c, np.zeros((4, 2)), W, H), "shape (N, 3)"),
    (lambda m, c: hsr.visible_points(m, c, [[np.nan, 0, 0]], W, H), "point 0"),
    (lambda m, c: hsr.visible_points(m, c, [[0, 0, 0]], W, H, convention="gl"),
     "convention must be"),
    (lambda m, c: hsr.visible_vertices(m, c, W, H, tolerance=1.0), "tolerance must be"),
    (lambda m, c: hsr.visible_vertices(m, "cam", W, H), "camera must be an hsr.Camera"),
    (lambda m, c: hsr.visible_vertices(m, c, 0, H), "width must be in"),
    (lambda m, c: hsr.visible_faces(m, c, W, H, cull="sideways"), "cull"),
    (lambda m, c: hsr.visibility_matrix(m, "sphere:0", 8), "N must be"),
    (lambda m, c: hsr.visibility_matrix(m, [c], 8, quality="yes"), "quality must be"),
    (lambda m, c: hsr.visibility_matrix(m, [c], 8, threads=2), "threads is not an option"),
])
def test_bad_queries_are_refused(call, message):
    mesh = hsr.scenes.cube()
    cam = hsr.Camera.look_at((0, 0, 5), (0, 0, 0))
    with pytest.raises(hsr.HsrError) as info:
        call(mesh, cam)
    assert message in str(info.value)


def test_cli_visibility_writes_what_the_library_computes(diablo, models_dir, tmp_path,
                                                         capsys):
    from hsr.cli import main

    model = os.path.join(models_dir, "diablo3_pose.obj")
    out = tmp_path / "faces.npz"
    assert main(["visibility", model, "--views", "sphere:4", "--size", "64x48", "-o",
                 str(out), "--quality"]) == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith("4 views at 64x48: faces visible per view min") and "\n" not in line
    data = np.load(out)
    vm = hsr.visibility_matrix(diablo, "sphere:4", (64, 48), quality=True)
    coo = vm.counts.tocoo()
    np.testing.assert_array_equal(data["face"], coo.row)
    np.testing.assert_array_equal(data["view"], coo.col)
    np.testing.assert_array_equal(data["pixels"], coo.data)
    np.testing.assert_allclose(data["cosine"], vm.cosine.tocoo().data)
    csv = tmp_path / "vertices.csv"
    assert main(["visibility", model, "--views", "sphere:4", "--size", "64x48", "--what",
                 "vertices", "-o", str(csv), "--quiet"]) == 0
    rows = np.loadtxt(csv, delimiter=",", skiprows=1, dtype=np.int64)
    rays = hsr.RayScene(diablo)
    for j, cam in enumerate(vm.cameras):
        np.testing.assert_array_equal(rows[rows[:, 1] == j, 0],
                                      np.flatnonzero(hsr.visible_vertices(rays, cam, 64, 48)))


@pytest.mark.parametrize("args, message", [
    (["--views", "sphere:4", "-o", "{tmp}/x.txt"], "unknown extension"),
    (["--views", "sphere:0", "-o", "{tmp}/x.npz"], "N must be"),
    (["--views", "sphere:4", "--what", "edges", "-o", "{tmp}/x.npz"], "--what must be"),
    (["--views", "sphere:4", "--what", "points:{tmp}/bad.npy", "-o", "{tmp}/x.npz"],
     "not a .npy array"),
    (["--views", "sphere:4", "--what", "points:{tmp}/empty.npy", "-o", "{tmp}/x.npz"],
     "points is empty"),
    (["--views", "sphere:4", "--what", "vertices", "--scheduler", "tcp://127.0.0.1:1",
      "-o", "{tmp}/x.npz"], "--scheduler goes with --what faces"),
    (["--views", "sphere:4", "--size", "0x3", "-o", "{tmp}/x.npz"], "--size"),
    (["--views", "{tmp}/missing.json", "-o", "{tmp}/x.npz"], "missing.json"),
    (["--views", "sphere:4", "-o", "{tmp}/exists.npz"], "exists"),
    # The planes for camera files are checked with any views (they were ignored unread
    # with generated ones).
    (["--views", "sphere:4", "--near", "5", "--far", "1", "-o", "{tmp}/x.npz"],
     "greater than near"),
    (["--views", "sphere:4", "--near", "nan", "-o", "{tmp}/x.npz"], "near"),
    (["--views", "sphere:4", "--near", "0", "-o", "{tmp}/x.npz"], "near must be > 0"),
])
def test_cli_visibility_refuses_bad_input(models_dir, tmp_path, capsys, args, message):
    from hsr.cli import main

    (tmp_path / "bad.npy").write_bytes(b"not numpy")
    np.save(tmp_path / "empty.npy", np.zeros((0, 3)))
    (tmp_path / "exists.npz").write_bytes(b"mine")
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    assert main(["visibility", os.path.join(models_dir, "spot.obj"), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("hsr: error: ") and message in err[0], err
    assert (tmp_path / "exists.npz").read_bytes() == b"mine"
