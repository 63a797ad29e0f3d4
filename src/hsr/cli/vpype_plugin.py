"""``vpype hsr``: hsr's exact visible lines as layers of a vpype document (the ``[plot]``
extra). A vpype global processor, registered through the ``vpype.plugins`` entry point::

    vpype hsr bunny.ply --view 35,25 linemerge linesort write out.svg

Each kind of line goes into its own layer, numbered as in hsr's SVG
(:data:`hsr.lines.drawing.LAYERS`: 1 silhouette, 2 boundary, 3 crease, 4 intersection,
5 non-manifold, 6 a CAD model's own edges, 7 the hidden parts with ``--hidden-layer``,
8 other edges, 9 object borders), named after the kind, in plotter order. Coordinates are
the image's pixels (CSS pixels to vpype); the page is the image unless the pipeline
already has one (``layout`` and ``scaleto`` fit it to paper). The options are ``hsr
lines``'s, read by the same code.
"""

from __future__ import annotations

import click
import vpype
import vpype_cli

from ..errors import HsrError
from ..geometry.state import CullMode, FrontFace
from ..lines.drawing import HIDDEN_LAYER, LAYERS
from ..lines.paths import JOIN_PX

__all__ = ["hsr_command"]

# click option -> hsr lines flag, for the options that take a value.
_VALUED = ("view", "size", "camera", "eye", "target", "up", "up_axis", "fov", "near",
           "far", "ortho", "edges", "crease_angle", "cull", "front_face", "threads")


def _argv(model, options: dict) -> list:
    """``hsr lines`` arguments for the same request (its parser checks them)."""
    argv = ["lines", model, "-o", "vpype.svg", "--quiet"]
    for name in _VALUED:
        value = options.get(name)
        if value is not None:
            argv.append(f"--{name.replace('_', '-')}={value}")
    for flag in ("intersections", "hidden_layer"):
        if options.get(flag):
            argv.append(f"--{flag.replace('_', '-')}")
    return argv


class _ModelFirst(click.Command):
    """Takes ``hsr MODEL --view 35,25 ...`` as well as vpype's options-first order: the
    options right after MODEL are moved before it (vpype chains commands, so click stops
    reading a command's options at its first positional argument)."""

    def parse_args(self, ctx, args):
        if args and not args[0].startswith("-"):
            takes_value = {opt: not p.is_flag for p in self.params
                           if isinstance(p, click.Option) for opt in p.opts}
            k = 1
            while k < len(args) and args[k].split("=", 1)[0] in takes_value:
                name = args[k].split("=", 1)[0]
                k += 2 if "=" not in args[k] and takes_value[name] else 1
            args = args[1:k] + args[:1] + args[k:]
        return super().parse_args(ctx, args)


@click.command("hsr", cls=_ModelFirst)
@click.argument("model", metavar="MODEL")
@click.option("--view", metavar="AZ,EL", help="frame the model from azimuth AZ and "
              "elevation EL, degrees (default: the first look, hsr.best_view)")
@click.option("--size", metavar="WxH", help="image in pixels (default 800x600, or the "
              "camera file's)")
@click.option("--camera", metavar="FILE[:INDEX]", help="a NeRF transforms.json or a COLMAP "
              "text model folder")
@click.option("--eye", metavar="X,Y,Z", help="camera position")
@click.option("--target", metavar="X,Y,Z", help="point looked at")
@click.option("--up", metavar="X,Y,Z", help="up vector of a camera placed with --eye")
@click.option("--up-axis", type=click.Choice(["y", "z"]), help="the model's up")
@click.option("--fov", type=float, help="vertical field of view, degrees (default 45)")
@click.option("--near", type=float, help="near plane distance")
@click.option("--far", type=float, help="far plane distance")
@click.option("--ortho", type=float, metavar="HEIGHT", help="orthographic, HEIGHT units high")
@click.option("--edges", type=click.Choice(["feature", "all"]), help="feature edges "
              "(default) or every edge")
@click.option("--crease-angle", type=float, help="creases sharper than this (default 30)")
@click.option("--intersections", is_flag=True, help="also where faces pass through each other")
@click.option("--hidden-layer", is_flag=True, help="also the hidden parts, in layer 7")
@click.option("--cull", type=click.Choice([m.value for m in CullMode]),
              help="glCullFace: culled faces neither hide nor draw lines")
@click.option("--front-face", type=click.Choice([m.value for m in FrontFace]), help="glFrontFace")
@click.option("--threads", type=int, help="threads for the kernels (default: all cores)")
@click.option("--join-tolerance", type=vpype_cli.LengthType(), default="0.05mm",
              help="join line ends closer than this, as linemerge does (default 0.05mm; "
              "0: only the ends that meet exactly, within 0.01 px)")
@vpype_cli.global_processor
def hsr_command(document: vpype.Document, model, **options) -> vpype.Document:
    """Exact visible lines of MODEL (a mesh file: OBJ, PLY, STL, OFF, glTF), one layer per
    kind of line."""
    from . import build_parser
    from .lines import drawing_from_args

    join = options.pop("join_tolerance")
    if not join >= 0:
        raise click.BadParameter(f"must be >= 0, got {join}", param_hint="--join-tolerance")
    try:
        args = build_parser().parse_args(_argv(model, options))
        # vpype's pixels are CSS pixels and the drawing's are the image's: one to one.
        drawing, _, _, _ = drawing_from_args(args, check_out=False,
                                             join_px=max(float(join), JOIN_PX))
    except HsrError as exc:
        raise click.UsageError(f"hsr: {exc}") from None
    numbers = {name: number for name, _, number in LAYERS}
    layers = [(numbers[name], name, lines) for name, lines in drawing.layers.items()]
    if options.get("hidden_layer") and drawing.hidden_polylines:
        layers.append((HIDDEN_LAYER, "hidden", drawing.hidden_polylines))
    for number, name, polylines in layers:
        lines = vpype.LineCollection([p[:, 0] + 1j * p[:, 1] for p in polylines])
        document.add(lines, number)
        document.layers[number].set_property(vpype.METADATA_FIELD_NAME, name)
    document.extend_page_size((float(drawing.width), float(drawing.height)))
    return document
