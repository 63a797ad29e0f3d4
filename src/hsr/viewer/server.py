"""The viewer's HTTP server (Starlette on uvicorn): the page, its static files and the
API the page uses (and scripts may call):

- ``GET /api/options``: every control, its default and allowed values, the scenes, the
  explanation views and the demonstrations.
- ``GET /api/render?...``: the view as an image (``format=png|jpeg``); its stats in the
  ``X-Hsr-Stats`` header (JSON).
- ``GET /api/stats?...``: the same stats as JSON.
- ``GET /api/pick?x=&y=&...``: what is at a pixel (JSON).
- ``GET /api/explain?view=&...``: an explanation view (PNG).
- ``GET /api/command?...``: the ``hsr render`` line and the Python call of the view.

Every parameter is validated (:mod:`hsr.viewer.params`): a bad request is HTTP 400 with
``{"error": "one line"}``. Renders run one at a time on a worker thread (the kernels use
every core already), so the event loop keeps answering while one runs.
"""

from __future__ import annotations

import json
import os
import threading

from .frames import Library, encode, explain_image, pick, render_request, reproduce
from .params import BUFFERS, CONTROLS, ViewerError, parse

__all__ = ["make_app", "serve", "DEMOS", "STATIC"]

STATIC = os.path.join(os.path.dirname(__file__), "static")

# The seeds' demonstrations, one click away: controls to set (and an explanation view).
DEMOS = [
    {"name": "depth test off", "text": "Without the depth test the last face drawn wins: "
     "the draw order shows through.", "set": {"scene": "cubes", "depth_test": "0"}},
    {"name": "culling off / on", "text": "Back-face culling removes faces turned away; "
     "culling the front faces shows the insides.", "set": {"scene": "cubes",
                                                           "cull": "front"}},
    {"name": "painter's cycle", "text": "Three triangles overlap in a cycle: no order of "
     "whole faces is right; the red pixels differ from the z-buffer.",
     "set": {"scene": "cyclic", "algorithm": "painter", "buffer": "painter_error"}},
    {"name": "z-fighting, 16-bit depth", "text": "Two floors a hair apart: a 16-bit depth "
     "buffer cannot tell them apart far away.", "set": {"scene": "terrain"},
     "explain": "precision"},
    {"name": "the y-buffer", "text": "Hidden-surface removal in 2-D: one depth per column.",
     "set": {}, "explain": "ybuffer"},
    {"name": "overdraw", "text": "Fragments tested per pixel: depth complexity.",
     "set": {"buffer": "overdraw"}},
    {"name": "depth buffer", "text": "Window depth, stretched over what is visible.",
     "set": {"buffer": "window_depth"}},
]


def _error(status: int, message: str):
    from starlette.responses import JSONResponse

    return JSONResponse({"error": " ".join(str(message).split())}, status_code=status)


