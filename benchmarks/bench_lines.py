"""Exact line drawings (hsr.hidden_lines, feature edges, hidden parts included: the call's
defaults) against the issue's targets and against peers measured in the same run:
hsr.render of the same view (pixels), OCCT's hidden-line removal on the same CAD
tessellation (HLRBRep_PolyAlgo, and the exact HLRBRep_Algo where it finishes in 60 s),
and vpype's linemerge linesort for the pen-up travel.

    python benchmarks/bench_lines.py [--skip-cad] [--skip-vpype]

Needs the [cad] and [plot] extras for those parts.
"""

from __future__ import annotations

import argparse
import gzip
import os
import subprocess
import sys
import tempfile

import numpy as np
from bench_regions import cpu_name

import hsr
from common import load_model, timed, timings
from hsr.lines.raster import HiddenLine

HERE = os.path.dirname(os.path.abspath(__file__))
MODELS = os.path.join(HERE, "..", "..", "shared", "models")
CAD = os.path.join(HERE, "..", "tests", "data", "cad")
FEATURE = HiddenLine(edges="feature")


def speed():
    print("\nvisible feature lines (hidden_lines, feature edges, with the hidden parts; "
          "medians of 3)")
    print(f"{'case (1920 x 1080)':36} {'faces':>9} {'lines s':>8} {'target s':>8} {'x target':>8} "
          f"{'x render':>8} {'polylines':>9}")
    cases = (("bunny", "first look", 0.2), ("terrain:1000000", "first look", 2.0),
             ("terrain:1000000", "low oblique", 2.0), ("terrain32:1000000", "first look", 2.0))
    for spec, view, target in cases:
        if spec == "bunny":
            mesh, label = hsr.load(os.path.join(MODELS, "stanford-bunny.obj")), "bunny"
        else:
            mesh, label = load_model(spec)
        if view == "low oblique":  # the terrain scene's own camera: ridges behind ridges
            camera = hsr.scenes.terrain(10)[1]
        else:
            camera = hsr.first_look(mesh, 1920 / 1080)
        drawing = hsr.hidden_lines(mesh, camera, 1920, 1080, FEATURE)
        # Medians of three calls after a warm-up one (the first call of a mesh pays for
        # nothing extra: no cache is kept between calls).
        (_, t_lines), (_, t_render) = timings(
            [lambda: hsr.hidden_lines(mesh, camera, 1920, 1080, FEATURE),
             lambda: hsr.render(mesh, camera, 1920, 1080)], repeat=3)
        print(f"{label + ', ' + view:36} {mesh.n_faces:9d} {t_lines / 1e3:8.2f} "
              f"{target:8.2f} {t_lines / 1e3 / target:8.2f} {t_lines / t_render:8.1f} "
              f"{len(drawing.visible_polylines):9d}", flush=True)


OCCT_EXACT = """
import sys, time
from OCP.STEPControl import STEPControl_Reader
from OCP.HLRBRep import HLRBRep_Algo, HLRBRep_HLRToShape
from OCP.HLRAlgo import HLRAlgo_Projector
from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
reader = STEPControl_Reader(); reader.ReadFile(sys.argv[1]); reader.TransferRoots()
shape = reader.OneShape()
d = [float(v) for v in sys.argv[2].split(",")]; r = [float(v) for v in sys.argv[3].split(",")]
start = time.perf_counter()
algo = HLRBRep_Algo(); algo.Add(shape)
algo.Projector(HLRAlgo_Projector(gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(*d), gp_Dir(*r))))
algo.Update(); algo.Hide()
HLRBRep_HLRToShape(algo).VCompound()
print(time.perf_counter() - start)
"""


