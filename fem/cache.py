"""On-disk cache of what a body computes once: its stiffness and compliance columns.

A CHOLMOD factor cannot be saved, but what the stance pipeline takes from it can:
the compliance columns of the nodes prints use (three sparse solves per node, about
0.1 s per node on the 13k-node cube) and the assembled stiffness (about 0.8 s there).
A second process working on the same body reads them back instead of assembling,
factorising and solving again.

Entries are files under ``<directory>/fem-v<FORMAT_VERSION>/<digest>/<name>.entry``, where
the digest is a SHA-256 of everything the cached numbers depend on: node and tet
arrays, elasticity matrix, fixed nodes, solver, the source of the fem modules that
compute them, library versions and CPU model (a different BLAS kernel rounds
differently, and a cached body must give the same bits as an uncached one). Each file
repeats the full digest and its own name; a file that cannot be read, or whose
record does not match, is ignored (and removed) and the value recomputed.

An entry is a short JSON header (its record, and each array's dtype, shape, place and
CRC-32; the header has a CRC-32 of its own) followed by the arrays' raw bytes, each at a
multiple of 64 bytes: reading one is a single file read into an aligned buffer and its
checksums. (Until 2026-11-26 entries were ``.npz`` archives: reading a node's
compliance columns on a foam mat, 192 kB, took 0.46-0.97 ms CPU in zip and header
parsing, now 0.15-0.32 ms, measured side by side; solving them takes about 4 ms.) Writes go
to a temporary file renamed into place, so a reader never sees half an entry. The
directory is kept under a size bound by removing the least recently used entries.
(``cbm.robot_mesh`` keeps a robot's drawn meshes here too, under a digest of its own.)

Environment variables (read when a body is made):

- ``SOFTCBM_CACHE_DIR``: the cache directory (default ``$XDG_CACHE_HOME/softcbm``,
  else ``~/.cache/softcbm``);
- ``SOFTCBM_CACHE``: ``off`` (or ``0``, ``false``, ``no``) disables the disk cache;
- ``SOFTCBM_CACHE_MAX_MB``: size bound in megabytes (default 8192).
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import os
import platform
import shutil
import struct
import tempfile
import zlib
from pathlib import Path

import numpy as np

from .errors import FemError

__all__ = ["DiskCache", "default_cache", "default_cache_directory", "cache_digest", "FORMAT_VERSION"]

logger = logging.getLogger(__name__)

# Bump when the layout of an entry changes; numerical changes are caught by the
# source fingerprint in the digest.
FORMAT_VERSION = 3
_MAGIC = b"softcbm fem cache entry\n"
_PREFIX = struct.Struct("<QI")  # after the magic: the JSON header's length in bytes and its CRC-32
_ALIGNMENT = 64  # bytes: the header is padded, and each array placed, so that arrays start aligned
_NUMERIC_KINDS = "biufc"  # bool, signed and unsigned integers, floats, complex: what an entry holds

DIRECTORY_VARIABLE = "SOFTCBM_CACHE_DIR"
SWITCH_VARIABLE = "SOFTCBM_CACHE"
SIZE_VARIABLE = "SOFTCBM_CACHE_MAX_MB"
# A planner suite run (11 scenes and their twins, 10 seeds) fills some 2.1 GB: under the
# 2048 MB bound of before it evicted, and each scene after rebuilt its tables inside its solves
# (a session's suite: 245.8 s of CPU against 189.6 with room for all).
DEFAULT_MAX_MEGABYTES = 8192
_OFF_VALUES = ("off", "0", "false", "no")

# Modules whose code decides the cached numbers: assembly (stiffness), ordering and
# solvers (the factor), body (how columns are solved), this one (entry layout),
# strain_average (the ball-mean matrix kept under the mesh's key).
_SOURCES = ("mesh.py", "assembly.py", "ordering.py", "solvers.py", "body.py", "cache.py", "strain_average.py")

# After eviction the cache holds at most this fraction of its bound, so that a run
# adding entries one by one does not rescan the directory at each of them.
_EVICT_TO = 0.8


def default_cache_directory() -> Path:
    """The cache directory: ``$SOFTCBM_CACHE_DIR``, else the user's cache directory."""
    configured = os.environ.get(DIRECTORY_VARIABLE)
    if configured:
        return Path(configured).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "softcbm"


