"""BSP-tree visibility (Fuchs, Kedem & Naylor 1980): build once in world space
(:mod:`hsr.algorithms.bsp_tree`), then for each view walk the tree back to front and paint
through the
shared fill with no depth test; or walk it front to back and fill only pixels not yet
covered (a coverage mask), which writes each pixel once."""

from __future__ import annotations

import numpy as np

from ..errors import RenderError, check_choice
from ..geometry.stage import ScreenTriangles, prepare
from ..geometry.state import DepthFunc, RenderState
from ..parallel import Workers
from ..raster.fill import FIRST_WINS, rasterize
from ..scene.mesh import Mesh, Scene
from . import bsp_tree
from .bsp_tree import BSPTree, build  # build: hsr.bsp.build
from .fragments import Fragments
from .support import Needs, apply_clear_depth, refuse_unless_nearest_wins, refuse_unsupported

__all__ = ["NAME", "OPTIONS", "check", "resolve", "build", "BSPTree"]

NAME = "bsp"
TRAVERSALS = ("back_to_front", "front_to_back")
# Accepted keys of render(..., options=...) and what each takes (see Options).
OPTIONS = {"tree": BSPTree, "heuristic": bsp_tree.HEURISTICS, "traversal": TRAVERSALS,
           "max_polygons": int, "progress": bool}
DESCRIPTION = "Fuchs-Kedem-Naylor BSP tree: split by planes, walk back to front, paint"


def ordered_screen(tree, view, state, workers, traversal):
    """The tree's polygons in traversal order, through the shared geometry stage.
    Returns (screen, source face of each screen triangle)."""
    walk = bsp_tree.back_to_front if traversal == "back_to_front" else bsp_tree.front_to_back
    order = walk(tree, view.camera)
    if len(order) == 0:  # nothing but degenerate faces: nothing to draw
        return (ScreenTriangles(np.zeros((0, 3, 2)), np.zeros((0, 3)), np.zeros(0, np.int64),
                                np.zeros(0, bool), view.width, view.height, np.zeros((0, 4)),
                                np.zeros((0, 3), np.int64)), np.zeros(0, np.int64), {})
    soup = tree.triangles[order]
    mesh = Mesh(soup.reshape(-1, 3), np.arange(3 * len(soup)).reshape(-1, 3), name="bsp")
    stats: dict = {}
    screen = prepare(Scene([mesh]), view.view_proj, view.width, view.height, state, stats,
                     workers)
    return screen, tree.face_id[order][screen.face_id], stats


def check(state: RenderState, needs: Needs) -> None:
    """Raise :class:`RenderError` for a request bsp cannot honour exactly."""
    refuse_unless_nearest_wins(NAME, state)
    refuse_unsupported(NAME, state, needs, allowed=("counts", "offset"))


def resolve(screen: ScreenTriangles, state: RenderState, workers: Workers | None = None,
            counts: bool = False, view=None, tree=None, heuristic: str = "balanced",
            traversal: str = "back_to_front", max_polygons: int | None = None,
            progress: bool = False, **_) -> Fragments:
    """BSP visibility: ``tree`` (from :func:`hsr.bsp.build`) or one built now with
    ``heuristic`` and ``max_polygons``; ``progress`` shows the build on the terminal."""
    if view is None:
        raise RenderError("bsp needs the scene and camera (call it through hsr.render)")
    check_choice(traversal, TRAVERSALS, "bsp traversal")
    workers = workers or Workers()
    stats: dict = {"traversal": traversal}
    if tree is None:
        tree = bsp_tree.build(view.scene, heuristic, max_polygons=max_polygons,
                              progress=progress)
    elif not isinstance(tree, BSPTree):
        raise RenderError(f"bsp option tree must be an hsr.bsp.BSPTree (from hsr.bsp.build), "
                          f"got {type(tree).__name__}")
    elif tree.n_faces != view.scene.n_faces:
        raise RenderError("the BSP tree was built for another scene")
    stats.update(bsp_nodes=tree.n_nodes, splits=tree.splits, bsp_depth=tree.depth(),
                 bsp_build_ms=tree.build_ms)
    pieces, source, _ = ordered_screen(tree, view, state, workers, traversal)
    # Back to front: paint over whatever is there; front to back: first fragment wins.
    func = DepthFunc.ALWAYS.code if traversal == "back_to_front" else FIRST_WINS
    face, depth, _, tested, written, count_tested, count_written = rasterize(
        pieces.xy_window, pieces.depth_window, source, screen.width, screen.height, state,
        workers, depth_test=True, depth_func=func, depth_write=True, counts=counts)
    stats.update(fragments_tested=int(tested), fragments_written=int(written),
                 pieces_drawn=len(pieces),
                 cleared_by_clear_depth=apply_clear_depth(face, depth, state))
    fragments = Fragments(face, depth, screen, stats, count_tested, count_written)
    # The ordered pieces are an exact vector picture (hsr.lines.svg) when painted in order.
    fragments.buffers["polygons"] = (pieces.xy_window, source, traversal)
    return fragments
