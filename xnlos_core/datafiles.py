"""Reading data files (recordings, transient volumes, checkpoints) without trusting their content.

A data file is named by a config or a caller, but what is *inside* it comes from wherever the
file came from, so every reader here holds to four rules, and every refusal is an
:class:`~xnlos_core.errors.InputError` that names the file, what is wrong and what was expected:

* **Regular files only.** :func:`open_regular` opens with ``O_NONBLOCK`` and checks the open
  descriptor with ``fstat`` before a byte is read: a FIFO (which would block the reader forever),
  a device (``/dev/zero`` never ends) or a directory is refused, even one swapped in after a check
  of the path. Every reader below reads through the descriptor it returns.
* **Self-contained HDF5.** HDF5 can make a file read *other* files: external links (a link to an
  object of another file), external storage (a dataset whose bytes live in raw files named in the
  dataset, ``external=``) and virtual datasets (mapped from datasets of other files). h5py follows
  all three, so a recording could name ``/etc/passwd`` or a FIFO as its data and escape the folder
  rule of :mod:`xnlos_core.files`. :func:`hdf5_file` walks every link of a file before any data is
  read and refuses all three anywhere in it; soft links (a path inside the same file) are fine.
  Datasets compressed with filters other than HDF5's built-in ones (deflate, shuffle, fletcher32,
  szip, n-bit, scale-offset) or LZF are refused too: reading them would load a filter plugin.
* **Declared sizes checked before allocation.** An array's header (HDF5 dataspace, ``.npy`` header,
  MATLAB variable header) declares its shape; a shape above ``max_bytes`` (default
  :data:`MAX_ARRAY_BYTES`) or, for uncompressed data, larger than the file itself is refused before
  memory is allocated (a 128 TiB dataset in a 2 kB file, a decompression bomb).
* **Format errors typed.** Whatever the parsing libraries raise on a damaged file (``zlib.error``,
  ``OSError``, ``KeyError``, ``ValueError``, ``struct.error`` …) becomes an InputError
  "<file>: <what> (expected …)".

The path rule itself (inside the config roots, symlinks resolved) is
:func:`xnlos_core.files.resolve_config_path`'s; these readers are what is applied to the file it
returns. h5py and scipy are imported by the functions that use them (cheap start-up).
"""
from __future__ import annotations

import contextlib
import math
import os
import struct
import tokenize
import zipfile
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from .errors import InputError, XnlosError
from .files import open_regular_fd, os_reason

MAX_ARRAY_BYTES = 4 * 2**30  # one array read into memory from a data file (a recording cube, a volume)
MAX_CHUNK_BYTES = 2**28  # one HDF5 chunk, decompressed whole to read any element of it
MAX_HDF5_LINKS = 10_000  # links walked in one HDF5 file; the files xnlos reads hold < 20

# Exceptions the parsers (h5py, numpy.lib.format, zipfile, scipy.io) raise on damaged or foreign
# bytes; each becomes an InputError naming the file. MemoryError: a declared size that got past the
# checks (e.g. many medium arrays); RecursionError: deeply nested MATLAB structs; SyntaxError,
# TokenError: a damaged .npy header (numpy tokenizes it).
PARSE_ERRORS = (OSError, ValueError, TypeError, KeyError, IndexError, AttributeError, RuntimeError, EOFError,
                OverflowError, NotImplementedError, UnicodeError, zlib.error, struct.error, zipfile.BadZipFile,
                MemoryError, RecursionError, SyntaxError, tokenize.TokenError)

# HDF5 filter ids read without a plugin: deflate, shuffle, fletcher32, szip, n-bit, scale-offset, LZF
# (h5py registers LZF itself).
BUILTIN_FILTERS = {1: "deflate", 2: "shuffle", 3: "fletcher32", 4: "szip", 5: "nbit", 6: "scaleoffset",
                   32000: "lzf"}


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0][:300]}" if text else type(exc).__name__


def _gib(n: int) -> str:
    return f"{n / 2**30:.3g} GiB" if n >= 2**30 else f"{n} bytes"


def open_regular(path: str | Path, *, what: str) -> BinaryIO:
    """``path`` opened for binary reading, after ``fstat`` of the open descriptor showed a regular file.

    ``what`` names the file in errors (e.g. "recording /data/c.h5"). Opened with ``O_NONBLOCK``, so a
    FIFO or a device is refused without blocking even when it replaced a checked path. Raises
    InputError when the file is missing, unreadable or not a regular file. The caller closes it."""
    fd = open_regular_fd(path, what=what, error=InputError)
    try:
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def file_size(f: BinaryIO) -> int:
    """Size [bytes] of the open file ``f`` (fstat)."""
    return os.fstat(f.fileno()).st_size


