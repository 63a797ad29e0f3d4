"""What a request to the viewer may ask for: every control with its allowed values
(:data:`CONTROLS`, served as ``/api/options``), the parsing of a query into a
:class:`ViewRequest` (a bad value is a :class:`ViewerError` naming it, which the server
answers with HTTP 400), and the orbit camera the page drives.

The camera orbits the centre of the scene's bounding sphere: azimuth ``az`` (degrees from
+Z towards +X) and elevation ``el`` as in :func:`hsr.views.direction`; ``dist`` scales the
distance at which the whole sphere fits the view; ``tx``, ``ty`` move the point looked at
along the image's right and up axes, in sphere radii (pan).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import HsrError

__all__ = ["ViewerError", "CONTROLS", "BUFFERS", "ViewRequest", "parse", "orbit_camera",
           "orbit_of", "MAX_PIXELS"]

MAX_PIXELS = 2048 * 2048
MAX_SIDE = 4096


class ViewerError(HsrError):
    """A request to the viewer names an unknown parameter or a value out of range."""


BUFFERS = ("color", "window_depth", "eye_depth", "face_ids", "normals", "overdraw",
           "painter_error", "zbuffer_diff")


def _controls():
    from ..algorithms import ALGORITHMS
    from ..appearance.shading import LIGHTS, SHADING_MODES
    from ..geometry.state import CullMode, DepthFunc, FrontFace

    # name -> (kind, default, allowed values or (low, high), what it is)
    return {
        "scene": ("scene", None, None, "a model named on the command line or a built-in scene"),
        "az": ("float", 35.0, (-100000.0, 100000.0), "azimuth, degrees from +Z towards +X"),
        "el": ("float", 25.0, (-89.9, 89.9), "elevation, degrees"),
        "dist": ("float", 1.0, (0.02, 50.0), "distance, 1 = the model just fits"),
        "tx": ("float", 0.0, (-20.0, 20.0), "pan right, in model radii"),
        "ty": ("float", 0.0, (-20.0, 20.0), "pan up, in model radii"),
        "fov": ("float", 45.0, (1.0, 170.0), "vertical field of view, degrees"),
        "w": ("int", 800, (1, MAX_SIDE), "width in pixels"),
        "h": ("int", 600, (1, MAX_SIDE), "height in pixels"),
        "algorithm": ("choice", "zbuffer", tuple(sorted(ALGORITHMS)), "visibility algorithm"),
        "cull": ("choice", "none", tuple(m.value for m in CullMode), "glCullFace"),
        "front_face": ("choice", "ccw", tuple(m.value for m in FrontFace), "glFrontFace"),
        "depth_test": ("bool", True, None, "glEnable(GL_DEPTH_TEST)"),
        "depth_write": ("bool", True, None, "glDepthMask"),
        "depth_func": ("choice", "less", tuple(m.value for m in DepthFunc), "glDepthFunc"),
        "clear_depth": ("float", 1.0, (0.0, 1.0), "glClearDepth"),
        "depth_near": ("float", 0.0, (0.0, 1.0), "glDepthRange near"),
        "depth_far": ("float", 1.0, (0.0, 1.0), "glDepthRange far"),
        "polygon_mode": ("choice", "fill", ("fill", "line", "point"), "glPolygonMode"),
        "offset_factor": ("float", 0.0, (-100.0, 100.0), "glPolygonOffset factor"),
        "offset_units": ("float", 0.0, (-1000.0, 1000.0), "glPolygonOffset units"),
        "shading": ("choice", "auto", tuple(SHADING_MODES), "how visible faces are coloured"),
        "light": ("choice", "studio", tuple(LIGHTS), "lights"),
        "fog": ("choice", "none", ("none", "linear", "exp", "exp2"), "depth cueing"),
        "fog_density": ("float", 0.3, (0.0, 100.0), "exp / exp2 fog density (per radius)"),
        "hidden_lines": ("bool", False, None, "draw the visible edges over the surfaces"),
        "occlusion_cull": ("bool", False, None, "skip objects hidden behind nearer ones"),
        "transparency": ("choice", "object", ("object", "exact"), "order of transparent "
                         "objects: per object or per fragment"),
        "buffer": ("choice", "color", BUFFERS, "what is shown"),
        "format": ("choice", "png", ("png", "jpeg"), "image format"),
        "quality": ("int", 85, (10, 95), "JPEG quality"),
        "x": ("int", 0, (0, MAX_SIDE - 1), "pixel column (pick)"),
        "y": ("int", 0, (0, MAX_SIDE - 1), "pixel row, 0 = top (pick)"),
        "view": ("choice", "depth", None, "explanation view (explain)"),
    }


CONTROLS = _controls()


@dataclass(frozen=True)
class ViewRequest:
    """One validated request: every control's value (see :data:`CONTROLS`)."""

    values: dict

    def __getattr__(self, name):
        try:
            return self.values[name]
        except KeyError:
            raise AttributeError(name) from None

    def state_fields(self) -> dict:
        """Keyword arguments of :class:`hsr.RenderState`."""
        return {"depth_test": self.depth_test, "depth_mask": self.depth_write,
                "depth_func": self.depth_func, "clear_depth": self.clear_depth,
                "depth_range": (self.depth_near, self.depth_far), "cull": self.cull,
                "front_face": self.front_face, "polygon_mode": self.polygon_mode,
                "polygon_offset": (self.offset_factor, self.offset_units)}


