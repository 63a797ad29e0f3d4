"""What an mplot3d axes holds, as geometry hsr can hide: polygons (as triangles, with
their outlines), polylines and markers, each with the colours mplot3d would draw it in.

Read from the artists' own 3D data (``Poly3DCollection._faces``, ``Line3D``'s
``get_data_3d``, ``Path3DCollection._offsets3d``, ...) after their ``do_3d_projection``
has brought colormaps and depth shading up to date, so colours are mplot3d's.
Non-finite vertices drop their polygon (as mplot3d leaves such faces out), their line
segments and their markers.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .view import to_box


@dataclass
class Fill:
    """A Poly3DCollection or Patch3D: polygons as ``vertices`` (V, 3) box coordinates, the
    polygon p being vertices[starts[p]:starts[p + 1]], and per polygon its face colour,
    edge colour (RGBA floats) and edge width (points)."""

    artist: object
    vertices: np.ndarray
    starts: np.ndarray
    face_rgba: np.ndarray
    edge_rgba: np.ndarray
    edge_width: np.ndarray
    closed: bool = True  # an open path's outline has no closing edge (an open PathPatch)


@dataclass
class Lines:
    """A Line3D or Line3DCollection: ``polylines`` (L,) of (n, 3) box coordinates, per
    polyline its colour, width (points) and line style; ``markers`` true for a Line3D whose
    vertices carry markers."""

    artist: object
    polylines: list
    rgba: np.ndarray
    width: np.ndarray
    styles: list
    markers: bool = False


@dataclass
class Markers:
    """A Path3DCollection (scatter): centres (N, 3) box coordinates, per marker its face
    and edge colour, size (points^2) and edge width, and ``order``, mplot3d's drawing order
    (far to near)."""

    artist: object
    centres: np.ndarray
    face_rgba: np.ndarray
    edge_rgba: np.ndarray
    sizes: np.ndarray
    widths: np.ndarray
    order: np.ndarray


@dataclass
class Gathered:
    fills: list = field(default_factory=list)
    lines: list = field(default_factory=list)
    markers: list = field(default_factory=list)
    skipped: list = field(default_factory=list)  # (artist, why)


def _per_item(values, n: int) -> np.ndarray:
    values = np.asarray(values)
    if len(values) == n:
        return values
    if len(values) == 0:
        return np.zeros((n,) + values.shape[1:], dtype=values.dtype if values.size else float)
    return np.repeat(values[:1], n, axis=0)


def _finite_rows(points: np.ndarray) -> np.ndarray:
    return np.all(np.isfinite(points), axis=-1)


def _poly_collection(ax, artist) -> Fill | str:
    from matplotlib.colors import to_rgba_array

    if getattr(artist, "_codes3d", None) is not None and len(artist._codes3d):
        return "polygons with path codes (holes) are not supported yet"
    # The colours mplot3d's do_3d_projection would take (without its projection and
    # sort): a colormap's current mapping, else the 3D colours as set.
    face_colors, edges = artist._facecolor3d, artist._edgecolor3d
    if artist._A is not None:
        artist.update_scalarmappable()
        if artist._face_is_mapped:
            face_colors = artist._facecolors
        if artist._edge_is_mapped:
            edges = artist._edgecolors
    faces = np.asarray(artist._faces, dtype=np.float64)
    n = len(faces)
    invalid = np.broadcast_to(np.asarray(artist._invalid_vertices, bool), faces.shape[:2])
    face = to_rgba_array(_per_item(face_colors, n)) if n else np.zeros((0, 4))
    # No edge colours: mplot3d strokes nothing (its _edgecolors2d stays empty).
    edge = to_rgba_array(_per_item(edges, n)) if n and len(edges) else np.zeros((n, 4))
    width = _per_item(np.atleast_1d(artist.get_linewidth()).astype(float), n)
    # Each polygon's valid vertices, in order; one with a non-finite one is left out.
    valid = ~invalid
    bad = np.any(valid & ~np.all(np.isfinite(faces), axis=2), axis=1)
    count = valid.sum(axis=1)
    keep = np.flatnonzero(~bad & (count >= 3))
    vertices = faces[keep][valid[keep]]
    starts = np.r_[0, np.cumsum(count[keep])].astype(np.int64)
    return Fill(artist, to_box(ax, vertices) if len(vertices) else vertices.reshape(0, 3),
                starts, face[keep], edge[keep], width[keep])


def _patch(ax, artist) -> Fill | str:
    from matplotlib.colors import to_rgba

    closed = True  # a Patch3D's vertices are its closed polygon
    if hasattr(artist, "_code3d"):  # a PathPatch3D: closed only by CLOSEPOLY
        from matplotlib.path import Path

        codes = np.asarray(artist._code3d if artist._code3d is not None else [])
        if np.count_nonzero(codes == Path.MOVETO) > 1:
            return "patches of several subpaths are not supported yet"
        closed = bool(len(codes)) and codes[-1] == Path.CLOSEPOLY
    points = np.array([tuple(p) for p in artist._segment3d], dtype=np.float64)
    if len(points) < 3 or not np.all(np.isfinite(points)):
        return Fill(artist, np.zeros((0, 3)), np.zeros(1, np.int64), np.zeros((0, 4)),
                    np.zeros((0, 4)), np.zeros(0))
    face = np.array([to_rgba(artist.get_facecolor())]) if artist.get_fill() else \
        np.array([[0.0, 0.0, 0.0, 0.0]])
    edge = np.array([to_rgba(artist.get_edgecolor())])
    return Fill(artist, to_box(ax, points), np.array([0, len(points)], np.int64), face, edge,
                np.array([float(artist.get_linewidth())]), closed)


def _line3d(ax, artist) -> Lines:
    from matplotlib.colors import to_rgba

    xs, ys, zs = (np.asarray(v, dtype=np.float64).ravel() for v in artist.get_data_3d())
    n = min(len(xs), len(ys), len(zs))
    pts = np.stack([xs[:n], ys[:n], zs[:n]], axis=1) if n else np.zeros((0, 3))
    rgba = to_rgba(artist.get_color(), artist.get_alpha())
    return Lines(artist, [to_box(ax, pts) if n else pts], np.array([rgba]),
                 np.array([float(artist.get_linewidth())]), [artist.get_linestyle()],
                 markers=artist.get_marker() not in (None, "None", "none", "", " "))


def _line_collection(ax, artist) -> Lines:
    from matplotlib.colors import to_rgba_array

    lines = [np.ma.filled(np.ma.asarray(seg, dtype=np.float64), np.nan).reshape(-1, 3)
             for seg in artist._segments3d]
    n = len(lines)
    rgba = to_rgba_array(_per_item(artist.get_colors(), n)) if n else np.zeros((0, 4))
    width = _per_item(np.atleast_1d(artist.get_linewidths()).astype(float), n)
    styles = list(artist.get_linestyles())
    styles = [styles[i % len(styles)] for i in range(n)] if styles else [None] * n
    return Lines(artist, [to_box(ax, seg) if len(seg) else seg for seg in lines], rgba, width,
                 styles)


def _scatter(ax, artist) -> Markers:
    artist.do_3d_projection()  # depth shading and mplot3d's z order
    xs, ys, zs = (np.ma.filled(np.ma.asarray(v, dtype=np.float64), np.nan).ravel()
                  for v in artist._offsets3d)
    n = len(xs)
    centres = np.stack([xs, ys, zs], axis=1)
    order = np.asarray(artist._z_markers_idx, dtype=np.int64) if n else np.zeros(0, np.int64)
    if len(order) != n:  # before any projection mplot3d keeps the given order
        order = np.arange(n)
    face, edge = np.zeros((n, 4)), np.zeros((n, 4))
    face_sorted, edge_sorted = artist.get_facecolor(), artist.get_edgecolor()
    face[order] = _per_item(face_sorted, n)
    edge[order] = _per_item(edge_sorted, n)
    sizes = _per_item(np.atleast_1d(artist._sizes3d).astype(float), n)
    widths = _per_item(np.atleast_1d(artist._linewidths3d).astype(float), n)
    finite = _finite_rows(centres)
    box = np.full_like(centres, np.nan)
    if finite.any():
        box[finite] = to_box(ax, centres[finite])
    return Markers(artist, box, face, edge, sizes, widths, order)


def gather(ax) -> Gathered:
    """The visible 3D artists of ``ax`` that hsr draws, and the others with the reason."""
    from mpl_toolkits.mplot3d import art3d

    out = Gathered()
    for artist in ax._children:
        if not artist.get_visible():
            continue
        got: Fill | Lines | Markers | str
        if isinstance(artist, art3d.Poly3DCollection):
            got = _poly_collection(ax, artist)
        elif isinstance(artist, art3d.Patch3D):
            got = _patch(ax, artist)
        elif isinstance(artist, art3d.Line3D):
            got = _line3d(ax, artist)
        elif isinstance(artist, art3d.Line3DCollection):
            got = _line_collection(ax, artist)
        elif isinstance(artist, art3d.Path3DCollection):
            got = _scatter(ax, artist)
        elif hasattr(artist, "do_3d_projection"):  # Patch3DCollection, Collection3D, ...
            got = f"{type(artist).__name__} is not supported yet"
        else:
            continue  # 2D artists and texts: drawn by matplotlib as they are
        if isinstance(got, str):
            out.skipped.append((artist, got))
        elif isinstance(got, Fill):
            out.fills.append(got)
        elif isinstance(got, Lines):
            out.lines.append(got)
        else:
            out.markers.append(got)
    return out
