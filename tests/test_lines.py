"""Polygon modes, polygon offset, hidden lines (raster and exact vector). Visibility of
points on edges is decided by tests/reference.py (segment eye -> point against every
triangle), independent of hsr's pipeline."""

import xml.etree.ElementTree as ET

import numpy as np
import pytest

import hsr
from hsr import scenes
from hsr.lines.paths import join_polylines, merge_collinear
from hsr.lines.raster import HiddenLine
from hsr.lines.svg import write_lines_svg
from hsr.lines.vector import hidden_lines
from reference import occluded, reference_render, unproject

W, H = 160, 120


def projected_edges(scene, camera, width=W, height=H):
    """(E, 2, 2) image-space (y down) edges of every face, projected here."""
    from reference import world_triangles

    tris = world_triangles(scene)
    vp = camera.projection_matrix(width / height) @ camera.view_matrix
    clip = np.concatenate([tris, np.ones(tris.shape[:2] + (1,))], axis=2) @ vp.T
    xy = clip[..., :2] / clip[..., 3:]
    img = np.stack([(xy[..., 0] + 1) * width / 2, (1 - xy[..., 1]) * height / 2], axis=-1)
    return np.concatenate([img[:, [0, 1]], img[:, [1, 2]], img[:, [2, 0]]])


def distance_to_segments(px, segs):
    a, b = segs[:, 0], segs[:, 1]
    d = b - a
    t = ((px[:, None, :] - a[None]) * d[None]).sum(-1) / np.maximum((d * d).sum(-1), 1e-300)
    t = np.clip(t, 0, 1)
    closest = a[None] + t[..., None] * d[None]
    return np.linalg.norm(px[:, None, :] - closest, axis=-1).min(axis=1)


def test_polygon_mode_line_draws_every_edge_and_nothing_else():
    scene, camera = scenes.get("cubes")
    frame = hsr.render(scene, camera, W, H, polygon_mode="line")
    edges = projected_edges(scene, camera)
    rows, cols = np.nonzero(frame.face_id >= 0)
    centres = np.c_[cols + 0.5, rows + 0.5]
    # Every drawn pixel is within half a pixel diagonal of some edge ...
    assert distance_to_segments(centres, edges).max() <= 0.72
    # ... and every edge, hidden ones included, is drawn along its length.
    t = np.linspace(0.02, 0.98, 25)
    samples = (edges[:, None, 0] + t[None, :, None] * (edges[:, None, 1] - edges[:, None, 0]))
    samples = samples.reshape(-1, 2)
    inside = (samples[:, 0] > 1) & (samples[:, 0] < W - 1) & (samples[:, 1] > 1) & (
        samples[:, 1] < H - 1)
    px = np.floor(samples[inside]).astype(int)
    drawn = np.zeros((H + 2, W + 2), bool)
    drawn[1:-1, 1:-1] = frame.face_id >= 0
    near = np.zeros(len(px), bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near |= drawn[px[:, 1] + 1 + dy, px[:, 0] + 1 + dx]
    assert near.all()
    assert frame.stats["edges"] == 3 * 48


def test_polygon_mode_point_draws_the_projected_corners():
    scene, camera = scenes.get("cubes")
    frame = hsr.render(scene, camera, W, H, polygon_mode="point", depth_test=False)
    edges = projected_edges(scene, camera)
    corners = np.floor(edges[:, 0]).astype(int)
    expected = np.zeros((H, W), bool)
    expected[corners[:, 1], corners[:, 0]] = True
    assert ((frame.face_id >= 0) == expected).all()


def test_line_and_point_modes_need_the_zbuffer():
    scene, camera = scenes.get("cubes")
    with pytest.raises(hsr.RenderError, match="polygon mode line"):
        hsr.render(scene, camera, W, H, polygon_mode="line", algorithm="bsp")


def test_polygon_offset_moves_depth_by_factor_slope_plus_units():
    # A slanted plane: its window-depth slope m comes from the reference renderer's depths.
    plane = hsr.Mesh([[-3, -2, -4], [3, -2, -7], [3, 2, -7], [-3, 2, -4]], [[0, 1, 2], [0, 2, 3]])
    camera = hsr.Camera.look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60, 1.0, 20)
    base = hsr.render(plane, camera, W, H)
    _, ref_depth = reference_render(plane, camera, W, H)
    inner = slice(40, 80), slice(60, 100)
    dzdx = np.diff(ref_depth, axis=1)[inner]
    dzdy = np.diff(ref_depth, axis=0)[inner]
    m = max(np.abs(dzdx).max(), np.abs(dzdy).max())
    for factor, units in ((1.0, 0.0), (0.0, 4.0), (2.0, -3.0)):
        off = hsr.render(plane, camera, W, H, polygon_offset=(factor, units))
        delta = off.depth[inner].astype(float) - base.depth[inner]
        z = base.depth[inner].astype(float)
        r = 2.0 ** (np.floor(np.log2(z.max())) - 23)  # float32 step at the largest depth
        expected = factor * m + units * r
        # float32 depth: within two float32 steps (and the slope varies slightly: the
        # spec's m is per triangle, the difference quotient is per pixel)
        assert np.abs(delta - expected).max() <= 2 * r + 0.05 * abs(factor) * m


