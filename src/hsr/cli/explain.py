"""``hsr explain VIEW``: a picture that explains one part of hidden-surface removal."""

from __future__ import annotations

from .options import add_scene_args
from .setup import input_plan, setup


def add_parser(sub) -> None:
    from ..explain.views import VIEWS

    e = sub.add_parser("explain", help="a picture that explains one part of hidden-surface "
                       "removal", description="Views: " + ", ".join(VIEWS) + ".")
    e.add_argument("view", choices=list(VIEWS))
    add_scene_args(e)
    e.add_argument("-o", "--output", help="PNG (or .gif for the painter animation); "
                   "default VIEW.png")


def run(args) -> int:
    from ..explain.views import explain
    from ..scene.files import check_output

    output = check_output(args.output or f"{args.view}.png")
    scene, camera, width, height, state, _, _ = setup(args)
    input_plan(args, scene).add("-o", output)
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
