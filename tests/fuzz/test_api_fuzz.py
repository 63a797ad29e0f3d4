"""``hsr.render`` and the public constructors with arguments of every odd value and type:
a Frame, or an HsrError; never another exception or a warning."""

import warnings

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import hsr

from . import scaled

_odd = st.sampled_from([None, True, False, 0, 1, -1, 2, 3.5, float("nan"), float("inf"), 1e300,
                        "", "x", "flat", "back", "linear", (1, 2), (1, 2, 3), (0, 0, 0, 0),
                        [255, 0, 0], {"a": 1}, np.zeros(3), np.eye(4), object()])
_keywords = {
    "width": _odd, "height": _odd, "algorithm": st.sampled_from(list(hsr.ALGORITHMS) + ["x"]),
    "shading": _odd, "background": _odd, "counts": _odd, "threads": _odd,
    "occlusion_cull": _odd, "options": _odd, "look": _odd, "fog": _odd, "textures": _odd,
    "texture_filter": _odd, "texture_wrap": _odd, "hidden_line": _odd, "transparency": _odd,
    "cull": _odd, "depth_func": _odd, "depth_test": _odd, "depth_mask": _odd,
    "clear_depth": _odd, "depth_range": _odd, "front_face": _odd, "polygon_mode": _odd,
    "polygon_offset": _odd, "into": _odd,
}


@settings(max_examples=scaled(150))
@given(kwargs=st.dictionaries(st.sampled_from(sorted(_keywords)), _odd, max_size=3),
       scene_name=st.sampled_from(["cubes", "cyclic", "glass"]))
def test_render_keywords_of_any_value(kwargs, scene_name):
    scene, cam = hsr.scenes.get(scene_name)
    args = {"width": 24, "height": 18, **kwargs}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            frame = hsr.render(scene, cam, **args)
        except hsr.HsrError:
            return
    assert frame.face_id.shape == (frame.height, frame.width)


@settings(max_examples=scaled(150))
@given(values=st.lists(_odd, min_size=1, max_size=6),
       which=st.sampled_from(["look_at", "orthographic", "mesh", "scene_add", "fog",
                              "hidden_line", "state", "frame"]))
def test_constructors_with_any_value(values, which):
    v = values + [None] * 6

    def d(i, default):  # value i, or the default where none was drawn
        return default if v[i] is None else v[i]

    calls = {
        "look_at": lambda: hsr.Camera.look_at(v[0], v[1], d(2, (0, 1, 0)), d(3, 45),
                                              d(4, 0.1), d(5, 10)),
        "orthographic": lambda: hsr.Camera.orthographic(v[0], v[1], height=v[2]),
        "mesh": lambda: hsr.Mesh(v[0], v[1]),
        "scene_add": lambda: hsr.Scene().add(hsr.scenes.cube(), v[0], d(1, 1.0)),
        "fog": lambda: hsr.Fog(d(0, "linear"), d(1, 0.0), d(2, 1.0)),
        "hidden_line": lambda: hsr.HiddenLine(d(0, "all"), d(1, 30.0)),
        "state": lambda: hsr.RenderState(cull=d(0, "none"), clear_depth=d(1, 1.0)),
        "frame": lambda: hsr.Camera.frame(v[0]),
    }
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            calls[which]()
        except hsr.HsrError:
            pass