def test_polygon_offset_resolves_a_decal():
    wall = hsr.Mesh([[-2, -2, -5], [2, -2, -5], [2, 2, -5], [-2, 2, -5]], [[0, 1, 2], [0, 2, 3]],
                    face_colors=[[0, 255, 0]] * 2)
    decal = hsr.Mesh([[-1, -1, -5], [1, -1, -5], [1, 1, -5], [-1, 1, -5]], [[0, 2, 1], [0, 3, 2]],
                     face_colors=[[255, 0, 0]] * 2)
    camera = hsr.Camera.look_at((0.5, 0.3, 0), (0, 0, -5), (0, 1, 0), 60, 0.1, 100)
    first = hsr.render(wall, camera, W, H)
    fighting = hsr.render(decal, camera, W, H, into=first)
    pulled = hsr.render(decal, camera, W, H, into=first, polygon_offset=(-1, -1))
    decal_px = reference_render(decal, camera, W, H)[0] >= 0
    assert decal_px.sum() > 200
    shows = lambda frame: frame.color[decal_px][:, 0] > frame.color[decal_px][:, 1]  # noqa: E731
    # Coplanar and drawn second with GL_LESS: the decal is lost (wholly or in patches).
    assert shows(fighting).mean() < 1.0
    # glPolygonOffset(-1, -1) pulls it in front everywhere.
    assert shows(pulled).all()
    assert (pulled.depth[decal_px] < first.depth[decal_px]).all()


def edge_samples(drawing, which, margin_px=0.75, per_piece=5):
    """World points sampled inside each piece, away from its ends."""
    segs = getattr(drawing, which)
    length = np.hypot(*(segs[:, 1, :2] - segs[:, 0, :2]).T)
    segs = segs[length > 2 * margin_px + 0.1]
    length = np.hypot(*(segs[:, 1, :2] - segs[:, 0, :2]).T)
    lo = margin_px / length
    t = lo[:, None] + (1 - 2 * lo)[:, None] * np.linspace(0, 1, per_piece)[None]
    pts = segs[:, None, 0] + t[..., None] * (segs[:, None, 1] - segs[:, None, 0])
    return pts.reshape(-1, 3)


VECTOR_SCENES = {
    "cubes": lambda: scenes.get("cubes"),
    "cyclic": lambda: scenes.get("cyclic"),
    "penetration": lambda: scenes.get("penetration"),
    "spheres": lambda: (scenes.spheres(detail=8)[0], scenes.spheres(detail=8)[1]),
}


@pytest.mark.parametrize("edges", ["feature", "all"])
@pytest.mark.parametrize("name", sorted(VECTOR_SCENES))
def test_exact_hidden_lines_against_the_reference(name, edges):
    scene, camera = VECTOR_SCENES[name]()
    drawing = hidden_lines(scene, camera, W, H, HiddenLine(edges=edges))
    assert len(drawing.visible) > 0
    vis = unproject(camera, W, H, edge_samples(drawing, "visible"))
    hid = unproject(camera, W, H, edge_samples(drawing, "hidden"))
    bad_visible = occluded(scene, camera, vis)
    assert bad_visible.sum() == 0, f"{bad_visible.sum()} of {len(vis)} visible samples are hidden"
    if len(hid):
        bad_hidden = ~occluded(scene, camera, hid)
        assert bad_hidden.sum() == 0, f"{bad_hidden.sum()} of {len(hid)} hidden samples are seen"


