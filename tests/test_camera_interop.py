"""Cameras from other tools (issue #14, the OpenCV and OpenGL-matrix part), checked with an
independent projection in plain NumPy: OpenCV's pinhole ``x_cam = R x_world + t``,
``(u, v) = (fx x / z + cx, fy y / z + cy)`` with pixel centres on integer (u, v). No hsr
matrix is used by the checks."""

import numpy as np
import pytest

import hsr

W, H = 96, 72


def random_opencv(rng):
    """K with fx != fy and an off-centre principal point, a random rotation, a t."""
    fx = rng.uniform(60, 160)
    K = np.array([[fx, 0.0, rng.uniform(0.25, 0.75) * W],
                  [0.0, fx * rng.uniform(0.7, 1.4), rng.uniform(0.25, 0.75) * H],
                  [0.0, 0.0, 1.0]])
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    R = q * np.sign(np.linalg.det(q))
    return K, R, rng.normal(size=3)


def soup_in_view(rng, K, R, t, n=8):
    """Triangles in camera coordinates in front of the camera, moved to world space."""
    centers = np.stack([rng.uniform(-0.6, 0.6, n), rng.uniform(-0.5, 0.5, n),
                        rng.uniform(3, 8, n)], axis=1)
    centers[:, :2] *= centers[:, 2:] * np.array([W / K[0, 0], H / K[1, 1]]) / 2
    cam = centers[:, None, :] + rng.normal(scale=0.8, size=(n, 3, 3))
    world = (cam - t) @ R  # x_world = R^T (x_cam - t)
    return hsr.Mesh(world.reshape(-1, 3), np.arange(3 * n).reshape(-1, 3))


def pixel_rays(K, R, t, cols, rows):
    """World-space rays through OpenCV pixel centres (u, v) = (col, row)."""
    pix = np.stack([cols, rows, np.ones(len(cols))], axis=1).astype(float)
    d_cam = pix @ np.linalg.inv(K).T
    return -R.T @ t, d_cam @ R  # origin, directions (R^T d)


def hits(origin, dirs, tri):
    """Moller-Trumbore: (t, u, v) of each ray against one triangle."""
    e1, e2 = tri[1] - tri[0], tri[2] - tri[0]
    p = np.cross(dirs, e2)
    det = p @ e1
    inv = 1.0 / np.where(det == 0, np.nan, det)
    s = origin - tri[0]
    u = (p @ s) * inv
    q = np.cross(s, e1)
    v = (dirs @ q) * inv
    return (q @ e2) * inv, u, v


@pytest.mark.parametrize("seed", range(6))
def test_opencv_pixel_centres_see_the_reported_face(seed):
    rng = np.random.default_rng(seed)
    K, R, t = random_opencv(rng)
    mesh = soup_in_view(rng, K, R, t)
    cam = hsr.Camera.from_opencv(K, R, t, W, H, near=0.5, far=50)
    frame = hsr.render(mesh, cam, W, H)
    rows, cols = np.mgrid[0:H, 0:W]
    rows, cols = rows.ravel(), cols.ravel()
    tris = mesh.positions[mesh.faces]
    # Samples at the pixel centre and 0.01 pixel around it: window coordinates are snapped
    # to 1/256 pixel, so a centre that close to an edge may go either way.
    samples = [(0.0, 0.0), (0.01, 0.01), (-0.01, 0.01), (0.01, -0.01), (-0.01, -0.01)]
    dist = np.full((len(samples), len(tris), len(rows)), np.inf)
    for s, (du, dv) in enumerate(samples):
        origin, dirs = pixel_rays(K, R, t, cols + du, rows + dv)
        for f, tri in enumerate(tris):
            d, u, v = hits(origin, dirs, tri)
            ok = (np.minimum(np.minimum(u, v), 1 - u - v) >= 0) & (d > 0)
            dist[s, f, ok] = d[ok]
    hit = np.isfinite(dist)
    face = frame.face_id.ravel()
    covered = np.flatnonzero(face >= 0)
    assert len(covered) > 200
    # Every covered pixel: its face is met by the centre ray (or a sample next to it) ...
    assert hit[:, face[covered], covered].any(axis=0).all()
    # ... and nothing is nearer where the centre ray meets it (float32 depth: 1e-5).
    centre = covered[hit[0, face[covered], covered]]
    assert len(centre) > 0.9 * len(covered)
    nearest = dist[0][:, centre].min(axis=0)
    assert (dist[0, face[centre], centre] <= nearest * (1 + 1e-5)).all()
    # Every pixel whose samples all meet one face is covered.
    assert (face[hit.all(axis=0).any(axis=0)] >= 0).all()


