"""Shards on disk: deterministic WebDataset tars, written atomically, and the manifest.

Layout of a dataset folder ``DIR``::

    DIR/dataset.json              manifest: schema, config, versions, counts, sha256 per shard
    DIR/shard-000000.tar          samples 0 … K−1 (K = shard size), WebDataset convention:
                                  <key>.<field>.npy per field, then <key>.json, per sample
    DIR/.manifest/shard-000000.json   the shard's record (sha256, bytes, samples), written
                                  after the tar; dataset.json is rebuilt from these records

A tar is byte-identical whoever writes it: members in a fixed order, USTAR headers with
mtime 0, uid/gid 0, empty user and group names, mode 0644; ``.npy`` members by
``numpy.save``; the JSON record with sorted keys. It is written to a temporary name in DIR,
fsynced and renamed (``os.replace``), so a shard file is either absent or complete; a shard
counts as done only when its record's sha256 matches the file.

``dataset.json`` is rebuilt from the shard records under an exclusive ``flock`` on
``DIR/.manifest/lock``, so concurrent runs over disjoint shard ranges (Slurm arrays) keep it
consistent; it carries no timestamps, so a dataset's files are byte-identical however it was
generated (resumed, any number of workers, any executor).
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import tarfile

import numpy as np

from ..io import sha256_file

MANIFEST = "dataset.json"
RECORDS = ".manifest"
SHARD_PATTERN = "shard-{:06d}.tar"


def shard_name(index: int) -> str:
    """The file name of shard ``index``: ``shard-000003.tar``.

    Parameters
    ----------
    index : int
        The shard, from 0.

    Returns
    -------
    str
    """
    return SHARD_PATTERN.format(index)


def sample_key(index: int) -> str:
    """The WebDataset key of sample ``index``: ``sample-00000042``.

    Parameters
    ----------
    index : int
        The sample, from 0.

    Returns
    -------
    str
    """
    return f"sample-{index:08d}"


def plan(samples: int, shard_size: int) -> list[tuple[int, int, int]]:
    """Shards ``(shard index, first sample, number of samples)`` covering ``samples``.

    Parameters
    ----------
    samples : int
        Samples of the dataset.
    shard_size : int
        Samples per shard (the last shard may hold fewer).

    Returns
    -------
    list of tuple of (int, int, int)
    """
    return [(k, first, min(shard_size, samples - first)) for k, first in enumerate(range(0, samples, shard_size))]


def dumps_json(obj) -> bytes:
    """Canonical JSON (sorted keys, exact float repr, UTF-8, trailing newline).

    Parameters
    ----------
    obj : JSON-able object

    Returns
    -------
    bytes
    """
    return (json.dumps(obj, sort_keys=True, indent=1, ensure_ascii=False, allow_nan=True) + "\n").encode("utf-8")


def npy_bytes(array: np.ndarray) -> bytes:
    """The ``.npy`` file of ``array`` (C order, no pickles), as bytes: a shard member.

    Parameters
    ----------
    array : ndarray
        Not of object dtype.

    Returns
    -------
    bytes
    """
    buf = io.BytesIO()
    np.save(buf, np.ascontiguousarray(array), allow_pickle=False)
    return buf.getvalue()


def _member(name: str, size: int) -> tarfile.TarInfo:
    info = tarfile.TarInfo(name)
    info.size = size
    info.mtime = 0
    info.mode = 0o644
    info.uid = info.gid = 0
    info.uname = info.gname = ""
    info.type = tarfile.REGTYPE
    return info


def fsync_dir(path: str) -> None:
    """Flush the folder ``path`` to disk, so that a rename into it survives a crash; a file
    system that cannot fsync a folder is left as it is.

    Parameters
    ----------
    path : str
        A folder.
    """
    with contextlib.suppress(OSError):  # not every file system lets a folder be fsynced
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def atomic_write(path: str, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (:func:`dopplertof.io.atomic_path`: temporary
    file, fsync, rename), then fsync the folder so the rename survives a crash.

    Parameters
    ----------
    path : str
        The file written.
    data : bytes

    Raises
    ------
    OSError
        The write failed; ``path`` is then left as it was.
    """
    from ..io import atomic_path

    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    fsync_dir(os.path.dirname(os.path.abspath(path)))


