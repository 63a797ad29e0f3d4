"""The ``hsr`` command line. Bad input ends with one line on stderr and exit code 2."""

from __future__ import annotations

import argparse
import functools
import math
import os
import sys

import numpy as np

from .errors import HsrError
from .scene.mesh import MAX_COORDINATE

EXIT_USAGE = 2


class CliError(HsrError):
    """A command-line argument is malformed."""


class _Parser(argparse.ArgumentParser):
    """argparse, but errors are one line (no usage block) and raise instead of exiting,
    so every bad input goes through the same reporting path."""

    def error(self, message):
        raise CliError(message)


class _Help(argparse.HelpFormatter):
    """Help that states each option's default (where it has one worth stating)."""

    def _get_help_string(self, action):
        text = action.help or ""
        if ("default" in text or not action.option_strings
                or action.default in (None, False, [], argparse.SUPPRESS)):
            return text
        return text + " (default: %(default)s)"


def _floats(text: str, count: int, what: str) -> tuple:
    parts = text.replace(" ", "").split(",")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        raise CliError(f"{what} must be {count} comma-separated numbers, got {text!r}") from None
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise CliError(f"{what} must be {count} finite comma-separated numbers, got {text!r}")
    if any(abs(v) > MAX_COORDINATE for v in values):
        raise CliError(f"{what} values must be within +-{MAX_COORDINATE:g}, got {text!r}")
    return values


def _color(text: str, what: str) -> tuple:
    """An r,g,b colour with components in 0..255."""
    color = _floats(text, 3, what)
    if not all(0 <= c <= 255 for c in color):
        raise CliError(f"{what} values must be in 0..255, got {text!r}")
    return tuple(int(c) for c in color)


def _size(text: str, option: str = "--size") -> tuple[int, int]:
    """WxH, each side in 1..MAX_SIZE, checked here so the error names the option (the
    size is used for the aspect ratio before any render sees it)."""
    from .geometry.viewport import MAX_SIZE

    parts = text.lower().split("x")
    try:
        width, height = (int(p) for p in parts)
    except ValueError:
        raise CliError(f"{option} must look like 800x600, got {text!r}") from None
    if not (0 < width <= MAX_SIZE and 0 < height <= MAX_SIZE):
        raise CliError(f"{option} sides must be in 1..{MAX_SIZE}, got {text!r}")
    return width, height


def _check_lens(args) -> None:
    """--fov, --near, --far and --ortho on their own, before any camera is framed from
    them, so a bad value is named (not blamed on the framing)."""
    for name, value in (("--fov", args.fov), ("--near", args.near), ("--far", args.far),
                        ("--ortho", args.ortho)):
        if value is not None and not (math.isfinite(value) and abs(value) <= MAX_COORDINATE):
            raise CliError(f"{name} must be a finite number within +-{MAX_COORDINATE:g}, "
                           f"got {value}")
    if not 0.0 < args.fov < 180.0:
        raise CliError(f"--fov must be in (0, 180) degrees, got {args.fov:g}")
    if args.ortho is not None and args.ortho <= 0.0:
        raise CliError(f"--ortho (the visible height) must be > 0, got {args.ortho:g}")
    if args.ortho is None:
        for name, value in (("--near", args.near), ("--far", args.far)):
            if value is not None and value <= 0.0:
                raise CliError(f"{name} must be > 0 for a perspective camera (with --ortho "
                               f"it may be negative), got {value:g}")
    if args.near is not None and args.far is not None and args.far <= args.near:
        raise CliError(f"--far ({args.far:g}) must be greater than --near ({args.near:g})")


def _add_scene_args(p, SCENES, CullMode, DepthFunc, FrontFace, SHADING_MODES):
    """Arguments shared by every command that renders, in groups: scene, camera, depth
    state, culling and polygons, appearance, run."""
    from .appearance.shading import LIGHTS

    p.add_argument("models", nargs="*", metavar="MODEL", help="mesh files (OBJ, PLY, STL, "
                   "OFF, glTF/GLB: one object per node), drawn in order")
    g = p.add_argument_group("scene")
    g.add_argument("--scene", default="cubes", choices=list(SCENES),
                   help="built-in scene when no MODEL is given (default %(default)s)")
    g.add_argument("--opacity", metavar="A[,A...]",
                   help="opacity per MODEL (or one for all), 0..1; < 1 is blended")
    g = p.add_argument_group("camera")
    g.add_argument("--size", help="WxH in pixels (default: the --camera file's, else 800x600)")
    g.add_argument("--view", dest="view_from", metavar="AZ,EL", help="frame the model from "
                   "azimuth AZ (degrees from +Z towards +X) and elevation EL (degrees up) "
                   "(default for MODELs: 35,25, a three-quarter view from above; built-in "
                   "scenes: their own camera)")
    g.add_argument("--eye", help="camera position x,y,z (default: frame the model)")
    g.add_argument("--target", help="point looked at x,y,z (default: centre of the model)")
    g.add_argument("--up", default="0,1,0", help="up vector x,y,z (default %(default)s)")
    g.add_argument("--camera", metavar="FILE[:INDEX]", help="camera INDEX (default 0) of a "
                   "NeRF transforms.json or a COLMAP text model folder")
    g.add_argument("--fov", type=float, default=45.0, help="vertical field of view, degrees")
    g.add_argument("--near", type=float, help="near plane distance (default: hug the model)")
    g.add_argument("--far", type=float, help="far plane distance (default: hug the model)")
    g.add_argument("--ortho", type=float, metavar="HEIGHT",
                   help="orthographic projection showing HEIGHT world units vertically")
    g = p.add_argument_group("depth state")
    g.add_argument("--depth-func", default="less", choices=[m.value for m in DepthFunc],
                   help="glDepthFunc")
    g.add_argument("--no-depth-test", action="store_true", help="glDisable(GL_DEPTH_TEST)")
    g.add_argument("--no-depth-write", action="store_true", help="glDepthMask(GL_FALSE)")
    g.add_argument("--clear-depth", type=float, default=1.0, help="glClearDepth value")
    g.add_argument("--depth-range", default="0,1", help="glDepthRange near,far")
    g = p.add_argument_group("culling and polygons")
    g.add_argument("--cull", default="none", choices=[m.value for m in CullMode],
                   help="glCullFace")
    g.add_argument("--front-face", default="ccw", choices=[m.value for m in FrontFace],
                   help="glFrontFace")
    g.add_argument("--polygon-mode", default="fill", choices=["fill", "line", "point"],
                   help="glPolygonMode: line draws every edge, visible and hidden")
    g.add_argument("--polygon-offset", metavar="FACTOR,UNITS",
                   help="glPolygonOffset for filled triangles")
    g = p.add_argument_group("appearance")
    g.add_argument("--shading", default="flat", choices=list(SHADING_MODES),
                   help="how visible faces are coloured")
    g.add_argument("--light", choices=list(LIGHTS),
                   help="studio: a key light from above-left-front and a fill, so shapes "
                   "read; headlight: one light along the view, the textbooks' (default: "
                   "studio for MODELs, headlight for built-in scenes, as the seeds draw them)")
    g.add_argument("--texture", action="append", default=[], metavar="[MODEL=]IMAGE",
                   help="diffuse texture for MODEL (or for the one MODEL given); the MODEL "
                   "needs texture coordinates; repeatable, once per MODEL")
    g.add_argument("--no-texture", action="store_true", help="ignore textures")
    g.add_argument("--texture-filter", default="bilinear", choices=["nearest", "bilinear"],
                   help="GL_NEAREST or GL_LINEAR")
    g.add_argument("--texture-wrap", default="repeat", choices=["repeat", "clamp"],
                   help="GL_REPEAT or GL_CLAMP_TO_EDGE")
    g.add_argument("--fog", metavar="MODE:PARAMS",
                   help="depth cueing: linear:START,END, exp:DENSITY or exp2:DENSITY")
    g.add_argument("--fog-color", default="128,128,128", help="fog colour r,g,b (0-255)")
    g.add_argument("--fog-distance", default="radial", choices=["radial", "plane"],
                   help="eye distance (radial) or |z_eye| (plane)")
    g.add_argument("--background", default="0,0,0", help="background colour r,g,b (0-255)")
    g = p.add_argument_group("run")
    g.add_argument("--threads", type=int, help="threads for the kernels (default: all cores)")
    g.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="algorithm option, e.g. accel=none (raycast); repeatable")
    g.add_argument("--quiet", action="store_true", help="print nothing on success")


