"""``hsr batch``: many views of many models on a Dask cluster."""

from __future__ import annotations

import sys

from .options import (
    CliError,
    add_algorithm,
    add_cull,
    add_depth_func,
    add_file_planes,
    add_front_face,
    add_up_axis,
    dask_client,
    key_values,
    rgb,
)


def add_parser(sub) -> None:
    from ..appearance.shading import LIGHTS, SHADING_MODES
    from ..batch.plan import FORMATS, OUTPUTS

    b = sub.add_parser("batch", help="many views of many models, on all cores or a Dask "
                       "cluster", description="Render every MODEL from every view and write "
                       "the buffers, a transforms.json per model and a manifest, on a local "
                       "Dask cluster or the one at --scheduler.")
    b.add_argument("models", nargs="+", metavar="MODEL", help="mesh files every worker "
                   "can read, or one partitioned scene (hsr partition), rendered part by "
                   "part and composited by depth (sort-last)")
    g = b.add_argument_group("job")
    g.add_argument("--views", default="orbit:8", metavar="SPEC",
                   help="orbit:N[:ELEVATION], sphere:N, hemisphere:N, a transforms.json or "
                   "COLMAP folder (the same cameras for every model), or per-model:FILE "
                   "(JSON: model -> camera file)")
    g.add_argument("--size", help="WxH in pixels, or N for NxN (default: a camera file's "
                   "size, else 512x512)")
    add_up_axis(g, "orbit, sphere and hemisphere turn about it")
    g.add_argument("--outputs", default="color", help="comma-separated, from: "
                   + ", ".join(OUTPUTS))
    g.add_argument("--out", default="batch", metavar="DIR", help="output folder")
    g.add_argument("--format", default="files", choices=list(FORMATS),
                   help="one file per view and output, or one Zarr v3 store per model")
    g.add_argument("--force", action="store_true", help="--format zarr: replace a "
                   "model's store that an earlier batch wrote (never another folder)")
    g.add_argument("--resume", action="store_true",
                   help="skip views whose outputs all exist (after an interrupted run)")
    add_file_planes(g)
    g = b.add_argument_group("cluster")
    g.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler, e.g. "
                   "tcp://10.0.0.5:8786 (default: a local cluster on this machine)")
    g.add_argument("--workers", type=int, help="size of the local cluster (default: one per "
                   "core): single-threaded worker processes for views under 512x512 pixels, "
                   "threads of one worker in this process for larger ones; for a "
                   "partitioned scene, N worker processes sharing its parts (default: "
                   "part after part in this process)")
    g.add_argument("--views-per-task", type=int, metavar="N", help="views in one task "
                   "(default: about 4M pixels, at least four tasks per worker)")
    g = b.add_argument_group("rendering")
    add_algorithm(g)
    add_cull(g)
    add_front_face(g)
    add_depth_func(g)
    g.add_argument("--shading", default="auto", choices=list(SHADING_MODES),
                   help="how visible faces are coloured")
    g.add_argument("--light", default="studio", choices=list(LIGHTS), help="lights")
    g.add_argument("--background", default="0,0,0", help="background colour r,g,b (0-255)")
    g.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="algorithm option; repeatable")
    g.add_argument("--quiet", action="store_true", help="print nothing but errors")


def run(args) -> int:
    from ..batch import render_views
    from .setup import views_size

    if args.scheduler and args.workers is not None:
        raise CliError("--workers sizes the local cluster: it does not combine with "
                       "--scheduler")
    client = dask_client(args.scheduler, "batch") if args.scheduler else None
    try:
        result = render_views(
            args.models, args.views, views_size([args.views], args.size), args.outputs,
            args.out, client,
            format=args.format, resume=args.resume, force=args.force, workers=args.workers,
            views_per_task=args.views_per_task,
            progress=not args.quiet and sys.stderr.isatty(), near=args.near, far=args.far,
            up_axis=args.up_axis, algorithm=args.algorithm, cull=args.cull,
            front_face=args.front_face, depth_func=args.depth_func, shading=args.shading,
            light=args.light,
            background=rgb(args.background, "--background"),
            options=key_values(args.option) or None)
    finally:
        if client is not None:
            client.close()
    if result.failed:
        print(f"hsr: {result.summary()}", file=sys.stderr)
        return 1
    if not args.quiet:
        print(f"wrote {result.manifest}: {result.summary()}")
    return 0
