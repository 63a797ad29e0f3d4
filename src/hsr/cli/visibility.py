"""``hsr visibility``: which faces, vertices or points each view sees."""

from __future__ import annotations

import sys

from .options import (
    CliError,
    add_algorithm,
    add_cull,
    add_depth_func,
    add_file_planes,
    add_up_axis,
    dask_client,
    load_models,
)


def add_parser(sub) -> None:
    p = sub.add_parser("visibility", help="which faces, vertices or points each view sees",
                       description="For every view, the faces (with their pixel counts), "
                       "the vertices or the points of a .npy file that the camera sees, "
                       "written as .npz or .csv.")
    p.add_argument("models", nargs="+", metavar="MODEL", help="mesh files, one scene")
    p.add_argument("--views", required=True, metavar="SPEC", action="append",
                   help="sphere:N, hemisphere:N, orbit:N[:ELEVATION], a transforms.json or a "
                   "COLMAP folder; repeat to use several")
    p.add_argument("--size", help="WxH in pixels, or N for NxN (default: the camera "
                   "file's size, else 512x512)")
    add_up_axis(p, "orbit, sphere and hemisphere turn about it")
    p.add_argument("--what", default="faces", metavar="faces|vertices|points:FILE.npy",
                   help="faces: pixel counts per face and view; vertices: the scene's "
                   "vertices seen by each view; points:FILE.npy: an (N, 3) array's points")
    p.add_argument("--exact", action="store_true", help="faces: exact visible areas (px^2) "
                   "from each face's visible region (hsr.visible_regions): every face "
                   "with a visible part counts, however small")
    p.add_argument("--quality", action="store_true", help="faces: also the mean cosine "
                   "and distance per face and view")
    p.add_argument("--tolerance", type=float, default=1e-4, help="vertices and points: the "
                   "share of each eye-to-point segment left out at the point's end")
    p.add_argument("-o", "--out", required=True, metavar="OUT", help="OUT.npz or OUT.csv")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")
    add_cull(p, "faces: glCullFace")
    add_depth_func(p, "faces: glDepthFunc")
    add_algorithm(p, "faces: the visibility algorithm")
    add_file_planes(p)
    p.add_argument("--scheduler", metavar="ADDRESS", help="faces: a running Dask scheduler "
                   "to spread the views over")
    p.add_argument("--quiet", action="store_true", help="no progress bar, no summary")


def run(args) -> int:
    from ..scene.files import check_output
    from ..scene.write import check_new
    from ..visibility import cameras_for
    from ..visibility.queries import write_visibility
    from .setup import input_plan, view_inputs, views_size

    width, height = views_size(args.views, args.size)
    check_output(args.out, (".npz", ".csv"))
    if not args.force:
        check_new([args.out], "--force")
    what, _, points_file = args.what.partition(":")
    if what not in ("faces", "vertices", "points") or (what == "points") != bool(points_file):
        raise CliError(f"--what must be faces, vertices or points:FILE.npy, got {args.what!r}")
    if what != "faces":
        # Vertices and points are answered by rays (hsr.visible_points), which have no
        # raster algorithm, culling or depth function: refused, never silently ignored.
        for flag, given in (("--scheduler", args.scheduler), ("--quality", args.quality),
                            ("--exact", args.exact),
                            ("--algorithm", args.algorithm != "zbuffer"),
                            ("--cull", args.cull != "none"),
                            ("--depth-func", args.depth_func != "less")):
            if given:
                raise CliError(f"{flag} goes with --what faces ({what} are seen by rays, "
                               f"which take no {flag})")
    if args.exact and args.algorithm != "zbuffer":
        raise CliError("--exact computes visible regions: it takes no --algorithm")
    points = read_points(points_file) if what == "points" else None
    scene, _ = load_models(args.models, "visibility")
    plan = input_plan(args, scene, *view_inputs(args.views),
                      *([("the points file", points_file)] if points_file else []))
    plan.add("-o", args.out)
    cameras = cameras_for(scene, args.views, width / height, args.near, args.far,
                          args.up_axis)
    client = dask_client(args.scheduler, "visibility") if args.scheduler else None
    try:
        result = write_visibility(scene, cameras, (width, height), what, points, args.out,
                                  quality=args.quality, tolerance=args.tolerance,
                                  client=client, progress=not args.quiet and
                                  sys.stderr.isatty(), cull=args.cull,
                                  depth_func=args.depth_func, exact=args.exact,
                                  **({} if args.exact else {"algorithm": args.algorithm}))
    finally:
        if client is not None:
            client.close()
    if not args.quiet:
        print(result)
    return 0


def read_points(path: str):
    """The (N, 3) points of a .npy file, checked before they are used (see
    :func:`hsr.scene.files.read_npy`)."""
    from ..scene.files import read_npy

    return read_npy(path, "--what points", MAX_POINTS_BYTES, CliError)


# A points file of up to 2 GiB (89 million float64 points).
MAX_POINTS_BYTES = 1 << 31