def build_parser() -> argparse.ArgumentParser:
    from .algorithms import ALGORITHMS
    from .appearance.shading import SHADING_MODES
    from .geometry.state import CullMode, DepthFunc, FrontFace
    from .scene.builtin import SCENES

    shared = (SCENES, CullMode, DepthFunc, FrontFace, SHADING_MODES)
    parser = _Parser(prog="hsr", description="Hidden-surface removal: render meshes headless.")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument("--version", action="store_true", help="print hsr's version")
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    # Every option's help ends with its default.
    sub.add_parser = functools.partial(sub.add_parser, formatter_class=_Help)
    r = sub.add_parser("render", help="render meshes (or a built-in scene) to an image",
                       description="Render MODEL files (OBJ, PLY, STL, OFF, glTF) as one scene, "
                       "or a built-in scene when no MODEL is given.")
    _add_scene_args(r, *shared)
    rv = r.add_argument_group("visibility")
    rv.add_argument("--algorithm", default="zbuffer", choices=sorted(ALGORITHMS),
                   help="visibility algorithm")
    rv.add_argument("--occlusion-cull", action="store_true",
                   help="skip objects hidden behind nearer ones (same result, less work)")
    rv.add_argument("--transparency", default="object", choices=["object", "exact"],
                   help="order transparent objects per object (painter's) or per fragment")
    rl = r.add_argument_group("lines")
    rl.add_argument("--svg", help="with --lines: the exact visible edges as SVG; with "
                   "--algorithm bsp or newell: the ordered polygons (exact, no rasterization)")
    rl.add_argument("--lines", action="store_true",
                   help="--svg draws visible edges, cut exactly where they become hidden")
    rl.add_argument("--hidden-layer", action="store_true",
                   help="--svg --lines also draws the hidden parts, dashed")
    rl.add_argument("--hidden-line", action="store_true",
                   help="draw only visible edges (depth test against the polygon-offset fill)")
    rl.add_argument("--edges", default="all", choices=["all", "feature"],
                   help="edges for --hidden-line and --lines: all, or feature edges "
                   "(silhouettes, creases, boundaries)")
    rl.add_argument("--crease-angle", type=float, default=30.0,
                   help="feature edges: creases sharper than this many degrees")
    rl.add_argument("--line-color", help="line colour r,g,b (default: contrast with background)")
    rl.add_argument("--hidden-line-fill", default="background", choices=["background", "shaded"],
                   help="what --hidden-line draws under the edges")
    ro = r.add_argument_group("output")
    ro.add_argument("-o", "--output", help="colour image (default render.png; with --svg and "
                   "no -o, only the SVG is written)")
    ro.add_argument("--depth-out", help="write a depth buffer (.npy or .exr float32, or 16-bit "
                    ".png)")
    ro.add_argument("--depth-kind", default="window", choices=["window", "eye", "distance"],
                   help="window depth (0..1), eye depth or distance from the eye in world "
                        "units (16-bit PNG: 1/1000 units) (default %(default)s)")
    ro.add_argument("--orbit", type=int, metavar="N", help="N views around the model at equal "
                   "azimuth steps (elevation 20 degrees, or --view AZ,EL for the first): "
                   "OUTPUT_000.png ... (and likewise the buffer outputs)")
    ro.add_argument("--normals-out", help="write world-space normals (.npy or .exr float32, or "
                    "8-bit .png)")
    ro.add_argument("--ids-out", help="write the face-id buffer (.npy int32, -1 = background)")
    ro.add_argument("--error-map", help="write where the result differs from the z-buffer "
                   "(red) as a PNG")
    c = sub.add_parser("compare", help="render one scene with every algorithm and compare",
                       description="Render the scene with each algorithm and print time, "
                       "agreement with the z-buffer and algorithm-specific counts.")
    _add_scene_args(c, *shared)
    c.add_argument("--algorithms", default=",".join(ALGORITHMS),
                   help="comma-separated algorithms (default: all: %(default)s)")
    c.add_argument("--montage", "-o", "--output", dest="montage",
                   help="write the images side by side with difference maps (PNG)")
    from .explain.views import VIEWS

    e = sub.add_parser("explain", help="a picture that explains one part of hidden-surface "
                       "removal", description="Views: " + ", ".join(VIEWS) + ".")
    e.add_argument("view", choices=list(VIEWS))
    _add_scene_args(e, *shared)
    e.add_argument("-o", "--output", help="PNG (or .gif for the painter animation); "
                   "default VIEW.png")
    rp = sub.add_parser("report", help="one HTML page with every view, the algorithm "
                        "comparison and stats")
    _add_scene_args(rp, *shared)
    rp.add_argument("-o", "--output", default="report.html", help="default %(default)s")
    rp.add_argument("--algorithms", default=",".join(ALGORITHMS),
                    help="algorithms to compare (default: all)")
    _add_batch_parser(sub, ALGORITHMS, CullMode, DepthFunc, FrontFace, SHADING_MODES)
    _add_prune_parser(sub, ALGORITHMS, CullMode, DepthFunc, FrontFace)
    _add_visibility_parser(sub, ALGORITHMS, CullMode, DepthFunc)
    v = sub.add_parser("view", help="an interactive page in the browser: every algorithm and "
                       "switch, live", description="Serve a local page that renders MODEL "
                       "(or the built-in scenes) with hsr as you drag, with every control.")
    v.add_argument("models", nargs="*", metavar="MODEL", help="mesh files to show (the "
                   "built-in scenes are always there)")
    v.add_argument("--scene", choices=list(SCENES), help="built-in scene shown first "
                   "(default: the first MODEL, else cubes)")
    v.add_argument("--host", default="127.0.0.1", help="address to listen on; anything but "
                   "127.0.0.1 / localhost lets other machines in")
    v.add_argument("--port", type=int, default=8765, help="port to listen on")
    v.add_argument("--no-browser", action="store_true", help="do not open the browser")
    return parser