def read_regular_bytes(path: str | Path, *, what: str, max_bytes: int) -> bytes:
    """All bytes of the regular file ``path`` (:func:`open_regular`); InputError when it is larger
    than ``max_bytes`` [bytes] or grows beyond it while being read."""
    with open_regular(path, what=what) as f:
        size = file_size(f)
        if size > max_bytes:
            raise InputError(f"{what} is {_gib(size)}; expected at most {_gib(max_bytes)}")
        try:
            data = f.read(max_bytes + 1)
        except OSError as exc:
            raise InputError(f"{what}: cannot read: {os_reason(exc)}") from None
    if len(data) > max_bytes:
        raise InputError(f"{what} grew beyond {_gib(max_bytes)} while being read")
    return data


def check_declared_size(what: str, shape: tuple[int, ...], dtype: np.dtype, max_bytes: int,
                        available: int | None = None) -> int:
    """Bytes of an array of ``shape`` and ``dtype`` as its header declares it; InputError when that is
    above ``max_bytes`` or (``available``: bytes the file holds for it uncompressed) more than the file
    has — checked before anything is allocated. ``what`` names the file and the array."""
    n = math.prod(int(s) for s in shape) * int(np.dtype(dtype).itemsize)
    if n > max_bytes:
        raise InputError(f"{what}: declares shape {tuple(shape)} of {np.dtype(dtype)} ({_gib(n)}); expected "
                         f"at most {_gib(max_bytes)} in memory")
    if available is not None and n > available:
        raise InputError(f"{what}: declares shape {tuple(shape)} of {np.dtype(dtype)} ({_gib(n)}) but the file "
                         f"holds {_gib(max(available, 0))} for it (truncated, or a header that does not describe "
                         "the data)")
    return n


# --- HDF5 -------------------------------------------------------------------------------------------

def _check_dataset_storage(dset, name: str, what: str) -> None:
    """InputError when dataset ``name`` reads another file (external storage, virtual) or needs a
    filter plugin."""
    if dset.is_virtual:
        sources = sorted({f"{s.file_name}:{s.dset_name}" for s in dset.virtual_sources()})
        raise InputError(f"{what}: dataset {name!r} is a virtual dataset mapped from {', '.join(sources)[:300]}; "
                         "expected a self-contained HDF5 file (virtual datasets are not followed)")
    ext = dset.external
    if ext:
        files = sorted({str(e[0]) for e in ext})
        raise InputError(f"{what}: dataset {name!r} keeps its data in external file(s) {', '.join(files)[:300]}; "
                         "expected a self-contained HDF5 file (external storage is not followed)")
    plist = dset.id.get_create_plist()
    for i in range(plist.get_nfilters()):
        code = plist.get_filter(i)[0]
        if code not in BUILTIN_FILTERS:
            raise InputError(f"{what}: dataset {name!r} is compressed with HDF5 filter {code}, which needs a "
                             f"plugin; expected one of {', '.join(sorted(BUILTIN_FILTERS.values()))}")


def check_hdf5_self_contained(f, what: str, max_links: int = MAX_HDF5_LINKS) -> None:
    """Walk every link of the open h5py file ``f`` (without following any) and raise InputError on an
    external link, a user-defined link, a dataset with external storage, a virtual dataset or a
    dataset that needs a filter plugin — before any data is read. Soft links stay inside the file and
    are allowed; groups hard-linked into a cycle are visited once. At most ``max_links`` links."""
    import h5py

    seen = {f.id}
    stack = [("", f)]
    count = 0
    while stack:
        prefix, group = stack.pop()
        for name in group:
            count += 1
            if count > max_links:
                raise InputError(f"{what}: more than {max_links} links; expected a recording or volume file "
                                 "of a few datasets")
            full = f"{prefix}/{name}"
            link = group.get(name, getlink=True)
            if isinstance(link, h5py.ExternalLink):
                raise InputError(f"{what}: {full!r} is an external link to {link.path!r} in file "
                                 f"{link.filename!r}; expected a self-contained HDF5 file (links into other "
                                 "files are not followed)")
            if isinstance(link, h5py.SoftLink):
                continue  # a path inside this file: what it names is checked where it is hard-linked
            if not isinstance(link, h5py.HardLink):
                raise InputError(f"{what}: {full!r} is a {type(link).__name__}; expected datasets and groups "
                                 "linked within the file")
            obj = group[name]
            if isinstance(obj, h5py.Group):
                if obj.id not in seen:
                    seen.add(obj.id)
                    stack.append((full, obj))
            elif isinstance(obj, h5py.Dataset):
                _check_dataset_storage(obj, full, what)


