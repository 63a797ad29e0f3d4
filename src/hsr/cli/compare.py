"""``hsr compare``: one scene with several algorithms, a table and a montage."""

from __future__ import annotations

import sys

import numpy as np

from .options import CliError, add_scene_args, algorithm_names
from .setup import input_plan, look, setup


def add_parser(sub) -> None:
    from ..algorithms import ALGORITHMS

    c = sub.add_parser("compare", help="render one scene with every algorithm and compare",
                       description="Render the scene with each algorithm and print time, "
                       "agreement with the z-buffer and algorithm-specific counts.")
    add_scene_args(c)
    c.add_argument("--algorithms", default=",".join(ALGORITHMS),
                   help="comma-separated algorithms (default: all: %(default)s)")
    c.add_argument("--montage", "-o", "--output", dest="montage",
                   help="write the images side by side with difference maps (PNG)")


def run(args) -> int:
    from ..algorithms import ALGORITHMS
    from ..explain.compare import compare_algorithms, montage
    from ..scene.files import check_output, save_image

    names = algorithm_names(args.algorithms)
    if args.montage:
        check_output(args.montage)
    scene, camera, width, height, state, background, options = setup(args)
    if args.montage:
        input_plan(args, scene).add("--montage", args.montage)
    known = {k for n in names for k in ALGORITHMS[n].OPTIONS}
    if set(options) - known:
        raise CliError(f"no chosen algorithm has option {', '.join(sorted(set(options) - known))}")
    results = compare_algorithms(scene, camera, width, height, names, state=state,
                                 look=look(args), background=background,
                                 threads=args.threads, options=options,
                                 progress=not args.quiet and sys.stderr.isatty())
    if not args.quiet:
        print(results.table())
    if args.montage:
        save_image(np.asarray(montage(results)), args.montage)
        if not args.quiet:
            print(f"wrote {args.montage}")
    return 0
