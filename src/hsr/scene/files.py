"""Files in and out: reading input files within bounds (regular files only, a size cap),
writing images and buffers (Pillow for images, NumPy for arrays)."""

from __future__ import annotations

import os
import stat

import numpy as np

from ..errors import MeshError, OutputError
from .outputs import staged

__all__ = ["check_output", "check_regular", "read_regular", "read_npy", "save_normals",
           "PNG_SCALES",
           "save_image", "save_depth", "save_ids", "MAX_MESH_BYTES", "MAX_MTL_BYTES"]

# Default caps on what one input file may hold: a 10M-triangle OBJ is about 500 MB.
MAX_MESH_BYTES = 1 << 30
# Files read in chunks (the streamed partition) exist to be larger than memory: 4 TiB.
MAX_STREAM_BYTES = 1 << 42
MAX_MTL_BYTES = 64 << 20


def check_regular(path, what: str, max_bytes: int, error=MeshError) -> int:
    """The size of ``path`` if it is a *regular* file of at most ``max_bytes``; raises
    :class:`MeshError` for a missing file, a directory, a device, pipe or socket (reading
    ``/dev/zero`` never ends and a FIFO blocks forever), or a file over the cap (``error``
    instead of :class:`MeshError` for files that are not mesh data)."""
    path = os.fspath(path)
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise error(f"file not found: {path}") from None
    except OSError as exc:
        raise error(f"cannot read {what} {path}: {exc.strerror}") from None
    if stat.S_ISDIR(info.st_mode):
        raise error(f"{path} is a directory, not a {what}")
    if not stat.S_ISREG(info.st_mode):
        raise error(f"{path} is not a regular file (a device, pipe or socket); "
                        f"hsr reads only regular files")
    if info.st_size > max_bytes:
        raise error(f"{path} is {info.st_size:,} bytes, more than the {max_bytes:,} "
                        f"bytes hsr reads for a {what}")
    return info.st_size


def read_regular(path, what: str, max_bytes: int, error=MeshError) -> bytes:
    """The bytes of ``path`` after :func:`check_regular`."""
    path = os.fspath(path)
    check_regular(path, what, max_bytes, error)
    try:
        with open(path, "rb") as fh:
            data = fh.read(max_bytes + 1)
    except OSError as exc:
        raise error(f"cannot read {what} {path}: {exc.strerror}") from None
    if len(data) > max_bytes:  # grew since the stat
        raise error(f"{path} holds more than the {max_bytes:,} bytes hsr reads for a {what}")
    return data


def read_npy(path, what: str, max_bytes: int, error=MeshError) -> np.ndarray:
    """A ``.npy`` array of real numbers (integers or floats), read only after its header
    (NumPy's format, version 1 to 3) was checked against the file: a regular file of at
    most ``max_bytes``, no pickled objects, a dtype of real numbers (complex values
    would lose their imaginary part), and a shape whose bytes the file holds exactly
    (a header claiming 10^12 rows is refused before anything is allocated). Raises
    ``error`` naming ``what`` and the path."""
    path = os.fspath(path)
    size = check_regular(path, "array file", max_bytes, error)
    fmt = np.lib.format
    try:
        with open(path, "rb") as fh:
            version = fmt.read_magic(fh)
            reader = {(1, 0): fmt.read_array_header_1_0, (2, 0): fmt.read_array_header_2_0}
            shape, fortran, dtype = reader.get(version, fmt.read_array_header_2_0)(fh)
            start = fh.tell()
            if dtype.hasobject or dtype.kind not in "iuf":
                raise ValueError(f"dtype {dtype} is not real numbers")
            count = int(np.prod(shape, dtype=object))  # Python ints: no overflow
            if count * dtype.itemsize != size - start:
                raise ValueError(f"the header's shape {shape} needs "
                                 f"{count * dtype.itemsize:,} bytes of data, the file "
                                 f"holds {size - start:,}")
            array = np.fromfile(fh, dtype=dtype, count=count)
    except (ValueError, OSError, EOFError, SyntaxError, TypeError) as exc:
        raise error(f"{what}: {path} is not a .npy array hsr reads ({exc})"[:400]) from None
    return array.reshape(shape, order="F" if fortran else "C")


def _check_dir(path) -> str:
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise OutputError(f"cannot write {path}: directory {folder} does not exist")
    return path


def check_output(path, extensions=None) -> str:
    """Raise :class:`OutputError` unless ``path`` can be written: its folder exists and
    its extension is one of ``extensions`` (default: an image format Pillow writes).
    Called before the work, so a bad path fails at once, not after a long render."""
    path = _check_dir(path)
    ext = os.path.splitext(path)[1].lower()
    if extensions is None:
        from PIL import Image

        allowed = {e for e, fmt in Image.registered_extensions().items() if fmt in Image.SAVE}
    else:
        allowed = set(extensions)
    if ext not in allowed:
        shown = ", ".join(sorted(allowed)) if len(allowed) <= 6 else "png, jpg, tga, ..."
        raise OutputError(f"cannot write {path}: unknown extension {ext or '(none)'!r} "
                          f"(use {shown})")
    return path


