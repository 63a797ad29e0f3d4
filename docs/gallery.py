"""Every picture of the documentation's gallery, made from the code (never edited by hand).

    python docs/gallery.py [OUT_DIR]            # default: docs/gallery
    python docs/gallery.py --readme docs/img/montage.png   # the README's picture

The docs build runs it (docs/hooks.py) when a picture is missing or older than this
script or hsr's sources, so the gallery always shows what the installed code draws.
Models come from ``../shared/models`` beside the repository; the built-in scenes need
nothing.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
from PIL import Image, ImageDraw

import hsr
from hsr.explain.compare import compare_algorithms, montage
from hsr.explain.views import explain

HERE = os.path.dirname(os.path.abspath(__file__))
MODELS = os.path.join(HERE, "..", "..", "shared", "models")
ALGORITHMS = ("zbuffer", "scanline", "raycast", "painter", "newell", "bsp")
# (file name, caption) of every picture, in page order; docs/gallery.md shows them.
PICTURES = {
    "algorithms.png": "The six algorithms on the cyclic scene (three triangles that overlap "
                      "in a cycle) and where each differs from the z-buffer: only the "
                      "painter's is wrong, and it says where.",
    "models.png": "Every shared model from the fixed three-quarter view (top) and from "
                  "its first look, the view `hsr render MODEL` chooses (bottom).",
    "buffers.png": "One render's buffers: colour, face ids (false colour), eye depth and "
                   "normals (world space, as colour).",
    "appearance.png": "Texture with Gouraud shading, fog, polygon mode `line` and exact "
                      "feature lines.",
    "transparency.png": "Transparency: per-object sorting (wrong where the objects "
                        "interpenetrate) and the exact per-pixel sort.",
    "explain-depth.png": "`hsr explain depth`: window depth as stored and linear eye depth.",
    "explain-overdraw.png": "`hsr explain overdraw`: fragments tested and written per pixel.",
    "explain-painter.png": "`hsr explain painter` on the cyclic scene: the painting order "
                           "and the pixels it gets wrong.",
    "explain-precision.png": "`hsr explain precision`: z-fighting in 16-bit, 24-bit, float "
                             "and reversed-z depth.",
    "explain-culling.png": "`hsr explain culling`: the four glCullFace modes.",
    "prune.png": "`hsr prune`: a housing with a part inside, as rendered, and an x-ray of "
                 "the faces removed (red).",
    "lines.png": "`hsr lines`: spot's silhouettes and creases with the hidden layer "
                 "(dashed grey), and the AS1 assembly from its STEP file: the B-rep's "
                 "own edges and silhouettes.",
}
# matplotlib issues whose figures hsr.mpl redraws (hsr.mpl.examples): mplot3d | hsr.
MPL_ISSUES = ("29060", "23392", "22165", "16071", "9499")
# The views drawn: the issue's own, or one where its failure shows (#16071's own view
# looks straight down the cylinder).
MPL_VIEWS = {"16071": (20, 30)}
for _issue in MPL_ISSUES:
    PICTURES[f"mpl-{_issue}.png"] = (f"matplotlib #{_issue}: mplot3d's figure (left) and the "
                                     f"same code with projection='hsr3d' (right).")


def model(name: str):
    return hsr.load(os.path.join(MODELS, name))


def label(image: np.ndarray, text: str) -> np.ndarray:
    """The image under a one-line caption."""
    h, w = image.shape[:2]
    sheet = Image.new("RGB", (w, h + 18), (24, 24, 24))
    sheet.paste(Image.fromarray(image), (0, 18))
    ImageDraw.Draw(sheet).text((4, 3), text, fill=(235, 235, 235))
    return np.asarray(sheet)


def side_by_side(images: list, gap: int = 4) -> np.ndarray:
    h = max(im.shape[0] for im in images)
    padded = [np.pad(im, ((0, h - im.shape[0]), (0, gap), (0, 0)), constant_values=24)
              for im in images]
    return np.concatenate(padded, axis=1)[:, :-gap]


def algorithms_picture() -> Image.Image:
    scene, camera = hsr.scenes.get("cyclic")
    return montage(compare_algorithms(scene, camera, 200, 150, ALGORITHMS))


def models_picture() -> np.ndarray:
    """Every shared model: the fixed view of hsr.views.default above, hsr.first_look
    (what ``hsr render MODEL`` draws) below."""
    rows = [], []
    for name in sorted(n for n in os.listdir(MODELS) if n.endswith(".obj")):
        mesh = model(name)
        az, el = hsr.best_view(mesh)
        for row, view, text in ((rows[0], hsr.views.DEFAULT_VIEW, "fixed 35,25"),
                                (rows[1], (az, el), f"first look {az:g},{el:g}")):
            frame = hsr.render(mesh, hsr.views.default(mesh, 4 / 3, view=view), 160, 120,
                               light="studio")
            row.append(label(frame.color, f"{name[:-4][:14]}: {text}"))
    top, bottom = side_by_side(rows[0]), side_by_side(rows[1])
    return np.concatenate([top, np.full((4, top.shape[1], 3), 24, np.uint8), bottom])


def buffers_picture() -> np.ndarray:
    bunny = model("stanford-bunny.obj")
    frame = hsr.render(bunny, hsr.first_look(bunny, 4 / 3), 200, 150, light="studio")
    ids = frame.face_id
    rng = np.random.default_rng(0)
    palette = rng.integers(40, 255, (bunny.n_faces, 3), dtype=np.uint8)
    id_image = np.where(ids[..., None] >= 0, palette[np.maximum(ids, 0)], 0).astype(np.uint8)
    eye = frame.eye_depth
    seen = np.isfinite(eye)
    lo, hi = eye[seen].min(), eye[seen].max()
    depth = np.zeros(eye.shape, np.uint8)
    depth[seen] = (255 - 215 * (eye[seen] - lo) / (hi - lo)).astype(np.uint8)
    normals = ((frame.normals + 1) * 127.5).astype(np.uint8) * seen[..., None]
    return side_by_side([label(frame.color, "color"), label(id_image, "face_id"),
                         label(np.repeat(depth[..., None], 3, -1), "eye_depth"),
                         label(normals, "normals")])


def appearance_picture() -> np.ndarray:
    head = model("african_head.obj")
    head.texture = os.path.join(MODELS, "african_head_diffuse.tga")
    cam = hsr.views.framed(head.bounds(), hsr.views.direction(20, 10))
    textured = hsr.render(head, cam, 200, 200, shading="gouraud", texture_filter="bilinear")
    scene, camera = hsr.scenes.get("cubes")
    fog = hsr.render(scene, camera, 267, 200, background=(200, 200, 210),
                     fog=hsr.Fog("linear", start=3, end=12, color=(200, 200, 210)))
    wire = hsr.render(scene, camera, 267, 200, polygon_mode="line")
    spot = model("spot.obj")
    lines = hsr.render(spot, hsr.first_look(spot, 4 / 3), 267, 200, background=(255,) * 3,
                       hidden_line=hsr.HiddenLine(edges="feature"))
    return side_by_side([label(textured.color, "texture, gouraud"),
                         label(fog.color, "fog linear 3..12"),
                         label(wire.color, "polygon mode line"),
                         label(lines.color, "feature lines")])


def transparency_picture() -> np.ndarray:
    scene, camera = hsr.scenes.get("glass")
    by_object = hsr.render(scene, camera, 267, 200)
    exact = hsr.render(scene, camera, 267, 200, transparency="exact")
    return side_by_side([label(by_object.color, "transparency=object"),
                         label(exact.color, "transparency=exact")])


def explain_picture(view: str) -> np.ndarray:
    if view in ("painter",):
        scene, camera = hsr.scenes.get("cyclic")
    elif view == "culling":
        scene = model("spot.obj")
        camera = hsr.views.default(scene, 4 / 3)
    else:
        scene, camera = hsr.scenes.get("cubes")
    return explain(view, scene, camera, 240, 180).image


def prune_picture() -> np.ndarray:
    import trimesh

    from hsr.visibility import subset_scene

    housing = trimesh.creation.box(extents=(2, 1.2, 1.2))
    inner = trimesh.creation.icosphere(subdivisions=3, radius=0.45)
    shaft = trimesh.creation.cylinder(radius=0.15, height=2.4, sections=24)
    shaft.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, (0, 1, 0)))
    scene = hsr.Scene().add(housing, name="housing").add(inner, name="part")
    scene.add(shaft, name="shaft")
    _, kept = hsr.prune(scene, "sphere:48", 256)
    keep = np.zeros(scene.n_faces, dtype=bool)
    keep[kept] = True
    camera = hsr.views.default(scene, 1.0)
    before = hsr.render(scene, camera, 240, 240, light="studio").color
    grey = hsr.render(subset_scene(scene, keep), camera, 240, 240, light="studio")
    red = hsr.render(subset_scene(scene, ~keep), camera, 240, 240, light="studio",
                     depth_test=False)
    xray = (grey.color * 0.45).astype(np.uint8)
    mask = red.face_id >= 0
    shade = red.color[..., 1:2].astype(float) / 255.0
    xray[mask] = (np.concatenate([0.55 + 0.45 * shade, 0.1 * shade, 0.1 * shade], axis=-1)
                  * 255).astype(np.uint8)[mask]
    return side_by_side([label(before, "as rendered"),
                         label(xray, f"removed: {int((~keep).sum())} of {keep.size} faces")])


def mpl_picture(issue: str) -> np.ndarray:
    """mplot3d's figure of a matplotlib issue's code beside hsr.mpl's, each labelled."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from hsr.mpl.examples import CASES

    images = []
    for projection, caption in (("3d", "mplot3d"), ("hsr3d", "hsr.mpl")):
        fig, ax = CASES[issue](plt, projection)
        if issue in MPL_VIEWS:
            ax.view_init(*MPL_VIEWS[issue])
        fig.set_dpi(80)
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=80)
        plt.close(fig)
        image = np.asarray(Image.open(buf).convert("RGB"))
        images.append(label(image, caption))
    return side_by_side(images)


