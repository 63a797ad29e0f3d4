"""`hsr view` (issue #17): the HTTP API against hsr.render called directly, its
validation, concurrency and the reproduce command; and the page in a real browser
(headless Chromium through Selenium)."""

import io
import json
import os
import shlex
import shutil
import socket
import urllib.error
import urllib.parse
import urllib.request
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from PIL import Image

import hsr
from conftest import need, viewer_server
from hsr.cli import main

pytest.importorskip("starlette")
pytest.importorskip("uvicorn")

from hsr.viewer.frames import Library  # noqa: E402
from hsr.viewer.params import CONTROLS, orbit_camera, parse  # noqa: E402

W, H = 160, 120


@pytest.fixture(scope="module")
def server(models_dir):
    """The viewer on a free port of 127.0.0.1 in this process, serving spot, the bunny
    and the built-in scenes."""
    library = Library([os.path.join(models_dir, "spot.obj"),
                       os.path.join(models_dir, "stanford-bunny.obj")])
    with viewer_server(library) as port:
        yield f"http://127.0.0.1:{port}", library


def get(base, path, **params):
    """(status, headers, body) of a GET."""
    url = f"{base}{path}" + ("?" + urllib.parse.urlencode(params) if params else "")
    try:
        with urllib.request.urlopen(url, timeout=60) as r:
            return r.status, dict(r.headers), r.read()
    except urllib.error.HTTPError as exc:
        return exc.code, dict(exc.headers), exc.read()


def png(body):
    return np.asarray(Image.open(io.BytesIO(body)).convert("RGB"))


def direct(library, **params):
    """What hsr.render draws for these view parameters, called directly: the render
    options are spelled out here from the controls' meaning, not taken from the viewer."""
    q = {k: str(v) for k, v in params.items()}
    view = parse(q, library.names)
    scene = library.get(view.scene)
    lo, hi = scene.bounds()
    camera = orbit_camera((lo, hi), view)
    # Fog over the model's depth from the eye (linear), or a density per model radius.
    radius = np.linalg.norm(hi - lo) / 2
    to_centre = np.linalg.norm(np.asarray(camera.eye) - (lo + hi) / 2)
    fog = (None if view.fog == "none" else
           hsr.Fog("linear", start=max(to_centre - radius, 0.0), end=to_centre + radius)
           if view.fog == "linear" else hsr.Fog(view.fog, density=view.fog_density / radius))
    return hsr.render(
        scene, camera, view.w, view.h, algorithm=view.algorithm, shading=view.shading,
        light=view.light, fog=fog, hidden_line=True if view.hidden_lines else None,
        occlusion_cull=view.occlusion_cull, transparency=view.transparency,
        depth_test=view.depth_test, depth_mask=view.depth_write, depth_func=view.depth_func,
        clear_depth=view.clear_depth, depth_range=(view.depth_near, view.depth_far),
        cull=view.cull, front_face=view.front_face, polygon_mode=view.polygon_mode,
        polygon_offset=(view.offset_factor, view.offset_units))


def test_the_orbit_camera_follows_its_controls(server):
    """az/el put the eye on hsr.views.direction from the target, dist scales the
    distance, tx/ty move the target along the image's right and up axes."""
    base, library = server
    bounds = library.get("spot.obj").bounds()
    centre, radius = bounds.mean(axis=0), np.linalg.norm(bounds[1] - bounds[0]) / 2
    one = orbit_camera(bounds, parse({"az": "60", "el": "20"}, library.names))
    eye, target = np.asarray(one.eye), np.asarray(one.target)
    assert np.allclose(target, centre)
    toward = (eye - target) / np.linalg.norm(eye - target)
    assert np.allclose(toward, hsr.views.direction(60, 20))
    two = orbit_camera(bounds, parse({"az": "60", "el": "20", "dist": "2"}, library.names))
    assert np.isclose(np.linalg.norm(np.asarray(two.eye) - centre),
                      2 * np.linalg.norm(eye - centre))
    pan = orbit_camera(bounds, parse({"az": "0", "el": "0", "tx": "0.5", "ty": "-0.25"},
                                     library.names))
    assert np.allclose(np.asarray(pan.target) - centre, radius * np.array([0.5, -0.25, 0]))
    # The whole bounding sphere is inside the view, between near and far.
    d = np.linalg.norm(eye - centre)
    assert one.near <= d - radius and one.far >= d + radius


# Every value of every control that changes the image (the others: numbers below).
CHOICES = [(name, value) for name in ("algorithm", "cull", "front_face", "depth_func",
                                      "polygon_mode", "shading", "light", "fog",
                                      "transparency")
           for value in CONTROLS[name][2]]
