"""Helpers the benchmark scripts share: timing, agreement, memory, progress."""

from __future__ import annotations

import resource
import statistics
import sys
import time

import numpy as np


def timed(fn):
    """(fn's result, milliseconds) of one call."""
    t0 = time.perf_counter()
    result = fn()
    return result, 1e3 * (time.perf_counter() - t0)


def timings(fns, repeat, rounds=1):
    """(min, median) milliseconds of each function. Each runs in blocks of ``repeat`` calls
    after one warm-up call (so no function pays for another's cache and page state inside
    a block); with several ``rounds`` the blocks alternate, so all see the same machine
    load over time."""
    times = [[] for _ in fns]
    for _ in range(rounds):
        for fn, bucket in zip(fns, times):
            bucket += block_ms(fn, repeat)
    return [(min(t), statistics.median(t)) for t in times]


def block_ms(fn, repeat) -> list:
    """Milliseconds of ``repeat`` calls of ``fn`` after one warm-up call (JIT caches,
    buffers, driver state)."""
    fn()
    return [timed(fn)[1] for _ in range(repeat)]


def agreement_percent(face_a: np.ndarray, face_b: np.ndarray) -> float:
    """Share (%) of the pixels either covers on which two face-id buffers agree."""
    covered = (face_a >= 0) | (face_b >= 0)
    return 100.0 * float((face_a == face_b)[covered].mean()) if covered.any() else 100.0


def peak_gb() -> float:
    """The process's peak resident memory so far, GB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6


def progress(items, desc):
    """A progress bar on a terminal, the plain iterable when piped."""
    if sys.stderr.isatty():
        from tqdm import tqdm

        return tqdm(items, desc=desc, leave=False)
    return items


def load_model(spec):
    """(mesh, label) of a mesh file, ``terrain:N`` (the generated grid of N triangles)
    or ``terrain32:N`` (the same with its vertices rounded to float32, as a binary PLY,
    STL or glTF file stores them)."""
    import os

    import numpy as np

    import hsr

    kind, _, count = spec.partition(":")
    if kind in ("terrain", "terrain32") and count:
        n = int(float(count))
        scene, _ = hsr.scenes.terrain(n)
        mesh = scene.instances[0].mesh
        if kind == "terrain32":
            return (hsr.Mesh(mesh.positions.astype(np.float32).astype(np.float64), mesh.faces),
                    f"terrain {n:,} (float32 vertices)")
        return mesh, f"terrain {n:,}"
    return hsr.load(spec), os.path.basename(spec)