def default_cache() -> DiskCache | None:
    """The cache bodies use by default, from the environment; None when turned off.

    Returns
    -------
    DiskCache or None
        One shared instance per (directory, bound), so that bodies of one process
        share its running size count.
    """
    if os.environ.get(SWITCH_VARIABLE, "").strip().lower() in _OFF_VALUES:
        return None
    text = os.environ.get(SIZE_VARIABLE, "").strip()
    try:
        megabytes = float(text) if text else float(DEFAULT_MAX_MEGABYTES)
    except ValueError:
        megabytes = float("nan")  # reported just below
    if not megabytes > 0.0:
        logger.warning("%s=%r is not a positive number of megabytes; using %d", SIZE_VARIABLE, text, DEFAULT_MAX_MEGABYTES)
        megabytes = float(DEFAULT_MAX_MEGABYTES)
    return _shared_cache(str(default_cache_directory()), int(megabytes * 2**20))


@functools.lru_cache(maxsize=None)
def _shared_cache(directory: str, max_bytes: int) -> DiskCache:
    return DiskCache(directory, max_bytes)


@functools.lru_cache(maxsize=None)
def _environment_fingerprint() -> dict:
    """What, besides a body's arrays, decides the bits of its cached values."""
    import scipy

    sources = hashlib.sha256()
    here = Path(__file__).parent
    for name in _SOURCES:
        sources.update(name.encode())
        sources.update((here / name).read_bytes())
    try:
        from importlib.metadata import version

        cvxopt_version = version("cvxopt")
    except Exception:  # noqa: BLE001 - absent or unreadable: recorded as such
        cvxopt_version = "none"
    cpu = platform.processor()
    try:
        with open("/proc/cpuinfo") as handle:
            cpu = next((line.split(":", 1)[1].strip() for line in handle if line.startswith("model name")), cpu)
    except OSError:
        pass
    return {
        "format": FORMAT_VERSION,
        "sources": sources.hexdigest(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "cvxopt": cvxopt_version,
        "machine": platform.machine(),
        "cpu": cpu,
    }


def cache_digest(arrays: dict, values: dict) -> str:
    """SHA-256 of a body's inputs and of the code and libraries that compute from them.

    Parameters
    ----------
    arrays : dict of str to ndarray
        Input arrays (nodes, tets, ...); dtype, shape and bytes all enter the digest.
    values : dict of str to JSON-serialisable
        Other inputs (e.g. the solver name).

    Returns
    -------
    str
        64 hexadecimal digits.
    """
    digest = hashlib.sha256()
    digest.update(json.dumps({"values": values, "environment": _environment_fingerprint()}, sort_keys=True).encode())
    for name in sorted(arrays):
        array = np.ascontiguousarray(arrays[name])
        digest.update(f"{name}:{array.dtype.str}:{array.shape}".encode())
        digest.update(array.tobytes())
    return digest.hexdigest()


class DiskCache:
    """A directory of entries (numeric arrays), each keyed by a digest and a name.

    Never raises on a bad or missing entry or an unwritable directory: loading then
    returns None and storing does nothing (logged), so a caller recomputes.

    Parameters
    ----------
    directory : str or path-like
        Root directory; entries go under ``fem-v<FORMAT_VERSION>/`` inside it.
    max_bytes : int, optional
        Size bound of that subdirectory; least recently used entries are removed
        beyond it. Default 2 GiB.

    Raises
    ------
    FemError
        If ``max_bytes`` is not a positive integer.

    Examples
    --------
    >>> import shutil, tempfile, numpy as np
    >>> directory = tempfile.mkdtemp()
    >>> cache = DiskCache(directory)
    >>> cache.store("0" * 64, "example", {"x": np.arange(3.0)})
    >>> cache.load("0" * 64, "example")["x"]
    array([0., 1., 2.])
    >>> cache.load("1" * 64, "example") is None      # another body: a miss
    True
    >>> shutil.rmtree(directory)
    """

    def __init__(self, directory, max_bytes: int = DEFAULT_MAX_MEGABYTES * 2**20) -> None:
        if not (isinstance(max_bytes, (int, np.integer)) and max_bytes > 0):
            raise FemError(f"max_bytes must be a positive integer, got {max_bytes!r}")
        self._root = Path(directory).expanduser() / f"fem-v{FORMAT_VERSION}"
        self._max_bytes = int(max_bytes)
        self._size: int | None = None  # running total since the last scan
        self._warned = False
        self._remove_older_formats()

    def _remove_older_formats(self) -> None:
        """Delete the directories of earlier entry formats: no version reads them again,
        and they fall outside this format's size bound (1.7 GB of format 1 were left
        on a development machine when a new format came)."""
        try:
            siblings = list(self._root.parent.iterdir())
        except OSError:
            return
        for path in siblings:
            version = path.name[len("fem-v"):]
            if path.name.startswith("fem-v") and version.isdigit() and int(version) < FORMAT_VERSION and path.is_dir():
                shutil.rmtree(path, ignore_errors=True)

    @property
    def directory(self) -> Path:
        """The directory holding this format's entries."""
        return self._root

    def path(self, digest: str, name: str) -> Path:
        """File of an entry."""
        return self._root / digest / f"{name}.entry"

    def load(self, digest: str, name: str) -> dict[str, np.ndarray] | None:
        """Arrays of an entry, or None if absent, unreadable or not this entry's.

        Parameters
        ----------
        digest : str
            The digest of the entry's inputs (:func:`cache_digest`).
        name : str
            The entry's name within them.

        Returns
        -------
        dict of str to read-only ndarray, or None
        """
        path = self.path(digest, name)
        try:
            arrays = _read_entry(_read_file(path), self._record(digest, name))
        except FileNotFoundError:
            return None
        except _ForeignEntry:
            logger.info("ignoring cache entry %s: written for other inputs", path)
            return None
        except Exception as error:  # noqa: BLE001 - any failure to read means: recompute
            logger.warning("ignoring unreadable cache entry %s (%s: %s)", path, type(error).__name__, error)
            self._remove(path)
            return None
        try:
            os.utime(path)  # its age is what eviction goes by: mark it used
        except OSError:
            pass
        for array in arrays.values():
            array.setflags(write=False)
        return arrays

    def store(self, digest: str, name: str, arrays: dict[str, np.ndarray]) -> None:
        """Write an entry atomically (temporary file, then rename); errors are logged.

        Parameters
        ----------
        digest : str
        name : str
        arrays : dict of str to ndarray
            Saved exactly (dtype, shape, bytes); no object arrays.
        """
        path = self.path(digest, name)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            handle, temporary = tempfile.mkstemp(prefix=".tmp-", suffix=".entry", dir=path.parent)
            try:
                with os.fdopen(handle, "wb") as stream:
                    stream.write(_entry_bytes(self._record(digest, name), arrays))
                size = os.path.getsize(temporary)
                os.replace(temporary, path)
            except BaseException:
                self._remove(Path(temporary))
                raise
        except OSError as error:
            if not self._warned:
                logger.warning("cannot write to the fem cache %s (%s); continuing without it", self._root, error)
                self._warned = True
            return
        self._account(size)

    @staticmethod
    def _record(digest: str, name: str) -> dict:
        return {"format": FORMAT_VERSION, "digest": digest, "name": name}

    @staticmethod
    def _remove(path: Path) -> None:
        try:
            path.unlink()
        except OSError:
            pass

    def _entries(self) -> list[tuple[float, int, Path]]:
        """(last use, size, path) of every file under the root, temporary ones included."""
        entries = []
        try:
            bodies = list(os.scandir(self._root))
        except OSError:
            return entries
        for body in bodies:
            try:
                files = list(os.scandir(body.path)) if body.is_dir() else []
            except OSError:
                continue
            for entry in files:
                try:
                    status = entry.stat()
                except OSError:  # removed meanwhile by another process
                    continue
                entries.append((status.st_mtime, status.st_size, Path(entry.path)))
        return entries

    def size(self) -> int:
        """Bytes held in the cache directory now."""
        return sum(size for _, size, _ in self._entries())

    def _account(self, added: int) -> None:
        if self._size is None:
            self._size = self.size()
        else:
            self._size += added
        if self._size <= self._max_bytes:
            return
        entries = sorted(self._entries())
        total = sum(size for _, size, _ in entries)
        removed = 0
        for _, size, path in entries:  # oldest first
            if total <= _EVICT_TO * self._max_bytes:
                break
            self._remove(path)
            total -= size
            removed += 1
        if removed:
            # Said once an eviction: a sweep over materials fills the bound, and the scenes
            # whose entries went rebuild them inside their solves (an audit's suite after two
            # fuzzes: solves of 5.5 s where 0.6 s had been), which nothing else would explain.
            logger.warning("fem cache %s reached its bound of %d MB: removed its %d oldest entries; scenes "
                           "that used them rebuild them (raise %s to keep more)", self._root.parent,
                           self._max_bytes // 2**20, removed, SIZE_VARIABLE)
        self._size = total

    def __repr__(self) -> str:
        return f"DiskCache({str(self._root.parent)!r}, max_bytes={self._max_bytes})"


class _ForeignEntry(Exception):
    """A well-formed entry whose record names other inputs."""


def _entry_bytes(record: dict, arrays: dict) -> bytes:
    """An entry: the magic, the JSON header's length and CRC-32, the header, then each
    array's bytes.

    The header holds the record and, per array, its dtype, shape, offset (from the
    start of the data) and CRC-32, so that a reader checks every byte it uses. The
    header is padded with spaces and each array placed at a multiple of
    ``_ALIGNMENT`` bytes, so that arrays read into an aligned buffer are aligned
    (BLAS may round an unaligned operand differently).

    Raises
    ------
    TypeError
        An array that is not plain numbers (objects, records, strings).
    """
    blobs, described, offset = [], [], 0
    for key, value in arrays.items():
        array = np.asarray(value)
        if array.dtype.kind not in _NUMERIC_KINDS or array.dtype.fields is not None:
            raise TypeError(f"cache entry array {key!r} has dtype {array.dtype}; only plain numeric arrays are stored")
        data = array.tobytes(order="C")
        described.append({"name": key, "dtype": array.dtype.str, "shape": list(array.shape),
                          "offset": offset, "bytes": len(data), "crc32": zlib.crc32(data)})
        padding = -len(data) % _ALIGNMENT
        blobs.append(data + b"\0" * padding)
        offset += len(data) + padding
    header = json.dumps({"record": record, "arrays": described}).encode()
    header += b" " * (-(len(_MAGIC) + _PREFIX.size + len(header)) % _ALIGNMENT)
    return b"".join([_MAGIC, _PREFIX.pack(len(header), zlib.crc32(header)), header, *blobs])


def _read_file(path: Path) -> np.ndarray:
    """A file's bytes in an aligned buffer, (n,) uint8."""
    with open(path, "rb") as stream:
        size = os.fstat(stream.fileno()).st_size
        buffer = np.empty(size, dtype=np.uint8)
        if stream.readinto(buffer) != size:
            raise ValueError("the file changed while it was read")
    return buffer


def _read_entry(content: np.ndarray, record: dict) -> dict:
    """The arrays of an entry (its bytes, (n,) uint8), views into it, after checking its
    header's and arrays' CRC-32 and its record.

    Raises
    ------
    _ForeignEntry
        A readable entry written for another record.
    ValueError, KeyError, TypeError
        Anything else wrong: not an entry, truncated, a checksum that does not match,
        a header that does not describe the data.
    """
    start = len(_MAGIC) + _PREFIX.size
    if content.size < start or content[: len(_MAGIC)].tobytes() != _MAGIC:
        raise ValueError("not a cache entry")
    length, header_crc = _PREFIX.unpack_from(content, len(_MAGIC))
    if length > content.size - start:
        raise ValueError("the header runs past the end of the file")
    header_bytes = content[start : start + length]
    if zlib.crc32(header_bytes) != header_crc:
        raise ValueError("the header fails its CRC-32")
    header = json.loads(header_bytes.tobytes().decode())
    if header["record"] != record:
        raise _ForeignEntry()
    data = content[start + length :]
    arrays = {}
    for item in header["arrays"]:
        dtype = np.dtype(item["dtype"])
        offset, size = int(item["offset"]), int(item["bytes"])
        shape = tuple(int(n) for n in item["shape"])
        if (dtype.kind not in _NUMERIC_KINDS or dtype.fields is not None or min(shape, default=0) < 0
                or offset < 0 or size != dtype.itemsize * int(np.prod(shape)) or offset + size > data.size):
            raise ValueError(f"array {item['name']!r} does not fit the entry")
        chunk = data[offset : offset + size]
        if zlib.crc32(chunk) != item["crc32"]:
            raise ValueError(f"array {item['name']!r} fails its CRC-32")
        arrays[item["name"]] = chunk.view(dtype).reshape(shape)
    return arrays
