"""Asserts two HDF5 files hold the same groups, datasets (values, dtypes, shapes) and attributes.

Usage: compare_hdf5.py A B  (used by the Rust round-trip test).
"""
import sys

import h5py
import numpy as np


def compare(a, b, path):
    assert set(a.attrs) == set(b.attrs), f"{path}: attrs {set(a.attrs)} != {set(b.attrs)}"
    for k in a.attrs:
        x, y = a.attrs[k], b.attrs[k]
        assert type(x) is type(y) and np.array_equal(np.asarray(x), np.asarray(y)), f"{path}@{k}: {x!r} != {y!r}"
        assert a.attrs.get_id(k).dtype == b.attrs.get_id(k).dtype, f"{path}@{k}: dtype differs"
    if isinstance(a, h5py.Dataset):
        assert isinstance(b, h5py.Dataset), path
        assert a.dtype == b.dtype and a.shape == b.shape, f"{path}: {a.dtype}{a.shape} != {b.dtype}{b.shape}"
        x, y = a[()], b[()]
        assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), f"{path}: values differ"
        if x.dtype.kind == "f":
            assert x.tobytes() == y.tobytes(), f"{path}: bits differ"
        assert a.chunks == b.chunks and a.compression == b.compression, f"{path}: storage differs"
        return
    assert set(a.keys()) == set(b.keys()), f"{path}: members {set(a.keys())} != {set(b.keys())}"
    for k in a:
        compare(a[k], b[k], f"{path}/{k}")


with h5py.File(sys.argv[1], "r") as a, h5py.File(sys.argv[2], "r") as b:
    compare(a, b, "")
print("identical")
