"""Running compiled kernels on several threads.

Kernels are plain ``@njit(nogil=True)`` functions over an index range; they release the
GIL, so Python threads run them truly in parallel. Each call owns its outputs' slices (a
range of faces, a band of rows), so there are no races, and the split never changes a
result. (Numba's ``parallel=True`` would do the same but triples compile time, which every
user pays on the first run, and its OpenMP workers spin between calls.)
"""

from __future__ import annotations

import itertools
import math
import queue
import threading
import weakref
from concurrent.futures import ThreadPoolExecutor, wait
from contextlib import AbstractContextManager, contextmanager

import numba
import numpy as np
from numpy.typing import DTypeLike

__all__ = ["Workers", "Workspace", "OutputPool", "split_range", "progress_bar",
           "default_workspace", "release_default_workspace", "DEFAULT_KEEP_BYTES",
           "OUTPUT_KEEP_BYTES"]


class _NoBar:
    """What :func:`progress_bar` gives when no bar is drawn: the calls a bar takes, doing
    nothing."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass


def progress_bar(enabled: bool, total: int, desc: str, unit: str = "view"):
    """A tqdm bar over ``total`` items, drawn only when ``enabled`` (on a terminal, not
    when piped), cleared when done. Not enabled, a bar that does nothing, without
    tqdm: even disabled, a tqdm bar's making took 8 us, and several times that in a
    call that starts with its code out of cache (a ray query after a large one)."""
    if not enabled:
        return _NoBar()
    from tqdm import tqdm

    return tqdm(total=total, unit=unit, desc=desc, leave=False, dynamic_ncols=True)


def split_range(n: int, parts: int) -> np.ndarray:
    """(k + 1,) boundaries cutting range(n) into at most ``parts`` near-equal chunks."""
    parts = max(1, min(parts, n)) if n > 0 else 1
    # Integer arithmetic, not np.linspace: this runs several times per render, and for
    # a few parts the Python loop costs a microsecond where linspace costs twenty.
    return np.array([k * n // parts for k in range(parts + 1)], dtype=np.int64)


def check_threads(threads) -> None:
    """Raise :class:`~hsr.errors.RenderError` unless ``threads`` is None (all of numba's)
    or a positive integer (0 is refused: it is not "all")."""
    from .errors import RenderError

    if threads is not None and (isinstance(threads, bool) or not isinstance(
            threads, (int, np.integer)) or threads < 1):
        raise RenderError(f"threads must be a positive integer or None, got {threads!r}")


# Bytes of dropped outputs an OutputPool keeps for later calls: a 1080p frame's buffers
# are 23 MB (colour, depth, face ids), the nearest hits of 1M rays 56 MB; a 4K frame's
# are 91 MB, of which two of its three blocks are kept. Per thread that renders (each
# has its own default workspace) and per RayScene.
OUTPUT_KEEP_BYTES = 64 << 20


class _Lease:
    """The memory of one array a call returned: the array is made from this object's
    ``__array_interface__``, so NumPy keeps the object as the array's base, and every
    view of it keeps it too. When the last of them is gone, the block goes back to its
    pool."""

    __slots__ = ("block", "address", "pool", "__array_interface__")

    def __init__(self, block: np.ndarray, address: int, shape: tuple, dtype: np.dtype,
                 pool) -> None:
        self.block, self.address, self.pool = block, address, pool
        self.__array_interface__ = {"shape": shape, "typestr": dtype.str, "version": 3,
                                    "data": (address, False)}

    def __del__(self):
        pool = self.pool()
        if pool is not None:
            pool.give_back(self.block, self.address)


class OutputPool:
    """Memory for the arrays a call returns to its caller (a frame's colour, depth and
    face ids; a ray query's answers), recycled once the caller has dropped them: up to
    ``keep_bytes`` of dropped blocks are kept, the oldest let go first, and a call
    asking for an array of a kept block's size gets that block (uninitialised, as
    ``np.empty``). Arrays larger than ``keep_bytes`` are plain ``np.empty`` ones.

    Why: an array freed by the caller goes back to glibc, whose heap gives its top back
    to the kernel when a free leaves more than M_TRIM_THRESHOLD there; the next call's
    outputs then fault every page in again (on this project's VMs 1,500-3,000 page
    faults a call and several milliseconds: see :class:`Workspace`). Thread-safe: an
    array may be dropped on any thread."""

    def __init__(self, keep_bytes: int = OUTPUT_KEEP_BYTES) -> None:
        self.keep_bytes = int(keep_bytes)
        # (block, its address), oldest first: the address is read once per block (its
        # ctypes attribute, Python code of NumPy's, was most of an array's lease in a
        # call that starts with its code out of cache).
        self._free: list[tuple[np.ndarray, int]] = []
        self._free_bytes = 0
        self._lock = threading.Lock()
        self._self = weakref.ref(self)

    def empty(self, shape: int | tuple[int, ...], dtype: DTypeLike = np.float64) -> np.ndarray:
        """An uninitialised array of ``shape`` and ``dtype``, in a kept block when one of
        its size is free."""
        dtype = np.dtype(dtype)
        dims = tuple(int(n) for n in ((shape,) if isinstance(shape, (int, np.integer))
                                      else shape))
        nbytes = math.prod(dims) * dtype.itemsize
        if nbytes == 0 or nbytes > self.keep_bytes or dtype.hasobject:
            return np.empty(dims, dtype=dtype)
        kept: tuple[np.ndarray, int] | None = None
        with self._lock:
            for k in range(len(self._free) - 1, -1, -1):
                if self._free[k][0].nbytes == nbytes:
                    kept = self._free.pop(k)
                    self._free_bytes -= nbytes
                    break
        if kept is None:
            fresh = np.empty(nbytes, dtype=np.uint8)
            kept = fresh, int(fresh.ctypes.data)
        block, address = kept
        return np.asarray(_Lease(block, address, dims, dtype, self._self))

    def give_back(self, block: np.ndarray, address: int) -> None:
        """Keep ``block`` (its arrays are all gone) for a later :meth:`empty`."""
        # Called from _Lease.__del__, on whichever thread dropped the last array, maybe
        # inside empty() on this one (a garbage collection there): never wait for the
        # lock. When another holder has it, the block is simply freed.
        if not self._lock.acquire(blocking=False):
            return
        try:
            self._free.append((block, address))
            self._free_bytes += block.nbytes
            while self._free_bytes > self.keep_bytes:
                self._free_bytes -= self._free.pop(0)[0].nbytes
        finally:
            self._lock.release()

    def __reduce__(self):
        # Pickled (a RayScene sent to another process) as an empty pool of the same cap:
        # its lock and its blocks stay here.
        return OutputPool, (self.keep_bytes,)

    def held_bytes(self) -> int:
        """Bytes of dropped outputs kept."""
        return self._free_bytes

    def clear(self) -> None:
        """Let every kept block go."""
        with self._lock:
            self._free.clear()
            self._free_bytes = 0


class Workers:
    """A few threads for one render. ``threads`` defaults to numba's thread count
    (``NUMBA_NUM_THREADS`` / ``numba.set_num_threads``)."""

    def __init__(self, threads: int | None = None) -> None:
        check_threads(threads)
        self.threads = max(1, int(threads or numba.get_num_threads()))
        self._pool: ThreadPoolExecutor | None = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self._pool is not None:
            # Idle threads exit on their own; joining them costs a render milliseconds.
            self._pool.shutdown(wait=False)
            self._pool = None

    def run(self, kernel, bounds, *args, each=None, on_done=None) -> list:
        """``kernel(bounds[i], bounds[i + 1], *args)`` for every chunk; results in order.
        ``each``: one more argument per chunk (e.g. the rows of an array that each chunk
        accumulates into on its own), passed last. ``on_done(lo, hi)`` is called on the
        calling thread as chunks finish (progress).

        The calling thread and ``threads - 1`` pool threads take the chunks in order, each
        the next one left as it comes free, so more chunks than threads balance uneven
        work (the ray caster's rows). (With the caller running only the first chunk, the
        ray caster's 16 chunks on two threads ran 15 on the pool's one thread: the bunny
        at 1024x1024 took 195-202 ms instead of 116-119.)"""
        chunks = [(int(bounds[i]), int(bounds[i + 1])) for i in range(len(bounds) - 1)]
        extra = [args + (each[k],) for k in range(len(chunks))] if each is not None else \
            [args] * len(chunks)
        if self.threads == 1 or len(chunks) <= 1:
            results = []
            for k, (lo, hi) in enumerate(chunks):
                results.append(kernel(lo, hi, *extra[k]))
                if on_done is not None:
                    on_done(lo, hi)
            return results
        if self._pool is None:
            self._pool = ThreadPoolExecutor(self.threads - 1)
        pool = self._pool
        results = [None] * len(chunks)
        order = itertools.count(1)  # next() is atomic under the GIL; 0 is the caller's
        # Chunk indices as they finish, for on_done.
        finished: queue.SimpleQueue[int] = queue.SimpleQueue()
        failed: list[int] = []

        def report(timeout=None):
            while on_done is not None:
                try:
                    on_done(*chunks[finished.get(timeout=timeout) if timeout
                                    else finished.get_nowait()])
                except queue.Empty:
                    return

        def take(k, calling=False):
            """Chunk k, then the next one left, until none are (or one failed)."""
            while k < len(chunks) and not failed:
                try:
                    results[k] = kernel(*chunks[k], *extra[k])
                except BaseException:
                    failed.append(k)  # the others stop taking chunks
                    raise
                finished.put(k)
                if calling:
                    report()
                k = next(order)

        # The calling thread works too, from chunk 0: one hand-off fewer, and it is busy
        # at once instead of waiting for a pool thread to wake.
        helpers = [pool.submit(take, next(order))
                   for _ in range(min(self.threads, len(chunks)) - 1)]
        try:
            take(0, calling=True)
            while on_done is not None and not all(h.done() for h in helpers):
                report(timeout=0.05)
        finally:
            # No chunk may still be writing into the caller's arrays once this returns.
            wait(helpers)
        for helper in helpers:
            helper.result()  # re-raises a pool thread's exception
        report()
        return results

    def output(self, shape: int | tuple[int, ...], dtype: DTypeLike = np.float64) -> np.ndarray:
        """An uninitialised array the render returns (a frame's buffers). Fresh here; a
        :class:`Workspace` recycles the memory of the outputs its caller has dropped
        (:class:`OutputPool`)."""
        return np.empty(shape, dtype=dtype)

    def scratch(self, key: str, rows: int, shape: tuple = (),
                dtype: DTypeLike = np.float64) -> np.ndarray:
        """An uninitialised (rows, *shape) array for work inside one render (never for
        what the render returns). Fresh here; a :class:`Workspace` keeps them."""
        return np.empty((rows, *shape), dtype=dtype)

    def split(self, n: int, min_chunk: int = 4096) -> np.ndarray:
        """Boundaries cutting ``range(n)`` into one chunk per thread, none smaller than
        ``min_chunk`` (below that a thread hand-off costs more than it saves)."""
        return split_range(n, min(self.threads, max(1, n // min_chunk)))

    def run_range(self, kernel, n: int, *args, min_chunk: int = 4096) -> list:
        """Run ``kernel`` over ``range(n)`` cut by :meth:`split`."""
        return self.run(kernel, self.split(n, min_chunk), *args)


class Workspace(Workers):
    """Threads and scratch buffers kept from one render to the next:
    ``hsr.render(..., workspace=ws)`` for many renders in a row (views, meshes, frames of
    an animation). Results are the same as without it.

    Why: glibc gives the top of its heap back to the kernel when a free leaves more than
    M_TRIM_THRESHOLD there (at most 64 MB when it adapts), so a render whose scratch is
    freed at its end faults every page of it in again at the next one, depending on the
    process's heap history: the 1M-face terrain at 1080p rendered after the
    tinyrenderer head and the bunny faulted 5,200-5,700 pages (~21 MB) a render and took
    99-168 ms; kept here, 0-2 faults and 72-100 ms. Kept: the z-buffer's set-up records
    and face status, and the thread pool. The frames' own buffers (colour, depth, face
    ids), which the caller holds, come from an :class:`OutputPool` (:attr:`outputs`):
    once the caller drops a frame, a later render reuses its memory. One render at a
    time uses a workspace (another thread's render raises
    :class:`~hsr.errors.RenderError`); it holds its largest buffers until closed or
    dropped. Plain ``hsr.render`` calls use one of the calling
    thread's own (:func:`default_workspace`)."""

    def __init__(self, threads: int | None = None) -> None:
        super().__init__(threads)
        self._buffers: dict = {}
        self._lock = threading.Lock()
        self.outputs = OutputPool()
        self.busy = False  # held by a render (the per-thread default's own flag)
        self.requested = threads

    def kept_bytes(self) -> int:
        """Bytes of scratch kept."""
        return sum(b.nbytes for b in self._buffers.values())

    def drop_buffers(self) -> None:
        """Drop the scratch, keep the threads."""
        self._buffers.clear()

    def __exit__(self, *exc):
        self.close()

    def close(self) -> None:
        """Stop the threads and drop the buffers and the kept outputs (a later render
        starts them again)."""
        super().__exit__()
        self.drop_buffers()
        self.outputs.clear()

    def output(self, shape: int | tuple[int, ...], dtype: DTypeLike = np.float64) -> np.ndarray:
        """An uninitialised array the render returns, from :attr:`outputs`: memory of
        an earlier frame's buffers the caller has dropped when there is some of the
        size."""
        return self.outputs.empty(shape, dtype)

    def scratch(self, key: str, rows: int, shape: tuple = (),
                dtype: DTypeLike = np.float64) -> np.ndarray:
        dtype = np.dtype(dtype)
        kept = self._buffers.get(key)
        if kept is None or kept.shape[1:] != tuple(shape) or kept.dtype != dtype \
                or len(kept) < rows:
            kept = self._buffers[key] = np.empty((rows, *shape), dtype=dtype)
        return kept[:rows]

    def claim(self) -> AbstractContextManager[Workers]:
        """Context manager for one render's use: raises RenderError if another holds it."""
        from contextlib import contextmanager

        from .errors import RenderError

        @contextmanager
        def held():
            if not self._lock.acquire(blocking=False):
                raise RenderError("this Workspace is in use by another render; give each "
                                  "thread its own")
            try:
                yield self
            finally:
                self._lock.release()

        return held()


# What the per-thread default workspace keeps between renders: scratch up to this size
# (the 1M-face terrain at 1080p keeps about 60 MB); a render that needed more gives its
# buffers back at its end, so a one-off 10M-face render does not hold a gigabyte.
DEFAULT_KEEP_BYTES = 256 << 20
_THREAD_DEFAULTS = threading.local()


@contextmanager
def default_workspace(threads: int | None, replace: bool = True):
    """The calling thread's own :class:`Workspace` for ``threads`` (made on first use),
    held for one render: what ``hsr.render`` uses when it is given no workspace, so plain
    calls keep their scratch from one to the next as a Workspace does (the reason is in
    :class:`Workspace`'s notes). Per thread, so no two renders share one; a render
    nested in another on the same thread (or given ``threads`` other than the kept
    one's) gets fresh threads and scratch. Scratch over :data:`DEFAULT_KEEP_BYTES` is
    dropped after the render; :func:`release_default_workspace` drops all of it.

    ``replace=False`` (callers that use only the threads, as ``RayScene``'s queries):
    a kept workspace made for other ``threads`` is left as it is, with its scratch, and
    this call gets fresh threads, instead of the kept one being closed and made anew."""
    kept = getattr(_THREAD_DEFAULTS, "workspace", None)
    other = kept is not None and kept.requested != threads  # made for other threads
    if kept is None or (other and replace):
        if kept is not None and not kept.busy:
            kept.close()
        kept = Workspace(threads)
        kept.requested = threads
        _THREAD_DEFAULTS.workspace = kept
    elif other or kept.busy:  # left as it is, or in use further up this thread's stack
        with Workers(threads) as workers:
            yield workers
        return
    kept.busy = True
    try:
        yield kept
    finally:
        kept.busy = False
        if kept.kept_bytes() > DEFAULT_KEEP_BYTES:
            kept.drop_buffers()


def release_default_workspace() -> None:
    """Stop the calling thread's default workspace's threads and drop its scratch."""
    kept = getattr(_THREAD_DEFAULTS, "workspace", None)
    if kept is not None and not kept.busy:
        kept.close()
        _THREAD_DEFAULTS.workspace = None


def run_with_progress(kernel, args, report, total: int, desc: str):
    """``kernel(*args)`` on a thread (a ``nogil`` kernel runs while Python waits) with a
    progress bar that follows ``report[0]`` (items done) and ``report[1]`` (items in all,
    which may grow). Returns the kernel's result; re-raises its exception."""
    import threading

    from tqdm import tqdm

    outcome = {}

    def target():
        try:
            outcome["value"] = kernel(*args)
        except BaseException as exc:  # re-raised on the caller's thread
            outcome["error"] = exc

    worker = threading.Thread(target=target, daemon=True)
    worker.start()
    with tqdm(total=total, desc=desc, unit="poly", leave=False) as bar:
        while worker.is_alive():
            worker.join(0.1)
            bar.total = max(total, int(report[1]))
            bar.n = int(report[0])
            bar.refresh()
    if "error" in outcome:
        raise outcome["error"]
    return outcome["value"]
