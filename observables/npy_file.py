"""A ``.npy`` file read as data, never as code.

``read_npy(path)`` returns what the file holds: a plain numeric array (read with ``allow_pickle=False``,
its declared shape checked against the file's size before anything is allocated), or, for an array of
objects (idtracker.ai's ``trajectories.npy`` is ``np.save`` of a dictionary), the objects rebuilt by a
restricted unpickler. That unpickler knows only what numpy writes for arrays, scalars and dtypes, plus
``collections.OrderedDict`` and paths (kept as text); any other class or function a file names, which is
how a pickle runs code, is refused with :class:`NotData` before anything is called. A file that is not
an ``.npy`` file at all (a raw pickle renamed ``.npy`` included) is refused too: ``np.load``'s fallback
to ``pickle.load`` is never reached.

Plain Python values (dicts, lists, strings, numbers, None) need no class and are read as they are.

``npy_header(path)`` and ``npz_headers(path)`` give the declared shape, dtype and size of a file's arrays
from their headers alone, each checked against the bytes the file (or archive member) holds and, for a
compressed member, against what zlib can expand to (:data:`DEFLATE_RATIO`), before anything is allocated;
``read_npz(path, keys)`` reads an archive's arrays after that check, with pickling off (an object array
is :class:`NotData`).
"""
from __future__ import annotations

import io
import pickle
from pathlib import Path, PurePosixPath, PureWindowsPath

import numpy as np

#: how the numpy versions that write idtracker.ai's files name the functions an array's pickle calls
_NUMPY_CORE = ("numpy.core.multiarray", "numpy._core.multiarray", "numpy.core.numeric", "numpy._core.numeric")
_NUMPY_FUNCTIONS = {"_reconstruct", "scalar", "_frombuffer"}


class NotData(ValueError):
    """The file asks for a class or function beyond arrays, scalars and dtypes: it could run code."""


def _path_text(*parts) -> str:
    return str(PurePosixPath(*map(str, parts)))


def _windows_path_text(*parts) -> str:
    return str(PureWindowsPath(*map(str, parts)))


def _encode(text, encoding="latin1"):
    """``_codecs.encode`` as protocol-2 pickles use it for bytes (only text to bytes)."""
    if not isinstance(text, str) or not isinstance(encoding, str):
        raise NotData("_codecs.encode with other than text")
    return text.encode(encoding)


def _allowed(module: str, name: str):
    import numpy._core.multiarray as multiarray
    import numpy._core.numeric as numeric
    if module in _NUMPY_CORE and name in _NUMPY_FUNCTIONS:
        return getattr(multiarray if name != "_frombuffer" else numeric, name)
    if module == "numpy" and name in ("ndarray", "dtype"):
        return getattr(np, name)
    if module == "numpy.dtypes" and name.endswith("DType"):
        return np.dtype           # a dtype class stands for the dtype it makes
    if module == "collections" and name == "OrderedDict":
        from collections import OrderedDict
        return OrderedDict
    if module in ("pathlib", "pathlib._local") and name in ("PosixPath", "PurePosixPath"):
        return _path_text
    if module in ("pathlib", "pathlib._local") and name in ("WindowsPath", "PureWindowsPath"):
        return _windows_path_text
    if module in ("_codecs", "codecs") and name == "encode":
        return _encode
    return None


class _DataUnpickler(pickle.Unpickler):
    """An unpickler that builds arrays, scalars, dtypes and plain values, and nothing else."""

    def find_class(self, module: str, name: str):
        found = _allowed(module, name)
        if found is None:
            raise NotData(f"it names {module}.{name}, which is not array data (a pickle that names a class or "
                          "function can run code, so it is not opened)")
        return found

    def persistent_load(self, pid):
        raise NotData("it refers to objects outside the file")


