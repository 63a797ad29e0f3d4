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


def test_the_public_api_has_type_hints():
    """Every parameter and return of the public functions and methods (``hsr.__all__``,
    hsr.visibility, hsr.batch, hsr.views, hsr.scenes) is annotated, so that mypy checks
    their bodies and users' type checkers see what they take."""
    import inspect

    import hsr

    def unannotated(function, name):
        try:
            sig = inspect.signature(function)
        except (TypeError, ValueError):  # a builtin or a Numba dispatcher
            return []
        missing = [p.name for p in sig.parameters.values()
                   if p.name not in ("self", "cls") and p.annotation is inspect.Parameter.empty
                   and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]
        if sig.return_annotation is inspect.Signature.empty and not inspect.isclass(function):
            missing.append("return")
        return [f"{name}({', '.join(missing)})"] if missing else []

    found = []
    for owner in (hsr, hsr.visibility, hsr.batch, hsr.views, hsr.scenes):
        names = getattr(owner, "__all__", None) or [
            n for n, v in vars(owner).items()
            if not n.startswith("_") and inspect.isfunction(v) and v.__module__ == owner.__name__]
        for name in names:
            value = getattr(owner, name)
            if inspect.ismodule(value):
                continue
            if inspect.isclass(value):
                for attr, member in vars(value).items():
                    if attr == "__init__" or (not attr.startswith("_") and (
                            inspect.isfunction(member)
                            or isinstance(member, (classmethod, staticmethod)))):
                        found += unannotated(getattr(value, attr), f"{name}.{attr}")
            elif inspect.isfunction(value):
                found += unannotated(value, f"{owner.__name__}.{name}")
    assert not found, f"public functions without type hints: {sorted(set(found))}"
