"""CAD models (STEP, IGES, BREP) through OCCT (the ``[cad]`` extra, ``cadquery-ocp``): the
B-rep is read, tessellated by OCCT's own mesher (``BRepMesh_IncrementalMesh``) at a stated
tolerance, and returned as one :class:`~hsr.scene.mesh.Mesh` whose ``feature_lines`` are
the B-rep's edges on that tessellation (each edge's polygon on the triangulation, so the
lines lie exactly on the triangles that hide them; seams, degenerate edges and edges
inside one smooth surface left out)
and its free edges (wires in no face: sketches, construction lines), as OCCT's hidden-line
removal draws them.

Triangles come B-rep face by face in the order OCCT explores them, each wound by the
face's orientation (a reversed face's triangles turned round), so the outside is
counter-clockwise. CAD files are Z-up (``Mesh.up_axis = "z"``).
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from ..errors import MeshError, require_extra
from .files import check_regular
from .mesh import Mesh

__all__ = ["CAD_SUFFIXES", "read_cad", "DEFAULT_TOLERANCE"]

CAD_SUFFIXES = (".step", ".stp", ".iges", ".igs", ".brep")
# Linear deflection as a share of the bounding box's diagonal, and the angular deflection
# (radians) of OCCT's mesher: 1/1000 of the part keeps chords within a pen width on A4.
DEFAULT_TOLERANCE = 1e-3
ANGULAR_DEFLECTION = 0.35  # 20 degrees
READ_TIMEOUT_S = 600.0


def is_cad(path) -> bool:
    return isinstance(path, (str, os.PathLike)) and \
        os.fspath(path).lower().endswith(CAD_SUFFIXES)


def _read_shape(path: str):
    """The OCCT shape of a STEP, IGES or BREP file, or a MeshError."""
    suffix = os.path.splitext(path)[1].lower()
    if suffix == ".brep":
        from OCP.BRep import BRep_Builder
        from OCP.BRepTools import BRepTools
        from OCP.TopoDS import TopoDS_Shape

        shape = TopoDS_Shape()
        if not BRepTools.Read_s(shape, path, BRep_Builder()):
            raise MeshError(f"{path}: cannot read the BREP file")
        return shape
    from OCP.IFSelect import IFSelect_RetDone

    if suffix in (".step", ".stp"):
        from OCP.STEPControl import STEPControl_Reader

        reader = STEPControl_Reader()
    else:
        from OCP.IGESControl import IGESControl_Reader

        reader = IGESControl_Reader()
    if reader.ReadFile(path) != IFSelect_RetDone:
        raise MeshError(f"{path}: cannot read the {suffix[1:].upper()} file")
    if reader.TransferRoots() == 0:
        raise MeshError(f"{path}: no shape in the file")
    return reader.OneShape()


def _diagonal(shape, path: str) -> float:
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    box = Bnd_Box()
    BRepBndLib.Add_s(shape, box)
    if box.IsVoid():
        raise MeshError(f"{path}: the file holds no geometry")
    lo, hi = np.array(box.CornerMin().Coord()), np.array(box.CornerMax().Coord())
    diagonal = float(np.linalg.norm(hi - lo))
    if not np.isfinite(diagonal) or diagonal <= 0:
        raise MeshError(f"{path}: the file holds no geometry")
    return diagonal


def _transform(points: np.ndarray, location) -> np.ndarray:
    if location.IsIdentity():
        return points
    trsf = location.Transformation()
    m = np.array([[trsf.Value(i, j) for j in range(1, 5)] for i in range(1, 4)])
    return points @ m[:, :3].T + m[:, 3]


def _faces(shape):
    """Per B-rep face occurrence: (face, triangulation nodes (N, 3) world, triangles (T, 3)
    0-based, outward counter-clockwise, the triangulation and its location)."""
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    explorer = TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        face = TopoDS.Face(explorer.Current())
        explorer.Next()
        location = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(face, location)
        if tri is None or tri.NbTriangles() == 0:
            continue
        nodes = np.array([tri.Node(i).Coord() for i in range(1, tri.NbNodes() + 1)])
        tris = np.array([tri.Triangle(i).Get() for i in range(1, tri.NbTriangles() + 1)],
                        dtype=np.int64) - 1
        if face.Orientation() == TopAbs_REVERSED:
            tris = tris[:, [0, 2, 1]]
        yield face, _transform(nodes, location), tris, tri, location


def _edge_polylines(face, tri, location, nodes, seen: dict) -> list:
    """The face's B-rep edges not met before, as index arrays into ``nodes``."""
    from OCP.BRep import BRep_Tool
    from OCP.GeomAbs import GeomAbs_G2
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    out = []
    explorer = TopExp_Explorer(face, TopAbs_EDGE)
    while explorer.More():
        edge = TopoDS.Edge(explorer.Current())
        explorer.Next()
        if BRep_Tool.Degenerated_s(edge) or BRep_Tool.IsClosed_s(edge, face) \
                or BRep_Tool.MaxContinuity_s(edge).value >= GeomAbs_G2.value:
            # A collapsed edge (a cone's apex), a seam, or where one surface goes on
            # across two faces (curvature-continuous: OCCT's "sewn" RgN lines): no line on
            # the part. Tangent (G1) edges, a fillet's, are drawn, as OCCT's Rg1 lines.
            continue
        same = seen.setdefault(hash(edge), [])
        if any(edge.IsSame(other) for other in same):
            continue
        same.append(edge)
        polygon = BRep_Tool.PolygonOnTriangulation_s(edge, tri, location)
        if polygon is None:
            continue
        out.append(np.array([polygon.Node(i) for i in range(1, polygon.NbNodes() + 1)],
                            dtype=np.int64) - 1)
    return out


