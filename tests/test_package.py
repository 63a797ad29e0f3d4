"""The package as an index would take it (issue #62): ``python -m build`` makes a wheel
and an sdist from a copy of the tree, ``twine check --strict`` passes both, and the
wheel holds what an installed hsr needs (the viewer's page, the licence, the metadata)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile

from conftest import require

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))


def test_the_wheel_and_sdist_build_and_pass_twine(tmp_path):
    require("build")
    require("twine")
    tree = tmp_path / "tree"
    shutil.copytree(ROOT, tree, ignore=shutil.ignore_patterns(
        ".git", "build", "dist", "*.egg-info", "__pycache__", "*.nbi", "*.nbc", "site"))
    out = tmp_path / "dist"
    built = subprocess.run([sys.executable, "-m", "build", "--outdir", str(out), str(tree)],
                           capture_output=True, text=True, timeout=600)
    assert built.returncode == 0, built.stderr[-2000:]
    files = sorted(os.listdir(out), key=lambda f: f.endswith(".whl"))  # sdist, wheel
    assert [f.rsplit(".", 1)[-1] for f in files] == ["gz", "whl"], files
    checked = subprocess.run([sys.executable, "-m", "twine", "check", "--strict",
                              *[str(out / f) for f in files]],
                             capture_output=True, text=True, timeout=300)
    assert checked.returncode == 0, checked.stdout + checked.stderr
    with zipfile.ZipFile(out / files[1]) as wheel:
        names = wheel.namelist()
        meta = wheel.read(next(n for n in names if n.endswith("METADATA"))).decode()
    assert "hsr/viewer/static/viewer.js" in names and "hsr/py.typed" in names
    assert any(n.endswith("licenses/LICENSE") for n in names)
    for field in ("License-Expression: MIT", "Keywords:", "Classifier: Topic",
                  "Author: the hsr developers", "Requires-Python: >=3.11"):
        assert field in meta, field


def test_the_literal_types_name_what_the_code_accepts():
    """Enum-like arguments are typed as Literal names an IDE completes (they were plain
    str); each must equal what the code checks at run time, or one of them is lying."""
    from typing import get_args

    import hsr
    from hsr import choices
    from hsr.appearance.shading import LIGHTS, SHADING_MODES
    from hsr.appearance.texture import FILTERS, WRAPS
    from hsr.appearance.transparency import ORDERS
    from hsr.scene.load import UP_AXIS_CHOICES
    from hsr.scene.views import UP_AXES

    pairs = [(choices.Algorithm, tuple(hsr.ALGORITHMS)), (choices.Shading, SHADING_MODES),
             (choices.Light, LIGHTS), (choices.TextureFilter, FILTERS),
             (choices.TextureWrap, WRAPS), (choices.Transparency, ORDERS),
             (choices.Cull, tuple(m.value for m in hsr.CullMode)),
             (choices.DepthFuncName, tuple(m.value for m in hsr.DepthFunc)),
             (choices.FrontFaceName, tuple(m.value for m in hsr.FrontFace)),
             (choices.PolygonModeName, tuple(m.value for m in hsr.PolygonMode)),
             (choices.UpAxis, UP_AXES), (choices.UpAxisChoice, UP_AXIS_CHOICES)]
    for literal, accepted in pairs:
        assert set(get_args(literal)) == set(accepted), (literal, accepted)
    for edges in get_args(choices.EdgeKind):
        hsr.HiddenLine(edges=edges)
    hints = hsr.render.__annotations__
    assert hints["shading"] == "Shading" and hints["algorithm"] == "Algorithm"


def test_import_hsr_loads_nothing_heavy():
    """``import hsr`` took about a second (NumPy, Numba and trimesh at import); the public
    names now load on first use, so the import itself pulls in none of them."""
    code = ("import sys, hsr; heavy = [m for m in ('numpy', 'numba', 'trimesh', 'scipy') "
            "if m in sys.modules]; print(heavy); hsr.Mesh; print('numba' in sys.modules); "
            "print(sorted(set(hsr.__all__) - set(dir(hsr))))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split("\n")[:3] == ["[]", "True", "[]"], done.stdout


def test_hsr_render_is_the_function_whatever_was_imported_first():
    """With lazy names, importing the submodule hsr.render (as hsr.visibility does) bound
    ``hsr.render`` to the module: ``hsr.render(scene)`` raised 'module is not callable'."""
    code = ("import hsr.visibility, hsr; import hsr.render; s, c = hsr.scenes.get('cubes'); "
            "print(hsr.render(s, c, 8, 6).face_id.shape)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0 and done.stdout.strip() == "(6, 8)", done.stderr[-500:]
