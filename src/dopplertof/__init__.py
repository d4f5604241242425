"""dopplertof: physically based simulation of Doppler time-of-flight cameras on stock Mitsuba 3.

Everything is imported on first use (``dopplertof.render``, ``dopplertof.reconstruct``,
``dopplertof.sensor``, …), so that the command line starts fast. The Mitsuba integrator
plugins ``dopplertof``/``dopplertofpath`` are registered as soon as Mitsuba is imported,
before or after this package (:mod:`dopplertof.plugin`).
"""

from ._startup import guard_interrupts as _guard_interrupts

_guard_interrupts()  # the command's imports end with one line on Ctrl-C, not a traceback

from .backend import configure_llvm_path as _configure_llvm_path  # noqa: E402

_configure_llvm_path()  # must precede the first `import drjit`

__version__ = "0.2.0"

import importlib as _importlib  # noqa: E402

from .plugin import register_when_mitsuba_loads as _register_plugin  # noqa: E402

# Not lazy: importing the submodule `render` would bind the module over the function.
from .render import RenderResult, render  # noqa: E402

_register_plugin()

_ATTRIBUTES = {
    "Camera": "modulation",
    "RawFrame": "sensors",
    "Sensor": "sensors",
    "DynamicScene": "scene",
    "SceneError": "scene",
    "RenderSettings": "settings",
    "load_scene": "loader",
    "set_variant": "backend",
}
_MODULES = ("scenes", "reconstruct", "sensor", "io", "viz", "experiments", "animate", "outputs", "settings", "oracles", "folder", "tracing", "dataset", "sensors", "codes", "design")


def __getattr__(name):
    """Names and modules of the package, imported on first use."""
    if name in _ATTRIBUTES:
        return getattr(_importlib.import_module(f".{_ATTRIBUTES[name]}", __name__), name)
    if name in _MODULES:
        return _importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module 'dopplertof' has no attribute {name!r}")


def __dir__():
    return sorted([*globals(), *_ATTRIBUTES, *_MODULES])


__all__ = ["Camera", "DynamicScene", "RenderResult", "RenderSettings", "SceneError", "load_scene", "render", "scenes", "set_variant", "reconstruct", "sensor", "sensors", "codes", "Sensor", "RawFrame"]
