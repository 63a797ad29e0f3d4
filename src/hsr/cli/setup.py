"""The scene, camera, size, render state and appearance that the rendering commands'
shared options describe (:func:`setup`), with the camera framed from the model, read from
a camera file or taken from a built-in scene."""

from __future__ import annotations

import os

import numpy as np

from .options import CliError, check_lens, check_threads, floats, key_values, load_models, rgb, size


def auto_near_far(eye: np.ndarray, bounds: np.ndarray) -> tuple[float, float]:
    """Near/far that enclose the box as seen from ``eye``."""
    from ..scene.camera import box_corners

    dist = np.linalg.norm(box_corners(bounds) - eye, axis=1)
    diag = max(float(np.linalg.norm(bounds[1] - bounds[0])), 1e-9)
    far = float(dist.max()) * 1.05 + 1e-6 * diag
    inside = np.all((eye >= bounds[0]) & (eye <= bounds[1]))
    closest = 0.0 if inside else float(np.linalg.norm(np.clip(eye, bounds[0], bounds[1]) - eye))
    near = max(closest * 0.9, far * 1e-4)
    return near, far


def camera_file(spec: str) -> tuple:
    """``(path, index)`` of --camera FILE[:INDEX]."""
    path, index = spec, 0
    if ":" in path and path.rsplit(":", 1)[1].isdigit():
        path, index = path.rsplit(":", 1)[0], int(path.rsplit(":", 1)[1])
    return path, index


def input_plan(args, scene, *files):
    """The :class:`~hsr.scene.outputs.OutputPlan` of a command's inputs: the MODEL files
    and every file the scene was read from (.mtl, textures, buffers), the --camera file,
    and ``files`` (``(what, path)`` pairs: camera files of --views, a points file)."""
    from ..scene.outputs import OutputPlan

    plan = OutputPlan()
    for path in getattr(args, "models", None) or [getattr(args, "model", None)]:
        if path is not None:
            plan.add_input("a MODEL", path)
    for path in scene.sources() if callable(getattr(scene, "sources", None)) else ():
        plan.add_input("a file the model is read from", path)
    if getattr(args, "camera", None):
        plan.add_input("the --camera file", camera_file(args.camera)[0])
    for what, path in files:
        plan.add_input(what, path)
    return plan


def views_size(specs, default: str, option: str = "--size") -> tuple:
    """The image size for --views SPECs: --size when given (``default`` is None then),
    else the first camera file's own size, else ``default``."""
    from ..scene.camera_files import read_colmap, read_transforms

    if default is not None:
        return size(default, option)
    for spec in specs or ():
        if isinstance(spec, str) and os.path.isdir(spec):
            return read_colmap(spec)[2][0]
        if isinstance(spec, str) and os.path.isfile(spec):
            return read_transforms(spec)[2]
    return 512, 512


def view_inputs(specs) -> list:
    """``(what, path)`` of each --views SPEC that names a camera file or folder."""
    return [("a --views camera file", spec) for spec in specs or ()
            if isinstance(spec, str) and os.path.lexists(spec)]


def camera_from_file(args, bounds=None):
    """(camera, (w, h)) from --camera FILE[:INDEX], else (None, None); its planes are
    --near / --far, else the file's, else fitted to the scene's box ``bounds``."""
    if not args.camera:
        return None, None
    from ..scene.camera_files import read_colmap, read_transforms

    for flag, dest in (("eye", "eye"), ("target", "target"), ("view", "view_from"),
                       ("ortho", "ortho")):
        if getattr(args, dest) is not None:
            raise CliError(f"--camera sets the camera: it does not combine with --{flag}")
    path, index = camera_file(args.camera)
    if os.path.isdir(path):
        cameras, _, sizes = read_colmap(path, near=args.near, far=args.far, bounds=bounds)
    else:
        cameras, _, size = read_transforms(path, near=args.near, far=args.far,
                                           bounds=bounds)
        sizes = [size] * len(cameras)
    if index >= len(cameras):
        raise CliError(f"--camera: {path} has {len(cameras)} cameras, no index {index}")
    return cameras[index], sizes[index]