@contextlib.contextmanager
def hdf5_file(path: str | Path, *, what: str) -> Iterator[Any]:
    """The HDF5 file ``path`` open for reading (an ``h5py.File``), after :func:`open_regular` and
    :func:`check_hdf5_self_contained`. Errors are InputErrors naming ``what``; h5py reads through
    the checked descriptor (its file-object driver), never through the path again."""
    import h5py

    with open_regular(path, what=what) as raw:
        try:
            h5 = h5py.File(raw, "r")
        except PARSE_ERRORS as exc:
            raise InputError(f"{what}: not a readable HDF5 file ({_first_line(exc)})") from None
        try:
            try:
                check_hdf5_self_contained(h5, what)
            except XnlosError:
                raise
            except PARSE_ERRORS as exc:
                raise InputError(f"{what}: damaged HDF5 structure ({_first_line(exc)})") from None
            yield h5
        finally:
            with contextlib.suppress(Exception):
                h5.close()


def read_hdf5_array(f, key: str, *, what: str, kinds: str = "biufc", max_bytes: int = MAX_ARRAY_BYTES,
                    expected: str = "a numeric array") -> np.ndarray:
    """Dataset ``key`` of the open (checked) HDF5 file ``f`` as an array.

    Refused with InputError naming ``what`` and ``key`` (``expected`` says what should be there): a
    missing key or a group; a dtype whose kind is not in ``kinds`` (numpy kind letters); a declared
    size above ``max_bytes``, or, uncompressed and contiguous, above the file's size; a chunk above
    :data:`MAX_CHUNK_BYTES`; a read that fails (a corrupt compressed chunk, a truncated file)."""
    import h5py

    try:
        if key not in f:
            raise InputError(f"{what}: no dataset {key!r}; expected {expected} there (the file holds "
                             f"{sorted(f.keys())[:20]})")
        dset = f[key]
        if not isinstance(dset, h5py.Dataset):
            raise InputError(f"{what}: {key!r} is a {type(dset).__name__}; expected {expected}")
        dtype = dset.dtype
        if dtype.kind not in kinds or dtype.hasobject or dtype.fields is not None:
            raise InputError(f"{what}: dataset {key!r} has dtype {dtype}; expected {expected}")
        plist = dset.id.get_create_plist()
        raw = plist.get_nfilters() == 0 and plist.get_layout() != h5py.h5d.CHUNKED  # stored as declared
        nbytes = check_declared_size(f"{what}: dataset {key!r}", dset.shape or (), dtype, max_bytes,
                                     f.id.get_filesize() if raw else None)
        if raw and plist.get_layout() == h5py.h5d.CONTIGUOUS and nbytes:
            stored = dset.id.get_storage_size()
            if stored < nbytes:
                raise InputError(f"{what}: dataset {key!r} declares shape {dset.shape} of {dtype} "
                                 f"({_gib(nbytes)}) but stores {_gib(stored)} (unwritten or truncated); expected "
                                 "the data in the file")
        if dset.chunks is not None:
            check_declared_size(f"{what}: dataset {key!r} chunk", dset.chunks, dtype, MAX_CHUNK_BYTES)
        return np.asarray(dset[()])
    except XnlosError:
        raise
    except PARSE_ERRORS as exc:
        raise InputError(f"{what}: dataset {key!r} cannot be read ({_first_line(exc)}); expected {expected}") from None


# --- numpy ------------------------------------------------------------------------------------------