def cad():
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
    from OCP.HLRAlgo import HLRAlgo_Projector
    from OCP.HLRBRep import HLRBRep_PolyAlgo, HLRBRep_PolyHLRToShape

    from hsr.scene import cad

    print("\nCAD: hsr on OCCT's tessellation against OCCT's hidden-line removal, 1000 x 1000, "
          "orthographic")
    print(f"{'file':36} {'triangles':>9} {'hsr s':>7} {'x PolyAlgo':>10} {'x Algo':>8}")
    with tempfile.TemporaryDirectory() as folder:
        for name in sorted(os.listdir(CAD)):
            if not name.endswith(".stp.gz"):
                continue
            path = os.path.join(folder, name[:-3])
            with gzip.open(os.path.join(CAD, name), "rb") as src, open(path, "wb") as dst:
                dst.write(src.read())
            mesh = hsr.load(path)
            lo, hi = mesh.positions.min(axis=0), mesh.positions.max(axis=0)
            target, diagonal = (lo + hi) / 2, float(np.linalg.norm(hi - lo))
            d = np.array([0.6, -0.7, 0.5]) / np.linalg.norm([0.6, -0.7, 0.5])
            right = np.cross(-d, (0, 0, 1))
            right /= np.linalg.norm(right)
            camera = hsr.Camera.orthographic(target + 2 * diagonal * d, target, (0, 0, 1),
                                             1.1 * diagonal, 0.5 * diagonal, 4 * diagonal)
            _, t_hsr = timed(lambda: hsr.hidden_lines(mesh, camera, 1000, 1000, FEATURE))
            shape = cad._read_shape(path)
            BRepMesh_IncrementalMesh(shape, cad.DEFAULT_TOLERANCE * cad._diagonal(shape, path),
                                     False, cad.ANGULAR_DEFLECTION, False)

            def poly():
                algo = HLRBRep_PolyAlgo()
                algo.Load(shape)
                algo.Projector(HLRAlgo_Projector(gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(*d),
                                                        gp_Dir(*right))))
                algo.Update()
                out = HLRBRep_PolyHLRToShape()
                out.Update(algo)
                return out.VCompound(), out.Rg1LineVCompound(), out.OutLineVCompound()

            _, t_poly = timed(poly)
            try:
                run = subprocess.run([sys.executable, "-c", OCCT_EXACT, path,
                                      ",".join(map(str, d)), ",".join(map(str, right))],
                                     capture_output=True, text=True, timeout=60)
                exact = f"{t_hsr / 1e3 / float(run.stdout.split()[-1]):8.2f}"
            except (subprocess.TimeoutExpired, ValueError, IndexError):
                exact = f"{'> 60 s':>8}"
            print(f"{name[:-3]:36} {mesh.n_faces:9d} {t_hsr / 1e3:7.3f} "
                  f"{t_hsr / t_poly:10.1f} {exact}", flush=True)


def pen_travel():
    import vpype_cli

    def travel(document):
        total = 0.0
        for lines in document.layers.values():
            here = 0j
            for line in lines:
                total += abs(line[0] - here)
                here = line[-1]
        return total

    print("\npen-up travel with the hidden layer, vpype hsr's order against vpype's: joining "
          "at linemerge's 0.05 mm (vpype hsr's default), and at hsr's 0.01 px")
    print(f"{'model':22} {'hsr px':>9} {'x linemerge linesort':>21} {'hsr px, 0.01':>13} "
          f"{'x the same':>11}")
    for name, view in (("spot.obj", "35,25"), ("stanford-bunny.obj", "-60,10"),
                       ("fandisk.obj", "120,30"), ("teapot.obj", "35,25"),
                       ("cow.obj", "35,25"), ("diablo3_pose.obj", "35,25")):
        base = f"hsr {os.path.join(MODELS, name)} --view {view} --hidden-layer"
        ours = travel(vpype_cli.execute(base))
        default = travel(vpype_cli.execute(base + " linemerge linesort"))
        exact = travel(vpype_cli.execute(base + " --join-tolerance 0"))
        same = travel(vpype_cli.execute(base + " --join-tolerance 0 linemerge --tolerance "
                                         "0.01px linesort"))
        print(f"{name:22} {ours:9.0f} {ours / default:21.4f} {exact:13.0f} "
              f"{exact / same:11.4f}", flush=True)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip-cad", action="store_true")
    parser.add_argument("--skip-vpype", action="store_true")
    args = parser.parse_args(argv)
    warm, cam = hsr.scenes.get("cubes")
    hsr.hidden_lines(warm, cam, 64, 48, FEATURE)
    hsr.render(warm, cam, 64, 48)
    print(f"CPU: {cpu_name()}, {os.cpu_count()} cores")
    speed()
    if not args.skip_cad:
        cad()
    if not args.skip_vpype:
        pen_travel()
    return 0


if __name__ == "__main__":
    sys.exit(main())
