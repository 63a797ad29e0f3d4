"""Which faces the views see, and removing the rest: per-face and per-instance visible
pixel counts over many views (:func:`face_visibility`, :func:`object_visibility`, here or
on a Dask client), :func:`decide` (fixed views, or automatic ones until the
decision is stable), :func:`prune` and :func:`verify`; ray queries (:class:`RayScene`) and
per-camera queries (:func:`visible_faces`, :func:`visible_vertices`,
:func:`visible_points`, :func:`visibility_matrix`)."""

from .count import VisibilityError, cameras_for, face_visibility, object_visibility
from .prune import (
    Decision,
    VisibilityWarning,
    auto_size,
    decide,
    grow_rings,
    keep_faces,
    prune,
    subset_scene,
    verify,
)
from .queries import (
    VisibilityMatrix,
    project_points,
    scene_vertices,
    visibility_matrix,
    visible_faces,
    visible_points,
    visible_vertices,
)
from .rays import RayError, RayHitLists, RayHits, RayScene
from .regions import Regions, RegionsError, visible_regions

__all__ = ["VisibilityError", "VisibilityWarning", "Decision", "cameras_for", "Regions",
           "RegionsError", "visible_regions",
           "face_visibility", "object_visibility", "decide", "auto_size", "grow_rings",
           "keep_faces", "prune", "subset_scene", "verify", "RayScene", "RayHits",
           "RayHitLists", "RayError", "visible_faces", "visible_vertices", "visible_points",
           "visibility_matrix", "VisibilityMatrix", "project_points", "scene_vertices"]
