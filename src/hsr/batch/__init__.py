"""Many views of many meshes on a Dask cluster (``hsr batch``): :func:`render_views`.
Dask (``dask.distributed``) is imported only when a batch runs (``pip install
'hsr[dask]'``)."""

from typing import Any

from .plan import OUTPUTS, BatchError, parse_views
from .sortlast import CompositeFrame, composite, each_partitioned, render_partitioned


def render_views(*args: Any, **kwargs: Any) -> Any:
    """See :func:`hsr.batch.run.render_views` (imported on first use: it needs Dask).
    Raises what that function raises, and :class:`~hsr.errors.MissingExtraError` when Dask
    (or, for ``format="zarr"``, Zarr) is not installed."""
    from ..errors import require_extra

    require_extra("hsr batch", "distributed")
    if kwargs.get("format") == "zarr":
        require_extra("hsr batch --format zarr", "zarr")
    from .run import render_views as run

    return run(*args, **kwargs)


__all__ = ["render_views", "parse_views", "OUTPUTS", "BatchError", "render_partitioned",
           "each_partitioned", "composite", "CompositeFrame"]