def make_app(library: Library):
    """The Starlette application serving ``library``'s scenes."""
    from starlette.applications import Starlette
    from starlette.concurrency import run_in_threadpool
    from starlette.responses import FileResponse, JSONResponse, Response
    from starlette.routing import Mount, Route
    from starlette.staticfiles import StaticFiles

    from ..algorithms import ALGORITHMS
    from ..errors import HsrError
    from ..explain.views import VIEWS

    render_lock = threading.Lock()
    names = sorted(ALGORITHMS)
    views = tuple(VIEWS)

    def job(fn):
        """Run ``fn`` on a worker thread, one render at a time; an HsrError (a state an
        algorithm refuses, a bad value) is a 400, never a 500."""
        async def call(request):
            try:
                return await run_in_threadpool(_locked, fn, request)
            except HsrError as exc:
                return _error(400, exc)
        return call

    def _locked(fn, request):
        with render_lock:
            return fn(request)

    def _request(request, extra=()):
        query = dict(request.query_params)
        if len(request.query_params.multi_items()) != len(query):
            raise ViewerError("a parameter is given twice")
        return parse(query, library.names, extra, views)

    def do_render(request):
        view = _request(request)
        _, image, stats = render_request(library.get(view.scene), view,
                                         library.bounds(view.scene))
        body = encode(image, view.format, view.quality)
        return Response(body, media_type=f"image/{view.format}",
                        headers={"X-Hsr-Stats": json.dumps(stats),
                                 "Cache-Control": "no-store"})

    def do_stats(request):
        view = _request(request)
        return JSONResponse(render_request(library.get(view.scene), view,
                                           library.bounds(view.scene))[2])

    def do_pick(request):
        view = _request(request, ("x", "y"))
        return JSONResponse(pick(library.get(view.scene), view, names,
                                 library.bounds(view.scene)))

    def do_explain(request):
        view = _request(request, ("view",))
        image = explain_image(library.get(view.scene), view, library.bounds(view.scene))
        return Response(encode(image, "png"), media_type="image/png")

    def do_command(request):
        view = _request(request)
        return JSONResponse(reproduce(library.get(view.scene), view, library.path(view.scene),
                                      library.bounds(view.scene)))

    async def options(request):
        if request.query_params:
            return _error(400, "options takes no parameters")
        controls = {}
        for name, (kind, default, allowed, text) in CONTROLS.items():
            if name == "scene":
                allowed, default = library.names, library.names[0]
            if name == "view":
                allowed = list(views)
            controls[name] = {"kind": kind, "default": default, "text": text,
                              "values" if kind in ("choice", "scene") else "range":
                              list(allowed) if allowed is not None else None}
        demos = [d for d in DEMOS if d["set"].get("scene", library.names[0]) in library.names]
        # A scene's opening view needs the scene built; the million-triangle terrain is
        # built when first shown instead (it then opens with the default view).
        initial = await run_in_threadpool(
            lambda: {name: library.initial(name) for name in library.names
                     if name != "terrain" or name == library.names[0]})
        return JSONResponse({"controls": controls, "buffers": list(BUFFERS),
                             "scenes": library.names, "views": list(views), "demos": demos,
                             "initial": initial})

    async def index(request):
        return FileResponse(os.path.join(STATIC, "index.html"),
                            headers={"Cache-Control": "no-store"})

    async def not_found(request, exc):
        return _error(getattr(exc, "status_code", 404), getattr(exc, "detail", "not found"))

    async def server_error(request, exc):  # an hsr bug: still one line, never a traceback
        return _error(500, f"{type(exc).__name__}: {exc}")

    routes = [
        Route("/", index),
        Route("/api/options", options),
        Route("/api/render", job(do_render)),
        Route("/api/stats", job(do_stats)),
        Route("/api/pick", job(do_pick)),
        Route("/api/explain", job(do_explain)),
        Route("/api/command", job(do_command)),
        Mount("/static", StaticFiles(directory=STATIC), name="static"),
    ]
    app = Starlette(routes=routes, exception_handlers={404: not_found, 405: not_found,
                                                       500: server_error})
    # "/api/render/" is a 404 like any other unknown path, not a redirect to the API.
    app.router.redirect_slashes = False
    return app


def serve(models=(), host: str = "127.0.0.1", port: int = 8765, open_browser: bool = True,
          first: str | None = None, announce=print, up_axis: str = "auto") -> None:
    """Serve ``models`` (and the built-in scenes) on ``host``:``port`` until interrupted;
    ``first``: the scene shown first; ``up_axis``: the models' up (``auto``: what each
    file declares, see :func:`hsr.load`), which the orbit turns about. Prints the URL
    and opens the browser. Raises :class:`~hsr.errors.MissingExtraError` when the
    ``view`` extra is not installed."""
    from ..errors import require_extra

    require_extra("hsr view", "starlette", "uvicorn")
    import uvicorn

    library = Library(models, up_axis=up_axis)
    if first is not None:
        library.names.remove(first)
        library.names.insert(0, first)
    # Warm the kernels (Numba's cache) before the first visitor waits for them.
    render_request(library.get(library.names[0]),
                   parse({"w": "64", "h": "48"}, library.names))
    app = make_app(library)
    config = uvicorn.Config(app, host=host, port=port, log_level="warning", access_log=False)
    server = uvicorn.Server(config)
    url = f"http://{'127.0.0.1' if host in ('0.0.0.0', '::') else host}:{port}/"
    announce(f"hsr view: {url}  (Ctrl-C stops)")
    if open_browser:
        import webbrowser

        threading.Timer(1.0, webbrowser.open, args=(url,)).start()
    server.run()