def _npy_header(f: BinaryIO, what: str) -> tuple[tuple[int, ...], bool, np.dtype]:
    """(shape, fortran_order, dtype) from the ``.npy`` header at ``f``'s position; InputError when it
    is not one or declares an object dtype (pickles are never read)."""
    from numpy.lib import format as npf

    try:
        version = npf.read_magic(f)
        if version == (1, 0):
            shape, fortran, dtype = npf.read_array_header_1_0(f)
        elif version == (2, 0):
            shape, fortran, dtype = npf.read_array_header_2_0(f)
        else:
            shape, fortran, dtype = npf._read_array_header(f, version)  # 3.0: UTF-8 field names
    except PARSE_ERRORS as exc:
        raise InputError(f"{what}: not a .npy array ({_first_line(exc)}); expected a file written by numpy.save") from None
    if dtype.hasobject:
        raise InputError(f"{what}: holds Python objects (dtype {dtype}); expected a numeric array (pickles are not read)")
    return tuple(int(s) for s in shape), bool(fortran), dtype


def load_npy(path: str | Path, *, what: str, mmap: bool = True, max_bytes: int = MAX_ARRAY_BYTES) -> np.ndarray:
    """The array of the ``.npy`` file ``path``: memory-mapped read-only (``mmap``; then any size the
    file really holds is allowed) or read into memory (at most ``max_bytes``). The header's shape is
    checked against the file's size before mapping or allocating. InputError naming ``what``."""
    with open_regular(path, what=what) as f:
        shape, fortran, dtype = _npy_header(f, what)
        offset = f.tell()
        available = file_size(f) - offset
        # memory-mapped: only what the file holds is needed (pages are read on use), so no memory cap
        nbytes = check_declared_size(what, shape, dtype, 2**62 if mmap else max_bytes, available)
        order = "F" if fortran else "C"
        try:
            if nbytes == 0:
                return np.zeros(shape, dtype=dtype, order=order)
            if mmap:
                return np.memmap(f, dtype=dtype, mode="r", offset=offset, shape=shape, order=order)
            data = f.read(nbytes)
            if len(data) != nbytes:
                raise InputError(f"{what}: {len(data)} of {nbytes} data bytes (the file shrank while read)")
            return np.frombuffer(data, dtype=dtype).reshape(shape, order=order)
        except XnlosError:
            raise
        except PARSE_ERRORS as exc:
            raise InputError(f"{what}: cannot read the array ({_first_line(exc)})") from None


class NpzArchive:
    """The arrays of an open ``.npz`` archive (from :func:`npz_archive`), read one by one: each
    array's ``.npy`` header is read first and its declared size checked against ``max_bytes`` and
    the zip member's size before anything is allocated or decompressed. Mirrors the part of
    ``numpy.lib.npyio.NpzFile`` that readers use: ``files``, ``in``, ``[key]``."""

    def __init__(self, z: zipfile.ZipFile, what: str, max_bytes: int):
        self.zip, self.what, self.max_bytes = z, what, max_bytes
        self._members = {(n[:-4] if n.endswith(".npy") else n): n for n in z.namelist()}
        self.files = list(self._members)

    def __contains__(self, key: str) -> bool:
        return key in self._members

    def __getitem__(self, key: str) -> np.ndarray:
        what = f"{self.what}: array {key!r}"
        if key not in self._members:
            raise InputError(f"{self.what}: no array {key!r}; it holds {sorted(self.files)[:20]}")
        try:
            info = self.zip.getinfo(self._members[key])
            with self.zip.open(info) as m:
                shape, fortran, dtype = _npy_header(m, what)
                nbytes = check_declared_size(what, shape, dtype, self.max_bytes, info.file_size - m.tell())
                data = m.read(nbytes)
            if len(data) != nbytes:
                raise InputError(f"{what}: holds {len(data)} of its {nbytes} bytes (truncated)")
            return np.frombuffer(data, dtype=dtype).reshape(shape, order="F" if fortran else "C").copy()
        except XnlosError:
            raise
        except PARSE_ERRORS as exc:
            raise InputError(f"{what}: damaged ({_first_line(exc)}); expected an array written by numpy.savez") from None


@contextlib.contextmanager
def npz_archive(path: str | Path, *, what: str, max_bytes: int = MAX_ARRAY_BYTES) -> Iterator[NpzArchive]:
    """The ``.npz`` file ``path`` open as an :class:`NpzArchive` (through :func:`open_regular`), each
    array at most ``max_bytes``. InputError naming ``what`` when it is not a readable zip archive."""
    with open_regular(path, what=what) as f:
        try:
            z = zipfile.ZipFile(f)
        except PARSE_ERRORS as exc:
            raise InputError(f"{what}: not a readable .npz archive ({_first_line(exc)}); expected a file written "
                             "by numpy.savez") from None
        with z:
            yield NpzArchive(z, what, max_bytes)


