"""``hsr lines``: a model's exact visible lines as a layered SVG for a pen plotter."""

from __future__ import annotations

from .options import CliError, add_camera_args, add_cull, add_front_face, rgb


def add_parser(sub) -> None:
    from ..scene.builtin import SCENES

    p = sub.add_parser("lines", help="exact visible lines as a layered SVG (pen plotters)",
                       description="Draw the visible feature lines of MODEL files (or a "
                       "built-in scene) exactly, one Inkscape layer per kind (object "
                       "border, silhouette, boundary, crease, intersection, ...), joined "
                       "into polylines and ordered for a pen plotter.")
    p.add_argument("models", nargs="*", metavar="MODEL", help="mesh files (OBJ, PLY, STL, "
                   "OFF, glTF/GLB), one scene")
    p.add_argument("--scene", default="cubes", choices=list(SCENES),
                   help="built-in scene when no MODEL is given (default %(default)s)")
    add_camera_args(p.add_argument_group("camera"))
    g = p.add_argument_group("lines")
    g.add_argument("--edges", default="feature", choices=["feature", "all"],
                   help="feature edges (silhouettes, creases, boundaries) or every edge")
    g.add_argument("--crease-angle", type=float, default=30.0,
                   help="creases sharper than this many degrees (0..180)")
    g.add_argument("--intersections", action="store_true",
                   help="also the lines where faces pass through each other")
    g.add_argument("--hidden-layer", action="store_true",
                   help="also the hidden parts, dashed, in their own layer")
    add_cull(g, "culled faces neither hide nor draw lines")
    add_front_face(g)
    g = p.add_argument_group("output")
    g.add_argument("-o", "--output", required=True, metavar="OUT.svg", help="the SVG")
    g.add_argument("--page", metavar="PAPER", help="A4, A3, letter, ... (turned to fit; "
                   "A4-portrait, A4-landscape to choose) or WxHmm; default: the image in "
                   "pixels")
    g.add_argument("--margin", type=float, help="page margin in mm (default 10)")
    g.add_argument("--stroke-width", type=float, help="pen width (default 0.3 mm on a "
                   "page, else 1 px)")
    g.add_argument("--line-color", default="0,0,0", help="line colour r,g,b")
    g.add_argument("--background", help="background rectangle r,g,b (default none: a "
                   "plotter would draw its outline)")
    g.add_argument("--threads", type=int, help="threads for the kernels (default: all cores)")
    g.add_argument("--quiet", action="store_true", help="print nothing on success")


def drawing_from_args(args, check_out: bool = True, join_px: float | None = None) -> tuple:
    """``(drawing, page, colour, background)`` from ``hsr lines`` arguments: everything
    checked (the output against the inputs, the page against the image) before drawing.
    ``join_px``: polyline ends closer than this are joined (default: hidden_lines')."""
    import sys

    from ..geometry.state import RenderState
    from ..lines.page import parse_page
    from ..lines.paths import JOIN_PX
    from ..lines.raster import HiddenLine
    from ..lines.vector import hidden_lines
    from ..scene import builtin
    from ..scene.files import check_output
    from .options import check_threads, load_models
    from .setup import input_plan, view_setup

    if check_out:
        check_output(args.output, (".svg",))
    check_threads(args)
    if args.page is None and args.margin is not None:
        raise CliError("--margin goes with --page")
    page = parse_page(args.page, 10.0 if args.margin is None else args.margin) \
        if args.page else None
    settings = HiddenLine(args.edges, args.crease_angle, intersections=args.intersections)
    color = rgb(args.line_color, "--line-color")
    background = rgb(args.background, "--background") if args.background else None
    default_camera = None
    if args.models:
        scene, _ = load_models(args.models, "lines")
    else:
        scene, default_camera = builtin.get(args.scene)
    camera, width, height = view_setup(args, scene, default_camera)
    if page is not None:
        page.fit(width, height)  # refuse a page with no room before drawing
    if check_out:
        input_plan(args, scene).add("-o", args.output)
    state = RenderState(cull=args.cull, front_face=args.front_face)
    drawing = hidden_lines(scene, camera, width, height, settings, state, threads=args.threads,
                           with_hidden=args.hidden_layer,
                           progress=not args.quiet and sys.stderr.isatty(),
                           join_px=JOIN_PX if join_px is None else join_px)
    return drawing, page, color, background


def run(args) -> int:
    from ..lines.svg import write_lines_svg

    drawing, page, color, background = drawing_from_args(args)
    write_lines_svg(args.output, drawing, background, color, hidden=args.hidden_layer,
                    stroke_width=args.stroke_width, page=page)
    if not args.quiet:
        layers = ", ".join(f"{name} {len(lines)}" for name, lines in drawing.layers.items())
        print(f"wrote {args.output}: {len(drawing.visible_polylines)} polylines "
              f"({layers or 'none visible'}), pen-up travel "
              f"{drawing.stats['pen_travel']:.0f} px")
    return 0
