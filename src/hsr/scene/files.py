"""Writing images and buffers (Pillow for images, NumPy for arrays)."""

from __future__ import annotations

import os

import numpy as np

from ..errors import OutputError

__all__ = ["save_image", "save_depth", "save_ids"]


def _check_dir(path) -> str:
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise OutputError(f"cannot write {path}: directory {folder} does not exist")
    return path


def save_image(color: np.ndarray, path) -> None:
    """Write an (H, W, 3) uint8 image; the format follows the extension."""
    from PIL import Image

    path = _check_dir(path)
    try:
        Image.fromarray(np.ascontiguousarray(color)).save(path)
    except (ValueError, KeyError) as exc:  # Pillow: unknown extension
        raise OutputError(f"cannot write {path}: {exc}") from None
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc}") from None


def save_depth(depth: np.ndarray, path) -> None:
    """``.npy``: the float32 buffer as is. ``.png``: 16-bit grey, round(depth * 65535)."""
    path = _check_dir(path)
    lower = path.lower()
    try:
        if lower.endswith(".npy"):
            np.save(path, depth.astype(np.float32))
        elif lower.endswith(".png"):
            from PIL import Image

            quantised = np.round(np.clip(depth, 0.0, 1.0) * 65535.0).astype(np.uint16)
            Image.fromarray(quantised).save(path)
        else:
            raise OutputError(f"cannot write depth to {path}: use .npy or .png")
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc}") from None


def save_ids(face_id: np.ndarray, path) -> None:
    """``.npy`` int32 face ids (-1 = background)."""
    path = _check_dir(path)
    if not path.lower().endswith(".npy"):
        raise OutputError(f"cannot write ids to {path}: use .npy")
    try:
        np.save(path, face_id.astype(np.int32))
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc}") from None