def shard_bytes(samples) -> bytes:
    """The tar of ``samples``: an iterable of ``(key, {field: array}, record)`` in order.

    Parameters
    ----------
    samples : iterable of tuple
        ``(key, {field: array}, record)``.

    Returns
    -------
    bytes
    """
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w", format=tarfile.USTAR_FORMAT) as tar:
        for key, fields, record in samples:
            for name, array in fields.items():
                data = npy_bytes(array)
                tar.addfile(_member(f"{key}.{name}.npy", len(data)), io.BytesIO(data))
            data = dumps_json(record)
            tar.addfile(_member(f"{key}.json", len(data)), io.BytesIO(data))
    return buf.getvalue()


def write_shard(folder: str, index: int, first: int, samples) -> dict:
    """Write shard ``index`` atomically, then its record; returns the record.

    Parameters
    ----------
    folder : str
        The dataset folder.
    index : int
        The shard, from 0.
    first : int
        Its first sample.
    samples : iterable of tuple
        As for :func:`shard_bytes`.

    Returns
    -------
    dict
        The shard's record (name, index, first sample, count, size in bytes, checksum).
    """
    samples = list(samples)
    data = shard_bytes(samples)
    name = shard_name(index)
    atomic_write(os.path.join(folder, name), data)
    record = {"name": name, "index": index, "first": first, "count": len(samples), "bytes": len(data),
              "sha256": hashlib.sha256(data).hexdigest()}
    os.makedirs(os.path.join(folder, RECORDS), exist_ok=True)
    atomic_write(os.path.join(folder, RECORDS, name.replace(".tar", ".json")), dumps_json(record))
    return record


def read_record(folder: str, index: int) -> dict | None:
    """The manifest record of shard ``index`` (``folder/.manifest/shard-NNNNNN.json``), or None
    if it is missing or unreadable (the shard is then not complete).

    Parameters
    ----------
    folder : str
        The dataset folder.
    index : int
        The shard, from 0.

    Returns
    -------
    dict or None
    """
    path = os.path.join(folder, RECORDS, shard_name(index).replace(".tar", ".json"))
    try:
        with open(path, "rb") as f:
            return json.loads(f.read())
    except (OSError, ValueError):
        return None


def shard_status(folder: str, index: int, expected_count: int | None = None) -> str:
    """``ok``, ``missing`` (no file), ``unrecorded`` (file without record) or ``corrupt``
    (checksum or size differs from the record, or the wrong number of samples).

    Parameters
    ----------
    folder : str
        The dataset folder.
    index : int
        The shard, from 0.
    expected_count : int or None, default None
        Samples it must hold; None: not checked.

    Returns
    -------
    str
    """
    path = os.path.join(folder, shard_name(index))
    if not os.path.exists(path):
        return "missing"
    record = read_record(folder, index)
    if record is None:
        return "unrecorded"
    if os.path.getsize(path) != record.get("bytes") or sha256_file(path) != record.get("sha256"):
        return "corrupt"
    if expected_count is not None and record.get("count") != expected_count:
        return "corrupt"
    return "ok"


@contextlib.contextmanager
def manifest_lock(folder: str):
    """Exclusive lock on ``DIR/.manifest/lock`` (no-op where flock is unavailable).

    Parameters
    ----------
    folder : str
        The dataset folder.

    Yields
    ------
    None
        While the lock is held.
    """
    os.makedirs(os.path.join(folder, RECORDS), exist_ok=True)
    with open(os.path.join(folder, RECORDS, "lock"), "a+b") as f:
        try:
            import fcntl

            fcntl.flock(f.fileno(), fcntl.LOCK_EX)
        except (ImportError, OSError):
            pass
        yield