def drawing_picture(drawing, size=(520, 390)) -> np.ndarray:
    """A line drawing on white: hidden parts grey (dashed in the SVG), visible black."""
    sheet = Image.new("RGB", (drawing.width, drawing.height), (255, 255, 255))
    pen = ImageDraw.Draw(sheet)
    for lines, color in ((drawing.hidden_polylines, (170, 170, 170)),
                         (drawing.visible_polylines, (0, 0, 0))):
        for line in lines:
            pen.line([tuple(p) for p in line], fill=color, width=2)
    return np.asarray(sheet.resize(size, Image.LANCZOS))


def lines_picture() -> np.ndarray:
    import gzip
    import tempfile

    from hsr.lines.raster import HiddenLine

    spot = model("spot.obj")
    spot_lines = hsr.hidden_lines(spot, hsr.first_look(spot, 4 / 3), 1040, 780,
                                  HiddenLine(edges="feature"))
    images = [label(drawing_picture(spot_lines), "spot.obj")]
    step = os.path.join(HERE, "..", "tests", "data", "cad", "as1-oc-214.stp.gz")
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "as1-oc-214.stp")
        with gzip.open(step, "rb") as src, open(path, "wb") as dst:
            dst.write(src.read())
        as1 = hsr.load(path)  # needs the [cad] extra
    as1_lines = hsr.hidden_lines(as1, hsr.first_look(as1, 4 / 3), 1040, 780,
                                 HiddenLine(edges="feature"))
    images.append(label(drawing_picture(as1_lines), "as1-oc-214.stp (STEP)"))
    return side_by_side(images)