def _free_edges(shape, deflection: float) -> list:
    """Edges in no face (wires: sketches, construction lines), as point arrays on the curve
    within ``deflection`` (OCCT's GCPnts_TangentialDeflection, as the mesher's edges)."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.GCPnts import GCPnts_TangentialDeflection
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    out = []
    explorer = TopExp_Explorer(shape, TopAbs_EDGE, TopAbs_FACE)
    while explorer.More():
        edge = TopoDS.Edge(explorer.Current())
        explorer.Next()
        if BRep_Tool.Degenerated_s(edge):
            continue
        points = GCPnts_TangentialDeflection(BRepAdaptor_Curve(edge), ANGULAR_DEFLECTION,
                                             deflection)
        if points.NbPoints() >= 2:
            out.append(np.array([points.Value(i).Coord()
                                 for i in range(1, points.NbPoints() + 1)]))
    return out


def tessellate(path: str, tolerance: float | None) -> tuple:
    """``(positions, faces, feature_lines)`` of a CAD file, read and tessellated by OCCT in
    this process (see :func:`read_cad`, which runs it in a child). Raises MeshError."""
    from OCP.BRepMesh import BRepMesh_IncrementalMesh

    shape = _read_shape(path)
    if shape is None or shape.IsNull():
        raise MeshError(f"{path}: no shape in the file")
    deflection = float(tolerance) if tolerance is not None else \
        DEFAULT_TOLERANCE * _diagonal(shape, path)
    # One thread: the child is forked, and OCCT's thread pool, if the parent started one,
    # does not survive a fork (the mesher would wait on it forever).
    BRepMesh_IncrementalMesh(shape, deflection, False, ANGULAR_DEFLECTION, False)
    positions, faces, lines, offset = [], [], [], 0
    seen: dict = {}
    for face, nodes, tris, tri, location in _faces(shape):
        positions.append(nodes)
        faces.append(tris + offset)
        for chain in _edge_polylines(face, tri, location, nodes, seen):
            lines.append(np.stack([nodes[chain[:-1]], nodes[chain[1:]]], axis=1))
        offset += len(nodes)
    if not faces:
        raise MeshError(f"{path}: the shape has no faces to tessellate (wires or points "
                        f"only?)")
    for points in _free_edges(shape, deflection):
        lines.append(np.stack([points[:-1], points[1:]], axis=1))
    feature_lines = np.concatenate(lines) if lines else np.zeros((0, 2, 3))
    return np.concatenate(positions), np.concatenate(faces), feature_lines


def _child(connection, path: str, tolerance) -> None:
    """Child process: OCCT's messages silenced (they go to the terminal), the result or the
    MeshError's message sent back. A crash here is expected on damaged files: no
    faulthandler report of it (the parent turns it into an error)."""
    import faulthandler

    faulthandler.disable()
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    os.dup2(null, 2)
    try:
        connection.send(("ok", tessellate(path, tolerance)))
    except MeshError as exc:
        connection.send(("error", str(exc)))
    except Exception as exc:  # OCCT raises its own types for malformed files
        connection.send(("error", f"{path}: cannot read the file ({type(exc).__name__}: "
                                  f"{exc})"))
    finally:
        connection.close()


def read_cad(path: str | os.PathLike, max_bytes: int, tolerance: float | None = None,
             timeout: float = READ_TIMEOUT_S) -> Mesh:
    """A STEP, IGES or BREP file as a Mesh tessellated by OCCT with linear deflection
    ``tolerance`` (model units; default :data:`DEFAULT_TOLERANCE` of the bounding box's
    diagonal) and 20 degrees angular deflection, with the B-rep's edges as
    ``feature_lines``. Only regular files of at most ``max_bytes`` are read.

    OCCT reads in a child process: its readers crash outright (segmentation faults) on
    some damaged files, and that must end in an error, not in the end of the caller's
    process; a read that takes longer than ``timeout`` seconds is stopped.

    Raises :class:`~hsr.errors.MissingExtraError` without the ``[cad]`` extra and
    :class:`~hsr.errors.MeshError` for a file that cannot be read (or crashes OCCT, or
    takes too long), holds no geometry or tessellates to no triangle, or a tolerance that
    is not a positive number."""
    import multiprocessing

    path = os.fspath(path)
    check_regular(path, "CAD file", max_bytes)
    require_extra(f"reading {path}", "OCP")
    if tolerance is not None and (isinstance(tolerance, bool) or not isinstance(
            tolerance, (int, float)) or not np.isfinite(tolerance) or tolerance <= 0):
        raise MeshError(f"the CAD tolerance must be a positive number, got {tolerance!r}")
    methods = multiprocessing.get_all_start_methods()
    context: Any = multiprocessing.get_context("fork" if "fork" in methods else "spawn")
    receive, send = context.Pipe(duplex=False)
    child = context.Process(target=_child, args=(send, path, tolerance), daemon=True)
    child.start()
    send.close()
    try:
        if not receive.poll(timeout):
            raise MeshError(f"{path}: reading took longer than {timeout:g} s; stopped")
        status, result = receive.recv()
    except EOFError:
        child.join()
        raise MeshError(f"{path}: OCCT crashed reading the file (exit code "
                        f"{child.exitcode}); it is damaged or not a {_kind(path)} file") from None
    finally:
        if child.is_alive():
            child.kill()
        child.join()
        receive.close()
    if status == "error":
        raise MeshError(result)
    positions, faces, feature_lines = result
    return Mesh(positions, faces, name=os.path.basename(path),
                sources=(os.path.abspath(path),), up_axis="z", feature_lines=feature_lines)


def _kind(path: str) -> str:
    return {".stp": "STEP", ".igs": "IGES"}.get(os.path.splitext(path)[1].lower(),
                                                os.path.splitext(path)[1][1:].upper())
