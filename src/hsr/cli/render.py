"""``hsr render``: one scene to an image, the buffers, an SVG, or an orbit of views."""

from __future__ import annotations

import os
import sys

from .options import CliError, add_algorithm, add_scene_args, floats
from .setup import hidden_line_args, look, setup


def add_parser(sub) -> None:

    r = sub.add_parser("render", help="render meshes (or a built-in scene) to an image",
                       description="Render MODEL files (OBJ, PLY, STL, OFF, glTF) as one scene, "
                       "or a built-in scene when no MODEL is given.")
    add_scene_args(r)
    rv = r.add_argument_group("visibility")
    add_algorithm(rv)
    rv.add_argument("--occlusion-cull", action="store_true",
                   help="skip objects hidden behind nearer ones (same result, less work)")
    rv.add_argument("--transparency", default="object", choices=["object", "exact"],
                   help="order transparent objects per object (painter's) or per fragment")
    rl = r.add_argument_group("lines")
    rl.add_argument("--svg", help="with --lines: the exact visible edges as SVG; with "
                   "--algorithm bsp or newell: the ordered polygons (exact, no rasterization)")
    rl.add_argument("--lines", action="store_true",
                   help="--svg draws visible edges, cut exactly where they become hidden")
    rl.add_argument("--pdf", help="with --fill: the same drawing as PDF (matplotlib)")
    rl.add_argument("--fill", action="store_true",
                   help="--svg draws each face's exact visible region, filled with its flat "
                   "colour (hsr.visible_regions: nothing hidden underneath; with --lines the "
                   "edges on top)"),
    rl.add_argument("--hidden-layer", action="store_true",
                   help="--svg --lines also draws the hidden parts, dashed")
    rl.add_argument("--hidden-line", action="store_true",
                   help="draw only visible edges (depth test against the polygon-offset fill)")
    rl.add_argument("--edges", default="all", choices=["all", "feature"],
                   help="edges for --hidden-line and --lines: all, or feature edges "
                   "(silhouettes, creases, boundaries)")
    rl.add_argument("--crease-angle", type=float, default=30.0,
                   help="feature edges: creases sharper than this many degrees")
    rl.add_argument("--intersections", action="store_true",
                   help="--lines and --hidden-line also draw where faces pass through each "
                   "other (exact segments, hidden like any edge)")
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


def run(args) -> int:
    from ..errors import require_extra
    from ..render import render
    from ..scene.files import check_output

    if args.output is None:
        args.output = None if args.svg or args.pdf else "render.png"
    if args.output:
        check_output(args.output)
    for path, kinds in ((args.depth_out, (".npy", ".exr", ".png")), (args.ids_out, (".npy",)),
                        (args.svg, (".svg",)), (args.pdf, (".pdf",)), (args.error_map, None),
                        (args.normals_out, (".npy", ".exr", ".png"))):
        if path:
            check_output(path, kinds)
            if path.lower().endswith(".exr"):  # before any output is written, not after
                require_extra(f"writing {path}", "OpenEXR")
    scene, camera, width, height, state, background, options = setup(args)
    _plan_outputs(args, scene)
    if args.lines and not (args.svg or (args.pdf and args.fill)):
        raise CliError("--lines writes an SVG: give --svg FILE")
    if args.hidden_layer and not args.lines:
        raise CliError("--hidden-layer goes with --svg FILE --lines")
    if args.fill and not (args.svg or args.pdf):
        raise CliError("--fill writes an SVG or a PDF: give --svg FILE or --pdf FILE")
    if args.pdf and not args.fill:
        raise CliError("--pdf writes the visible regions: give --fill")
    if args.fill and args.hidden_layer:
        raise CliError("--hidden-layer draws what --fill hides: use --svg FILE --lines")
    hidden_line = hidden_line_args(args)
    if args.algorithm in ("newell", "bsp") and not args.quiet and sys.stderr.isatty():
        options.setdefault("progress", True)

    def draw(cam):
        return render(scene, cam, width, height, algorithm=args.algorithm, state=state,
                      look=look(args), background=background,
                      occlusion_cull=args.occlusion_cull, threads=args.threads,
                      options=options, hidden_line=hidden_line if args.hidden_line else None,
                      transparency=args.transparency)

    if args.orbit is not None:
        return _render_orbit(args, scene, width, height, draw)
    frame = draw(camera)
    if frame.stats.get("pixels_covered", 1) == 0 and not args.quiet:
        # Exit 0 with a blank picture is what users met with a camera file's planes.
        print("hsr: warning: the view covers no pixel of the scene (is it behind the "
              "camera, or outside --near/--far?)", file=sys.stderr)
    _save_outputs(args, frame, "")
    if args.fill:
        _write_regions(args, scene, camera, width, height, state, background, hidden_line)
    elif args.svg and args.lines:
        from ..lines.svg import write_lines_svg
        from ..lines.vector import hidden_lines

        drawing = hidden_lines(scene, camera, width, height, hidden_line, state)
        write_lines_svg(args.svg, drawing, background, hidden_line.line_color(background),
                        hidden=args.hidden_layer)
        if not args.quiet:
            print(f"wrote {args.svg}: {len(drawing.visible_polylines)} visible polylines "
                  f"from {drawing.stats['edges']} edges")
    elif args.svg:
        _write_svg(args, frame, scene, camera, width, height, background)
    if args.error_map:
        from ..explain.compare import difference_map
        from ..scene.files import save_image

        truth = render(scene, camera, width, height, state=state, threads=args.threads)
        save_image(difference_map(frame, truth), args.error_map)
    if not args.quiet:
        s = frame.stats
        # The raster geometry stage's counts (the ray caster runs none).
        counts = "".join(f", {s[key]} {key}" for key in ("degenerate", "culled", "clipped")
                         if key in s)
        print(f"wrote {args.output or args.svg or args.pdf} ({width}x{height}, {args.algorithm}): "
              f"{s['triangles_in']} triangles{counts}, "
              f"{s['pixels_covered']} pixels covered, {s['timings_ms']['total']:.1f} ms"
              + _algorithm_summary(s))
    return 0


