"""Values of Mitsuba XML property elements, parsed as Mitsuba 3 parses them.

Shared by the loader and the Mitsuba 0.6 translator (:mod:`dopplertof.mitsuba06`).
"""

from __future__ import annotations

from .scene import SceneError


def property_value(el, where: str):
    """Python value of a Mitsuba property element (``<integer>``/``<float>``/``<boolean>``/
    ``<string>``), parsed as Mitsuba 3 does; SceneError naming the element otherwise."""
    value = el.attrib.get("value")
    kind = {"integer": "an integer", "float": "a number", "boolean": "true or false"}.get(el.tag)
    try:
        if el.tag == "integer":
            return int(value.strip())
        if el.tag == "float":
            return float(value)
        if el.tag == "boolean":
            return {"true": True, "false": False}[value.strip().lower()]
    except (AttributeError, KeyError, ValueError):
        raise SceneError(f"{where}: <{el.tag} name={el.attrib.get('name')!r} value={value!r}>: expected {kind}") from None
    if el.tag != "string":
        raise SceneError(f"{where}: <{el.tag} name={el.attrib.get('name')!r}> is not an integer, float, boolean or string property")
    return value