def load_npz_array(path: str | Path, key: str, *, what: str, max_bytes: int = MAX_ARRAY_BYTES) -> np.ndarray:
    """Array ``key`` of the ``.npz`` file ``path`` (:class:`NpzArchive`: header and declared size
    checked before decompression). InputError naming ``what`` and ``key`` (a missing key lists the
    ones present)."""
    with npz_archive(path, what=what, max_bytes=max_bytes) as z:
        return z[key]


# --- MATLAB -----------------------------------------------------------------------------------------

# MAT v5 codes (MATLAB "MAT-File Format", 2019): array classes whose data is numbers, and the numeric
# data types (miINT8 … miUINT64) with their item sizes [bytes].
_MX_NUMERIC = range(6, 16)  # mxDOUBLE … mxUINT64
_MX_NAMES = {1: "a cell array", 2: "a struct", 3: "an object", 4: "a char array", 5: "a sparse matrix",
             16: "a function handle", 17: "an opaque object"}
_MI_NUMERIC = {1: 1, 2: 1, 3: 2, 4: 2, 5: 4, 6: 4, 7: 4, 9: 8, 12: 8, 13: 8}
_MI_MATRIX, _MI_COMPRESSED = 14, 15


class _Mat5Stream:
    """Sequential reads of one MAT v5 top-level element's content: the file itself, or the zlib
    stream of an miCOMPRESSED element inflated piece by piece (never more than a block in memory)."""

    def __init__(self, f: BinaryIO, nbytes: int, compressed: bool, where: str):
        self.f, self.left, self.where = f, nbytes, where
        self.z = zlib.decompressobj() if compressed else None
        self.buf = b""

    def read(self, n: int) -> bytes:
        if self.z is None:
            if n > self.left:
                raise InputError(f"{self.where}: an element runs past its variable (damaged file)")
            data = self.f.read(n)
            self.left -= len(data)
        else:
            while len(self.buf) < n:
                if self.z.unconsumed_tail:
                    src = self.z.unconsumed_tail
                elif self.left > 0:
                    src = self.f.read(min(self.left, 1 << 16))
                    self.left -= len(src)
                    if not src:
                        break
                else:
                    break
                self.buf += self.z.decompress(src, max(n - len(self.buf), 1 << 16))
            data, self.buf = self.buf[:n], self.buf[n:]
        if len(data) != n:
            raise InputError(f"{self.where}: truncated (damaged file)")
        return data

    def skip(self, n: int) -> None:
        while n > 0:
            k = min(n, 1 << 20)
            self.read(k)
            n -= k


def _mat5_tag(stream: _Mat5Stream, order: str) -> tuple[int, bytes]:
    """(data type, payload) of the next sub-element; small elements (type and size in 4 bytes) too."""
    mdtype, nbytes = struct.unpack(order + "II", stream.read(8))
    if mdtype >> 16:  # small data element: size in the upper half, ≤ 4 bytes of data in the second word
        size = mdtype >> 16
        if size > 4:
            raise InputError(f"{stream.where}: small data element of {size} bytes (damaged file)")
        return mdtype & 0xFFFF, struct.pack(order + "I", nbytes)[:size]
    if nbytes > 2**16:
        raise InputError(f"{stream.where}: array header element of {nbytes} bytes (damaged file)")
    data = stream.read(nbytes)
    stream.read(-nbytes % 8)  # padding to 8 bytes
    return mdtype, data