def _add_visibility_parser(sub, ALGORITHMS, CullMode, DepthFunc):
    p = sub.add_parser("visibility", help="which faces, vertices or points each view sees",
                       description="For every view, the faces (with their pixel counts), "
                       "the vertices or the points of a .npy file that the camera sees, "
                       "written as .npz or .csv.")
    p.add_argument("models", nargs="+", metavar="MODEL", help="mesh files, one scene")
    p.add_argument("--views", required=True, metavar="SPEC", action="append",
                   help="sphere:N, hemisphere:N, orbit:N[:ELEVATION], a transforms.json or a "
                   "COLMAP folder; repeat to use several")
    p.add_argument("--size", default="512x512", help="WxH in pixels")
    p.add_argument("--what", default="faces", metavar="faces|vertices|points:FILE.npy",
                   help="faces: pixel counts per face and view; vertices: the scene's "
                   "vertices seen by each view; points:FILE.npy: an (N, 3) array's points")
    p.add_argument("--quality", action="store_true", help="faces: also the mean cosine "
                   "and distance per face and view")
    p.add_argument("--tolerance", type=float, default=1e-4, help="vertices and points: the "
                   "share of each eye-to-point segment left out at the point's end")
    p.add_argument("-o", "--out", required=True, metavar="OUT", help="OUT.npz or OUT.csv")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")
    p.add_argument("--cull", default="none", choices=[m.value for m in CullMode],
                   help="faces: glCullFace")
    p.add_argument("--depth-func", default="less", choices=[m.value for m in DepthFunc],
                   help="faces: glDepthFunc")
    p.add_argument("--algorithm", default="zbuffer", choices=sorted(ALGORITHMS),
                   help="faces: the visibility algorithm")
    p.add_argument("--near", type=float, default=0.1, help="near plane for camera files")
    p.add_argument("--far", type=float, default=100.0, help="far plane for camera files")
    p.add_argument("--scheduler", metavar="ADDRESS", help="faces: a running Dask scheduler "
                   "to spread the views over")
    p.add_argument("--quiet", action="store_true", help="no progress bar, no summary")


def _cmd_visibility(args) -> int:
    from .scene.files import check_output
    from .scene.load import load_scene
    from .scene.mesh import Scene
    from .scene.write import check_new
    from .visibility import cameras_for
    from .visibility.queries import write_visibility

    width, height = _size(args.size)
    check_output(args.out, (".npz", ".csv"))
    if not args.force:
        check_new([args.out], "--force")
    what, _, points_file = args.what.partition(":")
    if what not in ("faces", "vertices", "points") or (what == "points") != bool(points_file):
        raise CliError(f"--what must be faces, vertices or points:FILE.npy, got {args.what!r}")
    if what != "faces":
        for flag, given in (("--scheduler", args.scheduler), ("--quality", args.quality)):
            if given:
                raise CliError(f"{flag} goes with --what faces")
    points = _read_points(points_file) if what == "points" else None
    scene = Scene()
    for path in args.models:
        scene.instances.extend(load_scene(path).instances)
    cameras = cameras_for(scene, args.views, width / height, args.near, args.far)
    client = _client(args.scheduler, "visibility") if args.scheduler else None
    try:
        result = write_visibility(scene, cameras, (width, height), what, points, args.out,
                                  quality=args.quality, tolerance=args.tolerance,
                                  client=client, progress=not args.quiet and
                                  sys.stderr.isatty(), cull=args.cull,
                                  depth_func=args.depth_func, algorithm=args.algorithm)
    finally:
        if client is not None:
            client.close()
    if not args.quiet:
        print(result)
    return 0