@pytest.mark.parametrize("uv", [(10, 20), (0, 0), (W - 1, H - 1), (47, 35)])
def test_a_point_on_integer_uv_lands_in_that_pixel(uv):
    """OpenCV's pixel centre (u, v) = (10, 20) is hsr's pixel column 10, row 20: a tiny
    triangle around the point that projects there covers that pixel and no other."""
    rng = np.random.default_rng(1)
    K, R, t = random_opencv(rng)
    z = 4.0
    center = z * np.linalg.inv(K) @ np.array([uv[0], uv[1], 1.0])
    # A triangle 0.2 pixel across around it, in the image plane at depth z.
    px = np.array([[-0.1, -0.1], [0.1, -0.1], [0.0, 0.1]])
    cam_pts = center + np.c_[px[:, 0] * z / K[0, 0], px[:, 1] * z / K[1, 1], np.zeros(3)]
    mesh = hsr.Mesh((cam_pts - t) @ R, [[0, 1, 2]])
    frame = hsr.render(mesh, hsr.Camera.from_opencv(K, R, t, W, H, near=0.5, far=50), W, H)
    assert np.argwhere(frame.face_id == 0).tolist() == [[uv[1], uv[0]]]


def test_opencv_round_trips():
    rng = np.random.default_rng(3)
    for _ in range(20):
        K, R, t = random_opencv(rng)
        K2, R2, t2 = hsr.Camera.from_opencv(K, R, t, W, H, near=0.1, far=10).to_opencv(W, H)
        assert np.allclose(K2, K, atol=1e-9) and np.allclose(R2, R, atol=1e-9)
        assert np.allclose(t2, t, atol=1e-9)
    look = hsr.Camera.look_at((1, 2, 3), (0, 0.5, 0), fov_y=50, near=0.1, far=20)
    back = hsr.Camera.from_opencv(*look.to_opencv(W, H), W, H, near=0.1, far=20)
    assert np.allclose(back.view_matrix, look.view_matrix, atol=1e-9)
    assert np.allclose(back.projection_matrix(W / H), look.projection_matrix(W / H), atol=1e-9)


def test_from_matrices_keeps_the_projection():
    rng = np.random.default_rng(4)
    K, R, t = random_opencv(rng)
    off_axis = hsr.Camera.from_opencv(K, R, t, W, H, near=0.2, far=30)
    for cam in (off_axis, hsr.Camera.look_at((1, 2, 3), (0, 0, 0), fov_y=40, near=0.5,
                                             far=9)):
        view, proj = cam.view_matrix, cam.projection_matrix(W / H)
        again = hsr.Camera.from_matrices(view, proj)
        assert np.allclose(again.view_matrix, view, atol=1e-9)
        assert np.allclose(again.projection_matrix(W / H), proj, atol=1e-9)
        mesh = soup_in_view(rng, K, R, t)
        assert np.array_equal(hsr.render(mesh, again, W, H).face_id,
                              hsr.render(mesh, cam, W, H).face_id)