def _check_mat5(f: BinaryIO, names: tuple[str, ...], what: str) -> None:
    """Walk a MAT v5 file's variables and, for those named in ``names``, check before scipy reads them
    that each is a numeric array whose data elements have numeric MATLAB data types and the byte
    counts its dimensions need. scipy's reader indexes a table with the data type it reads from the
    file without a range check, so a damaged type code crashes the interpreter (segmentation fault)
    instead of raising; this is what prevents it. InputError naming ``what`` and the variable."""
    f.seek(0)
    head = f.read(128)
    if len(head) < 128 or head[126:128] not in (b"IM", b"MI"):
        return  # not v5 (v4 is read by scipy's pure-Python reader): scipy says what it is
    order = "<" if head[126:128] == b"IM" else ">"
    size = file_size(f)
    pos = 128
    while pos + 8 <= size:
        f.seek(pos)
        mdtype, nbytes = struct.unpack(order + "II", f.read(8))
        nxt = pos + 8 + nbytes
        if mdtype not in (_MI_MATRIX, _MI_COMPRESSED):
            return  # scipy refuses what is not a variable
        where = f"{what}: variable at byte {pos}"
        # an element longer than the file is still read by scipy as far as the file goes: so is it here
        stream = _Mat5Stream(f, min(nbytes, size - pos - 8), mdtype == _MI_COMPRESSED, where)
        if mdtype == _MI_COMPRESSED:
            inner, inner_bytes = struct.unpack(order + "II", stream.read(8))
            if inner != _MI_MATRIX:
                raise InputError(f"{where}: compressed element holds MATLAB data type {inner}, expected an array "
                                 "(miMATRIX): damaged file")
        t, flags = _mat5_tag(stream, order)
        t2, dims_raw = _mat5_tag(stream, order)
        t3, name_raw = _mat5_tag(stream, order)
        if t != 6 or len(flags) < 4 or t2 not in (5, 6) or len(dims_raw) % 4 or t3 not in (1, 16):
            raise InputError(f"{where}: damaged array header (flags, dimensions, name)")
        name = name_raw.decode("latin1")
        if name in names:
            word = struct.unpack(order + "I", flags[:4])[0]
            mclass, complex_ = word & 0xFF, bool(word & 0x800)
            if mclass not in _MX_NUMERIC:
                raise InputError(f"{what}: variable {name!r} is {_MX_NAMES.get(mclass, f'of MATLAB class {mclass}')}; "
                                 "expected a numeric array")
            dims = struct.unpack(f"{order}{len(dims_raw) // 4}i", dims_raw)
            if any(d < 0 for d in dims):
                raise InputError(f"{what}: variable {name!r} has negative dimensions {dims} (damaged file)")
            count = math.prod(dims)
            for part in ("real", "imaginary")[:1 + complex_]:
                dtype, dbytes = struct.unpack(order + "II", stream.read(8))
                small = dtype >> 16
                if small:
                    dtype, dbytes = dtype & 0xFFFF, small
                if dtype not in _MI_NUMERIC:
                    raise InputError(f"{what}: variable {name!r}: its {part} part has MATLAB data type {dtype}; "
                                     "expected a numeric type (damaged file)")
                if dbytes != count * _MI_NUMERIC[dtype]:
                    raise InputError(f"{what}: variable {name!r}: its {part} part holds {dbytes} bytes, its "
                                     f"dimensions {dims} need {count * _MI_NUMERIC[dtype]} (damaged file)")
                if not small and part == "real" and complex_:
                    stream.skip(dbytes + (-dbytes % 8))
        pos = nxt


def load_mat(path: str | Path, names: tuple[str, ...], *, what: str,
             max_bytes: int = MAX_ARRAY_BYTES) -> dict[str, Any]:
    """The variables of ``names`` present in the MATLAB ``.mat`` file ``path`` (v4 to v7.2; scipy.io),
    each a numeric array: their headers (``whosmat``) must declare at most ``max_bytes`` (counted as
    complex128) and, in a v5 file, their data elements numeric types and consistent sizes (checked
    by :func:`_check_mat5` before scipy reads them: scipy's reader crashes on some damaged type
    codes). Other variables are skipped unread. InputError naming ``what`` for anything else (a v7.3
    file, which is HDF5; a damaged header or compressed element; a struct, cell or string)."""
    import scipy.io

    with open_regular(path, what=what) as f:
        try:
            info = scipy.io.whosmat(f)
            want = []
            for name, shape, cls in info:
                if name in names and name not in want:
                    n = math.prod(int(s) for s in shape) * 16
                    if n > max_bytes:
                        raise InputError(f"{what}: variable {name!r} declares shape {tuple(shape)} ({_gib(n)} as "
                                         f"complex128); expected at most {_gib(max_bytes)}")
                    want.append(name)
            if not want:
                return {}
            _check_mat5(f, tuple(want), what)
            f.seek(0)
            m = scipy.io.loadmat(f, variable_names=want)
        except XnlosError:
            raise
        except Exception as exc:  # noqa: BLE001 — scipy's MATLAB reader raises whatever its Cython code
            # meets in damaged bytes (MatReadError, zlib.error, even UnboundLocalError), not one family
            raise InputError(f"{what}: not a readable MATLAB .mat file, v7.2 or older ({_first_line(exc)})") from None
    return {k: v for k, v in m.items() if k in want}
