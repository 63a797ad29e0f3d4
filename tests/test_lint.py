"""The code's style, checked with ruff as configured in pyproject.toml (pyflakes,
pycodestyle, isort, bugbear, pyupgrade): the whole tree, so a change that breaks it fails
the suite and CI."""

import os
import subprocess
import sys

from conftest import require

ROOT = os.path.join(os.path.dirname(__file__), "..")


def test_ruff_finds_nothing():
    require("ruff")
    proc = subprocess.run([sys.executable, "-m", "ruff", "check", "src", "tests", "benchmarks"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