def parse(query, scenes, extra=(), views=()) -> ViewRequest:
    """A :class:`ViewRequest` from a query mapping (strings), for the scene names
    ``scenes`` (the first is the default). Every endpoint takes the view's controls;
    ``extra`` adds pick's (``x``, ``y``) or explain's (``view``). ``views``: explanation
    views. Raises :class:`ViewerError` for an unknown parameter or a bad value."""
    allowed = (set(CONTROLS) - {"x", "y", "view"}) | set(extra)
    unknown = sorted(set(query) - allowed)
    if unknown:
        raise ViewerError(f"unknown parameter {unknown[0]!r} (this endpoint takes: "
                          f"{', '.join(sorted(allowed))})")
    values = {}
    for name in allowed:
        kind, default, allowed_values, _ = CONTROLS[name]
        if name == "scene":
            allowed_values, default = tuple(scenes), scenes[0]
        if name == "view":
            allowed_values = tuple(views)
        text = query.get(name)
        values[name] = default if text is None else _value(name, kind, text, allowed_values)
    if "w" in values and values["w"] * values["h"] > MAX_PIXELS:
        raise ViewerError(f"w x h must be at most {MAX_PIXELS:,} pixels, got "
                          f"{values['w']} x {values['h']}")
    for axis in ("x", "y"):
        if axis in values and "w" in values and values[axis] >= values["w" if axis == "x"
                                                                         else "h"]:
            raise ViewerError(f"{axis} = {values[axis]} is outside the {values['w']} x "
                              f"{values['h']} image")
    return ViewRequest(values)


def _value(name, kind, text, allowed):
    if len(text) > 64:
        raise ViewerError(f"{name}: value too long")
    if kind in ("choice", "scene"):
        if text not in allowed:
            raise ViewerError(f"{name} must be one of {', '.join(allowed)}, got {text!r}")
        return text
    if kind == "bool":
        if text not in ("0", "1", "true", "false"):
            raise ViewerError(f"{name} must be 0 or 1, got {text!r}")
        return text in ("1", "true")
    try:
        value = int(text) if kind == "int" else float(text)
    except ValueError:
        raise ViewerError(f"{name} must be {'an integer' if kind == 'int' else 'a number'}"
                          f", got {text!r}") from None
    low, high = allowed
    if not (math.isfinite(value) and low <= value <= high):
        raise ViewerError(f"{name} must be in {low:g}..{high:g}, got {text!r}")
    return value


def _frame(bounds, az, el, fov, aspect, up_axis="y"):
    """Centre, radius, the direction towards the eye, its right and up axes, and the
    distance at which the bounding sphere fits both fields of view (5% margin); azimuth
    and elevation turn about ``up_axis`` (:func:`hsr.views.direction`)."""
    from ..scene import views as view_sets

    lo, hi = np.asarray(bounds, dtype=np.float64)
    centre = (lo + hi) / 2
    radius = max(float(np.linalg.norm(hi - lo)) / 2, 1e-9)
    toward = view_sets.direction(az, el, up_axis)
    half = math.radians(fov) / 2
    fit = radius / math.sin(min(half, math.atan(math.tan(half) * aspect))) * 1.05
    right = np.cross(-toward, view_sets.up_vector(up_axis))
    right /= np.linalg.norm(right)
    up = np.cross(right, -toward)
    return centre, radius, toward, right, up, fit


def orbit_of(bounds, camera, aspect=4 / 3) -> dict:
    """The orbit controls (az, el, dist, tx, ty, fov) that place ``camera`` (a perspective
    camera looking at its target, up +Y): how a built-in scene opens with its own view."""
    eye, target = np.asarray(camera.eye, float), np.asarray(camera.target, float)
    toward = (eye - target) / np.linalg.norm(eye - target)
    el = math.degrees(math.asin(max(-1.0, min(1.0, toward[1]))))
    az = math.degrees(math.atan2(toward[0], toward[2]))
    el = max(-89.9, min(89.9, el))
    fov = float(camera.fov_y)
    centre, radius, toward, right, up, fit = _frame(bounds, az, el, fov, aspect)
    offset = target - centre
    tx, ty = float(offset @ right) / radius, float(offset @ up) / radius
    # The part of the offset along the view axis moves the orbit's target, not the eye.
    distance = float(np.linalg.norm(eye - (centre + radius * (tx * right + ty * up))))
    return {"az": round(az, 6), "el": round(el, 6), "dist": round(distance / fit, 6),
            "tx": round(tx, 6), "ty": round(ty, 6), "fov": fov}


def orbit_camera(bounds, request: ViewRequest, up_axis: str = "y"):
    """The camera of ``request`` around the bounding sphere of ``bounds`` (see the module),
    turning about ``up_axis`` (a Z-up model's own, so it stands up), near and far hugging
    the sphere."""
    from ..scene import views as view_sets
    from ..scene.camera import Camera

    centre, radius, toward, right, up, fit = _frame(bounds, request.az, request.el,
                                                    request.fov, request.w / request.h,
                                                    up_axis)
    distance = fit * request.dist
    up_world = view_sets.up_vector(view_sets.check_up_axis(up_axis))
    target = centre + radius * (request.tx * right + request.ty * up)
    eye = target + toward * distance
    to_centre = float(np.linalg.norm(eye - centre))
    near = max(to_centre - 1.05 * radius, to_centre * 1e-3)
    far = to_centre + 1.05 * radius
    return Camera.look_at(eye, target, up_world, request.fov, near, far)