NUMBERS = [("clear_depth", 0.5), ("depth_near", 0.25), ("depth_far", 0.75),
           ("offset_factor", 2.0), ("offset_units", 4.0), ("fog_density", 2.0),
           ("dist", 0.6), ("tx", 0.3), ("ty", -0.2), ("fov", 70.0), ("az", -120.0),
           ("el", -40.0), ("depth_test", 0), ("depth_write", 0), ("hidden_lines", 1),
           ("occlusion_cull", 1)]


@pytest.mark.parametrize("name, value", CHOICES + NUMBERS)
def test_every_control_renders_as_hsr_render(server, name, value):
    """The page's image (PNG, decoded) equals hsr.render's colour with the same camera
    and state, pixel for pixel; a state the algorithm refuses is a 400 with its reason."""
    base, library = server
    scene = "glass" if name == "transparency" else "cubes"
    params = {"scene": scene, "w": W, "h": H, name: value}
    status, headers, body = get(base, "/api/render", **params)
    try:
        expected = direct(library, **params)
    except hsr.HsrError as exc:
        assert status == 400 and json.loads(body)["error"] == " ".join(str(exc).split())
        return
    assert status == 200, body
    assert headers["content-type"] == "image/png"
    assert np.array_equal(png(body), expected.color)
    stats = json.loads(headers["x-hsr-stats"])
    assert stats["algorithm"] == params.get("algorithm", "zbuffer")


def test_every_scene_renders(server):
    base, library = server
    for name in library.names:
        if name == "terrain":  # a million triangles: covered by the scene's own tests
            continue
        status, _, body = get(base, "/api/render", scene=name, w=96, h=72)
        assert status == 200
        assert np.array_equal(png(body), direct(library, scene=name, w=96, h=72).color)


def test_buffers(server):
    """Each buffer against hsr.render's frame: ids colour-coded one to one, depth
    ordered, normals decoded, overdraw where fragments were tested, the painter's
    error map and count against both algorithms rendered directly."""
    base, library = server
    view = {"scene": "cubes", "w": W, "h": H}
    frame = direct(library, **view)
    covered = frame.face_id >= 0

    ids = png(get(base, "/api/render", buffer="face_ids", **view)[2]).astype(np.int64)
    code = (ids[..., 0] << 16) | (ids[..., 1] << 8) | ids[..., 2]
    pairs = set(zip(frame.face_id[covered].tolist(), code[covered].tolist()))
    assert len(pairs) == len(set(frame.face_id[covered].tolist())) == len(
        set(code[covered].tolist()))
    assert not ids[~covered].any()

    depth = png(get(base, "/api/render", buffer="window_depth", **view)[2])[..., 0]
    d = frame.depth[covered]
    nearer = d[:, None] < d[None, ::97] - 1e-3  # a sample of pairs, clearly apart
    brighter = depth[covered][:, None].astype(int) >= depth[covered][None, ::97]
    assert brighter[nearer].all()

    normals = png(get(base, "/api/render", buffer="normals", **view)[2]) / 127.5 - 1.0
    assert np.abs(normals[covered] - frame.normals[covered]).max() <= 1.0 / 127.5 + 1e-9

    heat = png(get(base, "/api/render", buffer="overdraw", **view)[2])
    assert heat[covered].any(axis=-1).all()

    cyc = dict(library.initial("cyclic"), scene="cyclic", w=W, h=H)  # its own view
    status, headers, body = get(base, "/api/render", buffer="painter_error", **cyc)
    painter = direct(library, algorithm="painter", **cyc)
    zbuffer = direct(library, **cyc)
    differ = (painter.face_id != zbuffer.face_id) & ((painter.face_id >= 0) |
                                                    (zbuffer.face_id >= 0))
    assert differ.sum() > 0
    assert json.loads(headers["x-hsr-stats"])["pixels_differing_from_zbuffer"] == differ.sum()
    red = png(body)
    assert np.array_equal((red[..., 0] == 255) & (red[..., 1] == 40), differ)