def _read_points(path: str):
    from .scene.files import read_regular

    try:
        import io

        array = np.load(io.BytesIO(read_regular(path, "points file", 1 << 31, CliError)),
                        allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise CliError(f"--what points:{path}: not a .npy array ({exc})") from None
    return array


def _add_prune_parser(sub, ALGORITHMS, CullMode, DepthFunc, FrontFace):
    from .scene.write import MESH_FORMATS
    from .visibility.prune import AUTO_SIZE, LEVELS

    p = sub.add_parser("prune", help="remove the geometry no viewpoint can see",
                       description="Render MODEL from many viewpoints, count the pixels where "
                       "each face is visible and write the model without the faces (or "
                       "objects) no view shows, face order kept.")
    p.add_argument("model", metavar="MODEL", help="mesh file (OBJ, PLY, STL, OFF, glTF/GLB)")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="the pruned model: " + ", ".join(MESH_FORMATS))
    p.add_argument("--force", action="store_true", help="replace OUT (and an OBJ's .mtl "
                   "and textures) if they exist; OUT may never be MODEL itself")
    g = p.add_argument_group("decision")
    g.add_argument("--views", action="append", metavar="SPEC",
                   help="auto (outside views added in rounds until a round changes "
                   "nothing), sphere:N, hemisphere:N, orbit:N[:ELEVATION] (outside the "
                   "bounding sphere), or a transforms.json / COLMAP folder (e.g. interior "
                   "cameras); repeat to use several (default: auto)")
    g.add_argument("--size", default="auto", metavar="R",
                   help="R x R pixels per view, or auto: about one pixel per face, "
                   f"{AUTO_SIZE[0]}..{AUTO_SIZE[1]} (default)")
    g.add_argument("--max-views", type=int, default=2048, metavar="N",
                   help="auto starts no round that would pass N views")
    g.add_argument("--level", default="faces", choices=list(LEVELS),
                   help="remove single faces, or whole objects (glTF nodes)")
    g.add_argument("--min-pixels", type=int, default=1, metavar="P",
                   help="keep a face seen on at least P pixels over all views")
    g.add_argument("--keep-neighbors", type=int, metavar="K",
                   help="also keep faces within K edge-rings of a kept face (default: 2 "
                   "with auto views, else 0)")
    g.add_argument("--algorithm", default="zbuffer", choices=sorted(ALGORITHMS),
                   help="visibility algorithm whose face ids decide")
    g.add_argument("--cull", default="none", choices=[m.value for m in CullMode],
                   help="face culling while deciding (none: a face seen from behind counts)")
    g.add_argument("--front-face", default="ccw", choices=[m.value for m in FrontFace])
    g.add_argument("--depth-func", default="less", choices=[m.value for m in DepthFunc],
                   help="depth test: with less an earlier coplanar face keeps its pixels")
    g.add_argument("--near", type=float, default=0.1, help="near plane for camera files")
    g.add_argument("--far", type=float, default=100.0, help="far plane for camera files")
    g = p.add_argument_group("check and run")
    g.add_argument("--verify", type=int, default=0, metavar="K",
                   help="render K random outside viewpoints not used for the decision, of "
                   "the original and the pruned model, and report the pixels that changed")
    g.add_argument("--seed", type=int, default=0, help="seed of the random viewpoints "
                   "(auto rounds and --verify draw different ones from it)")
    g.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler to "
                   "spread the views over (default: this process, all cores)")
    g.add_argument("--threads", type=int, help="kernel threads in this process (default: "
                   "numba's)")
    g.add_argument("--quiet", action="store_true", help="no progress bar, no summary")


def _cmd_prune(args) -> int:
    import time

    from .scene.load import load_scene
    from .scene.write import check_new, planned_files, write_mesh
    from .visibility.count import cameras_for
    from .visibility.prune import MAX_VERIFY, decide, split_auto, subset_scene, unsettled, verify

    start = time.perf_counter()
    _check_prune_output(args)
    _check_threads(args)
    if not 0 <= args.verify <= MAX_VERIFY:  # checked by verify() too, but after the work
        raise CliError(f"--verify must be a number of views in 0..{MAX_VERIFY}, got "
                       f"{args.verify}")
    if args.size != "auto":
        try:
            args.size = int(args.size)
        except ValueError:
            raise CliError(f"--size must be an integer or auto, got {args.size!r}") from None
    scene = load_scene(args.model)
    if not args.force:  # the .mtl and textures beside an OBJ, known once it is loaded
        check_new(planned_files(scene, args.output), "--force")
    auto, fixed = split_auto(args.views or ["auto"])
    # The cameras once, before any connection: a bad --views fails at once.
    cameras = cameras_for(scene, fixed, 1.0, args.near, args.far) if fixed else []
    client = _client(args.scheduler, "prune") if args.scheduler else None
    options = dict(algorithm=args.algorithm, cull=args.cull, front_face=args.front_face,
                   depth_func=args.depth_func)
    try:
        decision = decide(scene, cameras + (["auto"] if auto else []), args.size,
                          level=args.level, keep_neighbors=args.keep_neighbors,
                          min_pixels=args.min_pixels, seed=args.seed,
                          max_views=args.max_views, client=client, threads=args.threads,
                          progress=not args.quiet and sys.stderr.isatty(), **options)
    finally:
        if client is not None:
            client.close()
    kept = np.flatnonzero(decision.keep)
    pruned = subset_scene(scene, decision.keep)
    written = write_mesh(pruned, args.output, overwrite=args.force)
    seconds = time.perf_counter() - start
    width, height = decision.size
    if not decision.converged:
        print(f"hsr: warning: {unsettled(decision)}", file=sys.stderr)
    if not args.quiet:
        before, after = scene.n_faces, pruned.n_faces
        settled = (f" (auto: the last {decision.last_round} changed nothing)"
                   if auto and decision.converged else
                   " (auto: still changing at --max-views)" if auto else "")
        print(f"faces {before:,} -> {after:,} ({100.0 * (before - after) / before:.2f}% "
              f"removed); objects {len(scene):,} -> {len(pruned):,}; {decision.views:,} "
              f"views at {width}x{height}{settled}; {seconds:.1f} s; wrote "
              f"{', '.join(written)}")
    if args.verify:
        report = verify(scene, pruned, kept, args.verify, (width, height), seed=args.seed,
                        threads=args.threads, **options)
        print(f"verify: {report['changed']:,} of {report['covered']:,} covered pixels "
              f"changed ({report['percent']:.4f}%) over {report['views']} random outside "
              f"views at {width}x{height}")
    return 0


def _check_threads(args) -> None:
    if args.threads is not None and args.threads < 1:
        raise CliError(f"--threads must be >= 1, got {args.threads}")


def _check_prune_output(args) -> None:
    """Before any work: OUT is never MODEL (nor a link to it), and an OUT that exists is
    replaced only with --force."""
    from .scene.files import check_output
    from .scene.write import MESH_FORMATS, check_new

    check_output(args.output, MESH_FORMATS)
    if os.path.realpath(args.output) == os.path.realpath(args.model) or (
            os.path.exists(args.output) and os.path.exists(args.model)
            and os.path.samefile(args.output, args.model)):  # a hard link too
        raise CliError(f"-o {args.output} is MODEL itself: write the pruned model to "
                       f"another file")
    if not args.force:
        check_new([args.output], "--force")


def _cmd_view(args) -> int:
    import socket

    from .viewer import serve

    if not 1 <= args.port <= 65535:
        raise CliError(f"--port must be in 1..65535, got {args.port}")
    if args.host not in ("127.0.0.1", "localhost", "::1"):
        print(f"hsr: warning: listening on {args.host}: other machines can reach this "
              f"viewer", file=sys.stderr)
    try:  # a clear error now rather than a server that fails to start
        with socket.create_server((args.host, args.port)):
            pass
    except OSError as exc:
        raise CliError(f"cannot listen on {args.host}:{args.port} ({exc.strerror or exc})") \
            from None
    first = args.scene if args.scene else (None if args.models else "cubes")
    try:
        serve(args.models, args.host, args.port, not args.no_browser, first=first)
    except KeyboardInterrupt:
        pass
    return 0


