"""``hsr partition``: a scene split into spatially coherent parts, for sort-last rendering."""

from __future__ import annotations

import sys


def add_parser(sub) -> None:
    p = sub.add_parser("partition", help="split a scene into parts for sort-last rendering",
                       description="Split the faces of the MODELs (one scene) into PARTS "
                       "spatially coherent parts (Morton order of their centroids) and write "
                       "them to a Zarr v3 store that hsr batch renders part by part on a "
                       "Dask cluster (sort-last compositing), so no worker holds the whole "
                       "scene. One binary PLY of triangles is streamed: it may be larger "
                       "than memory.")
    p.add_argument("models", nargs="+", metavar="MODEL", help="mesh files, one scene")
    p.add_argument("--parts", type=int, required=True, metavar="K", help="how many parts")
    p.add_argument("--out", required=True, metavar="STORE", help="the store to write (a "
                   "folder)")
    p.add_argument("--force", action="store_true", help="replace STORE if it is a "
                   "partitioned scene already")
    p.add_argument("--stream", action="store_true", help="read one MODEL (binary PLY, OBJ "
                   "or GLB) in chunks, so it may be larger than memory; geometry only (a "
                   "binary PLY of geometry alone streams anyway)")
    p.add_argument("--quiet", action="store_true", help="no summary")


def run(args) -> int:
    from ..scene.partition import partition
    from ..scene.ply import is_binary_ply
    from .options import CliError, load_models

    if args.stream and len(args.models) != 1:
        raise CliError("--stream reads one MODEL file")
    if len(args.models) == 1 and (args.stream or is_binary_ply(args.models[0])):
        scene = args.models[0]  # partition() decides: streamed, or loaded
    else:
        scene, _ = load_models(args.models, "partition")
    store = partition(scene, args.parts, args.out, overwrite=args.force,
                      progress=not args.quiet and sys.stderr.isatty(),
                      stream=True if args.stream else None)
    if not args.quiet:
        sizes = store.part_faces
        print(f"wrote {store.path}: {store.n_faces:,} faces in {store.parts} parts "
              f"({min(sizes):,} to {max(sizes):,} faces each)")
    return 0
