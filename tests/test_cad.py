"""CAD models (issue #65): real STEP files (tests/data/cad, written by NX, Pro/ENGINEER and
Open CASCADE, none here) read through OCCT, drawn with their own B-rep edges, checked
against OCCT's own hidden-line removal (HLRBRep_PolyAlgo) on the same tessellation, and
against the brute-force reference ray test."""

from __future__ import annotations

import gzip
import os

import numpy as np
import pytest
from test_lines import edge_samples

import hsr
from conftest import run_cli
from hsr.lines.raster import HiddenLine
from hsr.lines.vector import hidden_lines
from reference import occluded, unproject

pytest.importorskip("OCP", reason="the [cad] extra (cadquery-ocp) is not installed")

DATA = os.path.join(os.path.dirname(__file__), "data", "cad")
PARTS = ("face_recognition_sample_part.stp", "as1_pe_203.stp", "as1-oc-214.stp")


@pytest.fixture(scope="module")
def step_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cad")
    for name in PARTS:
        with gzip.open(os.path.join(DATA, name + ".gz"), "rb") as src:
            (folder / name).write_bytes(src.read())
    return {name: str(folder / name) for name in PARTS}


@pytest.fixture(scope="module")
def meshes(step_files):
    return {name: hsr.load(path) for name, path in step_files.items()}


def test_step_files_tessellate_closed_and_outward(meshes):
    """Every part is a solid: the tessellation's signed volume is positive (faces wound
    outward by their B-rep orientation), the B-rep edges are there, Z is up."""
    for name, mesh in meshes.items():
        tri = mesh.positions[mesh.faces]
        volume = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
        extent = np.ptp(mesh.positions, axis=0)
        assert volume > 0.01 * np.prod(extent), name
        assert len(mesh.feature_lines) > 50 and mesh.up_axis == "z", name


def _occt_visible(path, view_dir, right) -> list:
    """OCCT's own visible lines (sharp, smooth and outlines) of the file, tessellated as
    hsr.load does, projected along ``view_dir`` (towards the eye): (n, 2) point arrays in
    world units (x along ``right``, y up)."""
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
    from OCP.HLRAlgo import HLRAlgo_Projector
    from OCP.HLRBRep import HLRBRep_PolyAlgo, HLRBRep_PolyHLRToShape
    from OCP.STEPControl import STEPControl_Reader
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    from hsr.scene.cad import ANGULAR_DEFLECTION, DEFAULT_TOLERANCE

    reader = STEPControl_Reader()
    reader.ReadFile(path)
    reader.TransferRoots()
    shape = reader.OneShape()
    # The same mesher call as hsr.load's.
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    box = Bnd_Box()
    BRepBndLib.Add_s(shape, box)
    diagonal = np.linalg.norm(np.subtract(box.CornerMax().Coord(), box.CornerMin().Coord()))
    BRepMesh_IncrementalMesh(shape, DEFAULT_TOLERANCE * diagonal, False, ANGULAR_DEFLECTION,
                             False)
    algo = HLRBRep_PolyAlgo()
    algo.Load(shape)
    algo.Projector(HLRAlgo_Projector(gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(*view_dir),
                                            gp_Dir(*right))))
    algo.Update()
    out = HLRBRep_PolyHLRToShape()
    out.Update(algo)
    lines = []
    for compound in (out.VCompound(), out.Rg1LineVCompound(), out.OutLineVCompound()):
        if compound is None or compound.IsNull():
            continue
        explorer = TopExp_Explorer(compound, TopAbs_EDGE)
        while explorer.More():
            curve = BRepAdaptor_Curve(TopoDS.Edge(explorer.Current()))
            explorer.Next()
            lines.append(np.array([curve.Value(u).Coord()[:2] for u in
                                   (curve.FirstParameter(), curve.LastParameter())]))
    return lines


def _dense(polylines, step=0.25) -> np.ndarray:
    out = [a + np.linspace(0, 1, max(2, int(np.linalg.norm(b - a) / step) + 1))[:, None]
           * (b - a) for p in polylines for a, b in zip(p[:-1], p[1:])]
    return np.concatenate(out)


class _FarEye:
    """An eye for the reference segment test far along the view direction: an
    orthographic view's ray to ``point``."""

    def __init__(self, point, toward_eye, distance):
        self.eye = np.asarray(point) + distance * np.asarray(toward_eye)


