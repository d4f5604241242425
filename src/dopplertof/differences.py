"""What differs between two records of a run (a checkpoint's settings, a dataset's header,
a clip's settings), said down to the entry: ``cameras[2].heterodyne: 1.0 in the
checkpoint, 0.5 now``, not two copies of a long value."""

from __future__ import annotations

import json

# Text longer than this (a sensor file's contents, say) is said to have changed, not shown.
SHOWN_TEXT_MAX = 60


def differences(old, new, old_label: str = "there", prefix: str = "") -> list[str]:
    """``path: old <old_label>, new now`` for each entry that differs between two JSON-like
    values (dicts by key, lists by index; a long text as ``path (changed)``).

    Parameters
    ----------
    old, new : JSON-like (dict, list, str, number, bool, None)
    old_label : str, default ``"there"``
        Where the old value is (``"in the checkpoint"``).
    prefix : str, default ``""``
        The path of ``old`` and ``new`` themselves.

    Returns
    -------
    list of str
    """
    if isinstance(old, dict) and isinstance(new, dict):
        keys = sorted(set(old) | set(new), key=str)
        return [d for k in keys for d in differences(old.get(k, _ABSENT), new.get(k, _ABSENT), old_label, f"{prefix}.{k}" if prefix else str(k))]
    if isinstance(old, list) and isinstance(new, list) and len(old) == len(new):
        return [d for i, (a, b) in enumerate(zip(old, new)) for d in differences(a, b, old_label, f"{prefix}[{i}]")]
    if old == new:
        return []
    if any(isinstance(v, str) and ("\n" in v or len(v) > SHOWN_TEXT_MAX) for v in (old, new)):
        return [f"{prefix} (changed)"]
    return [f"{prefix}: {_shown(old)} {old_label}, {_shown(new)} now"]


class _Absent:
    def __repr__(self):
        return "absent"


_ABSENT = _Absent()


def _shown(value) -> str:
    if value is _ABSENT:
        return "absent"
    text = json.dumps(value, default=str, sort_keys=True)
    return text if len(text) <= SHOWN_TEXT_MAX else text[: SHOWN_TEXT_MAX - 3] + "..."