@pytest.mark.parametrize("pixel", [(10, 20), (0, 0), (W - 1, H - 1), (61, 5)])
def test_from_matrices_orthographic_off_centre_box(pixel):
    """A glOrtho box with left != -right and bottom != -top, built here from its textbook
    formula: a point at the eye-space position of pixel centre (x + 0.5, y + 0.5), row 0
    at the top, lands in that pixel and no other; the matrices round-trip."""
    rng = np.random.default_rng(7)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    rot = q * np.sign(np.linalg.det(q))
    view = np.eye(4)
    view[:3, :3], view[:3, 3] = rot, rng.normal(size=3)
    left, right, bottom, top, near, far = -0.7, 2.1, -0.4, 1.3, 0.5, 9.0
    proj = np.array([[2 / (right - left), 0, 0, -(right + left) / (right - left)],
                     [0, 2 / (top - bottom), 0, -(top + bottom) / (top - bottom)],
                     [0, 0, -2 / (far - near), -(far + near) / (far - near)],
                     [0, 0, 0, 1.0]])
    cam = hsr.Camera.from_matrices(view, proj)
    assert cam.is_orthographic
    assert np.allclose(cam.view_matrix, view, atol=1e-9)
    assert np.allclose(cam.projection_matrix(W / H), proj, atol=1e-12)
    col, row = pixel
    x_eye = left + (col + 0.5) / W * (right - left)
    y_eye = top - (row + 0.5) / H * (top - bottom)
    size = 0.1 * (right - left) / W  # a tenth of a pixel
    pts_eye = np.array([[x_eye - size, y_eye - size, -4.0], [x_eye + size, y_eye - size, -4.0],
                        [x_eye, y_eye + size, -4.0]])
    world = (pts_eye - view[:3, 3]) @ rot  # x_world = R^T (x_eye - t)
    frame = hsr.render(hsr.Mesh(world, [[0, 1, 2]]), cam, W, H)
    assert np.argwhere(frame.face_id == 0).tolist() == [[row, col]]
    assert abs(frame.eye_depth[row, col] - 4.0) < 1e-5


@pytest.mark.parametrize("proj,message", [
    (np.diag([1.0, 1.0, 1.0, 1.0]), "near < far"),  # glOrtho form but near > far
    (np.array([[1.0, 0, 0.2, 0], [0, 1, 0, 0], [0, 0, -1, 0], [0, 0, 0, 1]]), "glOrtho"),
])
def test_from_matrices_refuses_a_bad_box(proj, message):
    with pytest.raises(hsr.CameraError, match=message):
        hsr.Camera.from_matrices(np.eye(4), proj)


@pytest.mark.parametrize("make,message", [
    (lambda K, R, t: hsr.Camera.from_opencv(np.array([[100, 3, 40], [0, 100, 30], [0, 0, 1.0]]),
                                            R, t, W, H), "no skew"),
    (lambda K, R, t: hsr.Camera.from_opencv(K * np.array([[-1], [1], [1]]), R, t, W, H),
     "fx, fy > 0"),
    (lambda K, R, t: hsr.Camera.from_opencv(K, 2 * R, t, W, H), "rotation"),
    (lambda K, R, t: hsr.Camera.from_opencv(K, -R, t, W, H), "rotation"),
    (lambda K, R, t: hsr.Camera.from_opencv(K, R, t[:2], W, H), "three numbers"),
    (lambda K, R, t: hsr.Camera.from_opencv(K, R, t, 0, H), "width"),
    (lambda K, R, t: hsr.Camera.from_matrices(np.eye(4), np.eye(4)), "perspective frustum"),
    (lambda K, R, t: hsr.Camera.from_matrices(np.diag([2.0, 2, 2, 1]), hsr.Camera.look_at(
        (0, 0, 1), (0, 0, 0)).projection_matrix(1.0)), "rotation"),
    (lambda K, R, t: hsr.Camera.orthographic((0, 0, 1), (0, 0, 0)).to_opencv(W, H),
     "orthographic"),
])
def test_bad_camera_inputs_are_refused(make, message):
    K, R, t = random_opencv(np.random.default_rng(5))
    with pytest.raises(hsr.CameraError, match=message):
        make(K, R, t)


# ---------------------------------------------------------------- transforms.json, COLMAP
# Odd sizes: the image centre (W / 2, H / 2) in COLMAP/NeRF coordinates is the centre of
# pixel (48, 36); in OpenCV coordinates it would lie on the corner of four pixels.
OW, OH = 97, 73


