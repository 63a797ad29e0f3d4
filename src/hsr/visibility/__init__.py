"""Which faces the views see, and removing the rest: per-face and per-instance visible
pixel counts over many views (:func:`face_visibility`, :func:`object_visibility`, here or
on a Dask client), :func:`prune` and :func:`verify`."""

from .count import VisibilityError, cameras_for, face_visibility, object_visibility
from .prune import grow_rings, keep_faces, prune, subset_scene, verify

__all__ = ["VisibilityError", "cameras_for", "face_visibility", "object_visibility",
           "grow_rings", "keep_faces", "prune", "subset_scene", "verify"]