def _client(address: str, command: str):
    """A ``distributed.Client`` connected to ``address``, or a one-line error."""
    from .errors import require_extra

    require_extra(f"hsr {command} --scheduler", "distributed")
    from distributed import Client

    try:
        return Client(address, timeout="10s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise CliError(f"--scheduler {address}: cannot connect ({exc})") from None


def _add_batch_parser(sub, ALGORITHMS, CullMode, DepthFunc, FrontFace, SHADING_MODES):
    from .appearance.shading import LIGHTS
    from .batch.plan import FORMATS, OUTPUTS

    b = sub.add_parser("batch", help="many views of many models, on all cores or a Dask "
                       "cluster", description="Render every MODEL from every view and write "
                       "the buffers, a transforms.json per model and a manifest, on a local "
                       "Dask cluster or the one at --scheduler.")
    b.add_argument("models", nargs="+", metavar="MODEL", help="mesh files every worker "
                   "can read")
    g = b.add_argument_group("job")
    g.add_argument("--views", default="orbit:8", metavar="SPEC",
                   help="orbit:N[:ELEVATION], sphere:N, hemisphere:N, a transforms.json or "
                   "COLMAP folder (the same cameras for every model), or per-model:FILE "
                   "(JSON: model -> camera file)")
    g.add_argument("--size", default="512x512", help="WxH in pixels")
    g.add_argument("--outputs", default="color", help="comma-separated, from: "
                   + ", ".join(OUTPUTS))
    g.add_argument("--out", default="batch", metavar="DIR", help="output folder")
    g.add_argument("--format", default="files", choices=list(FORMATS),
                   help="one file per view and output, or one Zarr v3 store per model")
    g.add_argument("--resume", action="store_true",
                   help="skip views whose outputs all exist (after an interrupted run)")
    g.add_argument("--near", type=float, default=0.1, help="near plane for camera files")
    g.add_argument("--far", type=float, default=100.0, help="far plane for camera files")
    g = b.add_argument_group("cluster")
    g.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler, e.g. "
                   "tcp://10.0.0.5:8786 (default: a local cluster on this machine)")
    g.add_argument("--workers", type=int, help="size of the local cluster (default: one per "
                   "core): single-threaded worker processes for views under 512x512 pixels, "
                   "threads of one worker in this process for larger ones")
    g.add_argument("--views-per-task", type=int, metavar="N", help="views in one task "
                   "(default: about 4M pixels, at least four tasks per worker)")
    g = b.add_argument_group("rendering")
    g.add_argument("--algorithm", default="zbuffer", choices=sorted(ALGORITHMS),
                   help="visibility algorithm")
    g.add_argument("--cull", default="none", choices=[m.value for m in CullMode],
                   help="glCullFace")
    g.add_argument("--front-face", default="ccw", choices=[m.value for m in FrontFace],
                   help="glFrontFace")
    g.add_argument("--depth-func", default="less", choices=[m.value for m in DepthFunc],
                   help="glDepthFunc")
    g.add_argument("--shading", default="flat", choices=list(SHADING_MODES),
                   help="how visible faces are coloured")
    g.add_argument("--light", default="studio", choices=list(LIGHTS), help="lights")
    g.add_argument("--background", default="0,0,0", help="background colour r,g,b (0-255)")
    g.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="algorithm option; repeatable")
    g.add_argument("--quiet", action="store_true", help="print nothing but errors")


def _cmd_batch(args) -> int:
    from .batch import render_views

    if args.scheduler and args.workers is not None:
        raise CliError("--workers sizes the local cluster: it does not combine with "
                       "--scheduler")
    client = _client(args.scheduler, "batch") if args.scheduler else None
    try:
        result = render_views(
            args.models, args.views, _size(args.size), args.outputs, args.out, client,
            format=args.format, resume=args.resume, workers=args.workers,
            views_per_task=args.views_per_task,
            progress=not args.quiet and sys.stderr.isatty(), near=args.near, far=args.far,
            algorithm=args.algorithm, cull=args.cull, front_face=args.front_face,
            depth_func=args.depth_func, shading=args.shading, light=args.light,
            background=_color(args.background, "--background"),
            options=_options(args.option) or None)
    finally:
        if client is not None:
            client.close()
    if result.failed:
        print(f"hsr: {result.summary()}", file=sys.stderr)
        return 1
    if not args.quiet:
        print(f"wrote {result.manifest}: {result.summary()}")
    return 0


def _auto_near_far(eye: np.ndarray, bounds: np.ndarray) -> tuple[float, float]:
    """Near/far that enclose the box as seen from ``eye``."""
    corners = np.array([[x, y, z] for x in bounds[:, 0] for y in bounds[:, 1]
                        for z in bounds[:, 2]])
    dist = np.linalg.norm(corners - eye, axis=1)
    diag = max(float(np.linalg.norm(bounds[1] - bounds[0])), 1e-9)
    far = float(dist.max()) * 1.05 + 1e-6 * diag
    inside = np.all((eye >= bounds[0]) & (eye <= bounds[1]))
    closest = 0.0 if inside else float(np.linalg.norm(np.clip(eye, bounds[0], bounds[1]) - eye))
    near = max(closest * 0.9, far * 1e-4)
    return near, far


def _file_camera(args):
    """(camera, (w, h)) from --camera FILE[:INDEX], else (None, None)."""
    if not args.camera:
        return None, None
    from .scene.camera_files import read_colmap, read_transforms

    for flag, dest in (("eye", "eye"), ("target", "target"), ("view", "view_from"),
                       ("ortho", "ortho")):
        if getattr(args, dest) is not None:
            raise CliError(f"--camera sets the camera: it does not combine with --{flag}")
    path, index = args.camera, 0
    if ":" in path and path.rsplit(":", 1)[1].isdigit():
        path, index = path.rsplit(":", 1)[0], int(path.rsplit(":", 1)[1])
    near = args.near if args.near is not None else 0.1
    far = args.far if args.far is not None else 100.0
    import os

    if os.path.isdir(path):
        cameras, _, sizes = read_colmap(path, near=near, far=far)
    else:
        cameras, _, size = read_transforms(path, near=near, far=far)
        sizes = [size] * len(cameras)
    if index >= len(cameras):
        raise CliError(f"--camera: {path} has {len(cameras)} cameras, no index {index}")
    return cameras[index], sizes[index]


