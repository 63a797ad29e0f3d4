"""Arrays read from .npy files (hsr visibility --what points:FILE.npy) against NumPy's own
reader: the same array for a file of real numbers, else one HsrError line; never a
complex value cut to its real part (with a warning), never a header of 10^12 rows
allocated (out of memory, exit 1), never a pickle (issue #61)."""

from __future__ import annotations

import io
import os
import struct
import tempfile
import warnings

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

import hsr
from conftest import run_cli
from hsr.scene.files import read_npy

DTYPES = ["<f8", ">f4", "<i4", "u1", "<c16", "?", "<m8[s]", "O"]


def _npy(shape, dtype, fortran, cut, header_rows):
    """A .npy file's bytes: an array as np.save writes it, its data cut short by ``cut``
    bytes, and its header's first dimension replaced by ``header_rows`` when given."""
    array = np.zeros(shape, dtype=np.dtype(dtype)) if dtype != "O" else np.empty(shape, object)
    if fortran:
        array = np.asfortranarray(array)
    buffer = io.BytesIO()
    np.save(buffer, array, allow_pickle=True)
    data = buffer.getvalue()
    if header_rows is not None and shape:
        (length,) = struct.unpack_from("<H", data, 8)
        header = data[10:10 + length].decode("latin1")
        claimed = (header_rows,) + tuple(shape[1:])
        header = header.replace(f"'shape': {tuple(shape)}", f"'shape': {claimed}")
        header = header.rstrip("\n").ljust(length - 1) + "\n"
        data = data[:10] + header.encode("latin1")[:length] + data[10 + length:]
    return data[:len(data) - cut] if cut else data


@settings(max_examples=80, deadline=None, derandomize=True)
@given(shape=st.lists(st.integers(0, 4), min_size=0, max_size=3).map(tuple),
       dtype=st.sampled_from(DTYPES), fortran=st.booleans(), cut=st.integers(0, 3),
       header_rows=st.one_of(st.none(), st.sampled_from([0, 7, 10 ** 12])))
@example(shape=(3, 3), dtype="<c16", fortran=False, cut=0, header_rows=None)
@example(shape=(2, 3), dtype="<f8", fortran=False, cut=0, header_rows=10 ** 12)
def test_a_npy_reads_as_numpy_reads_it_or_is_refused(shape, dtype, fortran, cut, header_rows):
    data = _npy(shape, dtype, fortran, cut, header_rows)
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "a.npy")
        with open(path, "wb") as fh:
            fh.write(data)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                got = read_npy(path, "points", 1 << 20)
        except hsr.HsrError as exc:
            assert "a.npy" in str(exc) and "\n" not in str(exc)
            real = np.dtype(dtype).kind in "iuf"
            assert not (real and cut == 0 and header_rows in (None, shape[0] if shape
                                                                else None)), exc
            return
        want = np.load(path, allow_pickle=False)
        assert got.dtype == want.dtype and np.array_equal(got, want)
        assert np.dtype(dtype).kind in "iuf"


@pytest.mark.parametrize("dtype, message", [("<c16", "not real numbers"),
                                            ("O", "not real numbers")])
def test_the_command_line_refuses_points_that_are_not_real(tmp_path, dtype, message):
    model = tmp_path / "m.obj"
    model.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "p.npy").write_bytes(_npy((4, 3), dtype, False, 0, None))
    code, err = run_cli(["visibility", str(model), "--views", "sphere:2", "--what",
                         f"points:{tmp_path / 'p.npy'}", "-o", str(tmp_path / "v.npz")])
    assert code == 2 and len(err) == 1 and message in err[0], err
    (tmp_path / "big.npy").write_bytes(_npy((2, 3), "<f8", False, 0, 10 ** 12))
    code, err = run_cli(["visibility", str(model), "--views", "sphere:2", "--what",
                         f"points:{tmp_path / 'big.npy'}", "-o", str(tmp_path / "v.npz")])
    assert code == 2 and "24,000,000,000,000 bytes" in err[0], err


def test_the_library_refuses_complex_points_without_a_warning():
    mesh = hsr.scenes.cube()
    cam = hsr.views.default(mesh)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(hsr.HsrError, match="real numbers"):
            hsr.visible_points(mesh, cam, np.zeros((2, 3), complex), 16, 16)
