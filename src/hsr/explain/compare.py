"""Run several visibility algorithms on one scene and compare them with the z-buffer:
time, agreement, coverage and each algorithm's own counts (``hsr compare``)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..algorithms import ALGORITHMS
from ..errors import RenderError
from ..render import Frame, render

__all__ = ["Comparison", "compare_algorithms", "montage", "difference_map"]

# Stats worth a column when an algorithm reports them.
_EXTRA_KEYS = ("fragments_tested", "spans", "depth_comparisons", "max_active_triangles",
               "bvh_nodes", "bvh_build_ms", "ray_triangle_tests", "splits", "pixels_wrong",
               "bsp_nodes", "objects_culled")


@dataclass
class Comparison:
    names: list
    frames: dict
    times_ms: dict
    reference: str = "zbuffer"
    rows: list = field(default_factory=list)
    refused: dict = field(default_factory=dict)  # algorithm -> why it refused the state

    def records(self) -> list:
        """One dict per algorithm: name, ms, covered, agree (%), differ, counts (text)."""
        ref = self.frames[self.reference].face_id
        out = []
        for name in self.names:
            frame = self.frames[name]
            covered = (frame.face_id >= 0) | (ref >= 0)
            n_cov = int(covered.sum())
            differ = int(np.count_nonzero((frame.face_id != ref) & covered))
            out.append({"name": name, "ms": self.times_ms[name], "covered": n_cov,
                        "agree": 100.0 * (n_cov - differ) / n_cov if n_cov else 100.0,
                        "differ": differ,
                        "counts": ", ".join(f"{k}={_fmt(frame.stats[k])}" for k in _EXTRA_KEYS
                                            if k in frame.stats)})
        return out

    def table(self) -> str:
        lines = [f"{'algorithm':10} {'ms':>9} {'covered':>9} {'agree':>9} {'differ':>8}  counts"]
        for r in self.records():
            lines.append(f"{r['name']:10} {r['ms']:9.1f} {r['covered']:9d} {r['agree']:8.3f}% "
                         f"{r['differ']:8d}  {r['counts']}")
        for name, why in self.refused.items():
            lines.append(f"{name:10} refused: {why}")
        return "\n".join(lines)


def _fmt(value):
    return f"{value:.1f}" if isinstance(value, float) else str(value)


def compare_algorithms(scene, camera, width, height, names, *, state=None, shading="auto",
                       background=(0, 0, 0), threads=None, options=None,
                       progress=False, look=None) -> Comparison:
    """Render with each algorithm in ``names`` (the z-buffer is always included as the
    reference). Times are warm: each algorithm first runs once on a tiny image so its
    kernels are compiled. An algorithm that refuses the state (a :class:`RenderError`) is
    listed in ``refused`` with its reason and left out of the frames.

    Raises what :func:`hsr.render` raises for the z-buffer (bad scene, camera, size).
    """
    names = list(dict.fromkeys(["zbuffer"] + list(names)))
    frames, times, refused = {}, {}, {}
    iterator = names
    if progress:
        from tqdm import tqdm

        iterator = tqdm(names, desc="algorithms", leave=False)
    for name in iterator:
        # Each algorithm gets the options it understands.
        opts = {k: v for k, v in (options or {}).items() if k in ALGORITHMS[name].OPTIONS}
        try:
            render(scene, camera, 16, 12, algorithm=name, state=state, threads=threads,
                   options=_tiny(name, opts))
        except RenderError as exc:
            if name == "zbuffer":
                raise
            refused[name] = str(exc)  # a state it cannot honour: listed, not drawn
            continue
        t0 = time.perf_counter()
        frames[name] = render(scene, camera, width, height, algorithm=name, state=state,
                              shading=shading, look=look, background=background,
                              threads=threads, options=opts)
        times[name] = 1e3 * (time.perf_counter() - t0)
    drawn = [n for n in names if n in frames]
    return Comparison(drawn, frames, times, refused=refused)


def _tiny(name, opts):
    # The warm-up only compiles; never let it run the naive ray caster's refusal check.
    return dict(opts, force=True) if name == "raycast" else opts


def difference_map(frame: Frame, reference: Frame) -> np.ndarray:
    """(H, W, 3) uint8: red where the face differs from the reference, grey where they
    agree on a face, black where both show background."""
    out = np.zeros(frame.color.shape, dtype=np.uint8)
    covered = (frame.face_id >= 0) | (reference.face_id >= 0)
    differ = (frame.face_id != reference.face_id) & covered
    out[covered & ~differ] = (90, 90, 90)
    out[differ] = (255, 40, 40)
    return out


def montage(comparison: Comparison):
    """A PIL image: each algorithm's picture over its difference map, with labels."""
    from PIL import Image, ImageDraw

    ref = comparison.frames[comparison.reference]
    h, w = ref.color.shape[:2]
    label = 18
    sheet = Image.new("RGB", (w * len(comparison.names), 2 * h + 2 * label), (20, 20, 20))
    draw = ImageDraw.Draw(sheet)
    for k, name in enumerate(comparison.names):
        frame = comparison.frames[name]
        x = k * w
        differ = int(np.count_nonzero(frame.face_id != ref.face_id))
        draw.text((x + 4, 2), f"{name}  {comparison.times_ms[name]:.0f} ms", fill=(255, 255, 255))
        sheet.paste(Image.fromarray(frame.color), (x, label))
        draw.text((x + 4, h + label + 2), f"differs from zbuffer: {differ} px",
                  fill=(255, 120, 120))
        sheet.paste(Image.fromarray(difference_map(frame, ref)), (x, h + 2 * label))
    return sheet
