"""Many views of many meshes on a Dask cluster (``hsr batch``): :func:`render_views`.
Dask (``dask.distributed``) is imported only when a batch runs (``pip install
'hsr[dask]'``)."""

from .plan import OUTPUTS, BatchError, parse_views


def render_views(*args, **kwargs):
    """See :func:`hsr.batch.run.render_views` (imported on first use: it needs Dask).
    Raises what that function raises, and :class:`BatchError` when Dask is missing."""
    try:
        from .run import render_views as run
    except ImportError as exc:
        raise BatchError(f"hsr batch needs dask.distributed ({exc}); pip install "
                         f"'hsr[dask]'") from None
    return run(*args, **kwargs)


__all__ = ["render_views", "parse_views", "OUTPUTS", "BatchError"]