def read_manifest(folder: str) -> dict | None:
    """The content of ``folder/dataset.json``, or None if there is none.

    Parameters
    ----------
    folder : str
        The dataset folder.

    Returns
    -------
    dict or None

    Raises
    ------
    ValueError
        If the file is not valid JSON (naming the file).
    """
    try:
        with open(os.path.join(folder, MANIFEST), "rb") as f:
            return json.loads(f.read())
    except FileNotFoundError:
        return None
    except ValueError as exc:
        raise ValueError(f"{os.path.join(folder, MANIFEST)} is not valid JSON ({exc}); remove it: the same 'dataset generate' "
                         "command rebuilds it from the shards' records") from None


def rebuild_manifest(folder: str, header: dict, layout: list[tuple[int, int, int]]) -> dict:
    """Write ``dataset.json``: ``header`` (identity, schema, …) plus the recorded shards.

    Must be called under :func:`manifest_lock`. Shards are listed from their records
    (trusted here; :func:`shard_status` checks them against the files).

    Parameters
    ----------
    folder : str
        The dataset folder.
    header : dict
        The manifest's fixed part (:func:`dopplertof.dataset.generate.header_for`).
    layout : list of tuple of (int, int, int)
        The shards, as :func:`plan` gives them.

    Returns
    -------
    dict
        The manifest written.
    """
    shards = []
    for index, first, count in layout:
        record = read_record(folder, index)
        ok = record is not None and record.get("count") == count and record.get("first") == first
        shards.append({"name": shard_name(index), "first": first, "count": count, "sha256": record["sha256"] if ok else None,
                       "bytes": record["bytes"] if ok else None})
    done = [s for s in shards if s["sha256"]]
    manifest = {**header, "shards": shards, "shards_done": len(done), "samples_done": sum(s["count"] for s in done),
                "complete": len(done) == len(shards)}
    atomic_write(os.path.join(folder, MANIFEST), dumps_json(manifest))
    return manifest


def remove_stale_temporaries(folder: str, indices) -> None:
    """Remove temporary files of the shards ``indices`` left by a killed writer.

    Parameters
    ----------
    folder : str
        The dataset folder.
    indices : iterable of int
        Shards.
    """
    wanted = {shard_name(i) for i in indices}
    with contextlib.suppress(FileNotFoundError):
        for name in os.listdir(folder):
            if name.startswith(".") and name.endswith(".tmp") and name[1:].split(".tar.", 1)[0] + ".tar" in wanted:
                with contextlib.suppress(OSError):
                    os.unlink(os.path.join(folder, name))


def verify(folder: str) -> dict:
    """Check every shard of the dataset in ``folder`` against its manifest.

    Parameters
    ----------
    folder : str
        The dataset folder.

    Returns
    -------
    dict
        ``{"ok": [names], "bad": {name: status}, "unwritten": [names]}``, status
        ``missing``, ``unrecorded`` or ``corrupt`` (see :func:`shard_status`; a shard the
        manifest never recorded as finished and that has no file is ``unwritten``, not
        bad: a generation under way or stopped), and ``complete`` (every shard ok).

    Raises
    ------
    ValueError
        If ``folder`` holds no ``dataset.json``.
    """
    manifest = read_manifest(folder)
    if manifest is None:
        raise ValueError(f"{folder}: no {MANIFEST}; not a dopplertof dataset folder")
    ok, bad, unwritten = [], {}, []
    for shard in manifest["shards"]:
        index = int(shard["name"][len("shard-"):-len(".tar")])
        status = shard_status(folder, index, shard["count"])
        if status == "ok" and shard["sha256"] not in (None, read_record(folder, index)["sha256"]):
            status = "corrupt"
        if status == "ok":
            ok.append(shard["name"])
        elif status == "missing" and shard["sha256"] is None:  # never finished (a generation under way or stopped)
            unwritten.append(shard["name"])
        else:
            bad[shard["name"]] = status
    return {"ok": ok, "bad": bad, "unwritten": unwritten, "complete": not bad and not unwritten}