def camera_from_args(args, scene, default_camera, aspect):
    from ..appearance.viewpoint import best_view
    from ..errors import CameraError
    from ..scene import views
    from ..scene.camera import Camera

    if args.up is not None and args.eye is None:
        # Half-applied before: the framing kept +Y's azimuth and elevation and tilted.
        raise CliError(f"--up {args.up} sets the up of a camera placed with --eye; to "
                       f"frame a model whose up is +Z (--view or the first look), give "
                       f"--up-axis z")
    up_axis = views.model_up(scene, args.up_axis)
    up = (floats(args.up, 3, "--up") if args.up is not None
          else tuple(views.up_vector(up_axis)))
    if args.view_from is not None and args.eye is not None:
        raise CliError("--view frames the model: it does not combine with --eye")
    if args.view_from is None and args.eye is None and args.target is None \
            and default_camera is not None:
        # A built-in scene: its own camera, with the user's lens settings applied.
        cam = default_camera
        near = args.near if args.near is not None else cam.near
        far = args.far if args.far is not None else cam.far
        if args.ortho is not None:
            return Camera.orthographic(cam.eye, cam.target, cam.up, args.ortho, near, far)
        fov = args.fov if args.fov != 45.0 else cam.fov_y
        return Camera.look_at(cam.eye, cam.target, cam.up, fov, near, far)
    points = views.model_points(scene)  # one pass over the vertices: box and framing
    bounds = np.stack([points.min(axis=0), points.max(axis=0)])
    target = np.array(floats(args.target, 3, "--target")) if args.target else bounds.mean(axis=0)
    eye = np.array(floats(args.eye, 3, "--eye")) if args.eye else None
    try:
        if eye is None:
            # Frame the model's bounding sphere for this aspect ratio from --view, or by
            # default from the side that shows the most of its shape (hsr.first_look).
            az, el = (floats(args.view_from, 2, "--view") if args.view_from is not None
                      else best_view(scene, args.fov, up_axis=up_axis))
            cam = Camera.frame(bounds, views.direction(az, el, up_axis), up, args.fov,
                               ortho_height=args.ortho, margin=views.MARGIN, aspect=aspect,
                               fit="points", points=points)
            if args.target is None:  # the framing's own aim (the middle of the picture)
                target = np.asarray(cam.target)
            eye = np.asarray(cam.eye) - np.asarray(cam.target) + target
            up = cam.up
            auto_near, auto_far = cam.near, cam.far
        else:
            with np.errstate(all="ignore"):  # an absurd eye fails in Camera below
                auto_near, auto_far = auto_near_far(eye, bounds)
        near = args.near if args.near is not None else auto_near
        far = args.far if args.far is not None else auto_far
        if args.ortho is not None:
            return Camera.orthographic(eye, target, up, args.ortho, near, far)
        return Camera.look_at(eye, target, up, args.fov, near, far)
    except CameraError as exc:
        # The options on their own passed check_lens: what is wrong is how they meet
        # the model (e.g. --far nearer than the framed near plane), or the model itself.
        given = [f"{name} {value}" for name, value in (
            ("--view", args.view_from), ("--eye", args.eye), ("--target", args.target),
            ("--near", args.near), ("--far", args.far), ("--ortho", args.ortho))
            if value is not None]
        if given:
            raise CliError(f"{', '.join(given)}: no valid camera for this model with "
                           f"{'this value' if len(given) == 1 else 'these values'} ({exc})") \
                from None
        raise CliError(f"the camera framed from the model's bounds is not valid ({exc}); "
                       f"set --eye, --target, --near and --far") from None


def view_setup(args, scene, default_camera=None) -> tuple:
    """``(camera, width, height)`` from the camera arguments (:func:`add_camera_args`)."""
    check_lens(args)
    # The camera file's planes, where it gives none, fit the scene (read after it).
    file_camera, file_size = camera_from_file(args, scene.bounds() if args.camera else None)
    width, height = size(args.size) if args.size else (file_size or (800, 600))
    camera = file_camera or camera_from_args(args, scene, default_camera, width / height)
    return camera, width, height


