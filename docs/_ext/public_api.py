"""The public API of :mod:`dopplertof`, listed once for the API reference (``conf.py``
writes its pages from it) and for ``tests/test_docs.py`` (every name listed has a docstring;
every function, class and method documents each parameter and what it returns in numpy
sections: :func:`incomplete_docstrings`).

Public are the names of ``dopplertof.__all__`` and the lazy modules of ``dopplertof._MODULES``
with, inside each module (and each non-private submodule of a lazy package), the names of
its ``__all__`` or, without one, the functions and classes it defines whose names do not
start with ``_``; of a public class, its public methods and properties.
"""

from __future__ import annotations

import dataclasses
import enum
import importlib
import inspect
import pkgutil
import re


def public_modules() -> list[str]:
    """Dotted names of the documented modules: the lazy modules and their public submodules."""
    import dopplertof

    names = []
    for short in dopplertof._MODULES:
        module = importlib.import_module(f"dopplertof.{short}")
        names.append(module.__name__)
        if hasattr(module, "__path__"):
            names += [f"{module.__name__}.{info.name}" for info in pkgutil.iter_modules(module.__path__) if not info.name.startswith("_")]
    return names


def module_members(module_name: str) -> list[str]:
    """The public names of one module (its ``__all__``, else what it defines)."""
    module = importlib.import_module(module_name)
    names = getattr(module, "__all__", None)
    if names is None:
        names = [n for n, o in vars(module).items() if not n.startswith("_") and (inspect.isfunction(o) or inspect.isclass(o)) and o.__module__ == module_name]
    return list(names)


def _documented(obj) -> bool:
    """A docstring of its own: not empty, not the signature a dataclass writes when there is none."""
    doc = (obj.__doc__ or "").strip()
    if inspect.isclass(obj) and dataclasses.is_dataclass(obj):
        return bool(doc) and not doc.startswith(f"{obj.__name__}(")
    return bool(doc)


def _public_names() -> list[tuple[str, object]]:
    """(dotted name, object) of every public name: the top level's, then each documented
    module and its members (a name exported twice appears twice)."""
    import dopplertof

    targets = [(f"dopplertof.{n}", getattr(dopplertof, n)) for n in dopplertof.__all__]
    for module_name in public_modules():
        module = importlib.import_module(module_name)
        targets.append((module_name, module))
        targets += [(f"{module_name}.{n}", getattr(module, n)) for n in module_members(module_name)]
    return targets


def undocumented() -> list[str]:
    """Every public name (module, function, class, method, property) without a docstring."""
    missing = []
    for name, obj in _public_names():
        if not (inspect.ismodule(obj) or inspect.isfunction(obj) or inspect.isclass(obj)):
            continue  # constants and tables: documented in their module's docstring
        if not _documented(obj):
            missing.append(name)
        if inspect.isclass(obj):
            for attribute, value in vars(obj).items():
                function = value.fget if isinstance(value, property) else getattr(value, "__func__", value)
                if not attribute.startswith("_") and (inspect.isfunction(function) or isinstance(value, property)):
                    if not (function.__doc__ or "").strip():
                        missing.append(f"{name}.{attribute}")
    return sorted(set(missing))


# A numpy section header: its name, then a line of dashes.
_SECTION = re.compile(r"^(?P<name>[A-Z][A-Za-z ]*)\n[ \t]*-{3,}[ \t]*$", re.MULTILINE)
# Sections that name a callable's parameters (a class's fields may be its Attributes).
_PARAMETER_SECTIONS = {"Parameters", "Other Parameters", "Keyword Arguments"}
_CLASS_PARAMETER_SECTIONS = _PARAMETER_SECTIONS | {"Attributes"}


def _sections(doc: str) -> list[tuple[str, str]]:
    """The numpy sections of a cleaned docstring, in order: (name, the text under the dashes)."""
    matches = list(_SECTION.finditer(doc))
    ends = [following.start() for following in matches[1:]] + [len(doc)]
    return [(match.group("name").strip(), doc[match.end() : end]) for match, end in zip(matches, ends)]


