"""The HTTP API of ``hsr view`` under random requests (issue #32): every endpoint with
random query strings (every control, unknown names, repeated names, long, unicode,
percent-encoded and odd values), every method, and paths that try to leave what is
served (``..``, ``%2e%2e``, encoded slashes, absolute paths, NUL) in the path and in the
scene parameter. Every answer is 200, or 400/404/405 with one line of JSON, never a 500
and never a byte of a file outside the static folder; 500 requests from 20 threads leave
the server's memory within a bound (measured here, in the process that serves)."""

from __future__ import annotations

import http.client
import json
import os
import random
import urllib.parse
from concurrent.futures import ThreadPoolExecutor

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from conftest import require, viewer_server

from . import scaled

require("starlette")
require("uvicorn")
psutil = require("psutil")

from hsr.viewer.frames import Library  # noqa: E402
from hsr.viewer.params import CONTROLS  # noqa: E402

SECRET = "hsr-fuzz-secret-7c1e"
ENDPOINTS = ["/api/render", "/api/stats", "/api/pick", "/api/explain", "/api/command",
             "/api/options", "/", "/static/viewer.js", "/static/index.html"]
TRAVERSALS = ["/static/../../secret.txt", "/static/%2e%2e/%2e%2e/secret.txt",
              "/static/..%2f..%2fsecret.txt", "/static/%2E%2E%2F%2E%2E%2Fsecret.txt",
              "/static//etc/passwd", "/static/%2fetc%2fpasswd", "/../../etc/passwd",
              "/static/....//....//secret.txt", "/static/%00", "/static/viewer.js%00.txt",
              "/api/../static/viewer.js", "/api/render/../../secret.txt", "//etc/passwd",
              "/static/..\\..\\secret.txt", "/static/%252e%252e/secret.txt",
              "/static/SECRETLINK", "/api/%72ender", "/api/render/", "/API/RENDER"]


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """The viewer on 127.0.0.1 in this process, with a model file whose folder holds a
    secret beside it."""
    folder = tmp_path_factory.mktemp("served")
    (folder / "secret.txt").write_text(SECRET)
    model = folder / "tri.obj"
    model.write_text("v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n")
    with viewer_server(Library([str(model)])) as port:
        yield "127.0.0.1", port


def request(server, method, target, timeout=120):
    """(status, content type, body) of one raw request: the target goes out as written
    (http.client does not normalise it)."""
    host, port = server
    conn = http.client.HTTPConnection(host, port, timeout=timeout)
    try:
        conn.putrequest(method, target, skip_accept_encoding=True)
        conn.endheaders()
        response = conn.getresponse()
        return response.status, response.getheader("content-type", ""), response.read()
    finally:
        conn.close()


def check(status, ctype, body, method, target):
    assert status in (200, 400, 404, 405), (method, target, status, body[:300])
    assert SECRET.encode() not in body and b"root:x:0:0" not in body, (method, target)
    if status != 200:
        assert ctype.startswith("application/json"), (target, status, ctype)
        if method != "HEAD":
            text = body.decode("utf-8")
            assert "\n" not in text.strip(), text
            assert isinstance(json.loads(text)["error"], str)


_values = st.one_of(
    st.sampled_from(["", "0", "1", "-1", "2", "0.5", "nan", "inf", "-inf", "1e400", "1e-400",
                     "4096", "4097", "99999999999999999999", "x", "true", "none", "cubes",
                     "tri.obj", "../../etc/passwd", "..%2f..%2fsecret.txt", "%00", "\u00e9\u00e8",
                     "\U0001f600", "a" * 5000, "1,2", "[1]", "{}", "zbuffer", "painter", "png",
                     "jpeg", "depth", "color", "terrain"]),
    st.text(max_size=40))
_names = st.one_of(st.sampled_from(sorted(CONTROLS) + ["", "W", "scene ", "x[]", "__class__",
                                                       "%73cene", "\u00e9"]),
                   st.text(max_size=8))


@st.composite
def targets(draw):
    if draw(st.integers(0, 9)) == 0:
        return draw(st.sampled_from(TRAVERSALS))
    path = draw(st.sampled_from(ENDPOINTS))
    pairs = draw(st.lists(st.tuples(_names, _values), max_size=6))
    if draw(st.booleans()):  # small images unless asked otherwise: keep examples fast
        pairs += [("w", str(draw(st.integers(1, 96)))), ("h", str(draw(st.integers(1, 72))))]
    if draw(st.booleans()):
        pairs.append(("scene", draw(st.sampled_from(["cubes", "tri.obj", "glass", "cyclic",
                                                      "../secret.txt", "/etc/passwd",
                                                      "%2e%2e/secret.txt", "nope"]))))
    query = urllib.parse.urlencode(pairs, quote_via=urllib.parse.quote)
    if draw(st.booleans()) and query:
        query = query.replace("%", draw(st.sampled_from(["%", "%%", "%2", "%zz"])), 1)
    return path + ("?" + query if query else "")


@settings(max_examples=scaled(300), suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(method=st.sampled_from(["GET", "GET", "GET", "POST", "PUT", "DELETE", "HEAD", "OPTIONS",
                               "PATCH"]), target=targets())
def test_random_requests_are_answered_cleanly(server, method, target):
    target = target.replace(" ", "%20")
    status, ctype, body = request(server, method, target)
    event(f"{method} {status}")
    check(status, ctype, body, method, target)


def test_traversal_never_leaves_the_static_folder(server, tmp_path):
    static = os.path.join(os.path.dirname(__import__("hsr.viewer").viewer.__file__), "static")
    for target in TRAVERSALS + ["/static/" + os.path.relpath("/etc/passwd", static)]:
        for method in ("GET", "HEAD"):
            status, ctype, body = request(server, method, target)
            check(status, ctype, body, method, target)
            if "viewer.js" not in target and target not in ("/api/render/", "/API/RENDER",
                                                              "/api/%72ender"):
                assert status in (400, 404, 405), (target, status)


def test_memory_stays_bounded_under_500_requests_from_20_threads(server):
    """RSS after 500 mixed requests from 20 threads, against RSS after a warm-up of the
    same mix: growth under 150 MB (a leak of one 96 x 72 frame a request would be 15 MB,
    of a request's JSON and image far less, so this bound catches caching without limit
    rather than allocator noise)."""
    process = psutil.Process()
    rng = random.Random(5)

    def one(_):
        kind = rng.random()
        if kind < 0.6:
            target = (f"/api/render?scene={rng.choice(['cubes', 'tri.obj', 'glass'])}"
                      f"&w={rng.randint(16, 96)}&h={rng.randint(12, 72)}"
                      f"&az={rng.uniform(-180, 180):.3f}"
                      f"&algorithm={rng.choice(['zbuffer', 'raycast', 'scanline'])}")
        elif kind < 0.8:
            target = f"/api/render?w={'9' * rng.randint(1, 3000)}"
        else:
            target = rng.choice(TRAVERSALS)
        status, ctype, body = request(server, "GET", target)
        check(status, ctype, body, "GET", target)
        return status

    with ThreadPoolExecutor(20) as pool:
        list(pool.map(one, range(100)))  # warm-up: kernels, caches, thread stacks
    before = process.memory_info().rss
    with ThreadPoolExecutor(20) as pool:
        statuses = list(pool.map(one, range(500)))
    growth = process.memory_info().rss - before
    assert statuses.count(200) > 100
    print(f"RSS growth over 500 requests: {growth / 2**20:.1f} MB")
    assert growth < 150 << 20, f"RSS grew by {growth / 2**20:.1f} MB"