def test_exact_hidden_lines_on_a_real_mesh(models_dir):
    mesh = hsr.load(f"{models_dir}/suzanne.obj")
    camera = hsr.Camera.frame(mesh.bounds())
    camera = hsr.Camera.look_at(np.asarray(camera.target) + [1.2, 0.8, 2.2], camera.target,
                                (0, 1, 0), 45, 0.1, 20)
    drawing = hidden_lines(mesh, camera, 320, 240, HiddenLine(edges="feature"))
    rng = np.random.default_rng(3)
    for which, expect_hidden in (("visible", False), ("hidden", True)):
        pts = edge_samples(drawing, which, per_piece=3)
        pts = pts[rng.choice(len(pts), min(600, len(pts)), replace=False)]
        world = unproject(camera, 320, 240, pts)
        hidden = occluded(mesh, camera, world)
        assert (hidden == expect_hidden).mean() == 1.0, which


def test_svg_parses_and_overlays_the_raster_hidden_line_image(tmp_path):
    scene, camera = scenes.get("cubes")
    settings = HiddenLine(edges="feature")
    drawing = hidden_lines(scene, camera, W, H, settings)
    path = tmp_path / "lines.svg"
    write_lines_svg(path, drawing, hidden=True)
    root = ET.parse(path).getroot()
    ns = {"s": "http://www.w3.org/2000/svg"}
    assert root.get("viewBox") == f"0 0 {W} {H}"
    ink = "{http://www.inkscape.org/namespaces/inkscape}"
    groups = {g.get(ink + "label"): g for g in root.findall("s:g", ns)}
    assert all(g.get(ink + "groupmode") == "layer" for g in groups.values())
    # Convex cubes: every silhouette outlines a cube (a border); the other edges are creases.
    assert set(groups) == {"border", "crease", "hidden"}
    assert groups["hidden"].get("stroke-dasharray")
    assert [groups[k].get("id") for k in ("crease", "hidden", "border")] == \
        ["layer3", "layer7", "layer9"]
    points = []
    for p in groups["border"].findall("s:path", ns) + groups["crease"].findall("s:path", ns):
        coords = [tuple(map(float, c.split())) for c in p.get("d")[1:].split(" L")]
        for a, b in zip(coords[:-1], coords[1:]):
            for t in np.linspace(0.1, 0.9, 9):
                points.append(np.add(a, t * np.subtract(b, a)))
    points = np.array(points)
    assert len(points) > 100
    frame = hsr.render(scene, camera, W, H, hidden_line=settings)
    drawn = np.pad(frame.fragments.buffers["lines"] >= 0, 1)
    px = np.floor(points).astype(int)
    near = np.zeros(len(px), bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near |= drawn[px[:, 1] + 1 + dy, px[:, 0] + 1 + dx]
    assert near.mean() >= 0.99, f"only {near.mean():.3f} of the SVG lies on raster lines"


def test_raster_hidden_line_matches_reference_visibility():
    scene, camera = scenes.get("cubes")
    settings = HiddenLine(edges="feature")
    frame = hsr.render(scene, camera, W, H, hidden_line=settings, background=(255, 255, 255))
    lines = frame.fragments.buffers["lines"] >= 0
    assert (frame.color[lines] == 0).all() and (frame.color[~lines] == 255).all()
    drawing = hidden_lines(scene, camera, W, H, settings)
    # Visible samples (confirmed by the reference) must be drawn within one pixel.
    vis_window = edge_samples(drawing, "visible", margin_px=1.5)
    assert not occluded(scene, camera, unproject(camera, W, H, vis_window)).any()
    px = np.floor(np.c_[vis_window[:, 0], H - vis_window[:, 1]]).astype(int)
    padded = np.pad(lines, 1)
    near = np.zeros(len(px), bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near |= padded[px[:, 1] + 1 + dy, px[:, 0] + 1 + dx]
    assert near.mean() >= 0.99
    # Hidden samples (confirmed occluded) far from any visible edge must not be drawn.
    hid_window = edge_samples(drawing, "hidden", margin_px=1.5)
    assert occluded(scene, camera, unproject(camera, W, H, hid_window)).all()
    vis_img = np.c_[drawing.visible[:, :, 0:1], H - drawing.visible[:, :, 1:2]]
    hid_img = np.c_[hid_window[:, 0], H - hid_window[:, 1]]
    far = distance_to_segments(hid_img, vis_img) > 2.5
    hpx = np.floor(hid_img[far]).astype(int)
    assert far.sum() > 20
    assert not lines[hpx[:, 1], hpx[:, 0]].any()


def test_merge_and_join():
    z = 0.5
    segs = np.array([[[0, 0, z], [2, 0, z]], [[1, 0, z], [3, 0, z]],  # overlapping, collinear
                     [[3, 0, z], [3, 2, z]], [[3, 2, z], [3, 4, z]]], dtype=float)
    merged = merge_collinear(segs)
    assert len(merged) == 2  # overlapping and touching collinear pieces become one
    lines = join_polylines(merged, height=10)
    assert len(lines) == 1
    # the straight continuation (3,2) is dropped: corner (3,0) stays; y flipped to image
    np.testing.assert_allclose(sorted(map(tuple, lines[0])), sorted([(0, 10), (3, 10), (3, 6)]))


def test_cli_writes_the_svg(tmp_path):
    from hsr.cli import main

    svg = tmp_path / "l.svg"
    assert main(["render", "--quiet", "--size", "80x60", "-o", str(tmp_path / "l.png"),
                 "--svg", str(svg), "--lines", "--edges", "feature", "--hidden-layer"]) == 0
    assert ET.parse(svg).getroot().tag.endswith("svg")
    assert main(["render", "--quiet", "--lines", "-o", str(tmp_path / "x.png")]) == 2
    assert main(["render", "--quiet", "--hidden-line", "--algorithm", "raycast",
                 "-o", str(tmp_path / "x.png")]) == 2


@pytest.mark.parametrize("name", ["spot.obj", "fandisk.obj"])
def test_feature_lines_do_not_depend_on_winding(models_dir, name):
    """A random 30% of the faces flipped (issue #65): the same silhouettes and creases,
    so the same visible feature lines (lengths equal to 1e-9, every piece within 1e-6 px
    of the other drawing). Before, flipping faces drew false silhouettes and creases."""
    mesh = hsr.load(f"{models_dir}/{name}")
    rng = np.random.default_rng(7)
    faces = mesh.faces.copy()
    flip = rng.random(len(faces)) < 0.3
    faces[flip] = faces[flip][:, ::-1]
    flipped = hsr.Mesh(mesh.positions, faces)
    camera = hsr.first_look(mesh, 4 / 3)
    settings = HiddenLine(edges="feature")
    a = hidden_lines(hsr.Mesh(mesh.positions, mesh.faces), camera, 400, 300, settings)
    b = hidden_lines(flipped, camera, 400, 300, settings)

    def length(segments):
        return float(np.linalg.norm(segments[:, 1, :2] - segments[:, 0, :2], axis=1).sum())

    assert len(a.visible) > 100
    assert abs(length(a.visible) - length(b.visible)) <= 1e-9 * length(a.visible)
    for one, other in ((a, b), (b, a)):
        mids = 0.5 * (one.visible[:, 0, :2] + one.visible[:, 1, :2])
        ends = np.concatenate([one.visible[:, 0, :2], one.visible[:, 1, :2], mids])
        for chunk in np.array_split(ends, max(1, len(ends) // 2000)):
            assert distance_to_segments(chunk, other.visible[:, :, :2]).max() <= 1e-6


def _cubes_and_sphere():
    import trimesh

    a = trimesh.creation.box(extents=(1, 1, 1))
    a.apply_translation((0.5, 0.5, 0.5))  # [0, 1]^3
    b = trimesh.creation.box(extents=(1, 1, 1))
    b.apply_translation((1.0, 1.0, 1.0))  # [0.5, 1.5]^3
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.6)
    sphere.apply_translation((3.0, 0.5, 0.5))
    plane = trimesh.creation.box(extents=(2.0, 2.0, 1e-9 + 0.0))
    plane = hsr.Mesh(np.array([[2, -0.5, 0.5], [4, -0.5, 0.5], [4, 1.5, 0.5],
                               [2, 1.5, 0.5]], float), np.array([[0, 1, 2], [0, 2, 3]]))
    meshes = [hsr.Mesh(np.asarray(m.vertices), np.asarray(m.faces)) for m in (a, b, sphere)]
    return meshes + [plane], sphere


def test_intersection_lines_are_the_exact_curves():
    """Two interpenetrating cubes cross along six edges of their common cube (total length
    3); a tessellated sphere cut by the plane z = 0.5 along a polygon on both (issue #65)."""
    from hsr.lines.intersect import intersection_edges

    meshes, sphere = _cubes_and_sphere()
    cubes = hsr.Scene(meshes[:2]).world_triangles()
    ends, pair = intersection_edges(cubes)
    length = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)
    assert abs(length.sum() - 3.0) <= 1e-9
    pts = np.concatenate([ends[:, 0], ends[:, 1], ends.mean(axis=1)])
    on_a = np.abs(np.abs(pts - 0.5).max(axis=1) - 0.5)  # on the boundary of [0, 1]^3
    on_b = np.abs(np.abs(pts - 1.0).max(axis=1) - 0.5)  # of [0.5, 1.5]^3
    assert on_a.max() <= 1e-9 and on_b.max() <= 1e-9
    assert np.all(pair[:, 0] < 12) and np.all(pair[:, 1] >= 12)  # one face of each cube
    cut = hsr.Scene(meshes[2:]).world_triangles()
    ends, pair = intersection_edges(cut)
    pts = np.concatenate([ends[:, 0], ends[:, 1], ends.mean(axis=1)])
    assert np.abs(pts[:, 2] - 0.5).max() <= 1e-9  # on the plane
    tris = np.asarray(sphere.vertices)[np.asarray(sphere.faces)][pair[:, 0]]
    normal = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    for p in (ends[:, 0], ends[:, 1]):  # on its sphere face's plane
        assert np.abs(np.einsum("ij,ij->i", p - tris[:, 0], normal)).max() <= 1e-9
    # A closed polygon: every end meets another segment's end.
    flat = ends.reshape(-1, 3)
    d = np.linalg.norm(flat[:, None] - flat[None], axis=2) + np.eye(len(flat)) * 9
    assert d.min(axis=1).max() <= 1e-9
    radius = np.linalg.norm(pts[:, :2] - [3.0, 0.5], axis=1)
    assert radius.max() <= 0.6 + 1e-9 and radius.min() >= 0.6 * 0.95  # chords inside


def test_intersection_lines_are_hidden_like_any_edge():
    meshes, _ = _cubes_and_sphere()
    scene = hsr.Scene(meshes)
    camera = hsr.Camera.look_at((4.5, -2.5, 3.5), (1.8, 0.6, 0.6), (0, 0, 1), 45, 0.1, 30)
    settings = HiddenLine(edges="feature", intersections=True)
    drawing = hidden_lines(scene, camera, 400, 300, settings)
    plain = hidden_lines(scene, camera, 400, 300, HiddenLine(edges="feature"))
    assert len(drawing.visible) > len(plain.visible)
    rng = np.random.default_rng(5)
    for which, expect_hidden in (("visible", False), ("hidden", True)):
        pts = edge_samples(drawing, which, per_piece=3)
        pts = pts[rng.choice(len(pts), min(600, len(pts)), replace=False)]
        world = unproject(camera, 400, 300, pts)
        assert (occluded(scene, camera, world) == expect_hidden).all(), which
    with pytest.raises(hsr.HsrError, match="intersections must be True or False"):
        HiddenLine(intersections="yes")


def test_polylines_are_ordered_for_a_plotter(models_dir):
    """Per layer, the pen-up travel is at most what a plain greedy loop over every end gives
    (here, O(n^2); hsr adds 2-opt moves to its greedy order), far below the joined order,
    and every polyline is kept (some reversed)."""
    from hsr.lines.drawing import layer_of
    from hsr.lines.paths import join_polylines, merge_collinear, order_for_plotter, pen_travel

    mesh = hsr.load(f"{models_dir}/spot.obj")
    camera = hsr.first_look(mesh, 4 / 3)
    drawing = hidden_lines(mesh, camera, 400, 300, HiddenLine(edges="feature"))
    assert set(drawing.layers) >= {"silhouette", "crease"}
    layer = layer_of(drawing.visible_kind)
    total = 0.0
    for name, ordered in drawing.layers.items():
        joined = join_polylines(merge_collinear(drawing.visible[layer == name]), 300)
        assert len(ordered) == len(joined) > 0

        def key(lines):
            return sorted(tuple(np.round(np.r_[min(tuple(p[0]), tuple(p[-1])), len(p)], 9))
                          for p in lines)

        assert key(joined) == key(ordered)
        here, left, naive = np.zeros(2), list(joined), []
        while left:
            d = [min(np.linalg.norm(p[0] - here), np.linalg.norm(p[-1] - here)) for p in left]
            line = left.pop(int(np.argmin(d)))
            if np.linalg.norm(line[-1] - here) < np.linalg.norm(line[0] - here):
                line = line[::-1]
            naive.append(line)
            here = line[-1]
        assert pen_travel(ordered) <= pen_travel(naive) + 1e-9
        if len(joined) > 50:
            assert pen_travel(ordered) < 0.5 * pen_travel(joined)
        total += pen_travel(ordered)
    assert drawing.stats["pen_travel"] == pytest.approx(total, rel=1e-12)
    assert sum(map(len, drawing.layers.values())) == len(drawing.visible_polylines) > 50
    assert order_for_plotter([]) == [] and len(order_for_plotter(joined[:1])) == 1
