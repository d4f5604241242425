"""Datasets for learning, at scale (DESIGN §5.4).

``generate(output, samples, seed, config, …)`` renders randomized scenes (indoor rooms and
streets, :mod:`.randomize`) into WebDataset-style tar shards with a manifest
(:mod:`.shards`); sample i depends only on (seed, i), so the bytes do not depend on the
executor (:mod:`.execute`: local processes or Ray). ``open(folder)`` reads a dataset
(:mod:`.reader`), ``verify(folder)`` checks it, ``info(folder)`` summarises it. The
configuration knobs are in :mod:`.config`, the per-sample fields in :mod:`.schema`.
"""

from .config import default_toml, load_config
from .generate import generate
from .reader import Dataset, open_dataset
from .shards import verify

open = open_dataset  # noqa: A001 - dopplertof.dataset.open(DIR), as the issue names it


def info(folder, **kwargs):
    """Summary statistics and a contact sheet (see :func:`dopplertof.dataset.summary.summarize`).

    Parameters
    ----------
    folder : str or path
        Dataset folder.
    **kwargs
        ``sheet`` (PNG path, default none), ``sheet_samples`` (int, default 4) and
        ``max_samples`` (int, default all) of :func:`~dopplertof.dataset.summary.summarize`.

    Returns
    -------
    dict
        ``lines`` (the printable report) and ``stats`` (the numbers).

    Raises
    ------
    ValueError
        ``folder`` holds no dataset.
    """
    from .summary import summarize

    return summarize(folder, **kwargs)


__all__ = ["Dataset", "default_toml", "generate", "info", "load_config", "open", "open_dataset", "verify"]