def setup(args):
    """Scene, camera, size, state, background and options from the shared arguments."""
    from ..geometry.state import RenderState
    from ..scene import builtin as scenes

    check_lens(args)
    default_camera = None
    if args.light is None:
        args.light = "studio" if args.models else "headlight"
    if args.models:
        # owner[i]: the MODEL instance i came from
        scene, owner = load_models(args.models, args.command)
        apply_textures(args, scene, owner)
    else:
        if args.texture:
            raise CliError("--texture needs MODEL files")
        scene, default_camera = scenes.get(args.scene)
        owner = list(range(len(scene.instances)))
    camera, width, height = view_setup(args, scene, default_camera)
    if args.opacity:
        count = len(args.models) if args.models else len(scene.instances)
        values = args.opacity.split(",")
        if len(values) not in (1, count):
            raise CliError(f"--opacity needs 1 or {count} values (one per "
                           f"{'MODEL' if args.models else 'object'}), got {len(values)}")
        try:
            opacity = [float(v) for v in values] * (count if len(values) == 1 else 1)
        except ValueError:
            raise CliError(f"--opacity values must be numbers, got {args.opacity!r}") from None
        for a in opacity:
            if not 0.0 <= a <= 1.0:
                raise CliError(f"--opacity values must be in 0..1, got {a}")
        for inst, k in zip(scene.instances, owner):
            inst.opacity = opacity[k]
    state = RenderState(depth_test=not args.no_depth_test, depth_func=args.depth_func,
                        depth_mask=not args.no_depth_write, clear_depth=args.clear_depth,
                        depth_range=floats(args.depth_range, 2, "--depth-range"),
                        cull=args.cull, front_face=args.front_face,
                        polygon_mode=args.polygon_mode,
                        polygon_offset=(floats(args.polygon_offset, 2, "--polygon-offset")
                                        if args.polygon_offset else (0.0, 0.0)))
    background = rgb(args.background, "--background")
    check_threads(args)
    return scene, camera, width, height, state, background, key_values(args.option)


def apply_textures(args, scene, owner) -> None:
    """--texture [MODEL=]IMAGE: each image to the instances of its MODEL (all of the one
    MODEL when no MODEL= is given). A MODEL named twice, a MODEL not on the command line,
    a bare IMAGE with several MODELs, or a MODEL without texture coordinates is an error:
    never a silent choice."""
    given: dict = {}
    for value in args.texture:
        model, image = None, value
        if "=" in value and not os.path.isfile(value):
            model, image = value.split("=", 1)
            matches = [k for k, path in enumerate(args.models)
                       if model in (path, os.path.basename(path))]
            if not matches:
                raise CliError(f"--texture {value}: {model!r} is not one of the MODELs "
                               f"({', '.join(args.models)})")
            if len(matches) > 1:
                raise CliError(f"--texture {value}: {model!r} names {len(matches)} MODELs; "
                               f"give its path")
            k = matches[0]
        elif len(args.models) == 1:
            k = 0
        else:
            raise CliError(f"--texture {value}: {len(args.models)} MODELs given; say which "
                           f"with MODEL=IMAGE")
        if k in given:
            raise CliError(f"--texture: {args.models[k]} is given two textures "
                           f"({given[k]} and {image})")
        given[k] = image
    for k, image in given.items():
        targets = [inst for inst, o in zip(scene.instances, owner) if o == k]
        if not any(inst.mesh.corner_uv is not None for inst in targets):
            raise CliError(f"--texture {image}: {args.models[k]} has no texture coordinates "
                           f"(OBJ vt / glTF TEXCOORD_0)")
        for inst in targets:  # read (and checked) when shading starts
            if inst.mesh.corner_uv is not None:
                inst.mesh.texture = image


def look(args):
    from ..appearance.fog import parse_fog
    from ..appearance.shading import Look

    fog = None
    if args.fog:
        fog = parse_fog(args.fog, rgb(args.fog_color, "--fog-color"), args.fog_distance)
    return Look(args.shading, not args.no_texture, args.texture_filter, args.texture_wrap, fog,
                args.light)


def hidden_line_args(args):
    from ..lines.raster import HiddenLine

    color = rgb(args.line_color, "--line-color") if args.line_color else None
    offset = (floats(args.polygon_offset, 2, "--polygon-offset") if args.polygon_offset
              else (1.0, 1.0))
    return HiddenLine(args.edges, args.crease_angle, offset, color, args.hidden_line_fill,
                      bool(getattr(args, "intersections", False)))
