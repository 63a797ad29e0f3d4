"""Exceptions raised by hsr. Every input problem is an :class:`HsrError` subclass, so
callers (and the CLI) can report it as one line."""


class HsrError(Exception):
    """Base class of every error hsr raises on bad input."""


class MeshError(HsrError):
    """A mesh is missing, unreadable, malformed or invalid (bad indices, NaN/inf, empty)."""


class CameraError(HsrError):
    """A camera has nonsense parameters (near <= 0, far <= near, fov outside (0, 180), ...)."""


class RenderError(HsrError):
    """Render arguments are invalid (size, algorithm name, render state)."""


class OutputError(HsrError):
    """An output file cannot be written (bad extension, missing directory, ...)."""


class HsrWarning(UserWarning):
    """Something hsr drew differently from what a file asks, and says so (a texture the
    model names that is not there); the command line prints it as one line."""


class MissingExtraError(HsrError):
    """An optional dependency that a feature needs is not installed."""


# The extra of pyproject.toml that installs each optional module.
EXTRAS = {"distributed": "dask", "zarr": "dask", "starlette": "view", "uvicorn": "view",
          "OpenEXR": "exr", "shapely": "regions",
          "matplotlib": "mpl", "OCP": "cad", "vpype": "plot"}


def require_extra(what: str, *modules: str) -> None:
    """Raise :class:`MissingExtraError` naming the extra to install unless every module
    imports (imported for real, so a broken install counts as missing, and the cost is
    paid once: the caller imports them next)."""
    import importlib

    for name in modules:
        try:
            importlib.import_module(name)
        except ImportError:
            raise MissingExtraError(f"{what} needs {name}, which is not installed: pip "
                                    f"install 'hsr[{EXTRAS[name]}]' (or 'hsr[all]')") from None


def check_choice(value, choices, what: str, error=None) -> str:
    """``value`` if it is one of the strings ``choices``, else an error (``error``, default
    :class:`RenderError`) that lists them. Safe for values of any type (an array is not
    compared element by element)."""
    if not isinstance(value, str) or value not in choices:
        raise (error or RenderError)(f"{what} must be one of {', '.join(choices)}; "
                                     f"got {value!r}")
    return value


def check_rgb(value, what: str) -> tuple:
    """``value`` as a tuple if it is three numbers in 0..255 (not booleans), else a
    :class:`RenderError` naming ``what``."""
    import numbers

    try:
        parts = tuple(value)
    except TypeError:
        parts = ()
    if len(parts) != 3 or not all(isinstance(c, numbers.Real) and not isinstance(c, bool)
                                  and 0 <= c <= 255 for c in parts):  # type: ignore[operator]
        raise RenderError(f"{what} must be three numbers in 0..255, got {value!r}")
    return parts