@pytest.mark.parametrize("params, message", [
    ({"foo": "1"}, "unknown parameter 'foo'"),
    ({"algorithm": "magic"}, "algorithm must be one of"),
    ({"w": "0"}, "w must be in"),
    ({"w": "4096", "h": "4096"}, "at most"),
    ({"el": "95"}, "el must be in"),
    ({"az": "nan"}, "az must be in"),
    ({"dist": "1e400"}, "dist must be in"),
    ({"depth_test": "maybe"}, "depth_test must be 0 or 1"),
    ({"scene": "../../etc/passwd"}, "scene must be one of"),
    ({"w": "x" * 100}, "too long"),
    ({"algorithm": "painter", "depth_test": "0"}, "painter draws the nearest surface"),
])
def test_bad_parameters_are_400_with_one_line_json(server, params, message):
    base, _ = server
    status, headers, body = get(base, "/api/render", **params)
    assert status == 400 and headers["content-type"] == "application/json"
    error = json.loads(body)["error"]
    assert message in error and "\n" not in error


def test_other_bad_requests(server):
    base, _ = server
    url = f"{base}/api/render?w=10&w=20"
    try:
        urllib.request.urlopen(url, timeout=30)
        raise AssertionError("a repeated parameter was accepted")
    except urllib.error.HTTPError as exc:
        assert exc.code == 400 and "twice" in json.loads(exc.read())["error"]
    for path in ("/api/nothing", "/static/../../pyproject.toml", "/etc/passwd"):
        status, _, body = get(base, path)
        assert status == 404 and "error" in json.loads(body)
    assert get(base, "/api/pick", x=W, y=0, w=W, h=H)[0] == 400
    assert get(base, "/api/options", scene="cubes")[0] == 400
    assert get(base, "/api/explain", view="nonsense")[0] == 400


def test_twenty_concurrent_requests(server):
    base, library = server
    views = [{"scene": "cubes", "w": W, "h": H, "az": 10 * k, "format": "png"}
             for k in range(20)]
    with ThreadPoolExecutor(20) as pool:
        results = list(pool.map(lambda v: get(base, "/api/render", **v), views))
    assert all(status == 200 for status, _, _ in results)
    for view, (_, _, body) in zip(views[::7], results[::7]):
        params = {k: v for k, v in view.items() if k != "format"}
        assert np.array_equal(png(body), direct(library, **params).color)


