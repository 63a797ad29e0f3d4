"""The explanation views and the HTML report: each view's numbers against values computed
by hand (or by the reference) on tiny scenes; images of the right size and not blank; the
report loaded in a real browser (Chromium, headless)."""

import os
import shutil

import numpy as np
import pytest
from PIL import Image

import hsr
from conftest import need
from hsr import scenes
from hsr.explain.views import (
    VIEWS,
    depth_step,
    explain,
    linear_z_depths,
    quantize_depth,
    resolvable_depth,
    window_depth,
    ybuffer,
)
from reference import ambiguous_pixels, reference_render, world_triangles

W, H = 96, 72


def two_quads(back_first=True):
    back = hsr.Mesh([[-1.1, -0.9, -6], [1.3, -0.9, -6], [1.3, 1.2, -6], [-1.1, 1.2, -6]],
                    [[0, 1, 2], [0, 2, 3]], face_colors=[[200, 50, 50]] * 2)
    front = hsr.Mesh([[-0.2, -0.3, -4], [0.9, -0.3, -4], [0.9, 0.7, -4], [-0.2, 0.7, -4]],
                     [[0, 1, 2], [0, 2, 3]], face_colors=[[50, 50, 200]] * 2)
    scene = hsr.Scene([back, front] if back_first else [front, back])
    camera = hsr.Camera.look_at((0.05, 0.03, 0), (0.05, 0.03, -1), (0, 1, 0), 50, 0.5, 20)
    return scene, camera


@pytest.mark.parametrize("back_first", [True, False])
def test_overdraw_counts_by_hand(back_first):
    scene, camera = two_quads(back_first)
    result = explain("overdraw", scene, camera, W, H)
    cover = [reference_render(hsr.Scene([inst]), camera, W, H)[0] >= 0
             for inst in scene.instances]
    amb = ambiguous_pixels(scene, camera, W, H)
    n_cover = cover[0].astype(int) + cover[1].astype(int)
    frame = hsr.render(scene, camera, W, H, counts=True)
    tested, written = frame.fragments.count_tested, frame.fragments.count_written
    assert (tested[~amb] == n_cover[~amb]).all()
    # Back to front every layer is written; front to back the far quad fails the test
    # where the near one covers it.
    expected_written = n_cover if back_first else np.minimum(n_cover, 1)
    assert (written[~amb] == expected_written[~amb]).all()
    assert result.numbers["max_tested_per_pixel"] == 2
    assert result.numbers["max_written_per_pixel"] == (2 if back_first else 1)
    assert result.numbers["fragments_tested"] == int(tested.sum())
    assert abs(result.numbers["fragments_tested"] - n_cover.sum()) <= amb.sum()


def test_linear_z_numbers_and_flips():
    r = explain("linear-z", *scenes.get("cubes"), W, H)
    assert r.numbers["midpoint_z_linear"] == pytest.approx(26 / 3)
    assert r.numbers["midpoint_z_from_1_over_z"] == pytest.approx(6.0)
    assert r.numbers["pixels_flipped"] == 0  # well separated cubes: z or 1/z, same order
    # A long floor from z = -1 to -60 and a small card standing on it, just behind the
    # floor's true surface along the view: interpolating z (too far in the middle of the
    # floor's screen span) lets the card through.
    floor = hsr.Mesh([[-3, -1, -1], [3, -1, -1], [3, -1, -60], [-3, -1, -60]],
                     [[0, 1, 2], [0, 2, 3]])
    card = hsr.Mesh([[-0.5, -1.3, -8.3], [0.5, -1.3, -8.3], [0.5, -0.98, -8.3],
                     [-0.5, -0.98, -8.3]], [[0, 1, 2], [0, 2, 3]])
    camera = hsr.Camera.look_at((0, 1, 0), (0, -1, -10), (0, 1, 0), 60, 0.5, 100)
    r = explain("linear-z", hsr.Scene([floor, card]), camera, W, H)
    assert r.numbers["pixels_flipped"] > 0


def test_linear_z_depths_are_eye_depths_normalised():
    scene, camera = scenes.get("cubes")
    frame = hsr.render(scene, camera, W, H)
    screen = frame.fragments.screen
    assert frame.stats["clipped"] == 0  # so each screen triangle has its face's corners
    got = linear_z_depths(screen, camera)
    # eye depth of each corner, computed here from the world position
    tris = world_triangles(scene)[screen.face_id]
    eye = -(tris @ camera.view_matrix[:3, :3].T + camera.view_matrix[:3, 3])[..., 2]
    expected = (eye - camera.near) / (camera.far - camera.near)
    assert np.allclose(got, expected, atol=1e-6)


