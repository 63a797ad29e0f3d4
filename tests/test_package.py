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
