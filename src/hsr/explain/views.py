"""Seeing why: pictures (and the numbers behind them) that explain hidden-surface removal.

Each view is a function ``view(scene, camera, width, height, state)`` returning an
:class:`Explanation`: an image of captioned panels, optional animation frames, the numbers
it shows and a short text. ``hsr explain VIEW`` writes them; ``hsr report`` puts them all
in one HTML page.

Views: ``depth`` (the depth buffer as stored and as linear eye depth), ``overdraw`` (depth
complexity: fragments tested / written per pixel), ``no-depth-test`` (submission order
without the test, seed 000 fig. 12-1), ``painter`` (painting back to front, animated, and
where it goes wrong), ``newell`` and ``bsp`` (their split polygons and painting order),
``linear-z`` (depth interpolated as z instead of 1/z, seed 000's 8.666 vs 6),
``precision`` (16/24-bit and float depth, reversed z, z-fighting), ``ybuffer``
(tinyrenderer's 2-D y-buffer, seed 002) and ``culling`` (glCullFace modes, culled faces
tinted).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import RenderError, check_choice
from ..geometry.conventions import midpoint_depth_example
from ..geometry.state import RenderState
from ..geometry.viewport import check_size
from ..render import render
from ..scene.camera import Camera
from ..scene.mesh import Mesh, Scene, as_scene

__all__ = ["Explanation", "VIEWS", "explain", "depth_formats", "resolvable_depth",
           "quantize_depth", "ybuffer", "YBUFFER_SEGMENTS"]

# Smallest image side an explanation is drawn at (its panels carry captions and legends).
MIN_SIZE = 32
_PANEL_BG = (24, 24, 28)
_TEXT = (235, 235, 235)


@dataclass
class Explanation:
    """One view: ``image`` (H, W, 3) uint8, ``frames`` (animation, may be empty),
    ``numbers`` (what the picture shows, as values), ``text`` (what to look at)."""

    name: str
    image: np.ndarray
    numbers: dict = field(default_factory=dict)
    text: str = ""
    frames: list = field(default_factory=list)

    def save(self, path) -> None:
        """PNG of the image, or an animated GIF of the frames for a ``.gif`` path."""
        from PIL import Image

        from ..errors import OutputError
        from ..scene.files import check_output
        from ..scene.outputs import staged

        check_output(path)
        try:
            with staged(path) as tmp:
                if str(path).lower().endswith(".gif"):
                    frames = self.frames or [self.image]
                    images = [Image.fromarray(f) for f in frames]
                    images[0].save(tmp, save_all=True, append_images=images[1:],
                                   duration=120, loop=0)
                else:
                    Image.fromarray(self.image).save(tmp)
        except (OSError, ValueError) as exc:
            raise OutputError(f"cannot write {path}: {exc}") from None


# ----------------------------------------------------------------------------- drawing

def _font():
    from PIL import ImageFont

    return ImageFont.load_default()


def panel(image: np.ndarray, caption: str, lines: int = 1) -> np.ndarray:
    """The image under a caption bar (one or more text lines)."""
    from PIL import Image, ImageDraw

    h, w = image.shape[:2]
    bar = 14 * lines + 6
    sheet = Image.new("RGB", (w, h + bar), _PANEL_BG)
    draw = ImageDraw.Draw(sheet)
    draw.multiline_text((4, 3), caption, fill=_TEXT, font=_font(), spacing=2)
    sheet.paste(Image.fromarray(np.ascontiguousarray(image[..., :3])), (0, bar))
    return np.asarray(sheet)


def _stack(parts: list, axis: int, gap: int) -> np.ndarray:
    """Images one after another along ``axis`` (1: side by side, tops aligned; 0: one
    under another, left edges aligned), ``gap`` pixels apart on the panel background."""
    across = 1 - axis
    shape = [0, 0, 3]
    shape[axis] = sum(p.shape[axis] for p in parts) + gap * (len(parts) - 1)
    shape[across] = max(p.shape[across] for p in parts)
    out = np.empty(shape, dtype=np.uint8)
    out[:] = _PANEL_BG
    at = 0
    for p in parts:
        index = [slice(None), slice(None)]
        index[axis] = slice(at, at + p.shape[axis])
        index[across] = slice(0, p.shape[across])
        out[tuple(index)] = p
        at += p.shape[axis] + gap
    return out


def row(panels: list, gap: int = 4) -> np.ndarray:
    """Panels side by side (tops aligned), on the panel background."""
    return _stack(panels, 1, gap)


def column(rows: list, gap: int = 4) -> np.ndarray:
    """Rows one under another (left edges aligned), on the panel background."""
    return _stack(rows, 0, gap)


# A perceptually ordered heat ramp (black - purple - orange - yellow - white).
_RAMP = np.array([[0, 0, 4], [80, 18, 123], [182, 54, 121], [251, 136, 97], [252, 253, 191]],
                 dtype=np.float64)


def heat(values: np.ndarray, vmax: float) -> np.ndarray:
    """(H, W, 3) uint8 heat map of ``values`` in [0, vmax]."""
    x = np.clip(np.asarray(values, dtype=np.float64) / max(vmax, 1e-12), 0.0, 1.0)
    pos = x * (len(_RAMP) - 1)
    i = np.minimum(pos.astype(int), len(_RAMP) - 2)
    f = (pos - i)[..., None]
    return np.round(_RAMP[i] * (1 - f) + _RAMP[i + 1] * f).astype(np.uint8)


def legend(vmax: int, width: int, label: str) -> np.ndarray:
    """A colour bar for integer counts 0..vmax with tick labels."""
    from PIL import Image, ImageDraw

    bar_h = 12
    sheet = Image.new("RGB", (width, bar_h + 34), _PANEL_BG)
    ramp = heat(np.linspace(0, vmax, width - 20)[None, :].repeat(bar_h, 0), vmax)
    sheet.paste(Image.fromarray(ramp), (10, 16))
    draw = ImageDraw.Draw(sheet)
    draw.text((10, 2), label, fill=_TEXT, font=_font())
    ticks = sorted(set(np.linspace(0, vmax, min(vmax, 6) + 1).round().astype(int)))
    for t in ticks:
        x = 10 + int((width - 21) * t / max(vmax, 1))
        draw.line([(x, 16 + bar_h), (x, 19 + bar_h)], fill=_TEXT)
        draw.text((max(0, x - 3), 20 + bar_h), str(t), fill=_TEXT, font=_font())
    return np.asarray(sheet)


def gray(values, covered, lo=None, hi=None, near_bright=True):
    """Values on covered pixels mapped to 255..40 (near = bright), background black."""
    out = np.zeros(values.shape + (3,), dtype=np.uint8)
    if not covered.any():
        return out
    v = values[covered].astype(np.float64)
    lo = v.min() if lo is None else lo
    hi = v.max() if hi is None else hi
    s = (v - lo) / (hi - lo) if hi > lo else np.zeros_like(v)
    g = (255 - 215 * s) if near_bright else (40 + 215 * s)
    out[covered] = np.clip(np.round(g), 0, 255).astype(np.uint8)[:, None]
    return out


def _outline(image, xy_image_list, color=(255, 220, 0)):
    """Draw closed outlines (lists of (x, y) image points) on a copy of the image."""
    from PIL import Image, ImageDraw

    sheet = Image.fromarray(image.copy())
    draw = ImageDraw.Draw(sheet)
    for pts in xy_image_list:
        draw.polygon([tuple(p) for p in pts], outline=color)
    return np.asarray(sheet)


def _triangles_image(frame, faces):
    """Image-space corners (y down) of the screen pieces of the given source faces."""
    screen = frame.fragments.screen
    keep = np.isin(screen.face_id, faces)
    xy = screen.xy_window[keep].copy()
    xy[..., 1] = screen.height - xy[..., 1]
    return list(xy)


# ------------------------------------------------------------------------------- views

def depth_view(scene, camera, width, height, state):
    from ..appearance.shading import linear_eye_depth

    frame = render(scene, camera, width, height, state=state)
    covered = frame.face_id >= 0
    depth = frame.depth.astype(np.float64)
    eye = linear_eye_depth(depth, camera, state.depth_range)
    raw = np.zeros((height, width, 3), np.uint8)
    raw[covered] = np.round(255 * (1 - depth[covered]))[:, None].astype(np.uint8)
    numbers = {}
    if covered.any():
        numbers = {"window_depth_min": float(depth[covered].min()),
                   "window_depth_max": float(depth[covered].max()),
                   "eye_depth_min": float(eye[covered].min()),
                   "eye_depth_max": float(eye[covered].max()),
                   "near": camera.near, "far": camera.far}
    image = row([
        panel(frame.color, "the image"),
        panel(raw, "window depth as stored\n(255 * (1 - z_w))", 2),
        panel(gray(depth, covered), "window depth, stretched\nover the visible range", 2),
        panel(gray(eye, covered), "linear eye depth, stretched\n(near bright, far dark)", 2)])
    text = ("The depth buffer holds window depth, which is 1/z-like: most of its range is "
            "spent near the camera, so on a perspective view the stored values crowd "
            "towards 1 and look flat; the linear eye depth shows the distances evenly.")
    return Explanation("depth", image, numbers, text)


def overdraw_view(scene, camera, width, height, state):
    frame = render(scene, camera, width, height, state=state, counts=True)
    tested = frame.fragments.count_tested
    written = frame.fragments.count_written
    covered = tested > 0
    vmax = int(max(tested.max(), 1))
    numbers = {"fragments_tested": int(tested.sum()), "fragments_written": int(written.sum()),
               "max_tested_per_pixel": int(tested.max()),
               "max_written_per_pixel": int(written.max()),
               "mean_depth_complexity": float(tested[covered].mean()) if covered.any() else 0.0,
               "pixels_covered": int(covered.sum())}
    image = column([
        row([panel(frame.color, "the image"),
             panel(heat(tested, vmax), f"fragments tested per pixel (max {tested.max()})"),
             panel(heat(written, vmax), f"fragments written per pixel (max {written.max()})")]),
        legend(vmax, min(3 * width, 480), "fragments per pixel")])
    text = ("Depth complexity: every fragment a triangle produces is tested against the depth "
            "buffer; only those nearer than what is stored are written. Drawing front to "
            "back writes each pixel about once; back to front writes every layer.")
    return Explanation("overdraw", image, numbers, text)


def no_depth_test_view(scene, camera, width, height, state):
    right = render(scene, camera, width, height, state=state)
    wrong = render(scene, camera, width, height, state=state.with_(depth_test=False))
    from .compare import difference_map

    differ = int(np.count_nonzero(right.face_id != wrong.face_id))
    image = row([panel(wrong.color, "depth test off:\nlast drawn wins", 2),
                 panel(right.color, "depth test on\n(GL_LESS)", 2),
                 panel(difference_map(wrong, right), f"differs: {differ} px", 2)])
    text = ("With glDisable(GL_DEPTH_TEST) every triangle simply overwrites the pixels it "
            "covers, in submission order: whatever was drawn last is on top (seed 000, "
            "figure 12-1).")
    return Explanation("no-depth-test", image, {"pixels_differing": differ}, text)


def _painting_frames(scene, camera, xy_window, face, width, height, state, caption,
                     n_frames=24):
    """Animation frames of polygons (window xy, source face) painted in the given order,
    each over the last, no depth test."""
    from ..appearance.shading import face_colors, paint_faces
    from ..parallel import Workers
    from ..raster.fill import rasterize

    frames = []
    depth = np.zeros(xy_window.shape[:2])
    with Workers() as workers:
        colors = face_colors("flat", scene, camera, workers)
        steps = np.unique(np.linspace(1, len(face), min(n_frames, len(face))).astype(int))
        for k in steps:
            painted, *_ = rasterize(xy_window[:k], depth[:k], face[:k], width, height, state,
                                    workers, depth_test=True, depth_func=7, depth_write=True)
            image = np.empty((height, width, 3), np.uint8)
            paint_faces(workers, painted, colors, np.zeros(3, np.uint8), image)
            frames.append(panel(image, caption.format(k=k, n=len(face))))
    return frames


def painter_view(scene, camera, width, height, state, n_frames: int = 24):
    from ..algorithms.painter import sort_far_to_near
    from .compare import difference_map

    painted = render(scene, camera, width, height, state=state, algorithm="painter")
    truth = render(scene, camera, width, height, state=state)
    screen = painted.fragments.screen  # type: ignore[union-attr]  # render() sets it
    order = sort_far_to_near(screen.depth_window, "max")
    frames = _painting_frames(scene, camera, screen.xy_window[order], screen.face_id[order],
                              width, height, state,
                              "painted {k} of {n} triangles, far to near", n_frames)
    wrong = painted.face_id != truth.face_id
    offending = np.unique(painted.face_id[wrong & (painted.face_id >= 0)])
    error = _outline(difference_map(painted, truth), _triangles_image(painted, offending))
    image = row([panel(painted.color, "painter's algorithm"),
                 panel(truth.color, "z-buffer"),
                 panel(error, f"wrong: {int(wrong.sum())} px, {len(offending)} triangles")])
    numbers = {"pixels_wrong": int(wrong.sum()), "offending_triangles": int(len(offending)),
               "triangles": int(len(order)), "animation_frames": len(frames)}
    text = ("The painter's algorithm sorts triangles by their farthest depth and paints them "
            "far to near without a depth test. Where triangles overlap cyclically or pierce "
            "each other no such order exists; the triangles painted wrongly are outlined.")
    return Explanation("painter", image, numbers, text, frames)


def _split_view(name, scene, camera, width, height, state, text, n_frames=24):
    """Newell's and the BSP tree's order: the polygons after splitting, painted in the
    algorithm's order (animation), outlined, and compared with the z-buffer."""
    from .compare import difference_map

    frame = render(scene, camera, width, height, state=state, algorithm=name)
    truth = render(scene, camera, width, height, state=state)
    xy, face, _ = frame.fragments.buffers["polygons"]
    frames = _painting_frames(scene, camera, xy, face, width, height, state,
                              "painted {k} of {n} polygons in " + name + " order", n_frames)
    outlines = xy.copy()
    outlines[..., 1] = height - outlines[..., 1]
    drawn = _outline(frame.color // 2, list(outlines), color=(255, 255, 255))
    differ = int(np.count_nonzero(frame.face_id != truth.face_id))
    splits = int(frame.stats.get("splits", 0))
    image = row([panel(frame.color, f"{name}"),
                 panel(drawn, f"{len(face)} polygons after {splits} splits"),
                 panel(difference_map(frame, truth), f"differs from z-buffer: {differ} px")])
    numbers = {"polygons": int(len(face)), "splits": splits, "pixels_differing": differ,
               "animation_frames": len(frames)}
    numbers.update({k: frame.stats[k] for k in ("bsp_nodes", "bsp_depth", "moves",
                                                "pair_tests") if k in frame.stats})
    return Explanation(name, image, numbers, text, frames)


def newell_view(scene, camera, width, height, state):
    return _split_view("newell", scene, camera, width, height, state,
                       "Newell, Newell and Sancha sort by farthest depth, then test each "
                       "overlapping pair (extents, planes, projections) and move or split "
                       "polygons until a true back-to-front order exists: cycles and "
                       "penetrations are cut along a plane, so painting is exact.")


def bsp_view(scene, camera, width, height, state):
    return _split_view("bsp", scene, camera, width, height, state,
                       "Fuchs, Kedem and Naylor's BSP tree splits polygons by the planes of "
                       "others once, in world space; any viewpoint then walks it back to front "
                       "(far side, node, near side), which is a correct painting order.")


def linear_z_depths(screen, camera, depth_range=(0.0, 1.0)):
    """Per-corner depths of the screen triangles as *eye* depth mapped to [0, 1] over
    near..far: interpolating these linearly across the screen is the mistake seed 000
    warns about (z is not linear in screen space, 1/z is)."""
    from ..appearance.shading import linear_eye_depth

    eye = linear_eye_depth(screen.depth_window, camera, depth_range)
    return (eye - camera.near) / (camera.far - camera.near)


def linear_z_view(scene, camera, width, height, state):
    from ..appearance.shading import face_colors, paint_faces
    from ..parallel import Workers
    from ..raster.fill import rasterize

    right = render(scene, camera, width, height, state=state)
    screen = right.fragments.screen
    with Workers() as workers:
        face, *_ = rasterize(screen.xy_window, linear_z_depths(screen, camera, state.depth_range),
                             screen.face_id, width, height, state, workers)
        image = np.empty((height, width, 3), np.uint8)
        paint_faces(workers, face, face_colors("flat", scene, camera, workers, face),
                    np.zeros(3, np.uint8), image)
    flips = face != right.face_id
    flip_map = right.color // 3
    flip_map[flips] = (255, 40, 40)
    z_linear, z_inverse, z_true = midpoint_depth_example()
    numbers = {"pixels_flipped": int(flips.sum()),
               "midpoint_z_linear": z_linear, "midpoint_z_from_1_over_z": z_inverse,
               "midpoint_z_true": z_true}
    image = row([panel(image, "depth interpolated as z\n(wrong)", 2),
                 panel(right.color, "depth interpolated as 1/z\n(window depth, right)", 2),
                 panel(flip_map, f"visibility flips: {int(flips.sum())} px\n"
                       f"seed 000: midpoint z {z_linear:.3f} vs {z_inverse:.3f}", 2)])
    text = (f"Seed 000's example: the segment from (-1, 0, 2) to (1, 0, 10) projects so that "
            f"its 3-D midpoint (0, 0, 6) lands where linear interpolation of z in screen "
            f"space says z = {z_linear:.3f}; interpolating 1/z gives {z_inverse:.3f}, the true "
            f"depth. Where two surfaces are close, the wrong depths reorder them.")
    return Explanation("linear-z", image, numbers, text)


# --------------------------------------------------------------------- depth precision

def depth_formats():
    """Names of the depth formats the precision view compares."""
    return ("unorm16", "unorm24", "float32", "float32-reversed")


def window_depth(z_eye, near, far, reversed_z=False, orthographic=False):
    """Window depth in [0, 1] of positive eye distances for a perspective projection:
    standard OpenGL (near -> 0, far -> 1) or reversed z (near -> 1, far -> 0, as with
    glClipControl(GL_ZERO_TO_ONE) and a reversed projection). Orthographic projections
    map depth linearly."""
    z = np.asarray(z_eye, dtype=np.float64)
    if orthographic:
        d = (z - near) / (far - near)
        return 1.0 - d if reversed_z else d
    if reversed_z:
        return near * (far - z) / (z * (far - near))
    return far * (z - near) / (z * (far - near))


def quantize_depth(d, fmt):
    """Store window depths in a depth format: unsigned normalised N-bit (round to the
    nearest of 2**N - 1 steps, as OpenGL converts) or float32 (round to nearest)."""
    d = np.clip(np.asarray(d, dtype=np.float64), 0.0, 1.0)
    if fmt == "unorm16":
        return np.round(d * 65535.0) / 65535.0
    if fmt == "unorm24":
        return np.round(d * 16777215.0) / 16777215.0
    if fmt in ("float32", "float32-reversed"):
        return d.astype(np.float32).astype(np.float64)
    raise RenderError(f"unknown depth format {fmt!r}")


def depth_step(d, fmt):
    """Smallest representable change of stored depth at window depth ``d``."""
    if fmt == "unorm16":
        return np.full(np.shape(d), 1.0 / 65535.0)
    if fmt == "unorm24":
        return np.full(np.shape(d), 1.0 / 16777215.0)
    return np.spacing(np.abs(np.asarray(d, dtype=np.float32))).astype(np.float64)


def resolvable_depth(z_eye, near, far, fmt, orthographic=False):
    """Smallest eye-space depth difference the format can tell apart at distance
    ``z_eye``: one depth step divided by |d(window depth)/d(z_eye)|, which is
    n f / ((f - n) z^2) for a perspective projection and 1 / (f - n) for an orthographic
    one."""
    z = np.asarray(z_eye, dtype=np.float64)
    reversed_z = fmt == "float32-reversed"
    d = window_depth(z, near, far, reversed_z, orthographic)
    if orthographic:
        slope = np.full(z.shape, 1.0 / (far - near))
    else:
        slope = near * far / ((far - near) * z * z)
    return depth_step(d, fmt) / slope


def _zfight_scene(gap):
    """A long floor and a second floor ``gap`` above it, drawn second (it should win
    everywhere as seen from above)."""
    pos = np.array([[-40, 0, 0], [40, 0, 0], [40, 0, -280], [-40, 0, -280]], dtype=float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    lower = Mesh(pos, faces, face_colors=[[220, 60, 50]] * 2, name="lower")
    upper = Mesh(pos + [0, gap, 0], faces, face_colors=[[60, 110, 230]] * 2, name="upper")
    return Scene().add(lower).add(upper)


def zfight_winner(scene, camera, width, height, fmt):
    """(H, W) int8: which floor wins each pixel (0 lower, 1 upper, -1 none) when both are
    drawn in order with GL_LESS into a depth buffer of format ``fmt``. Exact eye depths
    come from perspective-correct barycentrics on each floor."""
    from ..appearance.buffers import points_at

    base = render(scene, camera, width, height, depth_test=False)
    screen = base.fragments.screen
    view = camera.view_matrix
    stored = np.full((height, width), np.inf)
    winner = np.full((height, width), -1, np.int8)
    offsets = scene.face_offsets()
    world_mesh = scene.world_mesh()
    for k, inst in enumerate(scene.instances):
        single = render(Scene([inst]), camera, width, height)
        rows, cols = np.nonzero(single.face_id >= 0)
        faces = single.face_id[rows, cols] + offsets[k]
        world, _ = points_at(world_mesh, screen, rows, cols, faces)
        eye = world @ view[:3, :3].T + view[:3, 3]
        d = quantize_depth(window_depth(-eye[:, 2], camera.near, camera.far,
                                        fmt == "float32-reversed"), fmt)
        key = -d if fmt == "float32-reversed" else d  # reversed z: GL_GREATER
        passed = key < stored[rows, cols]
        stored[rows[passed], cols[passed]] = key[passed]
        winner[rows[passed], cols[passed]] = k
    return winner


def precision_view(scene, camera, width, height, state, gap=0.005):
    fmts = depth_formats()
    near, far = camera.near, camera.far
    # (up to 0.9 far: at the far plane itself reversed z stores 0, where a float is
    # denormal-fine and the table would say nothing useful)
    distances = np.geomspace(max(near * 2, 1e-6), 0.9 * far, 6)
    ortho = camera.is_orthographic
    table = {fmt: [float(v) for v in resolvable_depth(distances, near, far, fmt, ortho)]
             for fmt in fmts}
    small_w, small_h = max(width // 2, 80), max(height // 2, 60)
    panels_rows = []
    wrong = {}
    colors = np.array([[220, 60, 50], [60, 110, 230]], np.uint8)
    # Near matters most (precision is spent close to it); far hardly does.
    for z_near, z_far in ((0.01, 300.0), (1.0, 300.0), (1.0, 30000.0)):
        fight_cam = Camera.look_at((0, 12.0, 5.0), (0, 0, -90), (0, 1, 0), 50, z_near, z_far)
        fight = _zfight_scene(gap)
        panels = []
        for fmt in fmts:
            win = zfight_winner(fight, fight_cam, small_w, small_h, fmt)
            img = np.zeros((small_h, small_w, 3), np.uint8)
            img[win >= 0] = colors[win[win >= 0]]
            lost = float(np.mean(win[win >= 0] == 0)) if (win >= 0).any() else 0.0
            key = f"{fmt}@near={z_near}" + ("" if z_far == 300.0 else f",far={z_far:g}")
            wrong[key] = lost
            panels.append(panel(img, f"{fmt}, near {z_near:g}, far {z_far:g}\n"
                                     f"lower floor shows: {100 * lost:.1f}%", 2))
        panels_rows.append(row(panels))
    lines = [f"resolvable eye-depth difference, near {near:g}, far {far:g}"
             f"{' (orthographic)' if ortho else ''}:"]
    lines.append("distance  " + "  ".join(f"{f:>16}" for f in fmts))
    for i, z in enumerate(distances):
        lines.append(f"{z:8.3g}  " + "  ".join(f"{table[f][i]:16.3g}" for f in fmts))
    numbers = {"distances": [float(z) for z in distances], "resolvable": table,
               "zfight_lower_visible": wrong, "gap": gap,
               "steps": {"unorm16": 1 / 65535, "unorm24": 1 / 16777215}}
    text = (f"Two floors {gap} apart, the upper drawn second: wherever the stored depths of "
            "the two round to the same value (or the wrong way) the lower one shows "
            "through: z-fighting. Precision is spent near the near plane, so moving the near "
            "plane out helps most; reversed z with a float buffer spreads it evenly.\n"
            + "\n".join(lines))
    return Explanation("precision", column(panels_rows), numbers, text)


# ---------------------------------------------------------------------------- y-buffer

# tinyrenderer lesson 3: three segments in a 2-D scene seen from below (y up).
YBUFFER_SEGMENTS = (((20, 34), (744, 400), (255, 0, 0)),
                    ((120, 434), (444, 400), (0, 255, 0)),
                    ((330, 463), (594, 200), (0, 0, 255)))


def ybuffer(segments=YBUFFER_SEGMENTS, width=800):
    """Render 2-D segments to a one-pixel-high screen keeping, per column, the segment
    with the largest y (the y-buffer). Returns (colors (W, 3) uint8, ybuf (W,) float with
    -inf where empty)."""
    ybuf = np.full(width, -np.inf)
    colors = np.zeros((width, 3), np.uint8)
    for (x0, y0), (x1, y1), color in segments:
        if x0 > x1:
            x0, y0, x1, y1 = x1, y1, x0, y0
        for x in range(max(int(x0), 0), min(int(x1), width - 1) + 1):
            t = (x - x0) / (x1 - x0) if x1 != x0 else 0.0
            y = y0 + t * (y1 - y0)
            if y > ybuf[x]:
                ybuf[x] = y
                colors[x] = color
    return colors, ybuf


def ybuffer_view(scene=None, camera=None, width=800, height=None, state=None):
    from PIL import Image, ImageDraw

    size = 800
    scene_img = Image.new("RGB", (size, size), (0, 0, 0))
    draw = ImageDraw.Draw(scene_img)
    for (x0, y0), (x1, y1), color in YBUFFER_SEGMENTS:
        draw.line([(x0, size - 1 - y0), (x1, size - 1 - y1)], fill=color, width=3)
    colors, ybuf = ybuffer()
    screen = np.repeat(colors[None], 16, axis=0)
    plot = Image.new("RGB", (size, 200), (0, 0, 0))
    pd = ImageDraw.Draw(plot)
    pts = [(x, 199 - int(ybuf[x] * 199 / 800)) for x in range(size) if np.isfinite(ybuf[x])]
    for a, b in zip(pts[:-1], pts[1:]):
        if b[0] == a[0] + 1:
            pd.line([a, b], fill=(200, 200, 200))
    image = column([panel(np.asarray(scene_img), "2-D scene (seen from below: larger y = nearer)"),
                    panel(screen, "the one-pixel-high screen (stretched to 16 rows)"),
                    panel(np.asarray(plot), "the y-buffer: largest y seen in each column")])
    covered = np.isfinite(ybuf)
    numbers = {"columns_covered": int(covered.sum()),
               "ybuffer_max": float(ybuf[covered].max()),
               "winners": {name: int(np.all(colors == c, axis=1).sum()) for name, c in
                           zip(("red", "green", "blue"), ((255, 0, 0), (0, 255, 0), (0, 0, 255)))}}
    text = ("tinyrenderer's y-buffer (seed 002): a 2-D world rendered to a 1-D screen. For "
            "each screen column keep the largest y seen so far and the colour that gave it; "
            "a z-buffer is the same idea one dimension up.")
    return Explanation("ybuffer", image, numbers, text)


# ----------------------------------------------------------------------------- culling

def culling_view(scene, camera, width, height, state):
    base = render(scene, camera, width, height, state=state.with_(cull="none"))
    panels = []
    numbers = {}
    for mode in ("none", "back", "front", "front_and_back"):
        frame = render(scene, camera, width, height, state=state.with_(cull=mode))
        culled_faces = np.zeros(scene.n_faces, dtype=bool)
        culled_faces[base.fragments.screen.face_id] = True  # reached the screen
        culled_faces[frame.fragments.screen.face_id] = False  # ... and survived culling
        seen_culled = (base.face_id >= 0) & culled_faces[np.maximum(base.face_id, 0)]
        img = frame.color.copy()
        tint = np.array([255, 0, 180], np.float64)
        img[seen_culled] = np.round(0.45 * base.color[seen_culled] + 0.55 * tint).astype(np.uint8)
        numbers[mode] = {"culled": int(frame.stats["culled"]),
                         "drawn": int(len(frame.fragments.screen))}
        panels.append(panel(img, f"glCullFace {mode.upper()}\nculled {frame.stats['culled']}, "
                                 f"drawn {len(frame.fragments.screen)}", 2))
    image = column([row(panels[:2]), row(panels[2:])])
    text = ("Back-face culling drops triangles whose window-space winding is clockwise "
            "(with glFrontFace(GL_CCW)): on a closed mesh they are hidden anyway. Magenta marks "
            "where a culled triangle was the visible one: nothing for GL_BACK on closed "
            "objects, everything for GL_FRONT_AND_BACK.")
    return Explanation("culling", image, numbers, text)


VIEWS = {
    "depth": depth_view,
    "overdraw": overdraw_view,
    "no-depth-test": no_depth_test_view,
    "painter": painter_view,
    "newell": newell_view,
    "bsp": bsp_view,
    "linear-z": linear_z_view,
    "precision": precision_view,
    "ybuffer": ybuffer_view,
    "culling": culling_view,
}


def explain(view: str, scene, camera, width: int = 320, height: int = 240,
            state: RenderState | None = None) -> Explanation:
    """Build one view (see :data:`VIEWS`).

    Raises :class:`~hsr.errors.RenderError` for an unknown view, an image under 32x32 or
    a state the view's algorithm cannot honour; errors of :func:`hsr.render` otherwise.
    """
    check_choice(view, tuple(VIEWS), "view")
    check_size(width, height)
    if min(width, height) < MIN_SIZE:
        raise RenderError(f"explanation views need at least {MIN_SIZE}x{MIN_SIZE} pixels "
                          f"(panels, captions and legends), got {width}x{height}")
    return VIEWS[view](as_scene(scene), camera, width, height, state or RenderState())
