"""matplotlib 3D with exact hidden-surface removal (``pip install 'hsr[mpl]'``).

mplot3d sorts whole polygons, and whole artists, by one depth each (the painter's
algorithm), so surfaces that cross, lines through surfaces and points on them come out
wrong. On every draw, an axes made by hsr hides its 3D artists exactly under the axes' own
projection and draws 2D artists in their place: each polygon's visible region, the
visible pieces of lines and outlines, the markers whose centre is visible. Panes, grid,
ticks, labels and texts stay as mplot3d draws them. Vector output (PDF, SVG) holds only
what is seen.

Two ways in, one line each::

    import hsr.mpl
    ax = fig.add_subplot(projection="hsr3d")   # an Axes3D: every mplot3d call works
    ...
    hsr.mpl.occlude(ax)                        # or: an Axes3D you already filled

What is hidden exactly: ``Poly3DCollection`` (plot_surface, plot_trisurf, bar3d, voxels,
add_collection3d), ``Patch3D`` / ``PathPatch3D``, ``Line3D`` (plot, with markers),
``Line3DCollection`` (plot_wireframe, quiver, stem) and ``Path3DCollection`` (scatter:
a marker is hidden when its centre is). Any other 3D artist is drawn by mplot3d as
before, and a warning names it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..errors import require_extra
from .view import MplError

require_extra("hsr.mpl", "matplotlib")

import numpy as np  # noqa: E402
from matplotlib.projections import register_projection  # noqa: E402
from mpl_toolkits.mplot3d import Axes3D  # noqa: E402

__all__ = ["AxesScene", "HsrAxes3D", "MplError", "occlude", "scene_and_camera"]


class _Occluding:
    """The draw that hides exactly: the 3D artists hsr handles are swapped for their 2D
    visible parts for the length of one draw (the axes' own artists are untouched, so
    picking, legends and later calls see what the user made)."""

    def draw(self, renderer):
        if not self.get_visible():
            return
        from .flat import flat_artists

        self._unstale_viewLim()
        locator = self.get_axes_locator()
        self.apply_aspect(locator(self, renderer) if locator else None)
        self.M = self.get_proj()
        self.invM = np.linalg.inv(self.M)
        replaced, added = flat_artists(self)
        children, computed = self._children, self.computed_zorder
        base = max(axis.get_zorder() for axis in self._axis_map.values()) + 1
        for artist, rank in added:
            artist.zorder = base + rank
        self._children = [c for c in children if id(c) not in replaced] + \
            [a for a, _ in added]
        self.computed_zorder = False
        try:
            super().draw(renderer)
        finally:
            self._children, self.computed_zorder = children, computed


class HsrAxes3D(_Occluding, Axes3D):
    """An mplot3d ``Axes3D`` whose 3D artists are hidden exactly on every draw:
    ``fig.add_subplot(projection="hsr3d")`` once ``hsr.mpl`` is imported."""

    name = "hsr3d"


register_projection(HsrAxes3D)


def occlude(ax):
    """Turn exact hidden-surface removal on for an mplot3d axes already made (and filled,
    or not): it draws as an :class:`HsrAxes3D` from now on. Returns ``ax``.

    Raises :class:`MplError` for an axes that is not 3D."""
    if isinstance(ax, _Occluding):
        return ax
    if not isinstance(ax, Axes3D):
        raise MplError(f"hsr.mpl.occlude: {type(ax).__name__} is not a 3D axes (make it with "
                       f"projection='3d' or 'hsr3d')")
    cls = type(ax)
    ax.__class__ = HsrAxes3D if cls is Axes3D else \
        type("Hsr" + cls.__name__, (_Occluding, cls), {})
    ax.stale = True
    return ax


@dataclass
class AxesScene:
    """What :func:`scene_and_camera` returns: ``scene`` (the axes' polygons as triangles,
    in its box coordinates), ``camera`` (its current view onto the figure's pixels),
    ``width``, ``height`` (the figure's size in pixels) and ``face_artist`` (F,), the 3D
    artist each face comes from."""

    scene: Any
    camera: Any
    width: int
    height: int
    face_artist: list


def scene_and_camera(ax) -> AxesScene:
    """The axes' surfaces and view as an hsr scene and camera:
    ``hsr.render(s.scene, s.camera, s.width, s.height)`` draws what the figure's axes shows
    with hsr's z-buffer, pixel for pixel on the figure's canvas (y down)."""
    from .flat import Flattened, soup_scene
    from .gather import gather
    from .view import camera_for

    if not isinstance(ax, Axes3D):
        raise MplError(f"hsr.mpl.scene_and_camera: {type(ax).__name__} is not a 3D axes")
    figure = ax.get_figure(root=True) if hasattr(ax, "get_figure") else ax.figure
    ax.M = ax.get_proj()
    width = max(1, int(np.ceil(figure.bbox.width)))
    height = max(1, int(np.ceil(figure.bbox.height)))
    got = gather(ax)
    flat = Flattened(got)
    scene = soup_scene(flat.triangles)
    face_artist = [got.fills[flat.poly_fill[p]].artist for p in flat.tri_poly]
    return AxesScene(scene, camera_for(ax, flat.all_points(), width, height), width, height,
                     face_artist)
