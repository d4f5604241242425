"""Strict conversion of user-given values to the Python type a setting declares.

One rule everywhere (API, CLI, scene files, the Mitsuba plugin): a bool is a bool (not a
string, not a number), an integer is an integral number (``3.0`` passes, ``2.5`` does not),
a float is a finite real number, a string is a string. The error names the setting and
the value.
"""

from __future__ import annotations

import math

import numpy as np

KINDS = ("int", "float", "bool", "str")
_NOUNS = {"int": "an integer", "float": "a finite number", "bool": "a boolean (true/false)", "str": "a string"}


def checked(name: str, value, kind: str, where: str = ""):
    """``value`` as the Python ``kind`` (``int``, ``float``, ``bool`` or ``str``), else ValueError."""
    is_bool = isinstance(value, (bool, np.bool_))
    is_real = isinstance(value, (int, float, np.integer, np.floating)) and not is_bool
    if kind == "bool" and is_bool:
        return bool(value)
    if kind == "str" and isinstance(value, str):
        return value
    if kind == "float" and is_real and math.isfinite(value):
        return float(value)
    if kind == "int" and is_real and math.isfinite(value) and float(value).is_integer():
        return int(value)
    prefix = f"{where}: " if where else ""
    raise ValueError(f"{prefix}{name!r} must be {_NOUNS[kind]}, got {value!r}")


def checked_or_text(name: str, value, kind: str, where: str = ""):
    """As :func:`checked`, but a value given as text (a scene file's, the original code's
    parameters) is parsed first, strictly: ``"false"`` is False (:func:`parse_bool`),
    ``"2.5"`` is 2.5, ``"maybe"`` is a ValueError naming ``name``."""
    if isinstance(value, str) and kind != "str":
        prefix = f"{where}: " if where else ""
        if kind == "bool":
            return parse_bool(value, f"{prefix}{name!r}")
        try:
            value = float(value.strip())
        except ValueError:
            raise ValueError(f"{prefix}{name!r} must be {_NOUNS[kind]}, got {value!r}") from None
    return checked(name, value, kind, where)


def parse_bool(text: str, name: str) -> bool:
    """A boolean written as text (CLI, XML): true/false, yes/no, 1/0, on/off; else
    ValueError beginning with ``name`` (say what and where, e.g. ``"camera 'h=1': 'low_pass'"``)."""
    lowered = str(text).strip().lower()
    if lowered in ("true", "yes", "1", "on"):
        return True
    if lowered in ("false", "no", "0", "off"):
        return False
    raise ValueError(f"{name} must be true or false, got {text!r}")


def checked_in_range(name: str, value, *, above=None, at_least=None, below=None, at_most=None, kind: str = "float", where: str = "", unit: str = ""):
    """``value`` as :func:`checked` gives it, and inside the given bounds; else ValueError.

    One message for every range check: ``"{where}: {name!r} must be {requirement}, got
    {value!r}"``, the requirement written from the bounds (``> 0``, ``>= 0``, ``in (0, 1]``,
    ``in [0, 0.5)``, followed by ``unit``).

    Parameters
    ----------
    name : str. The setting, as the user wrote it.
    value : object. What the user gave.
    above, at_least : float or None. Exclusive or inclusive lower bound (at most one);
        None: no lower bound.
    below, at_most : float or None. Exclusive or inclusive upper bound (at most one);
        None: no upper bound.
    kind : str. ``"float"`` (default) or ``"int"``: the type :func:`checked` converts to.
    where : str. What holds the setting (``"Silicon"``), the message's prefix; default none.
    unit : str. The bounds' unit, appended to the requirement; default none.

    Returns
    -------
    float or int
        ``value`` converted to ``kind``.

    Raises
    ------
    ValueError
        If ``value`` is not a ``kind`` or lies outside the bounds, naming ``name`` and
        ``value``.
    """
    value = checked(name, value, kind, where)
    low = above if above is not None else at_least
    high = below if below is not None else at_most
    ok = (low is None or (value > low if above is not None else value >= low)) and (
        high is None or (value < high if below is not None else value <= high)
    )
    if ok:
        return value
    if low is not None and high is not None:
        requirement = f"in {'(' if above is not None else '['}{low:g}, {high:g}{')' if below is not None else ']'}"
    elif low is not None:
        requirement = f"{'>' if above is not None else '>='} {low:g}"
    else:
        requirement = f"{'<' if below is not None else '<='} {high:g}"
    prefix = f"{where}: " if where else ""
    suffix = f" {unit}" if unit else ""
    raise ValueError(f"{prefix}{name!r} must be {requirement}{suffix}, got {value!r}")