def _camera_from_args(args, scene, default_camera, aspect):
    from .errors import CameraError
    from .scene import views
    from .scene.camera import Camera

    up = _floats(args.up, 3, "--up")
    if args.view_from is not None and args.eye is not None:
        raise CliError("--view frames the model: it does not combine with --eye")
    if args.view_from is None and args.eye is None and args.target is None \
            and default_camera is not None:
        # A built-in scene: its own camera, with the user's lens settings applied.
        cam = default_camera
        near = args.near if args.near is not None else cam.near
        far = args.far if args.far is not None else cam.far
        if args.ortho is not None:
            return Camera.orthographic(cam.eye, cam.target, cam.up, args.ortho, near, far)
        fov = args.fov if args.fov != 45.0 else cam.fov_y
        return Camera.look_at(cam.eye, cam.target, cam.up, fov, near, far)
    points = views.model_points(scene)  # one pass over the vertices: box and framing
    bounds = np.stack([points.min(axis=0), points.max(axis=0)])
    target = np.array(_floats(args.target, 3, "--target")) if args.target else bounds.mean(axis=0)
    eye = np.array(_floats(args.eye, 3, "--eye")) if args.eye else None
    try:
        if eye is None:
            # Frame the model's bounding sphere for this aspect ratio from --view, or by
            # default from a three-quarter view above the front-right (views.DEFAULT_VIEW).
            az, el = (_floats(args.view_from, 2, "--view") if args.view_from is not None
                      else views.DEFAULT_VIEW)
            cam = Camera.frame(bounds, views.direction(az, el), up, args.fov,
                               ortho_height=args.ortho, margin=views.MARGIN, aspect=aspect,
                               fit="points", points=points)
            if args.target is None:  # the framing's own aim (the middle of the picture)
                target = np.asarray(cam.target)
            eye = np.asarray(cam.eye) - np.asarray(cam.target) + target
            up = cam.up
            auto_near, auto_far = cam.near, cam.far
        else:
            with np.errstate(all="ignore"):  # an absurd eye fails in Camera below
                auto_near, auto_far = _auto_near_far(eye, bounds)
        near = args.near if args.near is not None else auto_near
        far = args.far if args.far is not None else auto_far
        if args.ortho is not None:
            return Camera.orthographic(eye, target, up, args.ortho, near, far)
        return Camera.look_at(eye, target, up, args.fov, near, far)
    except CameraError as exc:
        # The options on their own passed _check_lens: what is wrong is how they meet
        # the model (e.g. --far nearer than the framed near plane), or the model itself.
        given = [f"{name} {value}" for name, value in (
            ("--view", args.view_from), ("--eye", args.eye), ("--target", args.target),
            ("--near", args.near), ("--far", args.far), ("--ortho", args.ortho))
            if value is not None]
        if given:
            raise CliError(f"{', '.join(given)}: no valid camera for this model with "
                           f"{'this value' if len(given) == 1 else 'these values'} ({exc})") \
                from None
        raise CliError(f"the camera framed from the model's bounds is not valid ({exc}); "
                       f"set --eye, --target, --near and --far") from None


def _options(pairs) -> dict:
    """--option KEY=VALUE pairs; numbers and true/false are converted."""
    options = {}
    for pair in pairs:
        if "=" not in pair:
            raise CliError(f"--option must look like KEY=VALUE, got {pair!r}")
        key, value = pair.split("=", 1)
        low = value.lower()
        if low in ("true", "false"):
            options[key] = low == "true"
        else:
            try:
                options[key] = int(value)
            except ValueError:
                try:
                    options[key] = float(value)
                except ValueError:
                    options[key] = value
    return options


def _setup(args):
    """Scene, camera, size, state, background and options from the shared arguments."""
    from .geometry.state import RenderState
    from .scene import builtin as scenes
    from .scene.load import load_scene
    from .scene.mesh import Scene

    _check_lens(args)
    file_camera, file_size = _file_camera(args)
    width, height = _size(args.size) if args.size else (file_size or (800, 600))
    default_camera = None
    if args.light is None:
        args.light = "studio" if args.models else "headlight"
    if args.models:
        scene, owner = Scene(), []  # owner[i]: the MODEL instance i came from
        for k, path in enumerate(args.models):
            for inst in load_scene(path).instances:
                scene.instances.append(inst)
                owner.append(k)
        _apply_textures(args, scene, owner)
    else:
        if args.texture:
            raise CliError("--texture needs MODEL files")
        scene, default_camera = scenes.get(args.scene)
        owner = list(range(len(scene.instances)))
    if args.opacity:
        count = len(args.models) if args.models else len(scene.instances)
        values = args.opacity.split(",")
        if len(values) not in (1, count):
            raise CliError(f"--opacity needs 1 or {count} values (one per "
                           f"{'MODEL' if args.models else 'object'}), got {len(values)}")
        try:
            opacity = [float(v) for v in values] * (count if len(values) == 1 else 1)
        except ValueError:
            raise CliError(f"--opacity values must be numbers, got {args.opacity!r}") from None
        for a in opacity:
            if not 0.0 <= a <= 1.0:
                raise CliError(f"--opacity values must be in 0..1, got {a}")
        for inst, k in zip(scene.instances, owner):
            inst.opacity = opacity[k]
    camera = file_camera or _camera_from_args(args, scene, default_camera, width / height)
    state = RenderState(depth_test=not args.no_depth_test, depth_func=args.depth_func,
                        depth_mask=not args.no_depth_write, clear_depth=args.clear_depth,
                        depth_range=_floats(args.depth_range, 2, "--depth-range"),
                        cull=args.cull, front_face=args.front_face,
                        polygon_mode=args.polygon_mode,
                        polygon_offset=(_floats(args.polygon_offset, 2, "--polygon-offset")
                                        if args.polygon_offset else (0.0, 0.0)))
    background = _color(args.background, "--background")
    _check_threads(args)
    return scene, camera, width, height, state, background, _options(args.option)