def test_pick_tells_what_is_at_a_pixel(server):
    base, library = server
    view = {"scene": "spot.obj", "w": W, "h": H}
    frame = direct(library, **view)
    ys, xs = np.nonzero(frame.face_id >= 0)
    y, x = int(ys[len(ys) // 2]), int(xs[len(xs) // 2])
    status, _, body = get(base, "/api/pick", x=x, y=y, **view)
    assert status == 200
    p = json.loads(body)
    assert p["face_id"] == frame.face_id[y, x] and p["object"] == "spot.obj"
    assert p["window_depth"] == pytest.approx(float(frame.depth[y, x]))
    assert p["eye_depth"] == pytest.approx(float(frame.eye_depth[y, x]), rel=1e-6)
    assert set(p["algorithms"]) == set(CONTROLS["algorithm"][2])
    assert all(r.get("face_id") == p["face_id"] for r in p["algorithms"].values())
    bg = json.loads(get(base, "/api/pick", x=0, y=0, **view)[2])
    assert bg["face_id"] == -1 and bg["object"] is None


def test_the_copy_command_draws_the_same_image(server, tmp_path, monkeypatch):
    """The `hsr render` line and the Python call the page offers reproduce the view
    exactly."""
    base, library = server
    view = {"scene": "spot.obj", "w": W, "h": H, "az": 71.5, "el": 12.25, "dist": 0.8,
            "cull": "back", "depth_func": "lequal", "fog": "linear", "shading": "gouraud"}
    _, _, body = get(base, "/api/render", **view)
    status, _, text = get(base, "/api/command", **view)
    assert status == 200
    command = json.loads(text)
    monkeypatch.chdir(tmp_path)
    args = shlex.split(command["command"])
    assert args[:2] == ["hsr", "render"]
    assert main(args[1:] + ["--quiet"]) == 0
    assert np.array_equal(np.asarray(Image.open(tmp_path / "view.png").convert("RGB")),
                          png(body))
    space = {}
    exec(command["python"], space)
    assert np.array_equal(space["frame"].color, png(body))


def test_options_and_explain(server):
    base, library = server
    status, _, body = get(base, "/api/options")
    options = json.loads(body)
    assert options["scenes"] == library.names and "painter_error" in options["buffers"]
    assert {d["name"] for d in options["demos"]} >= {"depth test off", "painter's cycle"}
    status, headers, body = get(base, "/api/render", scene="cubes", w=W, h=H,
                                format="jpeg", quality=90)
    assert status == 200 and headers["content-type"] == "image/jpeg"
    lossy = np.asarray(Image.open(io.BytesIO(body)).convert("RGB")).astype(int)
    assert np.abs(lossy - direct(library, scene="cubes", w=W, h=H).color).mean() < 4
    status, headers, body = get(base, "/api/explain", view="depth", scene="cubes", w=W, h=H)
    assert status == 200 and headers["content-type"] == "image/png"
    assert png(body).shape[1] > W


def test_cli_view_refuses_a_busy_port(capsys):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        assert main(["view", "--no-browser", "--port", str(port)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("hsr: error: cannot listen") and "\n" not in err


def _chromium():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1400,900"):
        options.add_argument(arg)
    options.binary_location = shutil.which("chromium") or "/usr/bin/chromium"
    return webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=options)


def test_the_page_in_a_real_browser(server, tmp_path, models_dir):
    """Load the page, wait for a frame, drag (the image changes), switch to the painter's
    algorithm on the cyclic scene (the error count shows), click a pixel (the face id is
    hsr.render's there), and measure the frames per second while dragging the bunny at
    800 x 600 (printed; docs/performance.md reports it)."""
    try:
        from selenium.webdriver.common.action_chains import ActionChains
        from selenium.webdriver.common.by import By
        from selenium.webdriver.support.ui import Select, WebDriverWait
    except ImportError:
        need(False, "selenium is not installed (pip install -e '.[test]')")
    need(shutil.which("chromium") is not None and shutil.which("chromedriver") is not None,
         "Chromium / ChromeDriver not installed (apt-get install chromium chromium-driver)")
    base, library = server
    driver = _chromium()
    try:
        driver.get(base + "/")
        wait = WebDriverWait(driver, 60)
        # "|| 0": before the page's script has run, window.hsr is undefined (None here).
        frames = "return (window.hsr && window.hsr.frames) || 0"
        wait.until(lambda d: d.execute_script(frames) >= 1)
        img = driver.find_element(By.ID, "frame")
        first = img.get_attribute("src")
        frames = driver.execute_script("return window.hsr.frames")
        ActionChains(driver).move_to_element(img).click_and_hold().move_by_offset(
            80, 20).move_by_offset(40, 10).release().perform()
        wait.until(lambda d: d.execute_script("return window.hsr.frames") > frames + 1)
        assert img.get_attribute("src") != first
        state = driver.execute_script("return Object.assign({}, window.hsr.state)")
        assert float(state["az"]) != 35.0

        Select(driver.find_element(By.ID, "c-scene")).select_by_value("cyclic")
        Select(driver.find_element(By.ID, "c-algorithm")).select_by_value("painter")
        wait.until(lambda d: "pixels differing from the z-buffer" in
                   d.find_element(By.ID, "stats").text)
        count = int(driver.find_element(By.ID, "stats").text.split(
            "pixels differing from the z-buffer:")[1].split()[0])
        state = driver.execute_script("return Object.assign({}, window.hsr.state)")
        expected_frame = direct(library, **{k: v for k, v in state.items()})
        zbuffer = direct(library, **dict(state, algorithm="zbuffer"))
        covered = (expected_frame.face_id >= 0) | (zbuffer.face_id >= 0)
        assert count == np.count_nonzero((expected_frame.face_id != zbuffer.face_id) & covered)
        assert count > 0

        # Click the middle of the image: the pick answers with hsr.render's face id.
        w, h = int(state["w"]), int(state["h"])
        ActionChains(driver).move_to_element(img).click().perform()
        wait.until(lambda d: d.execute_script("return window.hsr.lastPick") is not None)
        picked = driver.execute_script("return window.hsr.lastPick")
        assert picked["face_id"] == expected_frame.face_id[picked["y"], picked["x"]]
        assert abs(picked["x"] - w // 2) <= 1 and abs(picked["y"] - h // 2) <= 1
        driver.save_screenshot(str(tmp_path / "viewer.png"))

        # Frames per second while dragging the bunny at 800 x 600 (the page's own count).
        Select(driver.find_element(By.ID, "c-scene")).select_by_value("stanford-bunny.obj")
        Select(driver.find_element(By.ID, "c-algorithm")).select_by_value("zbuffer")
        wait.until(lambda d: d.execute_script("return window.hsr.lastStats.triangles_in")
                   == 69451)
        driver.set_script_timeout(30)
        measured = driver.execute_async_script(
            "window.hsr.drag(3).then(arguments[arguments.length - 1])")
        dragged, seconds = measured["frames"], measured["seconds"]
        print(f"\nbrowser: the bunny at 800 x 600, {dragged} frames in {seconds:.2f} s of "
              f"dragging ({dragged / seconds:.1f} frames/s)")
        assert dragged > 0
    finally:
        driver.quit()
