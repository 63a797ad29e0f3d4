"""hsr: hidden-surface removal, exactly and fast.

>>> import hsr
>>> scene, camera = hsr.scenes.get("cubes")
>>> frame = hsr.render(scene, camera, width=320, height=240)
>>> frame.face_id.shape
(240, 320)

The package follows the data path, one sub-package per stage (imports only go down it):
:mod:`hsr.scene` (meshes, cameras, files) -> :mod:`hsr.geometry` (state, transform,
clipping, culling, set-up) -> :mod:`hsr.raster` (the shared fill) -> :mod:`hsr.algorithms`
(the six visibility algorithms) -> :mod:`hsr.appearance` (shading, textures, fog,
transparency) and :mod:`hsr.lines` (polygon modes, hidden lines, SVG) -> :func:`hsr.render`
-> :mod:`hsr.explain` (views, compare, report) -> :mod:`hsr.cli`.
"""

from . import batch, visibility
from .algorithms import ALGORITHMS, bsp, raycast
from .appearance.fog import Fog
from .appearance.shading import Look
from .appearance.viewpoint import best_view, first_look
from .errors import CameraError, HsrError, HsrWarning, MeshError, OutputError, RenderError
from .geometry.state import CullMode, DepthFunc, FrontFace, PolygonMode, RenderState
from .lines.raster import HiddenLine
from .lines.vector import hidden_lines, write_lines_svg
from .parallel import Workspace
from .render import Frame, render
from .scene import builtin as scenes
from .scene import views
from .scene.camera import Camera
from .scene.camera_files import read_colmap, read_transforms, write_transforms
from .scene.load import load, load_scene
from .scene.mesh import Instance, Mesh, Scene
from .scene.partition import partition
from .scene.partitioned import PartitionedScene
from .scene.write import write_mesh
from .visibility import (
    RayHits,
    RayScene,
    prune,
    visibility_matrix,
    visible_faces,
    visible_points,
    visible_vertices,
)

__version__ = "0.1.0"

__all__ = [
    "ALGORITHMS", "Camera", "CameraError", "CullMode", "DepthFunc", "Fog", "Frame",
    "FrontFace", "HiddenLine", "HsrError", "Instance", "Look", "Mesh", "MeshError",
    "OutputError", "HsrWarning", "PolygonMode", "RenderError", "RenderState", "Scene",
    "batch", "bsp", "hidden_lines", "load", "load_scene", "prune", "raycast", "read_colmap",
    "read_transforms", "render", "scenes", "views", "visibility", "write_lines_svg",
    "Workspace", "write_mesh", "write_transforms", "RayScene", "RayHits", "visible_faces",
    "visible_vertices", "visible_points", "visibility_matrix", "first_look", "best_view",
    "partition", "PartitionedScene",
]