def _apply_textures(args, scene, owner) -> None:
    """--texture [MODEL=]IMAGE: each image to the instances of its MODEL (all of the one
    MODEL when no MODEL= is given). A MODEL named twice, a MODEL not on the command line,
    a bare IMAGE with several MODELs, or a MODEL without texture coordinates is an error:
    never a silent choice."""
    given = {}
    for value in args.texture:
        model, image = None, value
        if "=" in value and not os.path.isfile(value):
            model, image = value.split("=", 1)
            matches = [k for k, path in enumerate(args.models)
                       if model in (path, os.path.basename(path))]
            if not matches:
                raise CliError(f"--texture {value}: {model!r} is not one of the MODELs "
                               f"({', '.join(args.models)})")
            if len(matches) > 1:
                raise CliError(f"--texture {value}: {model!r} names {len(matches)} MODELs; "
                               f"give its path")
            k = matches[0]
        elif len(args.models) == 1:
            k = 0
        else:
            raise CliError(f"--texture {value}: {len(args.models)} MODELs given; say which "
                           f"with MODEL=IMAGE")
        if k in given:
            raise CliError(f"--texture: {args.models[k]} is given two textures "
                           f"({given[k]} and {image})")
        given[k] = image
    for k, image in given.items():
        targets = [inst for inst, o in zip(scene.instances, owner) if o == k]
        if not any(inst.mesh.corner_uv is not None for inst in targets):
            raise CliError(f"--texture {image}: {args.models[k]} has no texture coordinates "
                           f"(OBJ vt / glTF TEXCOORD_0)")
        for inst in targets:  # read (and checked) when shading starts
            if inst.mesh.corner_uv is not None:
                inst.mesh.texture = image


def _look(args):
    from .appearance.fog import parse_fog
    from .appearance.shading import Look

    fog = None
    if args.fog:
        fog = parse_fog(args.fog, _color(args.fog_color, "--fog-color"), args.fog_distance)
    return Look(args.shading, not args.no_texture, args.texture_filter, args.texture_wrap, fog,
                args.light)


def _hidden_line(args):
    from .lines.raster import HiddenLine

    color = _color(args.line_color, "--line-color") if args.line_color else None
    offset = (_floats(args.polygon_offset, 2, "--polygon-offset") if args.polygon_offset
              else (1.0, 1.0))
    return HiddenLine(args.edges, args.crease_angle, offset, color, args.hidden_line_fill)


def _cmd_render(args) -> int:
    from .render import render
    from .scene.files import check_output

    if args.output is None:
        args.output = None if args.svg else "render.png"
    if args.output:
        check_output(args.output)
    for path, kinds in ((args.depth_out, (".npy", ".exr", ".png")), (args.ids_out, (".npy",)),
                        (args.svg, (".svg",)), (args.error_map, None),
                        (args.normals_out, (".npy", ".exr", ".png"))):
        if path:
            check_output(path, kinds)
    scene, camera, width, height, state, background, options = _setup(args)
    if args.lines and not args.svg:
        raise CliError("--lines writes an SVG: give --svg FILE")
    if args.hidden_layer and not args.lines:
        raise CliError("--hidden-layer goes with --svg FILE --lines")
    hidden_line = _hidden_line(args)
    if args.algorithm in ("newell", "bsp") and not args.quiet and sys.stderr.isatty():
        options.setdefault("progress", True)

    def draw(cam):
        return render(scene, cam, width, height, algorithm=args.algorithm, state=state,
                      look=_look(args), background=background,
                      occlusion_cull=args.occlusion_cull, threads=args.threads,
                      options=options, hidden_line=hidden_line if args.hidden_line else None,
                      transparency=args.transparency)

    if args.orbit is not None:
        return _render_orbit(args, scene, width, height, draw)
    frame = draw(camera)
    _save_outputs(args, frame, "")
    if args.svg and args.lines:
        from .lines.vector import hidden_lines, write_lines_svg

        drawing = hidden_lines(scene, camera, width, height, hidden_line, state)
        write_lines_svg(args.svg, drawing, background, hidden_line.line_color(background),
                        hidden=args.hidden_layer)
        if not args.quiet:
            print(f"wrote {args.svg}: {len(drawing.visible_polylines)} visible polylines "
                  f"from {drawing.stats['edges']} edges")
    elif args.svg:
        _write_svg(args, frame, scene, camera, width, height, background)
    if args.error_map:
        from .explain.compare import difference_map
        from .scene.files import save_image

        truth = render(scene, camera, width, height, state=state, threads=args.threads)
        save_image(difference_map(frame, truth), args.error_map)
    if not args.quiet:
        s = frame.stats
        print(f"wrote {args.output or args.svg} ({width}x{height}, {args.algorithm}): "
              f"{s['triangles_in']} triangles, {s['degenerate']} degenerate, "
              f"{s['culled']} culled, {s['clipped']} clipped, "
              f"{s['pixels_covered']} pixels covered, {s['timings_ms']['total']:.1f} ms"
              + _algorithm_summary(s))
    return 0


def _numbered(path, suffix):
    if not path or not suffix:
        return path
    stem, ext = os.path.splitext(path)
    return f"{stem}{suffix}{ext}"


def _save_outputs(args, frame, suffix) -> None:
    """The colour image and the buffers asked for, each name with ``suffix`` before its
    extension."""
    if args.output:
        frame.save(_numbered(args.output, suffix))
    if args.depth_out:
        from .scene.files import save_depth

        buffer = {"window": frame.depth, "eye": frame.eye_depth,
                  "distance": frame.distance}[args.depth_kind]
        save_depth(buffer, _numbered(args.depth_out, suffix), args.depth_kind)
    if args.normals_out:
        from .scene.files import save_normals

        save_normals(frame.normals, _numbered(args.normals_out, suffix))
    if args.ids_out:
        frame.save_ids(_numbered(args.ids_out, suffix))


def _render_orbit(args, scene, width, height, draw) -> int:
    """``--orbit N``: N framed views at equal azimuth steps, outputs numbered _000, ..."""
    from .scene import views

    if not 1 <= args.orbit <= 100_000:
        raise CliError(f"--orbit must be 1..100000 views, got {args.orbit}")
    for flag, value in (("--eye", args.eye), ("--target", args.target), ("--camera",
                        args.camera), ("--svg", args.svg), ("--error-map", args.error_map),
                        ("--ortho", args.ortho)):
        if value is not None:
            raise CliError(f"--orbit places the cameras itself: it does not combine with {flag}")
    az0, elevation = _floats(args.view_from, 2, "--view") if args.view_from else (0.0, 20.0)
    cams = views.orbit(scene.bounds(), args.orbit, elevation, width / height, args.fov, az0)
    for k, cam in enumerate(cams):
        _save_outputs(args, draw(cam), f"_{k:03d}")
    if not args.quiet:
        print(f"wrote {args.orbit} views: {_numbered(args.output, '_000')} ... "
              f"{_numbered(args.output, f'_{args.orbit - 1:03d}')} ({width}x{height}, "
              f"{args.algorithm})")
    return 0


