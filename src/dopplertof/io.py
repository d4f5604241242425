"""File input and output for images and metadata.

Only file formats live here: no colour mapping (see :mod:`dopplertof.viz`), no rendering.

=============================  ===============================================================
Function                       Meaning
=============================  ===============================================================
``write_exr``                  float32 OpenEXR (ZIP) of a (H, W), (H, W, 3) or (H, W, C) array
``read_exr``                   the pixels of an EXR file as one float32 array
``read_exr_channels``          the pixels of an EXR file as ``{channel name: (H, W) array}``
``write_npy``, ``read_npy``    ``numpy.save`` / ``numpy.load`` that create parent directories
``write_image``                ``write_exr`` or ``write_npy``, chosen by the file suffix
``write_json``, ``read_json``  metadata; numpy scalars and arrays become JSON numbers/lists
``write_record``,              a scene's response record (:mod:`dopplertof.design.record`) as
``read_record``                one ``.npz`` file: its arrays and its metadata
=============================  ===============================================================

All functions take a path as ``str`` or :class:`pathlib.Path`. Readers raise
:class:`FileNotFoundError` naming the path when it does not exist and :class:`ValueError`
naming the path when the file cannot be parsed. Writers create missing parent directories.

Channel order in EXR files: the format stores channels sorted by name, so ``write_exr`` also
records the caller's order in the header attribute ``dopplertof_channel_order`` and the
readers restore it. For EXR files written by other programs the order is R, G, B (, A) for
RGB(A) images and the stored (alphabetical) order otherwise.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import sys
import tempfile
import zipfile
from pathlib import Path
from typing import Any, Sequence, Union

import numpy as np
import OpenEXR

PathLike = Union[str, "os.PathLike[str]"]

#: Header attribute in which ``write_exr`` records the caller's channel order.
EXR_CHANNEL_ORDER_ATTRIBUTE = "dopplertof_channel_order"

_RGB_CHANNELS = ("R", "G", "B")
_RGBA_CHANNELS = ("R", "G", "B", "A")


# ---------------------------------------------------------------------------------------------
# Helpers
# ---------------------------------------------------------------------------------------------

def _prepare_output(path: PathLike) -> Path:
    """Return ``path`` as a :class:`Path` after creating its parent directories."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


@contextlib.contextmanager
def atomic_path(path: PathLike):
    """A temporary path beside ``path`` (same suffix) to write to; renamed over ``path``
    when the block succeeds, removed when it fails, so that ``path`` is never a partial
    file (an interrupted, full or failing write leaves the previous file, or none).

    Parameters
    ----------
    path : str or path
        The file to write.

    Yields
    ------
    Path
        The temporary path to write to.
    """
    path = _prepare_output(path)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.partial{path.suffix}")
    try:
        yield tmp
        with open(tmp, "rb") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.remove(tmp)
        raise


_PARTIAL_NAME = re.compile(r"^\..+\.(\d+)\.partial(\.[^.]*)?$")