def _plan_outputs(args, scene) -> None:
    """Every output (each numbered one of an orbit) checked against the inputs and the
    other outputs before anything is rendered."""
    from .setup import input_plan

    plan = input_plan(args, scene)
    flags = (("-o", args.output), ("--depth-out", args.depth_out), ("--normals-out",
             args.normals_out), ("--ids-out", args.ids_out), ("--svg", args.svg),
             ("--pdf", args.pdf), ("--error-map", args.error_map))
    suffixes = ([f"_{k:03d}" for k in range(args.orbit)]
                if args.orbit is not None and 1 <= args.orbit <= 100_000 else [""])
    for flag, path in flags:
        if path:
            for suffix in suffixes:
                plan.add(flag, _numbered(path, suffix))


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
        from ..scene.files import save_depth

        buffer = {"window": frame.depth, "eye": frame.eye_depth,
                  "distance": frame.distance}[args.depth_kind]
        save_depth(buffer, _numbered(args.depth_out, suffix), args.depth_kind)
    if args.normals_out:
        from ..scene.files import save_normals

        save_normals(frame.normals, _numbered(args.normals_out, suffix))
    if args.ids_out:
        frame.save_ids(_numbered(args.ids_out, suffix))


def _render_orbit(args, scene, width, height, draw) -> int:
    """``--orbit N``: N framed views at equal azimuth steps, outputs numbered _000, ..."""
    from ..scene import views

    if not 1 <= args.orbit <= 100_000:
        raise CliError(f"--orbit must be 1..100000 views, got {args.orbit}")
    for flag, value in (("--eye", args.eye), ("--target", args.target), ("--camera",
                        args.camera), ("--svg", args.svg), ("--pdf", args.pdf),
                        ("--error-map", args.error_map),
                        ("--ortho", args.ortho)):
        if value is not None:
            raise CliError(f"--orbit places the cameras itself: it does not combine with {flag}")
    az0, elevation = floats(args.view_from, 2, "--view") if args.view_from else (0.0, 20.0)
    cams = views.orbit(scene.bounds(), args.orbit, elevation, width / height, args.fov, az0,
                       views.model_up(scene, args.up_axis))
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


def _write_regions(args, scene, camera, width, height, state, background, hidden_line):
    """``--svg FILE --fill``: the exact visible regions, flat-shaded, edges on top with
    ``--lines``."""
    from ..appearance.shading import face_colors
    from ..parallel import Workers
    from ..visibility.regions import visible_regions, write_regions_pdf, write_regions_svg

    if args.shading == "depth":
        raise CliError("--fill draws flat colours: use --shading flat, normal or random")
    fields = {name: getattr(state, name) for name in ("depth_test", "depth_func",
              "depth_mask", "clear_depth", "cull", "front_face", "polygon_mode",
              "polygon_offset")}
    regions = visible_regions(scene, camera, width, height, threads=args.threads, **fields)
    with Workers(args.threads) as workers:
        colors = face_colors(args.shading, scene, camera, workers, light=args.light)
    drawing = None
    if args.lines:
        from ..lines.vector import hidden_lines

        drawing = hidden_lines(scene, camera, width, height, hidden_line, state)
    written = []
    if args.svg:
        write_regions_svg(args.svg, regions, colors, background, drawing,
                          hidden_line.line_color(background))
        written.append(args.svg)
    if args.pdf:
        write_regions_pdf(args.pdf, regions, colors, background, drawing,
                          hidden_line.line_color(background))
        written.append(args.pdf)
    if not args.quiet:
        print(f"wrote {' and '.join(written)}: the visible regions of {len(regions)} faces "
              f"({len(regions.piece_row)} convex pieces, {regions.area.sum():.1f} px^2)")


def _write_svg(args, frame, scene, camera, width, height, background):
    from ..appearance.shading import face_colors
    from ..lines.svg import write_polygons_svg
    from ..parallel import Workers

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
