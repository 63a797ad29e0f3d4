"""Shared edges are covered exactly once: no cracks, no double hits."""

import numpy as np
import pytest

import hsr
from hsr import scenes
from reference import ambiguous_pixels, reference_render


def random_direction(rng):
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


@pytest.mark.parametrize("seed", range(8))
def test_closed_sphere_covered_exactly_twice(seed):
    """A closed convex mesh drawn with the depth test off: every pixel inside the
    silhouette receives exactly two fragments (front and back), outside none."""
    rng = np.random.default_rng(seed)
    mesh = scenes.uv_sphere(1.0, 6 + seed, 9 + 2 * seed)
    direction = random_direction(rng)
    up = np.cross(direction, random_direction(rng))
    cam = hsr.Camera.look_at(direction * rng.uniform(2.5, 6.0), (0, 0, 0), up,
                             fov_y=rng.uniform(30, 70), near=0.5, far=20)
    width, height = 120, 90
    frame = hsr.render(mesh, cam, width, height, depth_test=False, counts=True)
    written = frame.fragments.count_written
    assert set(np.unique(written)) <= {0, 2}, f"counts seen: {np.unique(written)}"
    ref, _ = reference_render(mesh, cam, width, height)
    amb = ambiguous_pixels(mesh, cam, width, height)
    inside = (ref >= 0) & ~amb
    outside = (ref < 0) & ~amb
    assert (written[inside] == 2).all(), "a crack: background inside the silhouette"
    assert (written[outside] == 0).all()
    culled = hsr.render(mesh, cam, width, height, depth_test=False, counts=True, cull="back")
    assert set(np.unique(culled.fragments.count_written)) <= {0, 1}


@pytest.mark.parametrize("n", [3, 7, 64, 257])
def test_triangle_fan_covers_each_pixel_once(n):
    """A disc of n triangles around one centre vertex, centred on a pixel centre so many
    edges pass exactly through pixel centres."""
    angles = np.linspace(0, 2 * np.pi, n, endpoint=False)
    rim = np.c_[np.cos(angles), np.sin(angles), np.zeros(n)] * 20.0 + [32.5, 32.5, 0]
    verts = np.vstack([[32.5, 32.5, 0], rim])
    faces = np.array([[0, 1 + i, 1 + (i + 1) % n] for i in range(n)])
    mesh = hsr.Mesh(verts, faces)
    cam = hsr.Camera.orthographic((32, 32, 1), (32, 32, 0), height=64, near=0.5, far=2)
    frame = hsr.render(mesh, cam, 64, 64, depth_test=False, counts=True)
    counts = frame.fragments.count_written
    assert set(np.unique(counts)) <= {0, 1}
    # The disc's area in pixels, up to its boundary.
    assert abs(int(counts.sum()) - 0.5 * n * 400 * np.sin(2 * np.pi / n)) < 4 * 20 * np.pi * 0.5


def test_grid_on_pixel_lattice_has_no_gaps_or_overlaps():
    """A 16x16 grid of quads whose corners sit exactly on pixel centres."""
    k = 17
    xs, ys = np.meshgrid(np.arange(k) * 3 + 4.5, np.arange(k) * 3 + 4.5)
    verts = np.c_[xs.ravel(), ys.ravel(), np.zeros(k * k)]
    faces = []
    for j in range(k - 1):
        for i in range(k - 1):
            a = j * k + i
            faces += [[a, a + 1, a + k + 1], [a, a + k + 1, a + k]]
    mesh = hsr.Mesh(verts, np.array(faces))
    cam = hsr.Camera.orthographic((32, 32, 1), (32, 32, 0), height=64, near=0.5, far=2)
    frame = hsr.render(mesh, cam, 64, 64, depth_test=False, counts=True)
    counts = frame.fragments.count_written
    assert set(np.unique(counts)) <= {0, 1}
    assert counts.sum() == 48 * 48  # exactly the pixel centres of [4.5, 52.5)^2