def _process_exists(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except (ProcessLookupError, OverflowError):
        return False
    except PermissionError:  # another user's process
        return True
    return True


def remove_stale_partials(folder: PathLike) -> list[Path]:
    """Remove the temporary files of :func:`atomic_path` in ``folder`` whose writer is gone
    (a process killed mid-write, by SIGKILL or the OOM killer, leaves one); the paths removed.
    Those of a running process (its id is in the name) are kept.

    Parameters
    ----------
    folder : str or path

    Returns
    -------
    list of Path
        The files removed.
    """
    removed = []
    for entry in os.scandir(folder):
        match = _PARTIAL_NAME.match(entry.name)
        if match and entry.is_file(follow_symlinks=False) and not _process_exists(int(match.group(1))):
            with contextlib.suppress(FileNotFoundError):
                os.remove(entry.path)
                removed.append(Path(entry.path))
    return removed


def _existing_file(path: PathLike, what: str) -> Path:
    """Return ``path`` as a :class:`Path`, or raise ``FileNotFoundError`` naming it."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{what} file not found: '{path}'")
    return path


def _default_channel_names(num_channels: int) -> list[str]:
    if num_channels == 1:
        return ["Y"]
    if num_channels == 3:
        return list(_RGB_CHANNELS)
    raise ValueError(
        f"an image with {num_channels} channels needs explicit channel names "
        f"(channels=[...] of length {num_channels}); only 1 ('Y') and 3 ('R', 'G', 'B') "
        "have defaults"
    )


# ---------------------------------------------------------------------------------------------
# OpenEXR
# ---------------------------------------------------------------------------------------------

def write_exr(path: PathLike, image: np.ndarray, channels: Sequence[str] | None = None) -> Path:
    """Write an image as a single-part, scanline, ZIP-compressed float32 OpenEXR file.

    Values are stored as 32-bit floats, so float32 input round-trips exactly, including
    negative values, infinities and NaN (signed quantities such as velocities are fine).

    Parameters
    ----------
    path : str or pathlib.Path
        Output file; missing parent directories are created. The suffix is not checked.
    image : array_like, shape (H, W), (H, W, 3) or (H, W, C)
        Real-valued pixels in any unit; cast to float32.
    channels : sequence of str, optional
        One name per channel (length 1 for a (H, W) image, C for (H, W, C)). Default:
        ``["Y"]`` for (H, W) or (H, W, 1), ``["R", "G", "B"]`` for (H, W, 3); other channel
        counts need explicit names. The order is recorded so that :func:`read_exr` returns
        the channels in this order.

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    ValueError
        If the image is not 2-D or 3-D, is empty, is not real-valued, or the channel names
        are missing, of the wrong count, empty or repeated.
    OSError
        If the file cannot be written (no space left, ...); ``path`` is left as it was.
    """
    array = np.asarray(image)
    if array.ndim not in (2, 3):
        raise ValueError(
            f"image must have shape (H, W) or (H, W, C), got shape {array.shape}"
        )
    if array.size == 0:
        raise ValueError(f"image must not be empty, got shape {array.shape}")
    if not (np.issubdtype(array.dtype, np.floating) or np.issubdtype(array.dtype, np.integer)
            or array.dtype == np.bool_):
        raise ValueError(f"image must be real-valued, got dtype {array.dtype}")
    planes = array[:, :, None] if array.ndim == 2 else array
    num_channels = planes.shape[2]

    names = _default_channel_names(num_channels) if channels is None else list(channels)
    if len(names) != num_channels:
        raise ValueError(
            f"got {len(names)} channel names {names} for an image with {num_channels} "
            f"channel(s) (shape {array.shape})"
        )
    for name in names:
        if not isinstance(name, str) or not name:
            raise ValueError(f"channel names must be non-empty strings, got {name!r}")
    if len(set(names)) != len(names):
        raise ValueError(f"channel names must be unique, got {names}")

    # OpenEXR reads the numpy buffer as if it were C-contiguous: a strided view (one channel
    # of an (H, W, C) array) would be written as garbage without this copy.
    pixels = {
        name: np.ascontiguousarray(planes[:, :, i], dtype=np.float32)
        for i, name in enumerate(names)
    }
    header = {
        "compression": OpenEXR.ZIP_COMPRESSION,
        "type": OpenEXR.scanlineimage,
        EXR_CHANNEL_ORDER_ATTRIBUTE: names,
    }
    with atomic_path(path) as tmp, OpenEXR.File(header, pixels) as exr_file:
        try:
            exr_file.write(str(tmp))
        except RuntimeError as exc:  # OpenEXR's word for a failed write (a full disk, say): an OSError like every other
            raise OSError(str(exc).replace(str(tmp), str(path))) from exc
    return Path(path)


def read_exr_channels(path: PathLike) -> dict[str, np.ndarray]:
    """Read every channel of the first part of an OpenEXR file.

    Parameters
    ----------
    path : str or pathlib.Path
        Input EXR file.

    Returns
    -------
    dict of str to numpy.ndarray
        ``{channel name: float32 array of shape (H, W)}``, in the order described in the
        module docstring. Half and uint channels are converted to float32.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file is not a readable OpenEXR image.
    """
    path = _existing_file(path, "EXR")
    library_lines: list[str] = []
    try:
        # Copy out everything needed inside the block: leaving it empties the header dict.
        with _library_output_into(library_lines), OpenEXR.File(str(path), separate_channels=True) as exr_file:
            recorded_order = exr_file.header().get(EXR_CHANNEL_ORDER_ATTRIBUTE)
            stored = {name: channel.pixels for name, channel in exr_file.channels().items()}
    except Exception as error:  # OpenEXR raises RuntimeError or ValueError, message varies
        said = next((line for line in library_lines if "EXR_ERR" in line), library_lines[0] if library_lines else "")
        said = said.removeprefix(f"{path}: ").strip()
        raise ValueError(f"cannot read '{path}' as an OpenEXR image: {error}{f' (OpenEXR: {said})' if said else ''}") from error
    for line in library_lines:  # a readable file's warnings are the user's to see
        print(line, file=sys.stderr)
    if not stored:
        raise ValueError(f"OpenEXR file '{path}' has no channels")

    order = _channel_order(list(stored), recorded_order)
    return {name: np.asarray(stored[name], dtype=np.float32) for name in order}


@contextlib.contextmanager
def _library_output_into(lines: list):
    """Collect into ``lines`` what a library prints, on file descriptors 1 and 2 or through
    Python's ``sys.stdout``/``sys.stderr`` (OpenEXR prints its reasons there before
    raising), so that a failure is reported in one line."""
    import io as text_io

    sys.stdout.flush(), sys.stderr.flush()
    saved = {fd: os.dup(fd) for fd in (1, 2)}
    python_streams = text_io.StringIO()
    with tempfile.TemporaryFile() as sink:
        for fd in saved:
            os.dup2(sink.fileno(), fd)
        try:
            with contextlib.redirect_stdout(python_streams), contextlib.redirect_stderr(python_streams):
                yield
        finally:
            for fd, original in saved.items():
                os.dup2(original, fd)
                os.close(original)
            sink.seek(0)
            text = python_streams.getvalue() + sink.read().decode(errors="replace")
            lines.extend(line for line in text.splitlines() if line.strip())


def _channel_order(stored_names: list[str], recorded: Any) -> list[str]:
    """Channel order for reading: as recorded by ``write_exr``, else RGB(A), else stored."""
    if isinstance(recorded, (list, tuple)) and sorted(recorded) == sorted(stored_names):
        return list(recorded)
    for canonical in (_RGB_CHANNELS, _RGBA_CHANNELS):
        if sorted(stored_names) == sorted(canonical):
            return list(canonical)
    return stored_names


def read_exr(path: PathLike) -> np.ndarray:
    """Read an OpenEXR file into a single float32 array.

    Parameters
    ----------
    path : str or pathlib.Path
        Input EXR file.

    Returns
    -------
    numpy.ndarray of float32
        Shape (H, W) for a single-channel file, (H, W, 3) in R, G, B order for an RGB file,
        otherwise (H, W, C) in the order described in the module docstring (use
        :func:`read_exr_channels` to get the names).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file is not a readable OpenEXR image, or its channels differ in size
        (subsampled channels).
    """
    channels = read_exr_channels(path)
    planes = list(channels.values())
    if len(planes) == 1:
        return planes[0]
    shapes = {plane.shape for plane in planes}
    if len(shapes) != 1:
        raise ValueError(
            f"channels of '{path}' have different shapes {sorted(shapes)}; "
            "use read_exr_channels"
        )
    return np.stack(planes, axis=-1)


# ---------------------------------------------------------------------------------------------
# NumPy
# ---------------------------------------------------------------------------------------------

def write_npy(path: PathLike, array: np.ndarray) -> Path:
    """Save an array with :func:`numpy.save`, creating parent directories.

    Parameters
    ----------
    path : str or pathlib.Path
        Output file, used as given (unlike :func:`numpy.save`, no ``.npy`` is appended).
    array : array_like, any shape and dtype
        Data to save (object arrays are refused when reading, so avoid them).

    Returns
    -------
    pathlib.Path
        The path written.
    """
    with atomic_path(path) as tmp, open(tmp, "wb") as file:  # a file object stops numpy.save appending ".npy"
        np.save(file, np.asarray(array))
    return Path(path)


def read_npy(path: PathLike) -> np.ndarray:
    """Load an array saved by :func:`write_npy` (``allow_pickle=False``).

    Parameters
    ----------
    path : str or pathlib.Path
        Input ``.npy`` file.

    Returns
    -------
    numpy.ndarray
        The stored array, with its shape and dtype.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file is not a readable ``.npy`` file.
    """
    path = _existing_file(path, "NPY")
    _check_magic(path, _NPY_MAGIC, "a .npy array")
    try:
        return np.load(path, allow_pickle=False)
    except Exception as error:
        raise ValueError(f"cannot read '{path}' as a .npy array: {error}") from error


_NPY_MAGIC, _ZIP_MAGIC = b"\x93NUMPY", b"PK\x03\x04"
# What np.load raises for a file that is not a whole .npz (truncated, a flipped byte, another format).
NPZ_READ_ERRORS = (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile)


def _check_magic(path, magic: bytes, what: str) -> None:
    """ValueError where the file at ``path`` does not start as ``what`` does (numpy would
    otherwise say the file "contains pickled (object) data")."""
    with open(path, "rb") as file:
        head = file.read(len(magic))
    if head != magic:
        raise ValueError(f"cannot read '{path}' as {what}: it is not one (it starts with {head!r})")


def write_image(path: PathLike, array: np.ndarray) -> Path:
    """Write an array with the writer chosen by the file suffix.

    Parameters
    ----------
    path : str or pathlib.Path
        Output file ending in ``.exr`` (:func:`write_exr` with default channel names) or
        ``.npy`` (:func:`write_npy`); case-insensitive.
    array : array_like
        For ``.exr``: shape (H, W) or (H, W, 3). For ``.npy``: anything.

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    ValueError
        If the suffix is neither ``.exr`` nor ``.npy``.
    """
    suffix = Path(path).suffix.lower()
    if suffix == ".exr":
        return write_exr(path, array)
    if suffix == ".npy":
        return write_npy(path, array)
    raise ValueError(
        f"unsupported image suffix {suffix!r} in '{path}'; use '.exr' or '.npy' "
        "(PNG pictures: dopplertof.viz)"
    )


# ---------------------------------------------------------------------------------------------
# JSON
# ---------------------------------------------------------------------------------------------

def _to_jsonable(obj: Any) -> Any:
    """Replace numpy scalars/arrays and paths by JSON-native values, recursively."""
    if isinstance(obj, dict):
        return {_to_jsonable(key): _to_jsonable(value) for key, value in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_to_jsonable(item) for item in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    return obj


def sha256_file(path: str) -> str:
    """The SHA-256 of the file at ``path``, as hex digits (read in 1 MiB blocks).

    Parameters
    ----------
    path : str

    Returns
    -------
    str
        64 hex digits.
    """
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def write_json(path: PathLike, obj: Any) -> Path:
    """Write metadata as indented JSON, creating parent directories.

    Numpy scalars become Python numbers/bools, numpy arrays nested lists, tuples lists and
    paths strings (also as dictionary keys). Non-finite floats are written as ``NaN`` /
    ``Infinity`` as Python's :mod:`json` does; :func:`read_json` reads them back.

    Parameters
    ----------
    path : str or pathlib.Path
        Output file.
    obj : object
        JSON-serialisable data after the conversions above.

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    TypeError
        If ``obj`` contains a value JSON cannot represent (e.g. a complex number).
    """
    text = json.dumps(_to_jsonable(obj), indent=2)  # serialise before touching the file
    with atomic_path(path) as tmp:
        tmp.write_text(text + "\n", encoding="utf-8")
    return Path(path)


def read_json(path: PathLike) -> Any:
    """Read a JSON file written by :func:`write_json` (or any JSON file).

    Parameters
    ----------
    path : str or pathlib.Path
        Input file, UTF-8.

    Returns
    -------
    object
        The decoded data (dicts, lists, str, int, float, bool, None).

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file is not valid JSON.
    """
    path = _existing_file(path, "JSON")
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ValueError(f"cannot read '{path}' as JSON: {error}") from error


def write_record(path: PathLike, record) -> Path:
    """Save a response record (``render(..., record=True).record``) as one ``.npz`` file
    (uncompressed: the phasors hardly compress), written atomically.

    Parameters
    ----------
    path : str or pathlib.Path
        Output file, used as given.
    record : :class:`dopplertof.design.Record`

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    TypeError
        If ``record`` is not a Record (a render's result, say, instead of its ``.record``).
    """
    from .design.record import Record

    if not isinstance(record, Record):
        raise TypeError(f"write_record: 'record' must be a dopplertof.design.Record (dopplertof.render(..., record=...).record), got {type(record).__name__}")
    arrays = record.to_arrays()
    with atomic_path(path) as tmp, open(tmp, "wb") as file:  # a file object stops numpy appending ".npz"
        np.savez(file, **arrays)
    return Path(path)


def read_record(path: PathLike):
    """Load a response record saved by :func:`write_record`.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file is not a response record.

    Parameters
    ----------
    path : str or path
        The ``.npz`` file.

    Returns
    -------
    dopplertof.design.Record
    """
    from .design.record import Record

    path = _existing_file(path, "record")
    _check_magic(path, _ZIP_MAGIC, "a response record (a .npz file)")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except Exception as error:
        raise ValueError(f"cannot read '{path}' as a response record: {error}") from error
    return Record.from_arrays(arrays, where=str(path))
