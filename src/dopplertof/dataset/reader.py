"""Reading a dataset: :func:`open_dataset` (``dopplertof.dataset.open``) and a PyTorch adapter.

The shards are plain tar files of ``.npy`` and ``.json`` members, so ``tarfile`` and numpy
alone read them (docs/datasets.md), and so does the ``webdataset`` package::

    import webdataset as wds
    ds = wds.WebDataset("DIR/shard-{000000..000003}.tar").decode()   # sample["measurements.npy"], sample["json"]
"""

from __future__ import annotations

import bisect
import io
import itertools
import json
import operator
import os
import tarfile
import warnings

import numpy as np

from ..io import sha256_file
from . import shards


def decode_member(name: str, data: bytes):
    """The value of a tar member: a numpy array (``.npy``) or the JSON record.

    Parameters
    ----------
    name : str
        The member's name (``<key>.<field>.npy`` or ``<key>.json``).
    data : bytes
        Its bytes.

    Returns
    -------
    ndarray or dict

    Raises
    ------
    ValueError
        Neither ``.npy`` nor ``.json``.
    """
    if name.endswith(".npy"):
        return np.load(io.BytesIO(data), allow_pickle=False)
    if name.endswith(".json"):
        return json.loads(data)
    raise ValueError(f"unexpected member {name!r}")


def _samples_of(path: str):
    """Yield ``(key, {field: array, "json": record})`` from one shard, in order."""
    with tarfile.open(path) as tar:
        current, sample = None, {}
        for member in tar:
            key, rest = member.name.split(".", 1)
            if key != current:
                if current is not None:
                    yield current, sample
                current, sample = key, {}
            field = "json" if rest == "json" else rest[: -len(".npy")]
            sample[field] = decode_member(member.name, tar.extractfile(member).read())
        if current is not None:
            yield current, sample


def _damaged(folder: str, shard: dict) -> bool:
    """Whether a finished shard's file is missing or of another size than its manifest
    entry says (a manifest without sizes: only missing)."""
    try:
        size = os.path.getsize(os.path.join(folder, shard["name"]))
    except OSError:
        return True
    return shard.get("bytes") is not None and size != shard["bytes"]