def optical_axis_triangle(c2w_gl, depth=5.0, size=0.01):
    """A tiny triangle on the optical axis, ``depth`` in front of a camera whose
    camera-to-world matrix (OpenGL axes) is ``c2w_gl``."""
    local = np.array([[-size, -size, -depth], [size, -size, -depth], [0.0, size, -depth]])
    return hsr.Mesh(local @ c2w_gl[:3, :3].T + c2w_gl[:3, 3], [[0, 1, 2]])


def test_transforms_json_principal_point_is_colmaps_half_pixel(tmp_path):
    c2w = np.eye(4)
    c2w[:3, 3] = [0.3, -0.2, 1.0]
    doc = {"fl_x": 80.0, "fl_y": 95.0, "cx": OW / 2, "cy": OH / 2, "w": OW, "h": OH,
           "frames": [{"file_path": "a.png", "transform_matrix": c2w.tolist()}]}
    (tmp_path / "transforms.json").write_text(__import__("json").dumps(doc))
    cams, names, size = hsr.read_transforms(tmp_path / "transforms.json", near=0.5, far=20)
    assert names == ["a.png"] and size == (OW, OH)
    frame = hsr.render(optical_axis_triangle(c2w), cams[0], OW, OH)
    assert np.argwhere(frame.face_id == 0).tolist() == [[36, 48]]


def test_transforms_json_round_trip(tmp_path):
    rng = np.random.default_rng(7)
    cams = [hsr.Camera.from_opencv(*random_opencv(rng), W, H, near=0.1, far=10)
            for _ in range(3)]
    cams.append(hsr.Camera.look_at((1, 2, 3), (0, 0, 0), fov_y=50, near=0.1, far=10))
    hsr.write_transforms(tmp_path / "t.json", cams, W, H)
    back, names, _ = hsr.read_transforms(tmp_path / "t.json", near=0.1, far=10)
    assert names == ["0000", "0001", "0002", "0003"]
    for a, b in zip(cams, back):
        assert np.allclose(a.view_matrix, b.view_matrix, atol=1e-9)
        assert np.allclose(a.projection_matrix(W / H), b.projection_matrix(W / H), atol=1e-9)
    same = [cams[3]] * 2  # shared intrinsics are written once, at the top
    hsr.write_transforms(tmp_path / "s.json", same, W, H)
    doc = __import__("json").loads((tmp_path / "s.json").read_text())
    assert "fl_x" in doc and "fl_x" not in doc["frames"][0]


def test_camera_angle_x_form(tmp_path):
    doc = {"camera_angle_x": 2 * np.arctan(0.5), "w": OW, "h": OH,
           "frames": [{"transform_matrix": np.eye(4).tolist()}]}
    (tmp_path / "t.json").write_text(__import__("json").dumps(doc))
    cam = hsr.read_transforms(tmp_path / "t.json")[0][0]
    K, _, _ = cam.to_opencv(OW, OH)
    assert np.isclose(K[0, 0], OW) and np.isclose(K[0, 2], OW / 2 - 0.5)


def test_colmap_text_model(tmp_path):
    """90 degrees about y: q = (cos 45, 0, sin 45, 0), world-to-camera R maps world +x to
    camera -z. The camera centre is -R^T t; the optical-axis point lands on pixel (48, 36)
    (COLMAP's principal point at W / 2 is the centre of the middle pixel)."""
    (tmp_path / "cameras.txt").write_text(
        "# Camera list\n1 PINHOLE 97 73 80 95 48.5 36.5\n2 SIMPLE_PINHOLE 97 73 90 48.5 36.5\n")
    (tmp_path / "images.txt").write_text(
        "# Image list\n"
        f"1 {np.cos(np.pi / 4)} 0 {np.sin(np.pi / 4)} 0 0.1 0.2 3.0 1 left.png\n"
        "10.0 20.0 -1\n"
        "2 1 0 0 0 0 0 0 2 front image.png\n\n")
    cams, names, sizes = hsr.read_colmap(tmp_path, near=0.5, far=20)
    assert names == ["left.png", "front image.png"] and sizes == [(97, 73)] * 2
    K, R, t = cams[0].to_opencv(97, 73)
    assert np.allclose(R, [[0, 0, 1], [0, 1, 0], [-1, 0, 0]], atol=1e-12)
    assert np.allclose(t, [0.1, 0.2, 3.0]) and np.allclose(K[:2, 2], [48.0, 36.0])
    for cam in cams:
        c2w = np.linalg.inv(cam.view_matrix)
        frame = hsr.render(optical_axis_triangle(c2w), cam, 97, 73)
        assert np.argwhere(frame.face_id == 0).tolist() == [[36, 48]]