def save_image(color: np.ndarray, path) -> None:
    """Write an (H, W, 3) uint8 image; the format follows the extension."""
    from PIL import Image

    path = check_output(path)
    try:
        with staged(path) as tmp:
            Image.fromarray(np.ascontiguousarray(color)).save(tmp)
    except (ValueError, KeyError) as exc:  # Pillow: unknown extension
        raise OutputError(f"cannot write {path}: {exc}") from None
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc}") from None


# 16-bit PNG scales: window depth in [0, 1] x 65535; eye depth and distance in 1/1000 world
# units (so 65.535 world units at most; background 0). Written into the PNG too.
PNG_SCALES = {"window": 65535.0, "eye": 1000.0, "distance": 1000.0}


def _save_buffer(path, array: np.ndarray, what: str, write_png) -> None:
    """Write ``array`` to a ``.npy`` (float32), an ``.exr`` (float32, see
    :func:`write_exr`) or, through ``write_png(path)``, a ``.png``; any other extension, or a
    failed write, is an :class:`OutputError`."""
    path = _check_dir(path)
    lower = path.lower()
    if not lower.endswith((".npy", ".exr", ".png")):
        raise OutputError(f"cannot write {what} to {path}: use .npy, .exr or .png")
    try:
        with staged(path) as tmp:
            if lower.endswith(".npy"):
                np.save(tmp, array.astype(np.float32))
            elif lower.endswith(".exr"):
                write_exr(tmp, array)
            else:
                write_png(tmp)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc}") from None


def write_exr(path, array: np.ndarray) -> None:
    """An OpenEXR file of float32 channels (ZIP compressed, lossless): ``Z`` for an (H, W)
    buffer, ``X``, ``Y``, ``Z`` for an (H, W, 3) one; row 0 at the top, as EXR stores it.
    Through the OpenEXR project's own binding (``pip install openexr``, the ``exr``
    extra). Raises :class:`OutputError` when it is not installed or the write fails."""
    try:
        import OpenEXR
    except ImportError:
        raise OutputError(f"cannot write {path}: .exr needs the OpenEXR package "
                          f"(pip install 'hsr[exr]' or pip install openexr)") from None
    data = np.ascontiguousarray(array, dtype=np.float32)
    if data.ndim == 2:
        channels = {"Z": data}
    else:
        channels = {name: np.ascontiguousarray(data[:, :, k]) for k, name in enumerate("XYZ")}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    try:
        with OpenEXR.File(header, channels) as exr:
            exr.write(os.fspath(path))
    except (RuntimeError, ValueError, TypeError) as exc:
        raise OutputError(f"cannot write {path}: {exc}") from None


def save_depth(depth: np.ndarray, path, kind: str = "window") -> None:
    """``.npy``: the float32 buffer as is (eye depth and distance: +inf on background).
    ``.png``: 16-bit grey, ``round(value * scale)`` clipped to 65535 with the scale of
    :data:`PNG_SCALES` (window: 65535; eye, distance: 1000 per world unit, background 0),
    recorded in the PNG's ``hsr`` text chunk."""

    def write_png(target):
        from PIL import Image, PngImagePlugin

        scale = PNG_SCALES[kind]
        finite = np.where(np.isfinite(depth), depth, 0.0)
        top = 1.0 if kind == "window" else 65535.0 / scale
        quantised = np.round(np.clip(finite, 0.0, top) * scale).astype(np.uint16)
        info = PngImagePlugin.PngInfo()
        info.add_text("hsr", f"{kind} depth: value = 16-bit pixel / {scale:g}"
                      + ("" if kind == "window" else " world units; 0 = background"))
        Image.fromarray(quantised).save(target, pnginfo=info)

    _save_buffer(path, depth, "depth", write_png)


def save_normals(normals: np.ndarray, path) -> None:
    """``.npy``: (H, W, 3) float32 unit normals (0 on background). ``.png``: 8-bit RGB
    ``round(127.5 (n + 1))``, background black."""

    def write_png(target):
        from PIL import Image

        rgb = np.round(127.5 * (np.clip(normals, -1, 1) + 1.0)).astype(np.uint8)
        rgb[~np.any(normals != 0, axis=2)] = 0
        Image.fromarray(rgb).save(target)

    _save_buffer(path, normals, "normals", write_png)


def save_ids(face_id: np.ndarray, path) -> None:
    """``.npy`` int32 face ids (-1 = background)."""
    path = _check_dir(path)
    if not path.lower().endswith(".npy"):
        raise OutputError(f"cannot write ids to {path}: use .npy")
    try:
        with staged(path) as tmp:
            np.save(tmp, face_id.astype(np.int32))
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc}") from None
