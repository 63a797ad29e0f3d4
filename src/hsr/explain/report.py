"""``hsr report``: one self-contained HTML page (images inlined as data URIs, no scripts,
no external files) with every explanation view, the algorithm comparison table, timings and
stats. The layout is a single fluid column, readable on a phone and on a laptop."""

from __future__ import annotations

import base64
import html
import io
import time

import numpy as np

from ..errors import OutputError, RenderError
from .views import VIEWS, explain

__all__ = ["build_report", "write_report"]

_CSS = """
:root { color-scheme: light dark; }
body { font: 16px/1.5 system-ui, sans-serif; margin: 0 auto; padding: 0 1rem 3rem;
       max-width: 68rem; }
h1 { font-size: 1.6rem; } h2 { font-size: 1.25rem; margin-top: 2.2rem; }
img { display: block; max-width: 100%; height: auto; image-rendering: pixelated;
      border-radius: 4px; }
figure { margin: 0.8rem 0; } figcaption { font-size: 0.9rem; opacity: 0.8; }
.scroll { overflow-x: auto; }
table { border-collapse: collapse; font-size: 0.9rem; }
td, th { padding: 0.25rem 0.6rem; border-bottom: 1px solid rgba(128,128,128,0.4);
         text-align: right; white-space: nowrap; }
td:first-child, th:first-child { text-align: left; }
pre { font-size: 0.8rem; overflow-x: auto; }
"""


def _data_uri(image: np.ndarray | None = None, frames: list | None = None) -> str:
    from PIL import Image

    buf = io.BytesIO()
    if frames:
        images = [Image.fromarray(f) for f in frames]
        images[0].save(buf, format="GIF", save_all=True, append_images=images[1:], duration=120,
                       loop=0)
        kind = "gif"
    else:
        Image.fromarray(np.asarray(image)).save(buf, format="PNG", optimize=True)
        kind = "png"
    return f"data:image/{kind};base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _img(uri, alt, width, height):
    return (f'<img src="{uri}" alt="{html.escape(alt)}" width="{width}" height="{height}" '
            f'loading="eager">')


def _numbers_html(numbers: dict) -> str:
    def fmt(v):
        if isinstance(v, float):
            return f"{v:.6g}"
        if isinstance(v, dict):
            return ", ".join(f"{k}: {fmt(x)}" for k, x in v.items())
        if isinstance(v, list):
            return ", ".join(fmt(x) for x in v)
        return str(v)

    rows = "".join(f"<tr><td>{html.escape(str(k))}</td><td>{html.escape(fmt(v))}</td></tr>"
                   for k, v in numbers.items())
    return f'<div class="scroll"><table>{rows}</table></div>'


def build_report(scene, camera, title: str, width: int = 480, height: int = 360, state=None,
                 algorithms=None, progress: bool = False) -> str:
    """The report page as a string."""
    from ..algorithms import ALGORITHMS
    from ..geometry.viewport import check_size
    from ..render import render
    from .compare import compare_algorithms
    from .views import MIN_SIZE

    check_size(width, height)
    if min(width, height) < MIN_SIZE:
        raise RenderError(f"the report needs at least {MIN_SIZE}x{MIN_SIZE} pixels, "
                          f"got {width}x{height}")
    t0 = time.perf_counter()
    names = list(algorithms or ALGORITHMS)
    comparison = compare_algorithms(scene, camera, width, height, names, state=state,
                                    progress=progress)
    # After the comparison has compiled and warmed the kernels: these timings are warm.
    frame = render(scene, camera, width, height, state=state)
    views = list(VIEWS)
    iterator = views
    if progress:
        from tqdm import tqdm

        iterator = tqdm(views, desc="views", leave=False)
    explanations, refused = [], {}
    for view in iterator:
        try:
            explanations.append(explain(view, scene, camera, width, height, state))
        except RenderError as exc:  # a view whose algorithm cannot honour the state
            refused[view] = str(exc)
    total_ms = 1e3 * (time.perf_counter() - t0)

    parts = [f"<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">"
             f"<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
             f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
             f"<h1>{html.escape(title)}</h1>",
             f"<p>{scene.n_faces} triangles in {len(scene.instances)} object(s), "
             f"{width}x{height} pixels, camera eye {np.round(camera.eye, 3).tolist()} "
             f"looking at {np.round(camera.target, 3).tolist()}, near {camera.near:g}, "
             f"far {camera.far:g}. Report built in {total_ms:.0f} ms.</p>",
             "<figure>" + _img(_data_uri(frame.color), "z-buffer image", width, height)
             + "<figcaption>z-buffer, flat shading</figcaption></figure>",
             "<h2>Algorithms compared</h2>",
             "<p>Each algorithm renders the same view; agreement is with the z-buffer.</p>",
             _comparison_html(comparison)]
    stats = {k: v for k, v in frame.stats.items() if not isinstance(v, dict)}
    stats.update({f"{k} ms": v for k, v in frame.stats["timings_ms"].items()})
    parts += ["<h2>Render statistics (z-buffer)</h2>", _numbers_html(stats)]
    for e in explanations:
        h, w = e.image.shape[:2]
        parts.append(f"<h2>{html.escape(e.name)}</h2>")
        parts.append(f"<p>{html.escape(e.text.splitlines()[0])}</p>")
        parts.append("<figure>" + _img(_data_uri(e.image), e.name, w, h) + "</figure>")
        if e.frames:
            fh, fw = e.frames[0].shape[:2]
            parts.append("<figure>" + _img(_data_uri(frames=e.frames), e.name + " animation",
                                           fw, fh)
                         + "<figcaption>animation</figcaption></figure>")
        extra = e.text.splitlines()[1:]
        if extra:
            parts.append("<pre>" + html.escape("\n".join(extra)) + "</pre>")
        parts.append(_numbers_html(e.numbers))
    for view, why in refused.items():
        parts.append(f"<h2>{html.escape(view)}</h2><p>Not shown: {html.escape(why)}</p>")
    parts.append("</body></html>")
    return "\n".join(parts)


def _comparison_html(comparison) -> str:
    head = ("<tr><th>algorithm</th><th>ms</th><th>pixels covered</th><th>agree</th>"
            "<th>differ</th><th>counts</th></tr>")
    rows = "".join(
        f"<tr><td>{r['name']}</td><td>{r['ms']:.1f}</td><td>{r['covered']}</td>"
        f"<td>{r['agree']:.3f}%</td><td>{r['differ']}</td>"
        f"<td style=\"text-align:left\">{html.escape(r['counts'])}</td></tr>"
        for r in comparison.records())
    rows += "".join(f'<tr><td>{name}</td><td colspan="5" style="text-align:left">refused: '
                    f"{html.escape(why)}</td></tr>" for name, why in comparison.refused.items())
    return f'<div class="scroll"><table>{head}{rows}</table></div>'


def write_report(path, scene, camera, title: str, **kwargs) -> None:
    """Write the self-contained HTML report (see :func:`build_report` for the arguments).

    Raises :class:`~hsr.errors.OutputError` when the file cannot be written and what
    :func:`build_report` raises (:class:`~hsr.errors.RenderError` under 32x32, errors of
    :func:`hsr.render`)."""
    page = build_report(scene, camera, title, **kwargs)
    from ..scene.outputs import staged

    try:
        with staged(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
            fh.write(page)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
