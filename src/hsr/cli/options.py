"""What several ``hsr`` commands share: the one-line error, the parser and help format,
the value parsers (numbers, colours, sizes, KEY=VALUE), the checks of options on their
own, the Dask client, and the scene/camera/state/appearance options that every
rendering command takes (each defined once, here)."""

from __future__ import annotations

import argparse
import math

from ..errors import HsrError
from ..scene.mesh import MAX_COORDINATE

EXIT_USAGE = 2


class CliError(HsrError):
    """A command-line argument is malformed."""


class Parser(argparse.ArgumentParser):
    """argparse, but errors are one line (no usage block) and raise instead of exiting,
    so every bad input goes through the same reporting path."""

    def error(self, message):
        raise CliError(message)


class HelpFormatter(argparse.HelpFormatter):
    """Help that states each option's default (where it has one worth stating)."""

    def _get_help_string(self, action):
        text = action.help or ""
        if ("default" in text or not action.option_strings
                or action.default in (None, False, [], argparse.SUPPRESS)):
            return text
        return text + " (default: %(default)s)"


def floats(text: str, count: int, what: str) -> tuple:
    parts = text.replace(" ", "").split(",")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        raise CliError(f"{what} must be {count} comma-separated numbers, got {text!r}") from None
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise CliError(f"{what} must be {count} finite comma-separated numbers, got {text!r}")
    if any(abs(v) > MAX_COORDINATE for v in values):
        raise CliError(f"{what} values must be within +-{MAX_COORDINATE:g}, got {text!r}")
    return values


def rgb(text: str, what: str) -> tuple:
    """An r,g,b colour with components in 0..255."""
    color = floats(text, 3, what)
    if not all(0 <= c <= 255 for c in color):
        raise CliError(f"{what} values must be in 0..255, got {text!r}")
    return tuple(int(c) for c in color)


def size(text: str, option: str = "--size") -> tuple[int, int]:
    """WxH (or N for NxN), each side in 1..MAX_SIZE, checked here so the error names the option (the
    size is used for the aspect ratio before any render sees it)."""
    from ..geometry.viewport import MAX_SIZE

    parts = text.lower().split("x")
    if len(parts) == 1:  # N: a square, as the library's size=N
        parts = parts * 2
    try:
        width, height = (int(p) for p in parts)
    except ValueError:
        raise CliError(f"{option} must look like 800x600 (or 96 for 96x96), got "
                       f"{text!r}") from None
    if not (0 < width <= MAX_SIZE and 0 < height <= MAX_SIZE):
        raise CliError(f"{option} sides must be in 1..{MAX_SIZE}, got {text!r}")
    return width, height


def check_lens(args) -> None:
    """--fov, --near, --far and --ortho on their own, before any camera is framed from
    them, so a bad value is named (not blamed on the framing)."""
    for name, value in (("--fov", args.fov), ("--near", args.near), ("--far", args.far),
                        ("--ortho", args.ortho)):
        if value is not None and not (math.isfinite(value) and abs(value) <= MAX_COORDINATE):
            raise CliError(f"{name} must be a finite number within +-{MAX_COORDINATE:g}, "
                           f"got {value}")
    if not 0.0 < args.fov < 180.0:
        raise CliError(f"--fov must be in (0, 180) degrees, got {args.fov:g}")
    if args.ortho is not None and args.ortho <= 0.0:
        raise CliError(f"--ortho (the visible height) must be > 0, got {args.ortho:g}")
    if args.ortho is None:
        for name, value in (("--near", args.near), ("--far", args.far)):
            if value is not None and value <= 0.0:
                raise CliError(f"{name} must be > 0 for a perspective camera (with --ortho "
                               f"it may be negative), got {value:g}")
    if args.near is not None and args.far is not None and args.far <= args.near:
        raise CliError(f"--far ({args.far:g}) must be greater than --near ({args.near:g})")


def key_values(pairs) -> dict:
    """--option KEY=VALUE pairs; numbers and true/false are converted."""
    options = {}
    for pair in pairs:
        if "=" not in pair:
            raise CliError(f"--option must look like KEY=VALUE, got {pair!r}")
        key, value = pair.split("=", 1)
        low = value.lower()
        if low in ("true", "false"):
            options[key] = low == "true"
        else:
            try:
                options[key] = int(value)
            except ValueError:
                try:
                    options[key] = float(value)
                except ValueError:
                    options[key] = value
    return options


