"""hsr: hidden-surface removal, exactly and fast.

>>> import hsr
>>> scene, camera = hsr.scenes.get("cubes")
>>> frame = hsr.render(scene, camera, width=320, height=240)
>>> frame.face_id.shape
(240, 320)
"""

from . import scenes
from .algorithms import ALGORITHMS
from .camera import Camera
from .errors import CameraError, HsrError, MeshError, OutputError, RenderError
from .mesh import Instance, Mesh, Scene, load
from .render import Frame, render
from .state import CullMode, DepthFunc, FrontFace, RenderState

__version__ = "0.1.0"

__all__ = [
    "ALGORITHMS", "Camera", "CameraError", "CullMode", "DepthFunc", "Frame", "FrontFace",
    "HsrError", "Instance", "Mesh", "MeshError", "OutputError", "RenderError", "RenderState",
    "Scene", "load", "render", "scenes",
]