def make(name: str):
    if name.startswith("mpl-"):
        return mpl_picture(name[len("mpl-"):-len(".png")])
    if name == "algorithms.png":
        return algorithms_picture()
    if name.startswith("explain-"):
        return explain_picture(name[len("explain-"):-len(".png")])
    return {"models.png": models_picture, "buffers.png": buffers_picture,
            "appearance.png": appearance_picture, "transparency.png": transparency_picture,
            "prune.png": prune_picture, "lines.png": lines_picture}[name]()


def save(image, path: str) -> None:
    image = image if isinstance(image, Image.Image) else Image.fromarray(image)
    tmp = path + ".tmp.png"
    image.save(tmp, optimize=True)
    os.replace(tmp, path)


def readme_montage(path: str) -> None:
    """The README's picture: the six algorithms, an explanation view and the viewer."""
    top = np.asarray(algorithms_picture().convert("RGB"))
    explained = explain_picture("painter")
    viewer = Image.open(os.path.join(HERE, "viewer.png")).convert("RGB")
    height = explained.shape[0]
    viewer = np.asarray(viewer.resize((round(viewer.width * height / viewer.height), height)))
    bottom = side_by_side([explained, viewer])
    width = max(top.shape[1], bottom.shape[1])
    rows = [np.pad(im, ((0, 4), (0, width - im.shape[1]), (0, 0)), constant_values=24)
            for im in (top, bottom)]
    save(np.concatenate(rows, axis=0)[:-4], path)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?", default=os.path.join(HERE, "gallery"))
    parser.add_argument("--readme", metavar="PNG", help="write the README's montage instead")
    args = parser.parse_args(argv)
    if args.readme:
        readme_montage(args.readme)
        return 0
    os.makedirs(args.out, exist_ok=True)
    start = time.perf_counter()
    for k, name in enumerate(PICTURES, 1):
        # The build waits minutes here (the first run compiles the kernels): say why.
        print(f"gallery: {k}/{len(PICTURES)} {name} ({time.perf_counter() - start:.0f} s)",
              file=sys.stderr, flush=True)
        save(make(name), os.path.join(args.out, name))
    return 0


if __name__ == "__main__":
    sys.exit(main())