def _header(handle) -> tuple[tuple, bool, np.dtype]:
    from numpy.lib import format as npy
    try:
        version = npy.read_magic(handle)
    except ValueError:
        raise NotData("it is not a .npy file (no numpy header); a raw pickle is never opened") from None
    readers = {(1, 0): npy.read_array_header_1_0, (2, 0): npy.read_array_header_2_0}
    if version not in readers:     # 3.0 differs from 2.0 only by utf-8 field names, which no track file has
        raise ValueError(f".npy format version {version[0]}.{version[1]} is not read; save it with numpy's "
                         "defaults (np.save)")
    return readers[version](handle)


def _declared(shape, dtype) -> int:
    return int(np.prod(shape, dtype=object)) * dtype.itemsize


def npy_header(path) -> tuple[tuple, np.dtype, int]:
    """(shape, dtype, declared bytes) of an ``.npy`` file, its data not read; ValueError when the file holds
    fewer bytes than its header declares (a truncated or crafted file)."""
    with open(path, "rb") as handle:
        shape, _, dtype = _header(handle)
        start = handle.tell()
        size = handle.seek(0, io.SEEK_END) - start
    need = _declared(shape, dtype)
    if not dtype.hasobject and need > size:
        raise ValueError(f"its header declares {shape} of {dtype} ({need:,} bytes) but the file holds {size:,} "
                         "bytes after it: a truncated or damaged file")
    return shape, dtype, need


DEFLATE_RATIO = 1100    # zlib cannot expand data more than about 1032 times


def npz_headers(path) -> dict:
    """{key: (shape, dtype, declared bytes)} of every array in an ``.npz`` archive, read from the members'
    headers only: a member whose header declares more data than the member holds, or a member that
    claims to expand more than zlib can, is a ValueError before anything is allocated."""
    import zipfile
    out = {}
    try:
        archive = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError) as err:
        raise ValueError(f"not an .npz archive ({err})") from None
    with archive:
        for info in archive.infolist():
            if not info.filename.endswith(".npy"):
                continue
            key = info.filename[:-4]
            if info.file_size > DEFLATE_RATIO * max(info.compress_size, 1) + 4096:
                raise ValueError(f"{key}: its member claims {info.file_size:,} bytes from {info.compress_size:,} "
                                 "compressed: a damaged or crafted archive")
            with archive.open(info) as member:
                shape, _, dtype = _header(member)
                start = member.tell()
            need = _declared(shape, dtype)
            if not dtype.hasobject and need > info.file_size - start:
                raise ValueError(f"{key}: its header declares {shape} of {dtype} ({need:,} bytes) but the member "
                                 f"holds {info.file_size - start:,}: a truncated or damaged archive")
            out[key] = (tuple(shape), dtype, need)
    return out


def read_npz(path, keys=None) -> dict:
    """The arrays of an ``.npz`` archive (all, or ``keys``), headers checked first (:func:`npz_headers`);
    pickling off: an object array is :class:`NotData`."""
    headers = npz_headers(path)
    keys = list(headers) if keys is None else list(keys)
    objects = [k for k in keys if k in headers and headers[k][1].hasobject]
    if objects:
        raise NotData(f"{objects[0]} is an array of Python objects, which is never unpickled")
    with np.load(path, allow_pickle=False) as archive:
        return {key: archive[key] for key in keys}


def read_npy(path) -> object:
    """What ``path`` (an ``.npy`` file) holds, as data; :class:`NotData` for anything that would run code,
    ``ValueError`` for a damaged or truncated file."""
    path = Path(path)
    with open(path, "rb") as handle:
        shape, fortran, dtype = _header(handle)
        start = handle.tell()
        size = handle.seek(0, io.SEEK_END) - start
        handle.seek(start)
        if not dtype.hasobject:
            need = int(np.prod(shape, dtype=object)) * dtype.itemsize
            if need > size:
                raise ValueError(f"its header declares {shape} of {dtype} ({need:,} bytes) but the file holds "
                                 f"{size:,} bytes after it: a truncated or damaged file")
            handle.seek(0)
            return np.load(handle, allow_pickle=False)
        array = _DataUnpickler(handle).load()
    if not isinstance(array, np.ndarray):
        raise NotData("its object array did not rebuild as an array")
    return array
