"""The public API of :mod:`dopplertof`, listed once for the API reference (``conf.py``
writes its pages from it) and for ``tests/test_docs.py`` (every name listed has a docstring).

Public are the names of ``dopplertof.__all__`` and the lazy modules of ``dopplertof._MODULES``
with, inside each module (and each non-private submodule of a lazy package), the names of
its ``__all__`` or, without one, the functions and classes it defines whose names do not
start with ``_``; of a public class, its public methods and properties.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import pkgutil


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


def undocumented() -> list[str]:
    """Every public name (module, function, class, method, property) without a docstring."""
    import dopplertof

    missing = []
    targets = [(f"dopplertof.{n}", getattr(dopplertof, n)) for n in dopplertof.__all__]
    for module_name in public_modules():
        module = importlib.import_module(module_name)
        targets.append((module_name, module))
        targets += [(f"{module_name}.{n}", getattr(module, n)) for n in module_members(module_name)]
    for name, obj in targets:
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
