"""``hsr view``: a local web page that renders with hsr as the user moves
(:func:`serve`, :func:`make_app`; Starlette and uvicorn, ``pip install 'hsr[view]'``)."""

from .params import ViewerError


def serve(*args, **kwargs):
    """See :func:`hsr.viewer.server.serve` (imported on first use: it needs the web
    stack). Raises :class:`ViewerError` when Starlette or uvicorn is missing."""
    try:
        from .server import serve as run
    except ImportError as exc:
        raise ViewerError(f"hsr view needs starlette and uvicorn ({exc}); pip install "
                          f"'hsr[view]'") from None
    return run(*args, **kwargs)


__all__ = ["serve", "ViewerError"]
