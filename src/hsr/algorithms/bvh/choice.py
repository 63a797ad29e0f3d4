"""Which walk rays go through (:func:`choose_walk`), with every threshold of the choice
named here. Both walks give the same answers, bit for bit; the choice is speed alone.

- :func:`hsr.algorithms.bvh.packets.trace_packets` walks four rays as one: for coherent
  rays (a camera's, a scanner's) while neighbouring rays meet the same triangles, so a
  node read serves four rays.
- :func:`hsr.algorithms.bvh.walk.trace_range` walks eight rays per thread in turn, so
  that their cache misses overlap: for scattered rays, and for coherent rays once the
  triangles where they land are much smaller than a ray's footprint (each ray then meets
  triangles of its own). In a scene of at most
  :data:`hsr.algorithms.bvh.walk.INTERLEAVE_BYTES` of corners and nodes it walks each ray
  to its end instead (its reads come from the cache).

The measurements behind each number: docs/history.md, "Ray core: the measurements behind
its constants"."""

from __future__ import annotations

from collections.abc import Callable

from .packets import trace_packets
from .walk import trace_range

__all__ = ["PACKET_RAYS_PER_FACE", "PACKET_FACES_PER_RAY", "PACKET_FACES_PER_PIXEL",
           "choose_walk"]

# Coherent rays at least this many a face walk in packets without an estimate: wherever
# they land, neighbours meet the same triangles.
PACKET_RAYS_PER_FACE = 4
# Below that, packets while the triangles where the rays land are at most this many a
# ray's footprint (as RayScene estimates it from a sample of the rays).
PACKET_FACES_PER_RAY = 3.0
# A camera's pixels (the ray caster, no estimate): packets while the scene has at most
# this many faces a pixel.
PACKET_FACES_PER_PIXEL = 5


def choose_walk(n_rays: int, n_faces: int, coherent: bool = True,
                faces_per_ray: Callable[[], float] | None = None):
    """The walk for ``n_rays`` rays through a tree of ``n_faces`` faces: ``trace_packets``
    or ``trace_range``. Rays not ``coherent`` (in runs of four from nearly one point in
    nearly one direction) go interleaved. Coherent ones go in packets when they are at
    least :data:`PACKET_RAYS_PER_FACE` a face; else, given ``faces_per_ray`` (called only
    then: an estimate of the faces in one ray's footprint where the rays land), while it
    is at most :data:`PACKET_FACES_PER_RAY`; without it (a camera's pixels filling a
    view), while the faces are at most :data:`PACKET_FACES_PER_PIXEL` a ray."""
    if not coherent:
        return trace_range
    if faces_per_ray is None:
        return trace_packets if n_faces <= PACKET_FACES_PER_PIXEL * n_rays else trace_range
    if n_rays >= PACKET_RAYS_PER_FACE * n_faces:
        return trace_packets
    return trace_packets if faces_per_ray() <= PACKET_FACES_PER_RAY else trace_range
