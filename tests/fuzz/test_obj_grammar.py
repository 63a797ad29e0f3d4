"""OBJ text from a grammar, with the noise the format allows (BOM, tabs, comments,
indentation, CRLF, continuation lines, w and colour columns, groups) and with mutations
(characters inserted, deleted or replaced). Both readers must give the same mesh or the
same MeshError; nothing else may escape; a clean file reads as an independent reader says."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from hsr.errors import MeshError
from hsr.scene.obj import read_obj

from . import scaled

_num = st.one_of(st.integers(-50, 50).map(str),
                 st.floats(-1e3, 1e3, allow_nan=False).map(lambda f: f"{f:.6g}"),
                 st.sampled_from(["0", "1e-3", "-0.5", "2.5E2"]))
_sep = st.sampled_from([" ", "  ", "\t", " \t "])


@st.composite
def obj_text(draw):
    """(text, expected triangles or None): a file drawn from the grammar and the corners of
    its fanned faces as an independent reader computes them (None when it is malformed
    on purpose)."""
    sep = draw(_sep)
    n_v = draw(st.integers(3, 8))
    n_t = draw(st.integers(0, 4))
    n_n = draw(st.integers(0, 3))
    lines, verts = [], []
    if draw(st.booleans()):
        lines.append("# made by a fuzzer")
    for _ in range(n_v):
        xyz = [draw(_num) for _ in range(3)]
        extra = draw(st.sampled_from([[], ["1"], ["0.5", "0.2", "0.1"]]))
        lines.append(draw(st.sampled_from(["", " ", "\t"])) + "v" + sep + sep.join(xyz + extra))
        verts.append([float(x) for x in xyz])
    for _ in range(n_t):
        lines.append("vt" + sep + sep.join(draw(_num) for _ in range(2)))
    for _ in range(n_n):
        lines.append("vn" + sep + sep.join(draw(_num) for _ in range(3)))
    if draw(st.booleans()):
        lines.append("g part" + sep + "s 1")
    form = draw(st.sampled_from(["v", "v/vt", "v//vn", "v/vt/vn"]))
    if "vt" in form and n_t == 0 or "vn" in form and n_n == 0:
        form = "v"
    tris = []
    for _ in range(draw(st.integers(1, 4))):
        k = draw(st.integers(3, 5))
        idx = [draw(st.integers(1, n_v)) for _ in range(k)]
        negative = draw(st.booleans())
        tokens = []
        for i in idx:
            ref = str(i - n_v - 1) if negative else str(i)
            t = str(draw(st.integers(1, max(n_t, 1))))
            n = str(draw(st.integers(1, max(n_n, 1))))
            tokens.append({"v": ref, "v/vt": f"{ref}/{t}", "v//vn": f"{ref}//{n}",
                           "v/vt/vn": f"{ref}/{t}/{n}"}[form])
        comment = " # face" if draw(st.booleans()) else ""
        lines.append("f" + sep + sep.join(tokens) + comment)
        tris += [[verts[idx[0] - 1], verts[idx[j] - 1], verts[idx[j + 1] - 1]]
                 for j in range(1, k - 1)]
    end = draw(st.sampled_from(["\n", "\r\n"]))
    text = end.join(lines) + end
    if draw(st.booleans()):
        text = "\ufeff" + text
    if draw(st.booleans()):  # a continuation line inside the first vertex
        text = text.replace("v" + sep, "v" + sep + "\\" + end, 1)
    return text, np.array(tris)


def outcome(path, method):
    try:
        m = read_obj(path, method)
    except MeshError as exc:
        return ("error", str(exc))
    return ("mesh", m.positions[m.faces].tolist(),
            None if m.corner_uv is None else m.corner_uv.tolist(),
            None if m.corner_normals is None else m.corner_normals.tolist())


@settings(max_examples=scaled(120))
@given(case=obj_text())
def test_clean_files_read_right_both_ways(tmp_path_factory, case):
    text, tris = case
    path = tmp_path_factory.mktemp("obj") / "f.obj"
    path.write_bytes(text.encode("utf-8"))
    a, b = outcome(str(path), "regex"), outcome(str(path), "careful")
    assert a == b
    assert a[0] == "mesh", a
    assert np.allclose(np.array(a[1]), tris)


@settings(max_examples=scaled(200))
@given(case=obj_text(), edits=st.lists(st.tuples(st.floats(0, 1), st.sampled_from(
    ["insert", "delete", "replace"]), st.sampled_from(list("v/ -#\t\n.0123456789fe+xn\\"))),
    min_size=1, max_size=4))
def test_mutated_files_agree_or_both_refuse(tmp_path_factory, case, edits):
    text = case[0]
    for where, op, ch in edits:
        i = int(where * len(text))
        text = (text[:i] + ch + text[i:] if op == "insert" else
                text[:i] + text[i + 1:] if op == "delete" else text[:i] + ch + text[i + 1:])
    path = tmp_path_factory.mktemp("obj") / "m.obj"
    path.write_bytes(text.encode("utf-8"))
    assert outcome(str(path), "regex") == outcome(str(path), "careful")
