"""``hsr prune``: remove the geometry no viewpoint can see."""

from __future__ import annotations

import sys

import numpy as np

from .options import (
    CliError,
    add_algorithm,
    add_cull,
    add_depth_func,
    add_file_planes,
    add_front_face,
    add_up_axis,
    check_threads,
    dask_client,
)


def add_parser(sub) -> None:
    from ..scene.write import MESH_FORMATS
    from ..visibility.prune import AUTO_SIZE, LEVELS

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
    add_up_axis(g, "orbit and the other view sets turn about it")
    g.add_argument("--max-views", type=int, default=2048, metavar="N",
                   help="auto starts no round that would pass N views")
    g.add_argument("--level", default="faces", choices=list(LEVELS),
                   help="remove single faces, or whole objects (glTF nodes)")
    g.add_argument("--min-pixels", type=int, default=1, metavar="P",
                   help="keep a face seen on at least P pixels over all views")
    g.add_argument("--exact", action="store_true", help="decide by each face's exact "
                   "visible area (hsr.visible_regions), so no visible face is removed "
                   "however small; --min-pixels is then an area in px^2 (1: any)")
    g.add_argument("--keep-neighbors", type=int, metavar="K",
                   help="also keep faces within K edge-rings of a kept face (default: 2 "
                   "with auto views, else 0)")
    add_algorithm(g, "visibility algorithm whose face ids decide")
    add_cull(g, "face culling while deciding (none: a face seen from behind counts)")
    add_front_face(g, None)
    add_depth_func(g, "depth test: with less an earlier coplanar face keeps its pixels")
    add_file_planes(g)
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


def run(args) -> int:
    import time

    from ..scene.load import load_scene
    from ..scene.partitioned import PartitionedScene
    from ..scene.write import check_new, planned_files, write_mesh
    from ..visibility.count import cameras_for
    from ..visibility.prune import MAX_VERIFY, decide, split_auto, subset_scene, unsettled, verify
    from .setup import input_plan, view_inputs

    start = time.perf_counter()
    _check_prune_output(args)
    check_threads(args)
    if not 0 <= args.verify <= MAX_VERIFY:  # checked by verify() too, but after the work
        raise CliError(f"--verify must be a number of views in 0..{MAX_VERIFY}, got "
                       f"{args.verify}")
    if args.size != "auto":
        try:
            args.size = int(args.size)
        except ValueError:
            raise CliError(f"--size must be an integer or auto, got {args.size!r}") from None
    scene = load_scene(args.model)
    store = None
    if isinstance(scene, PartitionedScene):  # counted part by part, cut in memory
        store, scene = scene, scene.assemble()
    planned = planned_files(scene, args.output)
    if not args.force:  # the .mtl and textures beside an OBJ, known once it is loaded
        check_new(planned, "--force")
    plan = input_plan(args, store or scene, *view_inputs(args.views))
    for path in planned:
        plan.add("-o", path)
    auto, fixed = split_auto(args.views or ["auto"])
    # The cameras once, before any connection: a bad --views fails at once.
    cameras = (cameras_for(scene, fixed, 1.0, args.near, args.far, args.up_axis)
               if fixed else [])
    client = dask_client(args.scheduler, "prune") if args.scheduler else None
    options = dict(algorithm=args.algorithm, cull=args.cull, front_face=args.front_face,
                   depth_func=args.depth_func)
    if args.exact:
        if args.algorithm != "zbuffer" or store is not None:
            raise CliError("--exact computes visible regions: it takes neither --algorithm "
                           "nor a partitioned scene (yet)")
        options = dict(options, exact=True)
        del options["algorithm"]
    try:
        decision = decide(scene, cameras + (["auto"] if auto else []), args.size,
                          level=args.level, keep_neighbors=args.keep_neighbors,
                          min_pixels=args.min_pixels, seed=args.seed,
                          max_views=args.max_views, client=client, threads=args.threads,
                          progress=not args.quiet and sys.stderr.isatty(), count_on=store,
                          **options)
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


def _check_prune_output(args) -> None:
    """Before any work: OUT is never MODEL (nor a link to it), and an OUT that exists is
    replaced only with --force."""
    from ..scene.files import check_output
    from ..scene.outputs import same_file
    from ..scene.write import MESH_FORMATS, check_new

    check_output(args.output, MESH_FORMATS)
    if same_file(args.output, args.model):  # a link, a hard link too
        raise CliError(f"-o {args.output} is MODEL itself: write the pruned model to "
                       f"another file")
    if not args.force:
        check_new([args.output], "--force")
