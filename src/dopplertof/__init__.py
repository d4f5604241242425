"""dopplertof: physically based simulation of Doppler time-of-flight cameras on stock Mitsuba 3."""

from .backend import configure_llvm_path as _configure_llvm_path

_configure_llvm_path()  # must precede the first `import drjit`

__version__ = "0.2.0"

import importlib as _importlib  # noqa: E402

from . import scenes  # noqa: E402
from .backend import set_variant  # noqa: E402
from .loader import load_scene  # noqa: E402
from .modulation import Camera  # noqa: E402
from .plugin import register_on_variant_change as _register_plugin  # noqa: E402
from .render import RenderResult, render  # noqa: E402
from .scene import DynamicScene, SceneError  # noqa: E402
from .settings import RenderSettings  # noqa: E402

# Like mitransient: the `dopplertof`/`dopplertofpath` integrators exist for mi.load_dict,
# mi.load_file and mi.render once a supported variant is active (now, or when one is set).
_register_plugin()

_LAZY_MODULES = ("reconstruct", "sensor", "io", "viz", "experiments", "animate", "outputs", "settings")


def __getattr__(name):
    """``dopplertof.reconstruct``, ``dopplertof.sensor``, … without importing them up front."""
    if name in _LAZY_MODULES:
        return _importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module 'dopplertof' has no attribute {name!r}")


__all__ = ["Camera", "DynamicScene", "RenderResult", "RenderSettings", "SceneError", "load_scene", "render", "scenes", "set_variant", "reconstruct", "sensor"]
