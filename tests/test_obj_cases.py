"""The OBJ reader on the inputs behind known failures (../shared/cases) and the grammar
they exercise: both readers (regular expressions and line by line) must give the same mesh
or the same error, and files that used to shift indices or be refused read correctly."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import hsr
from hsr.errors import MeshError
from hsr.scene.obj import normalise_obj, read_obj, scan_regex

CASES = sorted(n for n in os.listdir(os.path.join(os.path.dirname(__file__), "..", "..",
                                                  "shared", "cases"))
               if n.endswith(".obj")) if os.path.isdir(os.path.join(
                   os.path.dirname(__file__), "..", "..", "shared", "cases")) else []


def outcome(path, method):
    """What reading gives: ("mesh", arrays...) or ("error", message)."""
    try:
        m = read_obj(path, method)
    except MeshError as exc:
        return ("error", str(exc))
    return ("mesh", m.positions[m.faces].tolist(), m.faces.tolist(),
            None if m.corner_uv is None else m.corner_uv.tolist(),
            None if m.corner_normals is None else m.corner_normals.tolist(),
            None if m.face_colors is None else m.face_colors.tolist(), m.texture)


def independent_triangles(text):
    """Corners of each fanned face, read by a separate minimal reader that knows the
    grammar's noise (BOM, comments, tabs, indentation) but nothing of hsr."""
    text = text.lstrip("\ufeff")
    verts, tris = [], []
    for line in text.splitlines():
        parts = line.split("#")[0].split()
        if parts and parts[0] == "v":
            verts.append([float(x) for x in parts[1:4]])
        elif parts and parts[0] == "f":
            idx = [int(t.split("/")[0]) for t in parts[1:]]
            idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
            tris += [[verts[idx[0]], verts[idx[k]], verts[idx[k + 1]]]
                     for k in range(1, len(idx) - 1)]
    return np.array(tris)


@pytest.mark.parametrize("name", CASES)
def test_both_readers_agree_on_every_case(cases_dir, name):
    path = os.path.join(cases_dir, name)
    assert outcome(path, "regex") == outcome(path, "careful")


@pytest.mark.parametrize("name", ["utf8_bom.obj", "utf8_bom_shift.obj", "indented_v_shift.obj",
                                  "tabs.obj", "trailing_comment.obj"])
def test_grammar_noise_reads_the_right_vertices(cases_dir, name):
    """These files used to lose their first vertex (silently shifting every index) or be
    refused. The regular-expression reader must take them itself (not hand them over)."""
    path = os.path.join(cases_dir, name)
    raw = open(path, "rb").read()
    assert scan_regex(normalise_obj(raw, name), name) is not None
    expected = independent_triangles(raw.decode("utf-8"))
    for method in ("regex", "careful"):
        mesh = read_obj(path, method)
        assert np.array_equal(mesh.positions[mesh.faces], expected), method


@pytest.mark.parametrize("name,message", [
    ("malformed_token_accepted.obj", r":16: bad face vertex '2//3//3'"),
    ("trailing_slashes.obj", r":8: bad face vertex '1//'"),
    ("trailing_slash_vt.obj", r":8: bad face vertex '1/1/'"),
    ("index_overflow.obj", r":4: index 99999999999999999999999999 is out of range"),
    ("index_neg_overflow.obj", r":4: index -99999999999999999999999999 is out of range"),
    ("mtl_is_dir.obj", r"mtldir is a directory, not a material file"),
    ("kd_nan.obj", r"kdbad.mtl:2: Kd must be three finite numbers"),
])
def test_malformed_cases_are_refused_with_their_line(cases_dir, name, message):
    for method in ("regex", "careful"):
        with pytest.raises(MeshError, match=message):
            read_obj(os.path.join(cases_dir, name), method)


def test_texture_bomb_is_refused_before_decoding(cases_dir):
    mesh = hsr.load(os.path.join(cases_dir, "tex_bomb.obj"))
    cam = hsr.Camera.frame(mesh.bounds())
    with pytest.raises(MeshError, match="more pixels than hsr reads"):
        hsr.render(mesh, cam, 32, 24)


