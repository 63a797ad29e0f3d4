"""The ray core: a bounding volume hierarchy and the walks of rays through it, one module
per noun, each importing only those above it in this list:

- :mod:`.layout`: the walked tree's 256-byte node records;
- :mod:`.triangle`: the watertight ray/triangle test and who owns a hit on a shared edge;
- :mod:`.boxes`: the careful slab tests of a node's child boxes;
- :mod:`.stack`: a walk's stack of boxes still to enter;
- :mod:`.collapse`: the binary tree collapsed into the 8-wide one;
- :mod:`.sah`: the binned SAH build (:func:`build`, :class:`BVH`);
- :mod:`.ranking`: the ray caster's depth ranking, applied by the walks at each hit;
- :mod:`.hits`: the queries and their hit rules, the checks of a ray, the record of a hit;
- :mod:`.walk`: the interleaved walk, a few rays per thread in turn;
- :mod:`.packets`: the packet walk, four coherent rays as one;
- :mod:`.choice`: which of the two walks rays go through, its thresholds named.

The ray caster (:mod:`hsr.algorithms.raycast`) and the ray queries
(:class:`hsr.visibility.RayScene`) are built on these.
"""

from __future__ import annotations

from .sah import BVH, build, world_triangles

__all__ = ["BVH", "build", "world_triangles"]