class Dataset:
    """A dataset folder written by :func:`dopplertof.dataset.generate`.

    ``len(ds)`` is the number of samples in finished shards; ``ds[i]`` (``ds[a:b]`` a list)
    and iteration give a
    dict ``{field: numpy array, "json": record, "__key__": key}`` (fields as in
    ``ds.schema``). Indexing opens the sample's shard (the member offsets of each shard
    are read once); iteration streams shard by shard.

    Attributes
    ----------
    folder : str
    manifest : dict
        The content of ``dataset.json``.
    schema : dict
        ``{field: {dtype, shape, unit, meaning}}``.
    fields : list of str
    damaged : list of str
        Finished shards whose files differ in size from their records (truncated,
        missing): left out of ``len`` and indexing, with a warning; later samples' indices
        move down (their keys stay). A change that keeps the size is found by
        ``dopplertof dataset verify`` (checksums), not here.
    """

    def __init__(self, folder):
        self.folder = os.fspath(folder)
        manifest = shards.read_manifest(self.folder)
        if manifest is None:
            raise ValueError(f"{self.folder}: no {shards.MANIFEST}; not a dopplertof dataset folder")
        self.manifest = manifest
        self.schema = manifest["schema"]
        self.fields = list(manifest["fields"])
        finished = [s for s in manifest["shards"] if s["sha256"]]
        # A shard file whose size is not its record's (truncated, replaced) is left out, by
        # name: its tar would fail part way through reading (dataset verify checks the sums).
        self.damaged = [s["name"] for s in finished if _damaged(self.folder, s)]
        if self.damaged:
            warnings.warn(f"{self.folder}: shard(s) {', '.join(self.damaged)} are missing or differ from their records and are left out; "
                          "rerun 'dopplertof dataset generate' with the same command to write them again", stacklevel=3)
        self._shards = [s for s in finished if s["name"] not in self.damaged]
        self._ends = list(itertools.accumulate(s["count"] for s in self._shards))  # cumulative sample counts
        self._index: dict = {}
        self._verified: set = set()  # shards whose SHA-256 was checked (_checked)
        self._len = self._ends[-1] if self._ends else 0

    def __len__(self) -> int:
        return self._len

    @property
    def complete(self) -> bool:
        """True when every shard of the dataset is written (``dataset.json`` says so); an
        interrupted generation is incomplete until it is rerun."""
        return bool(self.manifest.get("complete"))

    def _locate(self, i: int) -> tuple[dict, int]:
        """(shard, sample index) of the i-th available sample."""
        if not -self._len <= i < self._len:
            raise IndexError(f"sample {i} out of range for a dataset of {self._len} finished samples")
        i %= self._len
        k = bisect.bisect_right(self._ends, i)
        shard = self._shards[k]
        return shard, shard["first"] + i - (self._ends[k] - shard["count"])

    def _checked(self, shard: dict) -> str:
        """The path of ``shard``'s file, its SHA-256 checked against its record the first time
        this dataset reads it (random bytes in a shard of the right size were read as data)."""
        path = os.path.join(self.folder, shard["name"])
        if shard["name"] not in self._verified:
            if sha256_file(path) != shard["sha256"]:
                raise ValueError(f"{path}: its contents differ from its record (SHA-256): damaged since it was written; "
                                 "'dopplertof dataset verify' lists such shards, and the same 'dataset generate' command writes them again")
            self._verified.add(shard["name"])
        return path

    def _members(self, shard: dict) -> dict:
        name = shard["name"]
        if name not in self._index:
            with tarfile.open(self._checked(shard)) as tar:
                self._index[name] = {m.name: (m.offset_data, m.size) for m in tar.getmembers()}
        return self._index[name]

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(self._len))]
        if isinstance(i, (bool, np.bool_)) or not hasattr(i, "__index__"):
            raise TypeError(f"dataset indices must be integers or slices, not {type(i).__name__}")
        shard, index = self._locate(operator.index(i))
        key = shards.sample_key(index)
        members = self._members(shard)
        out = {"__key__": key}
        with open(os.path.join(self.folder, shard["name"]), "rb") as f:
            for field in [*self.fields, "json"]:
                name = f"{key}.json" if field == "json" else f"{key}.{field}.npy"
                offset, size = members[name]
                f.seek(offset)
                out[field] = decode_member(name, f.read(size))
        return out

    def __iter__(self):
        for shard in self._shards:
            for key, sample in _samples_of(self._checked(shard)):
                yield {"__key__": key, **sample}

    def torch(self):
        """A ``torch.utils.data.Dataset`` over this dataset (needs PyTorch).

        Items are dicts of ``torch.Tensor`` (numpy arrays converted with
        ``torch.from_numpy``; ``uint16`` raw taps widened to int32, which torch lacks) and
        the JSON record under ``"json"``.
        """
        return TorchDataset(self)

    def __repr__(self):
        return f"Dataset({self.folder!r}, samples={self._len}, fields={self.fields})"


def open_dataset(folder) -> Dataset:
    """Open the dataset in ``folder`` (see :class:`Dataset`); ``dopplertof.dataset.open``.

    Parameters
    ----------
    folder : str or path

    Returns
    -------
    Dataset

    Raises
    ------
    ValueError
        ``folder`` holds no manifest.
    """
    return Dataset(folder)


def TorchDataset(dataset: Dataset):  # noqa: N802 - a class factory: torch is imported lazily
    """A map-style ``torch.utils.data.Dataset`` of ``dataset`` (see :meth:`Dataset.torch`).

    Parameters
    ----------
    dataset : Dataset

    Returns
    -------
    torch.utils.data.Dataset

    Raises
    ------
    ImportError
        torch is not installed.
    """
    try:
        import torch
        from torch.utils.data import Dataset as _TorchBase
    except ImportError:
        raise ImportError("the PyTorch adapter needs torch (pip install torch); dopplertof does not depend on it") from None

    class _Adapter(_TorchBase):
        def __init__(self, ds):
            self.ds = ds

        def __len__(self):
            return len(self.ds)

        def __getitem__(self, i):
            sample = self.ds[i]
            out = {}
            for k, v in sample.items():
                if isinstance(v, np.ndarray):
                    out[k] = torch.from_numpy(v.astype(np.int32) if v.dtype == np.uint16 else v)
                else:
                    out[k] = v
            return out

    return _Adapter(dataset)


__all__ = ["Dataset", "TorchDataset", "open_dataset", "decode_member"]
