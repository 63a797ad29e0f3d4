import contextlib
import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))

MODELS_DIR = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", "shared",
                                          "models"))
CASES_DIR = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", "shared",
                                         "cases"))
IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")


def need(condition: bool, reason: str):
    """Skip locally when a resource is missing; in CI a missing resource is a failure."""
    if not condition:
        if IN_CI:
            pytest.fail(f"required in CI: {reason}")
        pytest.skip(reason)


def require(module: str):
    """The module, imported; skipped locally when it is missing, a failure in CI (where
    the test extra installs every module the tests import)."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as exc:
        reason = f"{module} is not installed ({exc}): pip install -e '.[test]'"
        if IN_CI:
            pytest.fail(f"required in CI: {reason}", pytrace=False)
        pytest.skip(reason, allow_module_level=True)


@pytest.fixture(scope="session")
def models_dir():
    need(os.path.isdir(MODELS_DIR), f"shared models not found at {MODELS_DIR}")
    return MODELS_DIR


@pytest.fixture(scope="session")
def cases_dir():
    need(os.path.isdir(CASES_DIR), f"shared failure cases not found at {CASES_DIR}")
    return CASES_DIR


@pytest.fixture(scope="session")
def gl():
    try:
        from gl_reference import GLRenderer

        renderer = GLRenderer()
    except Exception as exc:  # no moderngl, no EGL, no Mesa
        need(False, f"OpenGL (moderngl + Mesa EGL) unavailable: {exc}")
    return renderer


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def coplanar_soup(n: int, seed: int = 3):
    """(mesh, camera): ``n`` random triangles all in the plane z = -5, overlapping, so only
    submission order can decide ties."""
    import hsr

    rng = np.random.default_rng(seed)
    corners = rng.uniform(-1, 1, size=(n, 3, 2))
    verts = np.concatenate([corners, np.full((n, 3, 1), -5.0)], axis=2).reshape(-1, 3)
    mesh = hsr.Mesh(verts, np.arange(3 * n).reshape(-1, 3))
    cam = hsr.Camera.look_at((0, 0, 0), (0, 0, -1), fov_y=30, near=1, far=10)
    return mesh, cam


def against_zbuffer(mesh, algorithm, width, height, **kwargs):
    """For a front and an oblique auto-framed view: (z-buffer frame, ``algorithm``'s frame,
    share of the pixels either covers on which their face ids agree)."""
    import hsr

    for direction in ((0, 0, 1), (1, 0.5, -0.7)):
        cam = hsr.Camera.frame(mesh.bounds(), direction=direction)
        a = hsr.render(mesh, cam, width, height)
        b = hsr.render(mesh, cam, width, height, algorithm=algorithm, **kwargs)
        covered = (a.face_id >= 0) | (b.face_id >= 0)
        yield a, b, float((a.face_id == b.face_id)[covered].mean())


def free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def viewer_server(library):
    """``hsr view``'s app for ``library`` on a free port of 127.0.0.1, served by uvicorn
    on a thread of this process: yields the port."""
    import threading
    import time

    import uvicorn

    from hsr.viewer.server import make_app

    port = free_port()
    srv = uvicorn.Server(uvicorn.Config(make_app(library), host="127.0.0.1", port=port,
                                        log_level="critical", access_log=False))
    thread = threading.Thread(target=srv.run, daemon=True)
    thread.start()
    deadline = time.time() + 30
    while not srv.started and time.time() < deadline:
        time.sleep(0.05)
    assert srv.started
    try:
        yield port
    finally:
        srv.should_exit = True
        thread.join(10)


def run_cli(args):
    """(exit code, stderr lines) of ``hsr ARGS`` in this process, stdout dropped,
    warnings raised as errors."""
    import io
    import warnings

    from hsr.cli import main

    err = io.StringIO()
    with warnings.catch_warnings(), contextlib.redirect_stderr(err), \
            contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("error")
        code = main(args)
    return code, err.getvalue().strip().splitlines()


def assert_one_line_or_success(args, code, lines):
    """The CLI's promise: exit 0, or 2 with exactly one line starting ``hsr: error:``."""
    assert code in (0, 2), (args, code, lines)
    if code == 2:
        assert len(lines) == 1 and lines[0].startswith("hsr: error: "), (args, lines)
