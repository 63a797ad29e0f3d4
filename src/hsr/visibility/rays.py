"""``hsr.RayScene``: what arbitrary rays hit. The scene's BVH is built once and every
query walks it (nearest hit, any hit, every hit), in parallel chunks of rays.

Conventions (those of Embree and Open3D's ``RaycastingScene``): a ray is
``origin + t * direction`` with ``t`` in ``[t_min, t_max]`` in units of the direction's
length (directions need not be unit vectors); the barycentric pair ``(u, v)`` places the
hit at ``(1 - u - v) * A + u * B + v * C`` for the face's corners A, B, C in file order;
the normal is the geometric one as wound, ``normalize((B - A) x (C - A))``, whichever
side the ray comes from. Faces and objects are numbered as everywhere in hsr: global face
ids in submission order, the instance index in the scene.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from ..algorithms.bvh.hits import ALL, ANY, COUNT, FIRST, NEAREST
from ..errors import HsrError
from ..parallel import OutputPool, check_threads, default_workspace, progress_bar, split_range
from ..scene.mesh import SceneLike, as_scene

__all__ = ["RayScene", "RayHits", "RayHitLists", "RayError"]

# Rays per chunk handed to a thread: large enough that a chunk costs far more than its
# hand-off, small enough that uneven rays (misses cost little) balance between threads.
CHUNK = 4096
# Faces whose mean area, times the faces, stands for the scene's surface area there (the
# leaf order spreads them over the whole scene; summing all is slow at 1M faces).
AREA_SAMPLES = 4096
# Runs of four rays cast to estimate it: up to 64 (a few hundred microseconds), one per
# 1024 rays of the query from eight up.
FOOTPRINT_RUNS = 64
# Queries this large draw a progress bar on a terminal.
PROGRESS_RAYS = 4_000_000
# Most rays one query takes: its outputs (t, ids, uv, normals: 56 bytes a ray) and its
# inputs as float64 must fit in memory, checked before anything is allocated.
MAX_RAYS = 1 << 30
# Most memory one all_hits query's lists may take (56 bytes a hit: t, ids, uv, normal),
# checked after the hits are counted and before anything is allocated; past it, the
# query asks for max_hits.
MAX_LIST_BYTES = 2 << 30
HIT_BYTES = 8 + 4 + 4 + 16 + 24


class RayError(HsrError):
    """Rays or a ray query are malformed (shapes, NaN, zero directions, bad intervals)."""


@dataclass
class RayHits:
    """The nearest hit of each ray, arrays of length N (rays in input order):

    - ``t`` (N,) float64: the ray parameter of the hit (units of the direction's
      length), ``+inf`` for a miss;
    - ``face_id`` (N,) int32: global face index, -1 for a miss;
    - ``object_id`` (N,) int32: instance index in the scene, -1 for a miss;
    - ``barycentric`` (N, 2) float64: ``(u, v)`` with the hit at
      ``(1 - u - v) * A + u * B + v * C`` (0 for a miss);
    - ``normal`` (N, 3) float64: the face's geometric unit normal as wound (0 for a miss).
    """

    t: np.ndarray
    face_id: np.ndarray
    object_id: np.ndarray
    barycentric: np.ndarray
    normal: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        """(N,) bool: rays that hit something."""
        return self.face_id >= 0

    def points(self, origins: ArrayLike, directions: ArrayLike) -> np.ndarray:
        """(N, 3) float64 hit points ``origin + t * direction`` (NaN for a miss)."""
        origin, direction = _broadcast(origins, directions)
        t = np.where(self.hit, self.t, np.nan)
        return origin + t[:, None] * direction

    def __len__(self):
        return len(self.t)


@dataclass
class RayHitLists:
    """Every hit of each of N rays, nearest first, as ragged arrays: ray i's hits are rows
    ``offsets[i] .. offsets[i + 1] - 1`` of the per-hit arrays (H hits in all):

    - ``offsets`` (N + 1,) int64, from 0 up to H;
    - ``t`` (H,) float64: the ray parameter of each hit, ascending along each ray (equal
      distances by face id);
    - ``face_id``, ``object_id`` (H,) int32, ``barycentric`` (H, 2) and ``normal`` (H, 3)
      float64: as in :class:`RayHits`.

    A crossing of the surface is listed once (a hit through a shared edge or vertex goes to
    one of the faces there, as :meth:`RayScene.count` counts it), so without ``max_hits``
    each ray's list is as long as its count.
    """

    offsets: np.ndarray
    t: np.ndarray
    face_id: np.ndarray
    object_id: np.ndarray
    barycentric: np.ndarray
    normal: np.ndarray

    @property
    def counts(self) -> np.ndarray:
        """(N,) int64: the hits listed for each ray."""
        return np.diff(self.offsets)

    @property
    def ray_id(self) -> np.ndarray:
        """(H,) int64: the ray of each hit."""
        return np.repeat(np.arange(len(self), dtype=np.int64), self.counts)

    def points(self, origins: ArrayLike, directions: ArrayLike) -> np.ndarray:
        """(H, 3) float64 hit points ``origin + t * direction``."""
        origin, direction = _broadcast(origins, directions)
        if len(origin) != len(self):
            raise RayError(f"{len(self)} rays were cast; got {len(origin)}")
        ray = self.ray_id
        return origin[ray] + self.t[:, None] * direction[ray]

    def __len__(self):
        return len(self.offsets) - 1


class RayScene:
    """A scene made ready for ray queries: ``RayScene(scene)`` with a :class:`~hsr.Mesh`,
    :class:`~hsr.Scene` or a mesh file's path (read with :func:`hsr.load_scene`).

    The BVH (binned SAH over world-space triangles, :func:`hsr.algorithms.bvh.sah.build`) is
    built once here; :meth:`cast`, :meth:`occluded` and :meth:`count` all reuse it.
    Several threads may query one RayScene at once: a query changes nothing in it but
    its pool of answers' memory (:class:`hsr.parallel.OutputPool`: the arrays of
    answers the caller has dropped, reused by later queries, up to
    :data:`hsr.parallel.OUTPUT_KEEP_BYTES`), which is thread-safe. ``threads``:
    threads per query (default: numba's thread count).

    Raises :class:`~hsr.errors.MeshError` for a scene that cannot be loaded, and
    :class:`~hsr.errors.RenderError` for a bad ``threads``.
    """

    def __init__(self, scene: SceneLike | str | os.PathLike,
                 threads: int | None = None) -> None:
        from ..algorithms.bvh.hits import surface_area
        from ..algorithms.bvh.sah import build
        from ..scene.load import load_scene

        check_threads(threads)
        if isinstance(scene, (str, os.PathLike)):
            scene = load_scene(scene)
        self.scene = as_scene(scene)
        self.threads = threads
        self.bvh = build(self.scene, threads)
        self.face_offsets = self.scene.face_offsets()
        lo, hi = self.bvh.bounds
        self.scene_size = float(np.linalg.norm(hi - lo)) if len(self.bvh.leaf_face) else 0.0
        self._outputs = OutputPool()
        # The faces' summed area, sampled (microseconds): _faces_per_ray's density.
        self._surface_area = surface_area(self.bvh.corners, AREA_SAMPLES,
                                          len(self.bvh.leaf_face))

    @property
    def n_faces(self) -> int:
        return self.bvh.n_faces

    def __repr__(self):
        return (f"<hsr.RayScene: {self.n_faces:,} faces, {len(self.scene)} objects, 8-wide "
                f"BVH of {self.bvh.n_wide_nodes:,} nodes built in {self.bvh.build_ms:.0f} ms>")

    def cast(self, origins: ArrayLike, directions: ArrayLike, t_min: float = 0.0,
             t_max: float = np.inf, progress: bool | None = None) -> RayHits:
        """The nearest hit of each ray (see :class:`RayHits`). ``origins``: (N, 3), or
        (3,) for one origin shared by all rays; ``directions``: (N, 3), any non-zero
        length; both any real dtype (computed in float64). ``t_min``, ``t_max``:
        scalars or (N,), ``0 <= t_min <= t_max`` (``t_max`` may be ``inf``). Equal
        distances go to the lower face id. Raises :class:`RayError` for bad input."""
        origin, direction, t0, t1 = self._rays(origins, directions, t_min, t_max)
        n = len(origin)
        empty = self._outputs.empty
        hits = RayHits(empty(n), empty(n, np.int32), empty(n, np.int32), empty((n, 2)),
                       empty((n, 3)))
        self._run(NEAREST, origin, direction, t0, t1, (hits.t, hits.face_id, hits.object_id,
                                                    hits.barycentric, hits.normal,
                                                    np.empty(0, np.int32)), progress)
        return hits

    def occluded(self, origins: ArrayLike, directions: ArrayLike, t_min: float = 0.0,
                 t_max: float = np.inf, progress: bool | None = None) -> np.ndarray:
        """(N,) bool: whether each ray meets any surface with ``t`` in
        ``[t_min, t_max]`` (its walk stops at the first one). Arguments as
        :meth:`cast`."""
        rays = self._rays(origins, directions, t_min, t_max)
        return self._counted(ANY, rays, progress).astype(bool)

    def count(self, origins: ArrayLike, directions: ArrayLike, t_min: float = 0.0,
              t_max: float = np.inf, progress: bool | None = None) -> np.ndarray:
        """(N,) int32: how many times each ray crosses the surface with ``t`` in
        ``[t_min, t_max]``. Watertight: a ray through a shared edge or vertex of a
        closed mesh counts it once, so an odd count with ``t_max = inf`` means the
        origin is inside (see :mod:`hsr.algorithms.bvh.triangle`). Arguments as
        :meth:`cast`."""
        return self._counted(COUNT, self._rays(origins, directions, t_min, t_max), progress)

    def all_hits(self, origins: ArrayLike, directions: ArrayLike, t_min: float = 0.0,
                 t_max: float = np.inf, max_hits: int | None = None,
                 progress: bool | None = None) -> RayHitLists:
        """Every hit along each ray with ``t`` in ``[t_min, t_max]``, nearest first (see
        :class:`RayHitLists`): for LiDAR's multiple returns, thickness, layers. Each ray
        lists exactly the crossings :meth:`count` counts, so its first hit is the one
        :meth:`cast` finds (but at a shared edge or vertex, where either face may be
        named). ``max_hits``: keep only each ray's nearest ``max_hits`` (a positive
        integer). Other arguments as :meth:`cast`.

        The hits are counted first (:meth:`count`'s walk), then listed by a second walk
        into arrays of exactly that size. Raises :class:`RayError` for bad input or a bad
        ``max_hits``, and when the lists would take more than :data:`MAX_LIST_BYTES`
        (ask for fewer rays or a ``max_hits``) before allocating them."""
        cap = _max_hits(max_hits)
        rays = self._rays(origins, directions, t_min, t_max)
        n = len(rays[0])
        offsets = np.zeros(n + 1, dtype=np.int64)
        counts = self._counted(COUNT, rays, progress)
        np.cumsum(counts if cap is None else np.minimum(counts, cap), out=offsets[1:])
        total = int(offsets[-1])
        if total * HIT_BYTES > MAX_LIST_BYTES:
            raise RayError(
                f"all_hits would list {total:,} hits ({total * HIT_BYTES / 2**30:.1f} GiB), "
                f"more than {MAX_LIST_BYTES / 2**30:g} GiB: ask for fewer rays or pass a "
                f"smaller max_hits" + ("" if cap is None else f" than {cap}"))
        empty = self._outputs.empty
        lists = RayHitLists(offsets, empty(total), empty(total, np.int32),
                            empty(total, np.int32), empty((total, 2)), empty((total, 3)))
        # With max_hits, rays with more hits keep their nearest (FIRST walks each ray's
        # every box); without, each list is as long as the count (ALL stops when full).
        outputs = (lists.t, lists.face_id, lists.object_id, lists.barycentric, lists.normal,
                   np.empty(0, np.int32), offsets)
        origins, directions, t0, t1 = rays
        self._run(ALL if cap is None else FIRST, origins, directions, t0, t1, outputs, progress)
        return lists

    def _counted(self, mode, rays, progress):
        """(N,) int32 answers of query ``mode`` (ANY or COUNT) for ``rays`` (:meth:`_rays`)."""
        origins, directions, t0, t1 = rays
        out = self._outputs.empty(len(origins), np.int32)
        self._run(mode, origins, directions, t0, t1,
                  (np.empty(0), np.empty(0, np.int32), np.empty(0, np.int32), np.empty((0, 2)),
                   np.empty((0, 3)), out), progress)
        return out

    def _run(self, mode, origins, directions, t0, t1, outputs, progress):
        n = len(origins)
        if n == 0:
            return
        if progress is None:
            progress = n >= PROGRESS_RAYS and sys.stderr.isatty()
        kernel = self._walk(origins, directions, t0, t1)
        # The calling thread's kept threads (hsr.render's, default_workspace), not a
        # pool started and stopped per call: the pool thread exiting after a call took
        # the GIL from the next one's Python set-up (measurements: docs/history.md, "Ray
        # core").
        with default_workspace(self.threads, replace=False) as workers, \
                progress_bar(progress, n, "rays", unit="ray") as bar:
            # Chunks of CHUNK rays or more, about 16 per thread: a chunk's hand-off
            # costs tens of microseconds of Python.
            chunk = max(CHUNK, n // (16 * workers.threads))
            results = workers.run(
                kernel, split_range(n, max(1, -(-n // chunk))), origins, directions,
                t0, t1, mode, None, *self.bvh.walked, self.face_offsets, *outputs,
                on_done=(lambda lo, hi: bar.update(hi - lo)) if progress else None)
        # The rays are checked chunk by chunk as they are traced (their data is in cache
        # then); the first bad ray of all is reported, whatever was traced.
        bad = [(ray, problem) for _, problem, ray in results if problem]
        if bad:
            ray, problem = min(bad)
            raise RayError(_problem(problem, ray, t0, t1))

    def _walk(self, origins, directions, t0, t1):
        """The walk these rays go through
        (:func:`hsr.algorithms.bvh.choice.choose_walk`): whether they come in coherent
        runs (:func:`_coherent`), and if so, when they are fewer than four a face, the
        faces in a ray's footprint where a sample of them lands (:meth:`_faces_per_ray`)."""
        from ..algorithms.bvh.choice import choose_walk

        return choose_walk(
            len(origins), self.n_faces, _coherent(origins, directions, self.scene_size),
            lambda: self._faces_per_ray(origins, directions, t0, t1,
                                        _sample_runs(len(origins))))

    def _faces_per_ray(self, origins, directions, t0, t1, runs) -> float:
        """About how many triangles lie in one ray's footprint where the rays land:
        the sampled ``runs`` of four neighbouring rays are cast, and for each run whose
        four rays hit, the spacing of its hits squared, over the cosine of the first
        hit's incidence (an oblique surface stretches the footprint), times the faces
        per unit of the scene's surface area (sampled, :data:`AREA_SAMPLES`); the
        median of the runs. 0 when no run lands whole (rays that miss are cheap on
        either walk)."""
        from ..algorithms.bvh.walk import trace_range

        if self._surface_area <= 0.0:
            return 0.0
        keep = min(FOOTPRINT_RUNS, max(8, len(origins) // 1024))
        index = runs[::max(1, len(runs) // keep)].ravel()
        m = len(index)
        o, d = origins[index], directions[index]
        lo, hi = (t if len(t) == 1 else t[index] for t in (t0, t1))
        t, face = np.empty(m), np.empty(m, np.int32)
        normal = np.empty((m, 3))
        _, problem, _ = trace_range(
            0, m, o, d, lo, hi, NEAREST, None, *self.bvh.walked, self.face_offsets, t, face,
            np.empty(m, np.int32), np.empty((m, 2)), normal, np.empty(0, np.int32))
        if problem:  # a bad ray: the query's walk reports it
            return 0.0
        whole = (face.reshape(-1, 4) >= 0).all(axis=1)
        if not whole.any():
            return 0.0
        # Only the runs whose rays all hit: a miss's t is inf, and inf times a zero
        # direction component is NaN (and NumPy's warning).
        run_d = d.reshape(-1, 4, 3)[whole]
        points = o.reshape(-1, 4, 3)[whole] + t.reshape(-1, 4)[whole][..., None] * run_d
        spacing = np.linalg.norm(points[:, 3] - points[:, 0], axis=1) / 3
        first = run_d[:, 0]
        cosine = np.abs(np.einsum("rc,rc->r", normal.reshape(-1, 4, 3)[whole, 0], first)
                        ) / np.linalg.norm(first, axis=1)
        footprint = spacing ** 2 / np.maximum(cosine, 0.1)
        return float(np.median(footprint)) * self.n_faces / self._surface_area

    @staticmethod
    def _rays(origins, directions, t_min, t_max):
        """(origins, directions) as contiguous (N, 3) float64 arrays, t_min and t_max as
        float64 arrays of length N, or 1 for a value shared by all rays."""
        origins, directions = _broadcast(origins, directions)
        n = len(directions)
        return origins, directions, _interval(t_min, n, "t_min"), _interval(t_max, n, "t_max")


@njit(cache=True, nogil=True)
def _sample_runs(n):
    """(R, 4) ray indices: up to 256 runs of four neighbouring rays spread over a query
    of n rays ((0, 4) below four rays), in integer steps: a call starts with its code
    out of cache after a large query, and np.linspace's many small NumPy calls took 90
    us there."""
    n_runs = n // 4
    m = min(256, n_runs)
    runs = np.empty((m, 4), dtype=np.int64)
    for k in range(m):
        first = k * (n_runs - 1) // max(1, m - 1) * 4
        for j in range(4):
            runs[k, j] = first + j
    return runs


@njit(cache=True, nogil=True, error_model="numpy")
def _coherent(origins, directions, size):
    """Whether the rays come in coherent runs (judged on the runs of
    :func:`_sample_runs`): in three of four, the four origins lie within 1/100 of the
    scene's ``size`` of each other and the directions within about 2.5 degrees.

    The runs are judged one by one, stopping once more than a quarter are incoherent
    (the answer is no by then). Random rays stop after a quarter of the runs, whose rays
    lie spread over the query and mostly out of cache when a call starts (measurements:
    docs/history.md, "Ray core"). A NaN or zero direction makes its run incoherent (its
    comparisons are false; the walk refuses the ray)."""
    reach = 1e-2 * size
    runs = _sample_runs(origins.shape[0])
    m = runs.shape[0]
    allowed = m - (3 * m + 3) // 4  # incoherent runs at most (a quarter)
    bad = 0
    for r in range(m):
        first = runs[r, 0]
        ax, ay, az = directions[first, 0], directions[first, 1], directions[first, 2]
        a_len = np.sqrt(ax * ax + ay * ay + az * az)
        close = True
        for k in range(1, 4):
            j = runs[r, k]
            bx, by, bz = directions[j, 0], directions[j, 1], directions[j, 2]
            cosine = (ax * bx + ay * by + az * bz) / (a_len * np.sqrt(bx * bx + by * by
                                                                      + bz * bz))
            near = (abs(origins[j, 0] - origins[first, 0]) <= reach) & (
                abs(origins[j, 1] - origins[first, 1]) <= reach) & (
                abs(origins[j, 2] - origins[first, 2]) <= reach)
            if not (near & (cosine >= 0.999)):
                close = False
        if not close:
            bad += 1
            if bad > allowed:
                return False
    return m > 0


def _problem(problem: int, k: int, t0: np.ndarray, t1: np.ndarray) -> str:
    """The message for :func:`hsr.algorithms.bvh.hits.check_rays`' problem at ray k."""
    t_min = float(t0[k if len(t0) > 1 else 0])  # plain floats: numpy's repr is np.float64(..)
    t_max = float(t1[k if len(t1) > 1 else 0])
    return {1: f"origins must be finite; ray {k} is not",
            2: f"directions must be finite; ray {k} is not",
            3: f"directions must be non-zero; ray {k} is (0, 0, 0)",
            4: f"t_min must be finite; ray {k} has {t_min!r}",
            5: f"t_max must not be NaN; ray {k} has it",
            6: f"t_min must be >= 0; ray {k} has {t_min!r}",
            7: f"t_min must not exceed t_max; ray {k} has t_min {t_min!r} > "
               f"t_max {t_max!r}"}[problem]


def _max_hits(value) -> int | None:
    """all_hits' ``max_hits``: None (no cap) or a positive integer."""
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise RayError(f"max_hits must be a positive integer or None, got {value!r}")
    if value <= 0:
        raise RayError(f"max_hits must be a positive integer, got {int(value)}")
    return int(value)


def _real(values, what: str) -> np.ndarray:
    try:
        array = np.asarray(values)
    except (TypeError, ValueError) as exc:
        raise RayError(f"{what} must be an array of numbers ({exc})") from None
    if array.dtype.kind not in "fiu":  # (bool is "b", complex "c", objects "O")
        raise RayError(f"{what} must be real numbers, got dtype {array.dtype}")
    return array


def _broadcast(origins, directions):
    """(N, 3) float64 origins and directions; a (3,) origin is shared by all rays."""
    o = _real(origins, "origins")
    d = _real(directions, "directions")
    if d.ndim != 2 or d.shape[1] != 3:
        raise RayError(f"directions must have shape (N, 3), got {d.shape}")
    if len(d) > MAX_RAYS:
        raise RayError(f"at most {MAX_RAYS:,} rays a query, got {len(d):,}")
    if o.shape == (3,):
        o = np.broadcast_to(o, d.shape)
    if o.shape != d.shape:
        raise RayError(f"origins must have shape (N, 3) like directions {d.shape}, or "
                       f"(3,), got {o.shape}")
    return (np.ascontiguousarray(o, dtype=np.float64),
            np.ascontiguousarray(d, dtype=np.float64))


def _interval(value, n: int, what: str) -> np.ndarray:
    """A float64 array of length n from an (n,) array, or of length 1 from a scalar
    (shared by all rays; a million copies of it cost milliseconds to write)."""
    array = _real(value, what).astype(np.float64)
    if array.ndim == 0:
        return array.reshape(1)
    if array.shape != (n,):
        raise RayError(f"{what} must be a number or an array of shape ({n},), got "
                       f"{array.shape}")
    return np.ascontiguousarray(array)