def _algorithm_summary(stats) -> str:
    """What an algorithm has to say for itself on the summary line: painter's wrong
    pixels, the polygons (and pixels) Newell left to its fallback, BSP splits."""
    parts = []
    if "pixels_wrong" in stats:
        parts.append(f"{stats['pixels_wrong']} pixels wrong (painter's order)")
    if "unresolved" in stats:
        parts.append(f"{stats['unresolved']} unresolved polygons "
                     f"({stats.get('unresolved_pixels', 0)} pixels drawn by the depth-test "
                     f"fallback)")
    if "bsp_nodes" in stats:
        parts.append(f"{stats['bsp_nodes']} BSP nodes, {stats['splits']} splits")
    return "".join("; " + p for p in parts)


def _write_svg(args, frame, scene, camera, width, height, background):
    from .appearance.shading import face_colors
    from .lines.svg import write_polygons_svg
    from .parallel import Workers

    polygons = frame.fragments.buffers.get("polygons")
    if args.algorithm == "newell" and frame.stats.get("unresolved"):
        raise CliError(f"--svg: newell could not order {frame.stats['unresolved']} polygons "
                       f"(see --option max_actions / max_pair_tests), so no exact vector "
                       f"picture exists; use --algorithm bsp")
    if polygons is None or polygons[2] != "back_to_front":
        raise CliError("--svg needs --algorithm bsp (back-to-front traversal) or newell")
    if args.shading == "depth":
        raise CliError("--svg draws flat colours: use --shading flat, normal or random")
    xy, source, _ = polygons
    with Workers(args.threads) as workers:
        colors = face_colors(args.shading, scene, camera, workers, light=args.light)[source]
    write_polygons_svg(args.svg, xy, colors, source, width, height, background)


def _algorithm_names(text: str) -> list:
    """A comma-separated list of algorithm names, checked."""
    from .algorithms import ALGORITHMS

    names = [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in ALGORITHMS]
    if unknown or not names:
        raise CliError(f"unknown algorithm {', '.join(unknown) or '(none)'}; choose from "
                       f"{', '.join(ALGORITHMS)}")
    return names


def _cmd_compare(args) -> int:
    from .algorithms import ALGORITHMS
    from .explain.compare import compare_algorithms, montage
    from .scene.files import check_output, save_image

    names = _algorithm_names(args.algorithms)
    if args.montage:
        check_output(args.montage)
    scene, camera, width, height, state, background, options = _setup(args)
    known = {k for n in names for k in ALGORITHMS[n].OPTIONS}
    if set(options) - known:
        raise CliError(f"no chosen algorithm has option {', '.join(sorted(set(options) - known))}")
    results = compare_algorithms(scene, camera, width, height, names, state=state,
                                 look=_look(args), background=background,
                                 threads=args.threads, options=options,
                                 progress=not args.quiet and sys.stderr.isatty())
    if not args.quiet:
        print(results.table())
    if args.montage:
        save_image(np.asarray(montage(results)), args.montage)
        if not args.quiet:
            print(f"wrote {args.montage}")
    return 0


def _cmd_explain(args) -> int:
    from .explain.views import explain
    from .scene.files import check_output

    output = check_output(args.output or f"{args.view}.png")
    scene, camera, width, height, state, _, _ = _setup(args)
    result = explain(args.view, scene, camera, width, height, state)
    result.save(output)
    if not args.quiet:
        print(f"wrote {output}")
        for line in result.text.splitlines()[1:]:
            print(line)
        for key, value in result.numbers.items():
            if not isinstance(value, (dict, list)):
                print(f"  {key}: {value:.6g}" if isinstance(value, float) else
                      f"  {key}: {value}")
    return 0


def _cmd_report(args) -> int:
    import os

    from .explain.report import write_report
    from .scene.files import check_output

    names = _algorithm_names(args.algorithms)
    check_output(args.output, (".html", ".htm"))
    scene, camera, width, height, state, _, _ = _setup(args)
    title = ("hsr report: " + ", ".join(os.path.basename(m) for m in args.models)
             if args.models else f"hsr report: built-in scene {args.scene}")
    write_report(args.output, scene, camera, title, width=width, height=height, state=state,
                 algorithms=names, progress=not args.quiet and sys.stderr.isatty())
    if not args.quiet:
        print(f"wrote {args.output}")
    return 0


def _attach_negative_values(argv: list) -> list:
    """``--view -55,25`` as ``--view=-55,25``: argparse takes a value that starts with '-'
    and is not a plain number for an option and fails ("expected one argument")."""
    out, k = [], 0
    while k < len(argv):
        token = argv[k]
        if (token.startswith("--") and "=" not in token and k + 1 < len(argv)
                and len(argv[k + 1]) > 1 and argv[k + 1][0] == "-"
                and (argv[k + 1][1].isdigit() or argv[k + 1][1] == ".")):
            out.append(f"{token}={argv[k + 1]}")
            k += 2
        else:
            out.append(token)
            k += 1
    return out


def main(argv=None) -> int:
    """Run the ``hsr`` command with ``argv`` (default: the process arguments) and return
    the exit code. Raises nothing for bad input: 0 on success, 2 with one line on stderr
    (``hsr: error: ...``) for any :class:`~hsr.errors.HsrError`, 130 when interrupted, 1
    when memory runs out after all."""
    argv = _attach_negative_values(sys.argv[1:] if argv is None else list(argv))
    debug = "--debug" in argv
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        if args.version:
            from . import __version__

            print(f"hsr {__version__}")
            return 0
        if args.command is None:
            parser.print_help()
            return EXIT_USAGE
        if args.command == "render":
            return _cmd_render(args)
        if args.command == "compare":
            return _cmd_compare(args)
        if args.command == "explain":
            return _cmd_explain(args)
        if args.command == "report":
            return _cmd_report(args)
        if args.command == "batch":
            return _cmd_batch(args)
        if args.command == "prune":
            return _cmd_prune(args)
        if args.command == "view":
            return _cmd_view(args)
        if args.command == "visibility":
            return _cmd_visibility(args)
        raise CliError(f"unknown command {args.command!r}")
    except HsrError as exc:
        if debug:
            raise
        print(f"hsr: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("hsr: interrupted", file=sys.stderr)
        return 130
    except MemoryError:
        print("hsr: error: out of memory (try a smaller --size or mesh)", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