def check_threads(args) -> None:
    if args.threads is not None and args.threads < 1:
        raise CliError(f"--threads must be >= 1, got {args.threads}")


def dask_client(address: str, command: str):
    """A ``distributed.Client`` connected to ``address``, or a one-line error."""
    from ..errors import require_extra

    require_extra(f"hsr {command} --scheduler", "distributed")
    from distributed import Client

    try:
        return Client(address, timeout="10s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise CliError(f"--scheduler {address}: cannot connect ({exc})") from None


def algorithm_names(text: str) -> list:
    """A comma-separated list of algorithm names, checked."""
    from ..algorithms import ALGORITHMS

    names = [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in ALGORITHMS]
    if unknown or not names:
        raise CliError(f"unknown algorithm {', '.join(unknown) or '(none)'}; choose from "
                       f"{', '.join(ALGORITHMS)}")
    return names


def add_algorithm(g, help="visibility algorithm") -> None:
    from ..algorithms import ALGORITHMS

    g.add_argument("--algorithm", default="zbuffer", choices=sorted(ALGORITHMS), help=help)


def add_cull(g, help="glCullFace") -> None:
    from ..geometry.state import CullMode

    g.add_argument("--cull", default="none", choices=[m.value for m in CullMode], help=help)


def add_front_face(g, help="glFrontFace") -> None:
    from ..geometry.state import FrontFace

    g.add_argument("--front-face", default="ccw", choices=[m.value for m in FrontFace],
                   help=help)


def add_depth_func(g, help="glDepthFunc") -> None:
    from ..geometry.state import DepthFunc

    g.add_argument("--depth-func", default="less", choices=[m.value for m in DepthFunc],
                   help=help)


def add_file_planes(g) -> None:
    """--near and --far for the cameras of camera files (default: the file's planes, as
    hsr writes them, else fitted to the scene)."""
    g.add_argument("--near", type=float, help="near plane for camera files (default: the "
                   "file's, else fitted to the scene)")
    g.add_argument("--far", type=float, help="far plane for camera files (default: the "
                   "file's, else fitted to the scene)")


def add_up_axis(group, what: str) -> None:
    """``--up-axis y|z``: the model's up (default: what the file declares, else y)."""
    group.add_argument("--up-axis", choices=["y", "z"], help=f"the model's up: y (glTF, "
                       f"OpenGL) or z (CAD, scans, Blender, STL); {what} (default: what "
                       f"the file declares: y for glTF, z for STL and 3MF, else y)")


def add_camera_args(g) -> None:
    """The camera: --size, --view, --eye, --target, --up, --up-axis, --camera, --fov,
    --near, --far, --ortho (read by :func:`hsr.cli.setup.view_setup`)."""
    g.add_argument("--size", help="WxH in pixels (default: the --camera file's, else 800x600)")
    g.add_argument("--view", dest="view_from", metavar="AZ,EL", help="frame the model from "
                   "azimuth AZ (degrees from +Z towards +X) and elevation EL (degrees up) "
                   "(default for MODELs: the side showing the most shape, hsr.best_view; "
                   "built-in scenes: their own camera)")
    g.add_argument("--eye", help="camera position x,y,z (default: frame the model)")
    g.add_argument("--target", help="point looked at x,y,z (default: centre of the model)")
    g.add_argument("--up", help="up vector x,y,z of a camera placed with --eye (default: "
                   "the --up-axis)")
    add_up_axis(g, "--view and the first look turn about it")
    g.add_argument("--camera", metavar="FILE[:INDEX]", help="camera INDEX (default 0) of a "
                   "NeRF transforms.json or a COLMAP text model folder")
    g.add_argument("--fov", type=float, default=45.0, help="vertical field of view, degrees")
    g.add_argument("--near", type=float, help="near plane distance (default: hug the model)")
    g.add_argument("--far", type=float, help="far plane distance (default: hug the model)")
    g.add_argument("--ortho", type=float, metavar="HEIGHT",
                   help="orthographic projection showing HEIGHT world units vertically")


def add_scene_args(p):
    """Arguments shared by every command that renders, in groups: scene, camera, depth
    state, culling and polygons, appearance, run."""
    from ..appearance.shading import LIGHTS, SHADING_MODES
    from ..scene.builtin import SCENES

    p.add_argument("models", nargs="*", metavar="MODEL", help="mesh files (OBJ, PLY, STL, "
                   "OFF, glTF/GLB: one object per node), drawn in order")
    g = p.add_argument_group("scene")
    g.add_argument("--scene", default="cubes", choices=list(SCENES),
                   help="built-in scene when no MODEL is given (default %(default)s)")
    g.add_argument("--opacity", metavar="A[,A...]",
                   help="opacity per MODEL (or one for all), 0..1; < 1 is blended")
    add_camera_args(p.add_argument_group("camera"))
    g = p.add_argument_group("depth state")
    add_depth_func(g)
    g.add_argument("--no-depth-test", action="store_true", help="glDisable(GL_DEPTH_TEST)")
    g.add_argument("--no-depth-write", action="store_true", help="glDepthMask(GL_FALSE)")
    g.add_argument("--clear-depth", type=float, default=1.0, help="glClearDepth value")
    g.add_argument("--depth-range", default="0,1", help="glDepthRange near,far")
    g = p.add_argument_group("culling and polygons")
    add_cull(g)
    add_front_face(g)
    g.add_argument("--polygon-mode", default="fill", choices=["fill", "line", "point"],
                   help="glPolygonMode: line draws every edge, visible and hidden")
    g.add_argument("--polygon-offset", metavar="FACTOR,UNITS",
                   help="glPolygonOffset for filled triangles")
    g = p.add_argument_group("appearance")
    g.add_argument("--shading", default="auto", choices=list(SHADING_MODES),
                   help="how visible faces are coloured (auto: smooth where the file "
                   "carries normals, else flat)")
    g.add_argument("--light", choices=list(LIGHTS),
                   help="studio: a key light from above-left-front and a fill, so shapes "
                   "read; headlight: one light along the view, the textbooks' (default: "
                   "studio for MODELs, headlight for built-in scenes, as the seeds draw them)")
    g.add_argument("--texture", action="append", default=[], metavar="[MODEL=]IMAGE",
                   help="diffuse texture for MODEL (or for the one MODEL given); the MODEL "
                   "needs texture coordinates; repeatable, once per MODEL")
    g.add_argument("--no-texture", action="store_true", help="ignore textures")
    g.add_argument("--texture-filter", default="bilinear", choices=["nearest", "bilinear"],
                   help="GL_NEAREST or GL_LINEAR")
    g.add_argument("--texture-wrap", default="repeat", choices=["repeat", "clamp"],
                   help="GL_REPEAT or GL_CLAMP_TO_EDGE")
    g.add_argument("--fog", metavar="MODE:PARAMS",
                   help="depth cueing: linear:START,END, exp:DENSITY or exp2:DENSITY")
    g.add_argument("--fog-color", default="128,128,128", help="fog colour r,g,b (0-255)")
    g.add_argument("--fog-distance", default="radial", choices=["radial", "plane"],
                   help="eye distance (radial) or |z_eye| (plane)")
    g.add_argument("--background", default="0,0,0", help="background colour r,g,b (0-255)")
    g = p.add_argument_group("run")
    g.add_argument("--threads", type=int, help="threads for the kernels (default: all cores)")
    g.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="algorithm option, e.g. accel=none (raycast); repeatable")
    g.add_argument("--quiet", action="store_true", help="print nothing on success")


def load_models(paths, command: str) -> tuple:
    """``(scene, owner)``: the MODEL files as one Scene, instances in file order, and for
    each instance the index of the MODEL it came from. A partitioned scene (a store that
    hsr partition wrote) is refused: only hsr batch renders one."""
    from ..scene.load import load_scene
    from ..scene.mesh import Scene
    from ..scene.partitioned import PartitionedScene

    scene, owner = Scene(), []
    for k, path in enumerate(paths):
        loaded = load_scene(path)
        if isinstance(loaded, PartitionedScene):
            raise CliError(f"{path} is a partitioned scene: hsr batch renders it (hsr "
                           f"{command} takes mesh files)")
        scene.instances.extend(loaded.instances)
        owner += [k] * len(loaded.instances)
    return scene, owner