def test_depth_quantisation_steps():
    assert quantize_depth(0.5, "unorm16") == round(0.5 * 65535) / 65535
    assert depth_step(0.3, "unorm16") == pytest.approx(1 / 65535)
    assert depth_step(0.3, "unorm24") == pytest.approx(1 / 16777215)
    assert depth_step(0.75, "float32") == 2.0 ** -24  # [0.5, 1): 23-bit mantissa steps
    assert depth_step(0.001, "float32") == 2.0 ** -33  # 2**-10 <= 0.001 < 2**-9
    values = quantize_depth(np.linspace(0, 1, 100001), "unorm16")
    assert len(np.unique(values)) == 65536
    n, f = 0.5, 40.0
    z = np.array([1.0, 5.0, 30.0])
    # Delta z_eye = step / (n f / ((f - n) z^2)), written out:
    assert np.allclose(resolvable_depth(z, n, f, "unorm24"),
                       (1 / 16777215) * (f - n) * z ** 2 / (f * n))
    assert (resolvable_depth(z[1:], n, f, "float32-reversed")
            < resolvable_depth(z[1:], n, f, "float32")).all()
    assert window_depth(n, n, f) == pytest.approx(0) and window_depth(f, n, f) == pytest.approx(1)
    assert window_depth(n, n, f, True) == pytest.approx(1)
    # orthographic: depth is linear, so one step is the same eye distance everywhere
    assert np.allclose(resolvable_depth(z, n, f, "unorm16", orthographic=True),
                       (f - n) / 65535)


def test_zfighting_gets_worse_with_fewer_bits_and_a_closer_near_plane():
    r = explain("precision", *scenes.get("cubes"), 160, 120)
    lost = r.numbers["zfight_lower_visible"]
    for near in (0.01, 1.0):
        assert lost[f"unorm16@near={near}"] >= lost[f"unorm24@near={near}"] >= \
            lost[f"float32-reversed@near={near}"]
        assert lost[f"float32-reversed@near={near}"] == 0.0
    assert lost["unorm16@near=0.01"] > lost["unorm16@near=1.0"] > 0
    assert lost["unorm24@near=0.01"] > 0 == lost["unorm24@near=1.0"]
    # a far plane 100 times farther changes little; the near plane is what matters
    assert lost["unorm16@near=1.0"] <= lost["unorm16@near=1.0,far=30000"] \
        < 2 * lost["unorm16@near=1.0"]


def test_ybuffer_by_hand():
    colors, ybuf = ybuffer()
    # x = 50: only the red segment (20, 34) -> (744, 400)
    assert ybuf[50] == pytest.approx(34 + (50 - 20) / 724 * 366)
    assert colors[50].tolist() == [255, 0, 0]
    # x = 400: red 226.1, green 404.6, blue 393.3: green is nearest
    assert ybuf[400] == pytest.approx(434 + (400 - 120) / 324 * (400 - 434))
    assert colors[400].tolist() == [0, 255, 0]
    # x = 500: red 276.6, blue 293.6 (green ended at 444)
    assert colors[500].tolist() == [0, 0, 255]
    assert not np.isfinite(ybuf[10]) and not np.isfinite(ybuf[790])
    r = explain("ybuffer", *scenes.get("cubes"))
    assert r.image.shape[1] == 800


def test_culling_counts_by_hand():
    scene, camera = scenes.get("cubes")
    r = explain("culling", scene, camera, W, H)
    tris = world_triangles(scene)
    vp = camera.projection_matrix(W / H) @ camera.view_matrix
    clip = np.concatenate([tris, np.ones((len(tris), 3, 1))], axis=2) @ vp.T
    xy = clip[..., :2] / clip[..., 3:]
    area = ((xy[:, 1, 0] - xy[:, 0, 0]) * (xy[:, 2, 1] - xy[:, 0, 1])
            - (xy[:, 2, 0] - xy[:, 0, 0]) * (xy[:, 1, 1] - xy[:, 0, 1]))
    back = int((area < 0).sum())
    assert r.numbers["back"]["culled"] == back
    assert r.numbers["front"]["culled"] == len(tris) - back
    assert r.numbers["front_and_back"]["culled"] == len(tris)
    assert r.numbers["none"]["culled"] == 0


def test_depth_view_numbers():
    scene, camera = scenes.get("cubes")
    r = explain("depth", scene, camera, W, H)
    frame = hsr.render(scene, camera, W, H)
    covered = frame.face_id >= 0
    d = frame.depth[covered].astype(float)
    assert r.numbers["window_depth_min"] == pytest.approx(d.min())
    n, f = camera.near, camera.far
    eye = f * n / (f - d * (f - n))  # inverse of d = f (z - n) / (z (f - n))
    assert r.numbers["eye_depth_min"] == pytest.approx(eye.min(), rel=1e-6)
    assert r.numbers["eye_depth_max"] == pytest.approx(eye.max(), rel=1e-6)


