import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))

MODELS_DIR = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", "shared",
                                          "models"))
IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")


def need(condition: bool, reason: str):
    """Skip locally when a resource is missing; in CI a missing resource is a failure."""
    if not condition:
        if IN_CI:
            pytest.fail(f"required in CI: {reason}")
        pytest.skip(reason)


@pytest.fixture(scope="session")
def models_dir():
    need(os.path.isdir(MODELS_DIR), f"shared models not found at {MODELS_DIR}")
    return MODELS_DIR


@pytest.fixture(scope="session")
def gl():
    try:
        from gl_reference import GLRenderer

        renderer = GLRenderer()
    except Exception as exc:  # no moderngl, no EGL, no Mesa
        need(False, f"OpenGL (moderngl + Mesa EGL) unavailable: {exc}")
    return renderer


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
