"""Which faces the views see, and removing the rest: per-face and per-instance visible
pixel counts over many views (:func:`face_visibility`, :func:`object_visibility`, here or
on a Dask client), :func:`decide` (fixed views, or automatic ones until the
decision is stable), :func:`prune` and :func:`verify`."""

from .count import VisibilityError, cameras_for, face_visibility, object_visibility
from .prune import (Decision, VisibilityWarning, auto_size, decide, grow_rings, keep_faces,
                    prune, subset_scene, verify)

__all__ = ["VisibilityError", "VisibilityWarning", "Decision", "cameras_for",
           "face_visibility", "object_visibility", "decide", "auto_size", "grow_rings",
           "keep_faces", "prune", "subset_scene", "verify"]