def test_painter_view_counts_and_animation(tmp_path):
    scene, camera = scenes.get("cyclic")
    r = explain("painter", scene, camera, W, H)
    painter = hsr.render(scene, camera, W, H, algorithm="painter")
    assert r.numbers["pixels_wrong"] == painter.stats["pixels_wrong"] > 0
    assert r.numbers["offending_triangles"] >= 1
    assert len(r.frames) == r.numbers["animation_frames"] >= 2
    # the last frame has painted every triangle: the painter's picture
    last = r.frames[-1][-H:]
    assert (last == painter.color).all()
    r.save(tmp_path / "p.gif")
    gif = Image.open(tmp_path / "p.gif")
    assert gif.n_frames == len(r.frames)


@pytest.mark.parametrize("view", ["newell", "bsp"])
def test_split_views_on_a_visibility_cycle(view):
    scene, camera = scenes.get("cyclic")
    r = explain(view, scene, camera, W, H)
    assert r.numbers["pixels_differing"] == 0  # exact, unlike the painter
    assert r.numbers["polygons"] > 3 and r.numbers["splits"] > 0  # the cycle was cut
    assert len(r.frames) == r.numbers["animation_frames"] == r.numbers["polygons"]
    assert (r.frames[-1][-H:] == hsr.render(scene, camera, W, H, algorithm=view).color).all()


@pytest.mark.parametrize("view", list(VIEWS))
def test_every_view_has_a_picture(view, tmp_path):
    scene, camera = scenes.get("cubes")
    r = explain(view, scene, camera, W, H)
    assert r.image.dtype == np.uint8 and r.image.ndim == 3
    if view != "ybuffer":
        assert r.image.shape[1] >= 2 * W  # at least two panels side by side
    assert len(np.unique(r.image.reshape(-1, 3), axis=0)) >= 5
    assert r.text and r.numbers
    r.save(tmp_path / "v.png")
    assert Image.open(tmp_path / "v.png").size == (r.image.shape[1], r.image.shape[0])


def test_cli_explain_and_report(tmp_path):
    from hsr.cli import main

    assert main(["explain", "overdraw", "--size", "64x48", "--quiet",
                 "-o", str(tmp_path / "o.png")]) == 0
    assert Image.open(tmp_path / "o.png").size[0] >= 128
    assert main(["explain", "painter", "--scene", "cyclic", "--size", "64x48", "--quiet",
                 "-o", str(tmp_path / "p.gif")]) == 0
    assert Image.open(tmp_path / "p.gif").n_frames > 1
    assert main(["explain", "bogus"]) == 2
    assert main(["report", "--size", "64x48", "--quiet", "-o", str(tmp_path / "r.html"),
                 "--algorithms", "zbuffer,painter"]) == 0
    assert main(["report", "--algorithms", "warp", "-o", str(tmp_path / "x.html")]) == 2


def _chromium():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"):
        options.add_argument(arg)
    options.binary_location = shutil.which("chromium") or "/usr/bin/chromium"
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service(shutil.which("chromedriver")), options=options)


def test_report_in_a_real_browser(tmp_path, models_dir):
    try:
        import selenium  # noqa: F401
    except ImportError:
        need(False, "selenium is not installed (pip install -e '.[test]')")
    need(shutil.which("chromium") is not None and shutil.which("chromedriver") is not None,
         "Chromium / ChromeDriver not installed (apt-get install chromium chromium-driver)")
    from hsr.explain.report import write_report

    mesh = hsr.load(os.path.join(models_dir, "spot.obj"))
    camera = hsr.Camera.frame(mesh.bounds())
    page = tmp_path / "report.html"
    write_report(page, hsr.Scene([mesh]), camera, "spot", width=200, height=150)
    text = page.read_text()
    assert "<script" not in text and "http" not in text.split("</style>")[1]  # self-contained
    driver = _chromium()
    try:
        for size in ((390, 844), (1366, 900)):  # a phone and a laptop
            driver.set_window_size(*size)
            driver.get(page.as_uri())
            images = driver.execute_script(
                "return Array.from(document.images).map(i => [i.complete, i.naturalWidth, "
                "i.getBoundingClientRect().right])")
            # the main image, every view, and the animations (painter, newell, bsp)
            assert len(images) == text.count("<img") == 1 + len(VIEWS) + 3
            assert all(done and width > 0 for done, width, _ in images), images
            inner = driver.execute_script("return window.innerWidth")
            assert all(right <= inner + 1 for _, _, right in images)  # scaled to fit
            errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
            assert errors == []
            shot = tmp_path / f"shot{size[0]}.png"
            driver.save_screenshot(str(shot))
            pixels = np.asarray(Image.open(shot).convert("RGB"))
            assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 50
    finally:
        driver.quit()
