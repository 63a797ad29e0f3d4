"""MkDocs hooks: make the gallery's pictures before the build (docs/gallery.py) when one
is missing or older than the script or any of hsr's sources, so the pictures always come
from the code and a rebuild with nothing changed costs nothing."""

from __future__ import annotations

import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCES = os.path.join(HERE, "..", "src", "hsr")


def _newest_source() -> float:
    newest = os.path.getmtime(os.path.join(HERE, "gallery.py"))
    for root, _dirs, files in os.walk(SOURCES):
        for name in files:
            if name.endswith(".py"):
                newest = max(newest, os.path.getmtime(os.path.join(root, name)))
    return newest


def on_pre_build(config, **kwargs) -> None:
    sys.path.insert(0, HERE)
    try:
        from gallery import PICTURES
    finally:
        sys.path.remove(HERE)
    out = os.path.join(HERE, "gallery")
    paths = [os.path.join(out, name) for name in PICTURES]
    if all(os.path.exists(p) for p in paths) and min(map(os.path.getmtime, paths)) >= \
            _newest_source():
        return
    # A process of its own: the renders' threads and compiled kernels stay out of MkDocs.
    print(f"gallery: drawing {len(paths)} pictures (minutes on a first run, while the "
          f"kernels compile)", file=sys.stderr, flush=True)
    subprocess.run([sys.executable, os.path.join(HERE, "gallery.py"), out], check=True)
