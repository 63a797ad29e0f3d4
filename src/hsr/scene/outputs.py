"""Where outputs land: the one guard every command that writes goes through, so that no
output is ever written over one of the command's inputs (the model, its .mtl, textures
and buffers, camera and point files) or over another output of the same call, no store
replaces a folder or file that is not a store hsr wrote, and every file appears whole or
not at all (written under a temporary name in its folder, then renamed: POSIX
``rename(2)`` is atomic within one file system).

Two paths are the same file when their real paths (links resolved) agree, or when both
exist and are one inode (a hard link).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import stat
import tempfile
import uuid

from ..errors import OutputError

__all__ = ["OutputPlan", "same_file", "staged", "write_atomic", "check_store_target",
           "check_outside", "input_inside", "input_files"]


def _identity(path: str) -> tuple:
    """``(real path, (device, inode) or None)`` of ``path``."""
    real = os.path.realpath(path)
    try:
        info = os.stat(path)
    except OSError:
        return real, None
    return real, (info.st_dev, info.st_ino)


def same_file(a, b) -> bool:
    """True when the paths ``a`` and ``b`` name one file (see the module)."""
    return _same(_identity(os.fspath(a)), _identity(os.fspath(b)))


def input_files(paths) -> list:
    """``paths`` with each folder among them (a COLMAP model, a store) followed by the
    files inside it, recursively: writing into an input folder is writing over input."""
    out = []
    for path in paths:
        if path is None:
            continue
        path = os.fspath(path)
        out.append(path)
        if os.path.isdir(path) and not os.path.islink(path):
            for root, dirs, files in os.walk(path):
                out += [os.path.join(root, name) for name in files + dirs]
                if len(out) > 100_000:  # a folder that large is refused as a whole
                    break
    return out


class OutputPlan:
    """The inputs of one command call and the outputs planned so far. :meth:`add` refuses
    an output that is one of the inputs or another output of the same call, with an
    :class:`~hsr.errors.OutputError` naming both; call it for every output before any
    work starts."""

    def __init__(self, inputs=()) -> None:
        self._inputs: list = []
        self._outputs: list = []
        for what, path in inputs:
            self.add_input(what, path)

    def add_input(self, what: str, path) -> None:
        """Record ``path`` (and, for a folder, everything in it) as an input."""
        for p in input_files([path]):
            self._inputs.append((what, p, _identity(p)))

    def add(self, flag: str, path) -> str:
        """Check and record the output ``path`` given by ``flag``; returns the path."""
        path = os.fspath(path)
        ident = _identity(path)
        for what, other, other_ident in self._inputs:
            if _same(ident, other_ident):
                raise OutputError(f"{flag} {path} is {what} ({other}), an input of this "
                                  f"command: write the output elsewhere")
        for other_flag, other, other_ident in self._outputs:
            if _same(ident, other_ident):
                raise OutputError(f"{flag} {path} and {other_flag} {other} are the same "
                                  f"file: give each output its own name")
        self._outputs.append((flag, path, ident))
        return path


def input_inside(inputs, targets) -> tuple | None:
    """The first ``(input, target)`` where one of the ``inputs`` is one of the ``targets``
    or lies inside one of them (folders an output is written into), else None."""
    for target in targets:
        inside = os.path.realpath(target)
        for path in inputs:
            real = os.path.realpath(path)
            if same_file(path, target) or os.path.commonpath([real, inside]) == inside:
                return path, target
    return None


def check_outside(inputs, targets, what: str = "--out") -> None:
    """Refuse (:class:`~hsr.errors.OutputError`) what :func:`input_inside` finds."""
    found = input_inside(inputs, targets)
    if found:
        raise OutputError(f"{what} would write {found[1]}, which holds the input "
                          f"{found[0]}: write the output elsewhere")


def _same(a: tuple, b: tuple) -> bool:
    return a[0] == b[0] or (a[1] is not None and a[1] == b[1])


def check_store_target(path, force: bool, is_own, flag: str, what: str = "store") -> str:
    """Where a command writes a store (a folder): nothing there, an empty folder, or (with
    ``force``) a store this command wrote, which ``is_own(path)`` recognises by its
    metadata. Anything else (an ordinary file, a link, a folder of other files, an own
    store without ``force``) is an :class:`~hsr.errors.OutputError`."""
    path = os.fspath(path)
    try:
        info = os.lstat(path)
    except FileNotFoundError:
        return path
    except OSError as exc:
        raise OutputError(f"{flag} {path}: {exc.strerror}") from None
    if not stat.S_ISDIR(info.st_mode):
        raise OutputError(f"{flag} {path} exists and is not a folder (a file or a link); "
                          f"hsr writes a {what} only where nothing, an empty folder or a "
                          f"{what} it wrote is")
    try:
        empty = not os.listdir(path)
    except OSError as exc:
        raise OutputError(f"{flag} {path}: {exc.strerror}") from None
    if empty:
        return path
    if not is_own(path):
        raise OutputError(f"{flag} {path} is a folder that holds other files, "
                          f"not a store hsr wrote ({what}); not replacing it")
    if not force:
        raise OutputError(f"{flag} {path} exists; hsr replaces a {what} it wrote only when "
                          f"asked (--force, overwrite=True)")
    return path


@contextlib.contextmanager
def staged(path):
    """Yield a temporary path with ``path``'s file name (so writers that choose a format by
    the extension, or name companion files by the stem, work unchanged) in a new hidden
    folder beside it; when the block ends without an exception, every file in that folder
    is renamed into ``path``'s folder (the main file last), else nothing is. The folder
    is always removed."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    try:
        scratch = tempfile.mkdtemp(prefix=".hsr-", dir=folder)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    try:
        tmp = os.path.join(scratch, os.path.basename(path))
        yield tmp
        names = sorted(os.listdir(scratch), key=lambda n: n == os.path.basename(path))
        for name in names:
            os.replace(os.path.join(scratch, name), os.path.join(folder, name))
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def write_atomic(path, write) -> None:
    """``write(binary file)`` into a temporary file beside ``path`` (its folder must
    exist), then rename it over ``path``."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    tmp = os.path.join(folder, f".{os.path.basename(path)}.{uuid.uuid4().hex}.tmp")
    try:
        with open(tmp, "wb") as handle:
            write(handle)
        os.replace(tmp, path)
    finally:
        if os.path.lexists(tmp):
            os.remove(tmp)
