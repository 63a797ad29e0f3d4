"""``hsr report``: one HTML page with every view, the comparison and stats."""

from __future__ import annotations

import sys

from .options import add_scene_args, algorithm_names
from .setup import input_plan, setup


def add_parser(sub) -> None:
    from ..algorithms import ALGORITHMS

    rp = sub.add_parser("report", help="one HTML page with every view, the algorithm "
                        "comparison and stats")
    add_scene_args(rp)
    rp.add_argument("-o", "--output", default="report.html", help="default %(default)s")
    rp.add_argument("--algorithms", default=",".join(ALGORITHMS),
                    help="algorithms to compare (default: all)")


def run(args) -> int:
    import os

    from ..explain.report import write_report
    from ..scene.files import check_output

    names = algorithm_names(args.algorithms)
    check_output(args.output, (".html", ".htm"))
    scene, camera, width, height, state, _, _ = setup(args)
    input_plan(args, scene).add("-o", args.output)
    title = ("hsr report: " + ", ".join(os.path.basename(m) for m in args.models)
             if args.models else f"hsr report: built-in scene {args.scene}")
    write_report(args.output, scene, camera, title, width=width, height=height, state=state,
                 algorithms=names, progress=not args.quiet and sys.stderr.isatty())
    if not args.quiet:
        print(f"wrote {args.output}")
    return 0