@pytest.mark.parametrize("name", PARTS)
def test_visible_lines_match_occt_hlr(step_files, meshes, name):
    """Orthographic views at 1000 x 1000 px, hsr's visible lines against OCCT's
    HLRBRep_PolyAlgo's (sharp edges, smooth edges and outlines) on the same tessellation,
    sampled every 1/4 px: everything OCCT draws is within 0.5 px of an hsr line, and every
    hsr point within 0.5 px of an OCCT line, or else seen by the brute-force reference ray
    test (where OCCT's polygonal algorithm drops a visible piece of outline: the AS1 rod's
    end, seen from the second view, against the background)."""
    from scipy.spatial import cKDTree

    mesh = meshes[name]
    lo, hi = mesh.positions.min(axis=0), mesh.positions.max(axis=0)
    target, diagonal = (lo + hi) / 2, float(np.linalg.norm(hi - lo))
    for toward_eye in ((0.6, -0.7, 0.5), (-0.5, -0.4, 0.75)):
        d = np.asarray(toward_eye) / np.linalg.norm(toward_eye)
        right = np.cross(-d, (0.0, 0.0, 1.0))
        right /= np.linalg.norm(right)
        up = np.cross(d, right)
        camera = hsr.Camera.orthographic(target + 2 * diagonal * d, target, (0, 0, 1),
                                         1.1 * diagonal, 0.5 * diagonal, 4 * diagonal)
        drawing = hidden_lines(mesh, camera, 1000, 1000, HiddenLine(edges="feature"),
                               with_hidden=False)
        scale = 1000 / (1.1 * diagonal)
        # OCCT projects onto the plane through the origin: shift by the target's image.
        occt = [np.c_[500 + (p[:, 0] - target @ right) * scale,
                      500 - (p[:, 1] - target @ up) * scale]
                for p in _occt_visible(step_files[name], d, right)]
        theirs = _dense(occt)
        ours_window = _dense(list(drawing.visible))  # x, y up, depth
        ours = np.c_[ours_window[:, 0], 1000 - ours_window[:, 1]]
        assert cKDTree(ours).query(theirs)[0].max() <= 0.5, (name, toward_eye)
        apart = np.flatnonzero(cKDTree(theirs).query(ours)[0] > 0.5)
        assert len(apart) <= 0.002 * len(ours), (name, toward_eye, len(apart))
        world = unproject(camera, 1000, 1000, ours_window[apart[::max(1, len(apart) // 40)]])
        for point in world:
            assert not occluded(mesh, _FarEye(point, d, 10 * diagonal), point[None])[0], \
                (name, toward_eye, point)


def test_lines_against_the_reference(meshes):
    """Perspective first look: points along the visible pieces are seen, along the hidden
    pieces hidden, by the brute-force segment test."""
    rng = np.random.default_rng(5)
    mesh = meshes["as1-oc-214.stp"]
    camera = hsr.first_look(mesh, 4 / 3)
    drawing = hidden_lines(mesh, camera, 400, 300, HiddenLine(edges="feature"))
    for which, expect in (("visible", False), ("hidden", True)):
        pts = edge_samples(drawing, which, per_piece=3)
        pts = pts[rng.choice(len(pts), min(800, len(pts)), replace=False)]
        hidden = occluded(mesh, camera, unproject(camera, 400, 300, pts))
        assert (hidden == expect).all(), (which, int((hidden != expect).sum()))


def test_flipped_faces_draw_the_same_lines(meshes):
    """A random 30% of the tessellation's triangles turned round: the same visible lines
    (the B-rep edges and the silhouettes do not depend on winding)."""
    from scipy.spatial import cKDTree

    mesh = meshes["as1_pe_203.stp"]
    rng = np.random.default_rng(30)
    flip = rng.random(mesh.n_faces) < 0.3
    faces = mesh.faces.copy()
    faces[flip] = faces[flip][:, [0, 2, 1]]
    flipped = hsr.Mesh(mesh.positions, faces, feature_lines=mesh.feature_lines)
    camera = hsr.first_look(mesh, 4 / 3)
    a = hidden_lines(mesh, camera, 800, 600, HiddenLine(edges="feature"), with_hidden=False)
    b = hidden_lines(flipped, camera, 800, 600, HiddenLine(edges="feature"),
                     with_hidden=False)
    length = [sum(np.hypot(*np.diff(p, axis=0).T).sum() for p in d.visible_polylines)
              for d in (a, b)]
    assert abs(length[0] - length[1]) <= 1e-9 * length[0]
    pa, pb = _dense(a.visible_polylines), _dense(b.visible_polylines)
    assert max(cKDTree(pb).query(pa)[0].max(), cKDTree(pa).query(pb)[0].max()) <= 1e-6


def test_hsr_lines_and_render_take_a_step_file(tmp_path, step_files):
    out = tmp_path / "part.svg"
    code, err = run_cli(["lines", step_files["face_recognition_sample_part.stp"], "--page",
                         "A4", "--hidden-layer", "-o", str(out)])
    assert code == 0, err
    text = out.read_text()
    for label in ("border", "model", "hidden"):
        assert f'inkscape:label="{label}"' in text
    code, err = run_cli(["render", step_files["as1-oc-214.stp"], "--size", "64x48", "-o",
                         str(tmp_path / "part.png")])
    assert code == 0, err


def test_bad_cad_files_are_one_line(tmp_path):
    """Empty and garbage files of each kind, a FIFO, a missing file: exit 2, one line,
    nothing written."""
    (tmp_path / "empty.step").write_bytes(b"")
    (tmp_path / "junk.stp").write_text("ISO-10303-21;\nthis is not STEP\n")
    (tmp_path / "junk.iges").write_text("not IGES at all\n")
    (tmp_path / "junk.brep").write_text("not a BREP\n")
    os.mkfifo(tmp_path / "pipe.step")
    out = tmp_path / "out.svg"
    for name in ("empty.step", "junk.stp", "junk.iges", "junk.brep", "pipe.step",
                 "missing.step"):
        code, err = run_cli(["lines", str(tmp_path / name), "-o", str(out)])
        assert code == 2 and len(err) == 1 and err[0].startswith("hsr: error: "), (name, err)
        assert not out.exists()
    from hsr.scene.cad import read_cad

    with pytest.raises(hsr.HsrError, match="tolerance"):
        read_cad(tmp_path / "junk.stp", 1 << 20, tolerance=-1)


def test_iges_and_brep_read_as_the_step_they_were_written_from(tmp_path, step_files):
    """The part written by OCCT's own BREP and IGES (B-rep mode) writers reads back as the
    STEP file does: the same bounds, and the same area and B-rep line length (the BREP's to
    1e-9; the IGES writer turns some surfaces into splines, so within 1%)."""
    from OCP.BRepTools import BRepTools
    from OCP.IGESControl import IGESControl_Writer

    from hsr.scene.cad import _read_shape

    step = step_files["face_recognition_sample_part.stp"]
    shape = _read_shape(step)
    assert BRepTools.Write_s(shape, str(tmp_path / "part.brep"))
    writer = IGESControl_Writer("MM", 1)
    writer.AddShape(shape)
    writer.ComputeModel()
    assert writer.Write(str(tmp_path / "part.igs"))
    def area(mesh):
        tri = mesh.positions[mesh.faces]
        return np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]),
                              axis=1).sum() / 2

    def length(mesh):
        return np.linalg.norm(mesh.feature_lines[:, 1] - mesh.feature_lines[:, 0],
                              axis=1).sum()

    reference = hsr.load(step)
    for name, tolerance in (("part.brep", 1e-9), ("part.igs", 0.01)):
        mesh = hsr.load(tmp_path / name)
        assert mesh.up_axis == "z", name
        np.testing.assert_allclose(mesh.bounds(), reference.bounds(), atol=1e-6)
        assert abs(area(mesh) / area(reference) - 1) < tolerance, name
        assert abs(length(mesh) / length(reference) - 1) < tolerance, name


def test_outputs_never_land_on_the_step_file(tmp_path, step_files):
    """`hsr lines` and `hsr render` of a STEP file: an output named as the model, or as a
    link to it under the output's own extension, is refused (exit 2, one line) and the
    model is unchanged."""
    import shutil

    step = tmp_path / "part.stp"
    shutil.copy(step_files["face_recognition_sample_part.stp"], step)
    before = step.read_bytes()
    (tmp_path / "link.svg").symlink_to(step)
    (tmp_path / "link.png").symlink_to(step)
    for args in (["lines", str(step), "-o", str(tmp_path / "link.svg")],
                 ["lines", str(step), "-o", str(step)],
                 ["render", str(step), "--size", "32x24", "-o", str(tmp_path / "link.png")]):
        code, err = run_cli(args)
        assert code == 2 and len(err) == 1 and err[0].startswith("hsr: error: "), (args, err)
    assert step.read_bytes() == before


def test_cad_files_meet_hsr_load_checks(tmp_path, step_files):
    """The CAD reader is hsr.load's: the same size cap (check_regular), refused in the same
    words as an OBJ file (but for naming the kind of file), before OCCT sees the file."""
    import re
    import shutil

    step = tmp_path / "part.step"
    shutil.copy(step_files["face_recognition_sample_part.stp"], step)
    obj = tmp_path / "part.obj"
    obj.write_bytes(b"v 0 0 0\n" * (step.stat().st_size // 8 + 1))
    messages = []
    for path in (step, obj):
        with pytest.raises(hsr.MeshError) as info:
            hsr.load(path, max_bytes=1000)
        messages.append(str(info.value).replace(str(path), "PATH"))
    shapes = {re.sub(r"[\d,]+ bytes", "N bytes", m).replace("CAD file", "mesh file")
              for m in messages}
    assert shapes == {"PATH is N bytes, more than the N bytes hsr reads for a mesh file"}
