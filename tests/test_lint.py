"""The code's style, checked with ruff as configured in pyproject.toml (pyflakes,
pycodestyle, isort, bugbear, pyupgrade): the whole tree, so a change that breaks it fails
the suite and CI; and the types, with mypy."""

import os
import subprocess
import sys

from conftest import require

ROOT = os.path.join(os.path.dirname(__file__), "..")


def test_ruff_finds_nothing():
    require("ruff")
    proc = subprocess.run([sys.executable, "-m", "ruff", "check", "src", "tests", "benchmarks",
                           "docs"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_types_check():
    """mypy at the level stated in pyproject.toml ([tool.mypy]: its defaults on src/hsr,
    untyped third-party packages taken as Any) finds nothing; hsr ships ``py.typed``, so
    users' type checkers read these hints."""
    require("mypy")
    assert os.path.isfile(os.path.join(ROOT, "src", "hsr", "py.typed"))
    proc = subprocess.run([sys.executable, "-m", "mypy", "--no-incremental"], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