@pytest.mark.parametrize("text,expected", [
    # A corner is v, v/vt, v//vn or v/vt/vn: mixed forms across faces are fine ...
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1 2/1 3\n", None),
    # ... a mixed block whose slash count adds up like a uniform one is not misread.
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvn 0 0 1\nf 1 2/1/1 3/1\nf 2 4 3\n", None),
    ("v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nf 1 2 3\r\n", None),
    ("v 0 0 \\\n0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", None),
    ("v 0 0 0 1\nv 1 0 0 1\nv 0 1 0 1\ng grp\ns off\nf 1 2 3\nl 1 2\n", None),
])
def test_grammar_variants_read_the_same_both_ways(tmp_path, text, expected):
    path = tmp_path / "g.obj"
    path.write_bytes(text.encode())
    a, b = outcome(str(path), "regex"), outcome(str(path), "careful")
    assert a == b and a[0] == "mesh"
    assert np.array_equal(np.array(a[1]), independent_triangles(text.replace("\\\n", " ")))


@pytest.mark.parametrize("text,message", [
    ("v 0 0 0\nv1 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", ":2: unknown statement 'v1 0 0'"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 +2 3\n", "bad face vertex '\\+2'"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/ 2/ 3/\n", "bad face vertex '1/'"),
])
def test_grammar_violations_are_refused_both_ways(tmp_path, text, message):
    path = tmp_path / "bad.obj"
    path.write_text(text)
    for method in ("regex", "careful"):
        with pytest.raises(MeshError, match=message):
            read_obj(str(path), method)


def test_non_regular_files_are_refused(tmp_path):
    for source in ("/dev/zero", str(tmp_path)):
        with pytest.raises(MeshError, match="not a regular file|directory"):
            hsr.load(source)
    (tmp_path / "m.obj").write_text("mtllib /dev/zero\nusemtl a\nv 0 0 0\nv 1 0 0\n"
                                    "v 0 1 0\nf 1 2 3\n")
    with pytest.raises(MeshError, match="/dev/zero is not a regular file"):
        hsr.load(str(tmp_path / "m.obj"))
    with pytest.raises(MeshError, match="not a regular file"):
        hsr.load("/dev/zero.ply" if os.path.exists("/dev/zero.ply") else "/dev/null")


def test_a_fifo_named_obj_does_not_block(tmp_path):
    """Opening a FIFO blocks until a writer comes: the reader must refuse it first. Run in
    a subprocess so that a regression fails by timeout instead of hanging the suite."""
    fifo = tmp_path / "x.obj"
    os.mkfifo(fifo)
    code = textwrap.dedent(f"""
        import hsr
        try:
            hsr.load({str(fifo)!r})
        except hsr.MeshError as exc:
            print(exc)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert "not a regular file" in out.stdout


def test_file_and_line_caps(tmp_path):
    big = tmp_path / "big.obj"
    big.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n" + "# " + "x" * 2000 + "\n")
    with pytest.raises(MeshError, match="more than the 100 bytes"):
        hsr.load(str(big), max_bytes=100)
    long_line = tmp_path / "line.obj"
    long_line.write_bytes(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n" + b"\0" * (2 << 20))
    with pytest.raises(MeshError, match=":5: line of 2,097,152 bytes"):
        hsr.load(str(long_line))


@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("algorithm", list(hsr.ALGORITHMS))
def test_every_case_renders_or_refuses_with_every_algorithm(cases_dir, name, algorithm):
    """Each input behind a known failure, through load and render with every algorithm:
    a picture, or an HsrError; nothing else, no warning."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            mesh = hsr.load(os.path.join(cases_dir, name))
            hsr.render(mesh, hsr.Camera.frame(mesh.bounds()), 32, 24, algorithm=algorithm)
        except hsr.HsrError:
            pass