def _section_names(body: str) -> set[str]:
    """The parameter names of one section: the entries at its least indentation,
    ``name : type …`` or ``a, b : type`` or ``**overrides``."""
    lines = [line for line in body.splitlines() if line.strip()]
    if not lines:
        return set()
    indent = min(len(line) - len(line.lstrip()) for line in lines)
    names = set()
    for line in lines:
        if len(line) - len(line.lstrip()) == indent:
            head = line.strip().split(" :")[0].split(":")[0] if ":" in line else line.strip()
            names.update(part.strip().lstrip("*").strip("`") for part in head.split(","))
    return names


def _table_names(doc: str) -> set[str]:
    """The first column of every ``=====`` table (plugin-style parameter tables)."""
    names, inside = set(), False
    for line in doc.splitlines():
        stripped = line.strip()
        if stripped and set(stripped) <= {"=", " "}:
            inside = True  # a border: the table's rows follow until a blank line
        elif not stripped:
            inside = False
        elif inside and not line.startswith(" "):  # indented lines continue a row's last column
            names.add(stripped.split()[0].strip("`"))
    return names


def _parameters(obj) -> list[str] | None:
    """The parameter names a caller passes (``self``/``cls`` left out), None where Python
    shows no signature (a built-in base's constructor)."""
    try:
        signature = inspect.signature(obj)
    except (TypeError, ValueError):
        return None
    names = list(signature.parameters)
    if inspect.isfunction(obj) and names and names[0] in ("self", "cls") and "." in obj.__qualname__:
        names = names[1:]
    return names


def _returns_value(function) -> bool:
    """Whether a function's return annotation names a value (not None, not absent)."""
    annotation = inspect.signature(function).return_annotation
    return annotation is not inspect.Signature.empty and annotation not in (None, "None")


def docstring_gaps(obj) -> list[str]:
    """What the numpy-style docstring of a callable lacks: ``no parameter section`` where
    it takes parameters and has none, else ``missing parameter NAME`` for each one
    (compared with :func:`inspect.signature`); ``no Returns section`` where a function is
    annotated to return a value; and ``section NAME twice`` for a section written twice
    (sections added to a docstring that had them).

    Parameters
    ----------
    obj : function or class
        A method's ``self`` or ``cls`` is left out. A class's parameters are its
        constructor's; its Attributes section (a dataclass's fields) and a ``=====`` table
        of its own or of its module's docstring (a plugin's properties, a sensor's
        parameters) count as parameter sections.

    Returns
    -------
    list of str
        Empty where every parameter is documented.
    """
    doc = inspect.cleandoc(obj.__doc__ or "")
    sections = _sections(doc)
    headers = [name for name, _ in sections]
    gaps = [f"section {name} twice" for name in sorted({h for h in headers if headers.count(h) > 1})]
    if not inspect.isclass(obj) and _returns_value(obj) and not {"Returns", "Yields"} & set(headers):
        gaps.append("no Returns section")
    parameters = _parameters(obj)
    if not parameters:
        return gaps
    wanted = _CLASS_PARAMETER_SECTIONS if inspect.isclass(obj) else _PARAMETER_SECTIONS
    documented = set().union(*(_section_names(body) for name, body in sections if name in wanted))
    documented |= _table_names(doc)
    if inspect.isclass(obj):  # a class whose module's table documents its parameters (sensor, silicon)
        documented |= _table_names(inspect.getdoc(inspect.getmodule(obj)) or "")
    if not documented:
        return [*gaps, "no parameter section"]
    return [*gaps, *(f"missing parameter {name}" for name in parameters if name not in documented)]


def _public_callables():
    """Every public function, class and method (a name exported twice, once each time)."""
    for _, obj in _public_names():
        if inspect.isfunction(obj):
            yield obj
        elif inspect.isclass(obj):
            if not issubclass(obj, enum.Enum) and not issubclass(obj, BaseException):
                yield obj
            for attribute, value in vars(obj).items():
                function = getattr(value, "__func__", value)
                if not attribute.startswith("_") and inspect.isfunction(function):
                    yield function


def incomplete_docstrings() -> list[str]:
    """Every public callable whose docstring lacks a numpy section or a parameter, as
    ``name: gap`` (:func:`docstring_gaps`)."""
    gaps = set()
    for obj in _public_callables():
        # A name exported twice is reported once, where it is defined.
        where = f"{obj.__module__}.{obj.__qualname__}"
        gaps.update(f"{where}: {gap}" for gap in docstring_gaps(obj))
    return sorted(gaps)
