"""Removing hidden geometry: ``hsr.prune`` against pymeshlab's ambient-occlusion route, in
the same run, on the same meshes.

    python benchmarks/bench_prune.py [--views 256] [--size 1024] [--keep-neighbors 0]
                                     [--also VIEWS@SIZE+RINGS|auto ...] [--verify 100]
                                     [--verify-size SIZE] [--rays 256] [--skip-million]
                                     [--picture FILE.png]

For each model: faces, views, seconds, faces removed and the verify error (changed
pixels of covered pixels over ``--verify`` random outside viewpoints not used for the
decision, at ``--verify-size``, by default the decision resolution) for hsr, at the
setting of ``--views``, ``--size`` and ``--keep-neighbors`` and at each ``--also``
setting (e.g. ``48@512+1``: ``sphere:48`` at 512 x 512, one ring of neighbours kept;
``auto``: the automatic views and size of ``hsr prune``'s default, two rings kept),
all verified the same way; for pymeshlab
(``compute_scalar_ambient_occlusion(rays=N)`` gives each vertex the share of rays that
escape; the faces whose three corners have none are deleted) the same, its deletion
applied with hsr's ``subset_scene`` so both are verified the same way. Models: the
shared bunny, spot and fandisk (scans and CAD, little is hidden), a closed 4 x 4 x 4
box holding three bunnies (208,365 faces), a CAD-like assembly of primitives (a housing
with bolts through its walls, parts inside and handles outside) and a 1M-triangle
assembly (a closed box holding 10 bunnies, 5 more outside: 1,041,777 faces). Runs on demand, never
in the test suite. pymeshlab is optional (``pip install pymeshlab``).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
import trimesh

import hsr
from hsr.visibility import decide, face_visibility, keep_faces, subset_scene, verify
from hsr.visibility.prune import AUTO_RINGS

MODELS = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "models")


def _mesh(m, name):
    return hsr.Mesh(np.asarray(m.vertices), np.asarray(m.faces), name=name)


def _placed(mesh, centre, size):
    """``mesh`` scaled to fit a cube of ``size`` and centred at ``centre``."""
    lo, hi = mesh.positions.min(axis=0), mesh.positions.max(axis=0)
    positions = (mesh.positions - (lo + hi) / 2) * (size / (hi - lo).max()) + centre
    return hsr.Mesh(positions, mesh.faces, name=mesh.name)


def box_of_bunnies(count=3, outside=0):
    """A closed 4 x 4 x 4 box (12 triangles) holding ``count`` bunnies, ``outside`` more
    around it."""
    bunny = hsr.load(os.path.join(MODELS, "stanford-bunny.obj"))
    scene = hsr.Scene()
    scene.add(_mesh(trimesh.creation.box(extents=(4, 4, 4)), "box"), name="box")
    grid = [(x, y, z) for x in (-1, 0, 1) for y in (-1, 0, 1) for z in (-1, 0, 1)]
    for k in range(count):
        scene.add(_placed(bunny, np.array(grid[k % len(grid)], float) * 1.2, 1.1),
                  name=f"inside{k}")
    for k in range(outside):
        angle = 2 * np.pi * k / max(outside, 1)
        scene.add(_placed(bunny, (4.5 * np.cos(angle), -1.0, 4.5 * np.sin(angle)), 2.0),
                  name=f"outside{k}")
    return scene


def cad_assembly():
    """A housing (a box shell, subdivided), four bolts through its lid (heads outside,
    shanks inside), a shaft and gears inside, two handles and feet outside."""
    scene = hsr.Scene()
    housing = trimesh.creation.box(extents=(4, 2, 3)).subdivide().subdivide()
    scene.add(_mesh(housing, "housing"), name="housing")
    for k, (x, z) in enumerate(((-1.5, -1), (1.5, -1), (-1.5, 1), (1.5, 1))):
        upright = trimesh.transformations.rotation_matrix(-np.pi / 2, (1, 0, 0))  # z -> y
        head = trimesh.creation.cylinder(radius=0.2, height=0.15, sections=32,
                                         transform=upright)
        head.apply_translation((x, 1.075, z))
        shank = trimesh.creation.cylinder(radius=0.08, height=1.2, sections=24,
                                          transform=upright)
        shank.apply_translation((x, 0.5, z))
        scene.add(_mesh(trimesh.util.concatenate([head, shank]), f"bolt{k}"), name=f"bolt{k}")
    shaft = trimesh.creation.cylinder(radius=0.15, height=4.6, sections=48)
    shaft.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (0, 1, 0)))
    scene.add(_mesh(shaft, "shaft"), name="shaft")  # pokes out of both ends
    for k, x in enumerate((-1.0, 0.0, 1.0)):
        gear = trimesh.creation.cylinder(radius=0.7, height=0.2, sections=96)
        gear.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (0, 1, 0)))
        gear.apply_translation((x, 0, 0))
        scene.add(_mesh(gear, f"gear{k}"), name=f"gear{k}")
    core = trimesh.creation.icosphere(subdivisions=4, radius=0.5)
    core.apply_translation((0, -0.4, 0.9))
    scene.add(_mesh(core, "core"), name="core")
    for k, z in enumerate((-1.9, 1.9)):
        handle = trimesh.creation.torus(0.5, 0.08, major_sections=64, minor_sections=16)
        handle.apply_translation((0, 0, z))
        scene.add(_mesh(handle, f"handle{k}"), name=f"handle{k}")
    for k, (x, z) in enumerate(((-1.7, -1.2), (1.7, -1.2), (-1.7, 1.2), (1.7, 1.2))):
        foot = trimesh.creation.box(extents=(0.4, 0.3, 0.4))
        foot.apply_translation((x, -1.15, z))
        scene.add(_mesh(foot, f"foot{k}"), name=f"foot{k}")
    return scene


def setting(text):
    """``VIEWS@SIZE+RINGS`` (``+RINGS`` optional) -> (views, size, rings); ``auto`` ->
    ("auto", "auto", None): :func:`hsr.visibility.decide`'s automatic views and size."""
    if text == "auto":
        return "auto", "auto", None
    try:
        views, rest = text.split("@")
        size, _, rings = rest.partition("+")
        return int(views), int(size), int(rings or 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected VIEWS@SIZE+RINGS, got {text!r}") from None


def pymeshlab_keep(scene, rays):
    """pymeshlab's route: per-vertex ambient occlusion on the scene as one mesh; keep the
    faces with a corner that some ray escapes from. (keep, seconds)"""
    import pymeshlab

    tri = scene.world_triangles()
    vertices, inverse = np.unique(tri.reshape(-1, 3), axis=0, return_inverse=True)
    faces = inverse.reshape(-1, 3).astype(np.int32)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=vertices, face_matrix=faces))
    start = time.perf_counter()
    ms.compute_scalar_ambient_occlusion(rays=rays)
    seconds = time.perf_counter() - start
    escaped = ms.current_mesh().vertex_scalar_array()
    if len(escaped) != len(vertices):
        raise RuntimeError("pymeshlab changed the vertices")
    return (escaped[faces] > 0).any(axis=1), seconds


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--views", type=int, default=256)
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--keep-neighbors", type=int, default=0)
    parser.add_argument("--also", action="append", default=[], type=setting,
                        metavar="VIEWS@SIZE+RINGS", help="another hsr setting to run, or "
                        "auto (hsr prune's default: automatic views and size)")
    parser.add_argument("--verify", type=int, default=100)
    parser.add_argument("--verify-size", type=int, help="default: --size")
    parser.add_argument("--rays", type=int, default=256)
    parser.add_argument("--skip-million", action="store_true")
    parser.add_argument("--picture", help="write the before/after picture of the CAD "
                        "assembly to this PNG")
    args = parser.parse_args()
    try:
        import pymeshlab  # noqa: F401
        have_meshlab = True
    except ImportError:
        have_meshlab = False
    models = [(name, hsr.load_scene(os.path.join(MODELS, name + ".obj")))
              for name in ("stanford-bunny", "spot", "fandisk")]
    models += [("box + 3 bunnies", box_of_bunnies(3)), ("CAD-like assembly", cad_assembly())]
    if not args.skip_million:
        models.append(("box + 15 bunnies, 1.04M", box_of_bunnies(10, 5)))
    # Warm the kernels (their compile is not what is measured).
    face_visibility(models[-1][1], "sphere:1", 64)
    settings = [(args.views, args.size, args.keep_neighbors)] + args.also
    verify_size = args.verify_size or args.size
    rows = []
    for name, scene in models:
        for k, (views, size, rings) in enumerate(settings):
            for inst in scene.instances:  # each route pays for its edge rings
                vars(inst.mesh).pop("_edge_groups", None)
            start = time.perf_counter()
            if views == "auto":
                decision = decide(scene, "auto", "auto", progress=False)
                keep, size = decision.keep, decision.size[0]
                label = (f"hsr auto: {decision.views} views at {size}, "
                         f"{AUTO_RINGS} rings kept")
            else:
                counts = face_visibility(scene, f"sphere:{views}", size, progress=False)
                keep = keep_faces(scene, counts, keep_neighbors=rings)
                label = f"hsr sphere:{views} at {size}" + (
                    f", {rings} ring{'s' if rings > 1 else ''} kept" if rings else "")
            seconds = time.perf_counter() - start
            pruned = subset_scene(scene, keep)
            report = verify(scene, pruned, np.flatnonzero(keep), args.verify, verify_size,
                            seed=7)
            rows.append((name, label, scene.n_faces, seconds, int((~keep).sum()), report))
            if args.picture and name == "CAD-like assembly" and k == 0:
                picture(scene, keep, args.picture)
            print(rows[-1], file=sys.stderr)
        if have_meshlab:
            keep_ml, ml_seconds = pymeshlab_keep(scene, args.rays)
            report_ml = verify(scene, subset_scene(scene, keep_ml), np.flatnonzero(keep_ml),
                               args.verify, verify_size, seed=7)
            rows.append((name, f"pymeshlab AO rays={args.rays}", scene.n_faces, ml_seconds,
                         int((~keep_ml).sum()), report_ml))
            print(rows[-1], file=sys.stderr)
    print(f"\nverify: {args.verify} random outside views at {verify_size}x{verify_size}\n")
    print("| model | route | faces | seconds | faces removed | verify: changed / covered px |")
    print("|---|---|---|---|---|---|")
    for name, route, faces, seconds, removed, report in rows:
        print(f"| {name} | {route} | {faces:,} | {seconds:.2f} | {removed:,} "
              f"({100.0 * removed / faces:.2f}%) | {report['changed']:,} / "
              f"{report['covered']:,} ({report['percent']:.4f}%) |")


def picture(scene, keep, path):
    """Left: the assembly as it renders. Right: x-ray of what was removed: the removed
    faces in red drawn with the depth test off over the kept ones, shaded grey."""
    from PIL import Image

    camera = hsr.views.default(scene, 1.0)
    before = hsr.render(scene, camera, 480, 480, light="studio").color
    kept = subset_scene(scene, keep)
    removed = subset_scene(scene, ~keep)
    grey = hsr.render(kept, camera, 480, 480, light="studio")
    red = hsr.render(removed, camera, 480, 480, light="studio", depth_test=False)
    xray = (grey.color * 0.45).astype(np.uint8)
    mask = red.face_id >= 0
    shade = red.color[..., 1:2].astype(float) / 255.0
    xray[mask] = (np.concatenate([0.55 + 0.45 * shade, 0.1 * shade, 0.1 * shade], axis=-1)
                  * 255).astype(np.uint8)[mask]
    Image.fromarray(np.concatenate([before, xray], axis=1)).save(path)


if __name__ == "__main__":
    main()
