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

from __future__ import annotations

import importlib
import sys
import types
from typing import TYPE_CHECKING

# Public names -> the module that defines them. ``import hsr`` loads none of them (NumPy,
# Numba and trimesh take about a second): each is imported on first use (PEP 562), so the
# command line's --help, --version and error paths start at once.
_LAZY = {
    "batch": (".batch", None), "visibility": (".visibility", None),
    "ALGORITHMS": (".algorithms", "ALGORITHMS"), "bsp": (".algorithms.bsp", None),
    "raycast": (".algorithms.raycast", None),
    "Fog": (".appearance.fog", "Fog"), "Look": (".appearance.shading", "Look"),
    "best_view": (".appearance.viewpoint", "best_view"),
    "first_look": (".appearance.viewpoint", "first_look"),
    "CameraError": (".errors", "CameraError"), "HsrError": (".errors", "HsrError"),
    "HsrWarning": (".errors", "HsrWarning"), "MeshError": (".errors", "MeshError"),
    "OutputError": (".errors", "OutputError"), "RenderError": (".errors", "RenderError"),
    "CullMode": (".geometry.state", "CullMode"), "DepthFunc": (".geometry.state", "DepthFunc"),
    "FrontFace": (".geometry.state", "FrontFace"),
    "PolygonMode": (".geometry.state", "PolygonMode"),
    "RenderState": (".geometry.state", "RenderState"),
    "HiddenLine": (".lines.raster", "HiddenLine"),
    "hidden_lines": (".lines.vector", "hidden_lines"),
    "write_lines_svg": (".lines.svg", "write_lines_svg"),
    "Workspace": (".parallel", "Workspace"),
    "Frame": (".render", "Frame"), "render": (".render", "render"),
    "scenes": (".scene.builtin", None), "views": (".scene.views", None),
    "Camera": (".scene.camera", "Camera"),
    "read_colmap": (".scene.camera_files", "read_colmap"),
    "read_transforms": (".scene.camera_files", "read_transforms"),
    "write_transforms": (".scene.camera_files", "write_transforms"),
    "load": (".scene.load", "load"), "load_scene": (".scene.load", "load_scene"),
    "Instance": (".scene.mesh", "Instance"), "Mesh": (".scene.mesh", "Mesh"),
    "Scene": (".scene.mesh", "Scene"), "partition": (".scene.partition", "partition"),
    "PartitionedScene": (".scene.partitioned", "PartitionedScene"),
    "write_mesh": (".scene.write", "write_mesh"),
    "RayHits": (".visibility", "RayHits"), "RayScene": (".visibility", "RayScene"),
    "RayHitLists": (".visibility", "RayHitLists"),
    "prune": (".visibility", "prune"), "visibility_matrix": (".visibility", "visibility_matrix"),
    "visible_faces": (".visibility", "visible_faces"),
    "visible_points": (".visibility", "visible_points"),
    "visible_vertices": (".visibility", "visible_vertices"),
    "visible_regions": (".visibility.regions", "visible_regions"),
    "Regions": (".visibility.regions", "Regions"),
}


class _Package(types.ModuleType):
    """The package's module type: importing the submodule ``hsr.render`` binds the name
    ``render`` to that module, but the public ``hsr.render`` is its function (as the eager
    ``from .render import render`` made it)."""

    def __setattr__(self, name, value):
        if name == "render" and isinstance(value, types.ModuleType):
            value = value.render
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


def __getattr__(name: str):
    try:
        module, attr = _LAZY[name]
    except KeyError:
        raise AttributeError(f"module 'hsr' has no attribute {name!r}") from None
    loaded = importlib.import_module(module, __name__)
    value = loaded if attr is None else getattr(loaded, attr)
    globals()[name] = value  # looked up once
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))


if TYPE_CHECKING:  # the names as type checkers and IDEs see them
    from . import batch, visibility
    from .algorithms import ALGORITHMS, bsp, raycast
    from .appearance.fog import Fog
    from .appearance.shading import Look
    from .appearance.viewpoint import best_view, first_look
    from .errors import (
        CameraError,
        HsrError,
        HsrWarning,
        MeshError,
        OutputError,
        RenderError,
    )
    from .geometry.state import CullMode, DepthFunc, FrontFace, PolygonMode, RenderState
    from .lines.raster import HiddenLine
    from .lines.svg import write_lines_svg
    from .lines.vector import hidden_lines
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
        RayHitLists,
        RayHits,
        RayScene,
        prune,
        visibility_matrix,
        visible_faces,
        visible_points,
        visible_vertices,
    )
    from .visibility.regions import Regions, visible_regions

__version__ = "0.1.0"

__all__ = [
    "ALGORITHMS", "Camera", "CameraError", "CullMode", "DepthFunc", "Fog", "Frame",
    "FrontFace", "HiddenLine", "HsrError", "Instance", "Look", "Mesh", "MeshError",
    "OutputError", "HsrWarning", "PolygonMode", "RenderError", "RenderState", "Scene",
    "batch", "bsp", "hidden_lines", "load", "load_scene", "prune", "raycast", "read_colmap",
    "read_transforms", "render", "scenes", "views", "visibility", "write_lines_svg",
    "Workspace", "write_mesh", "write_transforms", "RayScene", "RayHits", "RayHitLists",
    "visible_faces",
    "visible_vertices", "visible_points", "visibility_matrix", "first_look", "best_view",
    "partition", "PartitionedScene", "visible_regions", "Regions",
]