@pytest.mark.parametrize("cameras_txt,images_txt,message", [
    ("1 OPENCV 97 73 80 95 48.5 36.5 0.1 0 0 0\n", "", "camera model OPENCV has lens distortion"),
    ("1 PINHOLE 97 73 80 95 48.5\n", "", "PINHOLE takes 4 parameters"),
    ("1 PINHOLE 97 73 80 95 48.5 x\n", "", "bad number"),
    ("1 PINHOLE 97 73 80 95 48.5 36.5\n", "1 1 0 0 0 0 0 0 7 a.png\n\n", "camera 7 is not"),
    ("1 PINHOLE 97 73 80 95 48.5 36.5\n", "1 0 0 0 0 0 0 0 1 a.png\n\n", "zero quaternion"),
    ("1 PINHOLE 97 73 80 95 48.5 36.5\n", "# nothing\n", "no images"),
])
def test_colmap_errors_name_the_line(tmp_path, cameras_txt, images_txt, message):
    (tmp_path / "cameras.txt").write_text(cameras_txt)
    (tmp_path / "images.txt").write_text(images_txt)
    with pytest.raises(hsr.CameraError, match=message):
        hsr.read_colmap(tmp_path)


@pytest.mark.parametrize("doc,message", [
    ({"frames": []}, "non-empty 'frames'"),
    ({"w": 10, "h": 10, "frames": [{"transform_matrix": np.eye(4).tolist()}]},
     "needs 'fl_x' or 'camera_angle_x'"),
    ({"fl_x": 10, "w": 10, "h": 10, "frames": [{"transform_matrix": (2 * np.eye(4)).tolist()}]},
     "no scale"),
    ({"fl_x": "x", "w": 10, "h": 10, "frames": [{"transform_matrix": np.eye(4).tolist()}]},
     "fl_x must be a finite number"),
])
def test_transforms_errors(tmp_path, doc, message):
    (tmp_path / "t.json").write_text(__import__("json").dumps(doc))
    with pytest.raises(hsr.CameraError, match=message):
        hsr.read_transforms(tmp_path / "t.json")
    (tmp_path / "bad.json").write_text("{nope")
    with pytest.raises(hsr.CameraError, match="not JSON"):
        hsr.read_transforms(tmp_path / "bad.json")


# ------------------------------------------------------------------------------ view sets
@pytest.mark.parametrize("size", [(96, 72), (160, 40), (40, 160)])
@pytest.mark.parametrize("kind", ["orbit", "sphere", "hemisphere", "frame", "default"])
def test_view_sets_frame_the_whole_model(models_dir, kind, size):
    """Every camera of a set shows the whole model at every aspect ratio: no covered pixel
    touches the image border, and every box corner projects inside the image (independent
    pinhole through to_opencv's K, R, t)."""
    import os

    w, h = size
    mesh = hsr.load(os.path.join(models_dir, "spot.obj"))
    bounds = mesh.bounds()
    if kind == "frame":  # Camera.frame: straight on, and from above (up parallel to view)
        cams = [hsr.Camera.frame(bounds, d, aspect=w / h) for d in ((0, 0, 1), (0, 1, 0))]
    elif kind == "default":  # from the box's corners, and from the vertices themselves
        cams = [hsr.views.default(bounds, aspect=w / h), hsr.views.default(mesh, aspect=w / h)]
    else:
        cams = getattr(hsr.views, kind)(bounds, 6, aspect=w / h)
        assert len(cams) == 6
    corners = np.array([[x, y, z] for x in bounds[:, 0] for y in bounds[:, 1]
                        for z in bounds[:, 2]])
    if kind == "default":
        corners = mesh.positions  # the tightest: every vertex inside the image
    for cam in cams:
        frame = hsr.render(mesh, cam, w, h)
        covered = frame.face_id >= 0
        assert covered.sum() > 0.1 * min(w, h) ** 2  # the model fills the narrower side
        assert not (covered[0].any() or covered[-1].any() or covered[:, 0].any()
                    or covered[:, -1].any())
        K, R, t = cam.to_opencv(w, h)
        cam_pts = corners @ R.T + t
        uv = cam_pts[:, :2] / cam_pts[:, 2:] * [K[0, 0], K[1, 1]] + K[:2, 2]
        assert (cam_pts[:, 2] > 0).all()
        assert ((uv >= -0.5) & (uv <= [w - 0.5, h - 0.5])).all()
        if kind == "default" and cam is cams[1]:
            # As close as the vertices allow: one reaches the 5% margin.
            ndc = (uv + 0.5) / [w, h] * 2 - 1
            assert abs(np.abs(ndc).max() - 1 / 1.05) < 1e-6


