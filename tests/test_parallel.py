"""hsr.parallel.Workers: chunks run once each, results in order, the caller's thread
works too, and a failing chunk never leaves another still writing."""

import threading
import time

import numpy as np
import pytest

from hsr.parallel import Workers, split_range


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_every_chunk_runs_once_and_results_come_in_order(threads):
    n = 1000
    out = np.zeros(n, dtype=np.int64)

    def kernel(lo, hi, values, mark):
        values[lo:hi] += np.arange(lo, hi) ** 2
        return (lo, hi, mark)

    with Workers(threads) as workers:
        bounds = split_range(n, 5)
        results = workers.run(kernel, bounds, out, "m")
    assert out.tolist() == [i * i for i in range(n)]
    assert results == [(int(bounds[k]), int(bounds[k + 1]), "m") for k in range(5)]


def test_each_gives_every_chunk_its_own_argument():
    rows = np.zeros((3, 4))
    with Workers(2) as workers:
        workers.run(lambda lo, hi, row: row.fill(hi - lo), np.array([0, 2, 5, 9]), each=rows)
    assert rows[:, 0].tolist() == [2, 3, 4]


def test_the_calling_thread_runs_the_first_chunk():
    seen = {}

    def kernel(lo, hi):
        seen[lo] = threading.get_ident()
        time.sleep(0.05)

    with Workers(2) as workers:
        workers.run(kernel, np.array([0, 1, 2, 3]))
    assert seen[0] == threading.get_ident()
    assert len(set(seen.values())) == 2  # the pool's thread took chunks too


def test_more_chunks_than_threads_are_shared_as_threads_come_free():
    """The ray caster cuts rows into 8 chunks per thread; the calling thread used to run
    only the first and leave the other 15 to the pool's one thread (half the speed)."""
    ran, reported = {}, []

    def kernel(lo, hi):
        ran[lo] = threading.get_ident()
        time.sleep(0.02)
        return lo

    with Workers(2) as workers:
        results = workers.run(kernel, np.arange(9),
                              on_done=lambda lo, hi: reported.append(
                                  (lo, hi, threading.get_ident())))
    assert results == list(range(8))
    me = threading.get_ident()
    assert 2 <= sum(t == me for t in ran.values()) <= 6  # both threads worked
    assert sorted(r[:2] for r in reported) == [(k, k + 1) for k in range(8)]
    assert all(r[2] == me for r in reported)  # progress on the calling thread


def test_a_failing_chunk_waits_for_the_others_before_raising():
    started, finished = [], []

    def kernel(lo, hi):
        if lo == 0:
            raise ValueError("chunk 0 failed")
        started.append(lo)
        time.sleep(0.2)
        finished.append(lo)

    with Workers(2) as workers:
        with pytest.raises(ValueError, match="chunk 0"):
            workers.run(kernel, np.array([0, 1, 2, 3, 4]))
        # A chunk already running finished before the error reached the caller, and
        # no chunk started after the failure.
        assert sorted(finished) == sorted(started) and len(started) <= 1


def test_split_range_covers_the_range_in_near_equal_parts():
    for n in (0, 1, 7, 100, 10_001):
        for parts in (1, 2, 3, 8):
            b = split_range(n, parts)
            assert b[0] == 0 and b[-1] == n and np.all(np.diff(b) >= 0)
            if n >= parts:
                sizes = np.diff(b)
                assert len(sizes) == parts and sizes.max() - sizes.min() <= 1


def test_renders_leave_no_threads_behind():
    # Each render's pool is shut down without joining (joining cost milliseconds a view);
    # its idle threads must still exit rather than pile up over many renders.
    import hsr

    mesh = hsr.Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float), np.array([[0, 1, 2]]))
    camera = hsr.Camera.frame(mesh.bounds())
    before = threading.active_count()
    for _ in range(100):
        hsr.render(mesh, camera, 32, 24, threads=2)
    deadline = time.monotonic() + 5.0
    while threading.active_count() > before + 1 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert threading.active_count() <= before + 1


def test_a_workspace_keeps_its_scratch_and_grows_it():
    import hsr

    with hsr.Workspace(1) as workspace:
        first = workspace.scratch("a", 10, (3,), np.int32)
        again = workspace.scratch("a", 4, (3,), np.int32)
        assert np.shares_memory(again, first) and again.shape == (4, 3)
        assert again.flags.c_contiguous
        grown = workspace.scratch("a", 20, (3,), np.int32)
        assert grown.shape == (20, 3) and not np.shares_memory(grown, first)
        other = workspace.scratch("a", 5, (3,), np.float64)  # another layout: a new buffer
        assert other.dtype == np.float64 and other.shape == (5, 3)
    with Workers(1) as workers:  # plain workers: fresh every time
        assert not np.shares_memory(workers.scratch("a", 4), workers.scratch("a", 4))


def test_render_refuses_a_workspace_in_use_or_of_other_threads():
    import hsr
    from hsr.errors import RenderError

    mesh, cam = hsr.scenes.cubes()
    with hsr.Workspace(2) as workspace:
        with workspace.claim():  # another render holds it
            with pytest.raises(RenderError, match="in use by another render"):
                hsr.render(mesh, cam, 32, 24, workspace=workspace)
        with pytest.raises(RenderError, match="differs from the workspace's 2"):
            hsr.render(mesh, cam, 32, 24, threads=1, workspace=workspace)
        frame = hsr.render(mesh, cam, 32, 24, threads=2, workspace=workspace)  # free again
        assert (frame.face_id >= 0).any()
    with pytest.raises(RenderError, match="workspace must be an hsr.Workspace"):
        hsr.render(mesh, cam, 32, 24, workspace=Workers(1))