def test_view_directions():
    bounds = np.array([[-1.0, -1, -1], [1, 1, 1]])
    eyes = np.array([c.eye for c in hsr.views.orbit(bounds, 4, elevation=0)])
    # Azimuth from +Z towards +X: the first eye on +Z, the second on +X.
    assert np.allclose(eyes[0] / np.linalg.norm(eyes[0]), [0, 0, 1])
    assert np.allclose(eyes[1] / np.linalg.norm(eyes[1]), [1, 0, 0])
    top = hsr.views.orbit(bounds, 1, elevation=90)[0]  # straight down: still a camera
    assert np.allclose(np.asarray(top.forward), [0, -1, 0])
    dirs = np.array([np.asarray(c.eye) / np.linalg.norm(c.eye)
                     for c in hsr.views.sphere(bounds, 200)])
    # Evenly spread: no two directions closer than half the mean spacing.
    cos = np.clip(dirs @ dirs.T, -1, 1) - 2 * np.eye(len(dirs))
    nearest = np.arccos(cos.max(axis=1))
    assert nearest.min() > 0.5 * np.sqrt(4 * np.pi / 200)
    assert abs(dirs.mean(axis=0)).max() < 0.02  # no side favoured
    up = np.array([c.eye for c in hsr.views.hemisphere(bounds, 50)])
    assert (up[:, 1] > 0).all()
    with pytest.raises(hsr.CameraError, match="number of views"):
        hsr.views.sphere(bounds, 0)
    with pytest.raises(hsr.CameraError, match="bounds"):
        hsr.views.orbit([[0, 0, 0], [np.nan, 1, 1]], 3)


@pytest.mark.parametrize("seed", range(4))
def test_projection_matches_opencv_project_points(seed):
    """A second, outside reference: cv2.projectPoints with the same K, R, t (zero
    distortion) gives the pixel that hsr's matrices give, in OpenCV's pixels (hsr's
    continuous window coordinate minus the half pixel)."""
    from conftest import need

    try:
        import cv2
    except ImportError:
        cv2 = None
    need(cv2 is not None, "opencv-python-headless is not installed (the test extra has it)")
    rng = np.random.default_rng(seed)
    K, R, t = random_opencv(rng)
    cam = hsr.Camera.from_opencv(K, R, t, W, H, near=0.5, far=50)
    pts_cam = np.stack([rng.uniform(-2, 2, 50), rng.uniform(-2, 2, 50),
                        rng.uniform(1, 20, 50)], axis=1)
    world = (pts_cam - t) @ R
    uv_cv, _ = cv2.projectPoints(world, cv2.Rodrigues(R)[0], t, K, np.zeros(5))
    clip = np.c_[world, np.ones(len(world))] @ (cam.projection_matrix(W / H)
                                               @ cam.view_matrix).T
    ndc = clip[:, :2] / clip[:, 3:]
    x_window = (ndc[:, 0] + 1) / 2 * W
    y_window = (1 - ndc[:, 1]) / 2 * H  # row 0 at the top
    assert np.allclose(np.c_[x_window - 0.5, y_window - 0.5], uv_cv[:, 0], atol=1e-6)
