"""The D-ToF integrator as a Mitsuba 3 plugin, with the original code's parameter names.

Importing :mod:`dopplertof` registers the integrator under two names, ``dopplertof`` and
``dopplertofpath`` (the original Mitsuba 3 fork's), for every supported variant
(``llvm_ad_*``, ``cuda_ad_*``) as soon as it is active: whether the variant was set
before the import, later with :func:`dopplertof.set_variant` or with ``mi.set_variant``.
Stock Mitsuba then renders a *static* scene with it::

    scene = mi.load_dict({..., "integrator": {"type": "dopplertof", "w_g": 30, "hetero_frequency": 1.0}})
    image = mi.render(scene, spp=64)     # TensorXf (H, W, C), channels below

Moving bodies need :func:`dopplertof.load_scene` (stock Mitsuba cannot parse
``<animation>``); it keeps the ``<integrator>`` parameters, which ``dopplertof render``
turns into render settings through the same
:func:`dopplertof.settings.integrator_layer`.

Parameters: the original M3 integrator's names and defaults (reference §8.2). The SI name
may replace the original one; giving both is an error.

=============================================  ==========================  ======  ==========  =========================================
original name                                  SI name                     type    default     meaning
=============================================  ==========================  ======  ==========  =========================================
``time``                                       ``exposure``                float   0.0015      exposure T, s
``w_g``                                        ``modulation_frequency``    float   30          light modulation f_g (``w_g`` MHz, SI Hz)
``w_s``                                        –                           float   ``w_g``     sensor frequency, MHz: h = (w_s − w_g)·T
                                                                                               when ``hetero_frequency`` is absent
``hetero_frequency``                           ``heterodyne``              float   0           h, beat cycles per exposure
``sensor_phase_offset``                        ``phase``                   float   0           ψ, rad
``hetero_offset``                              ``phase``                   float   –           ψ = 2π·value (wins over the above)
``g_1`` / ``g_0``                              ``g1`` / ``g0``             float   0.5 / 0.5   light amplitude / DC offset
``wave_function_type``                         ``waveform``                string  sinusoidal  sinusoidal, rectangular, triangular,
                                                                                               trapezoidal
``low_frequency_component_only``               ``low_pass``                bool    true        low-pass correlation model
``time_sampling_method``                       ``time_sampling``           string  antithetic  uniform, stratified, antithetic,
                                                                                               antithetic_mirror
``antithetic_shift``                           (same)                      float   0.5 or 0    a, units of T (0.5 for antithetic)
``use_stratified_sampling_for_each_interval``  ``stratify_intervals``      bool    true        stratify each interval over the groups
``path_correlation_depth``                     ``correlation``,            int     (replay)    0 → ``none``, 1 → ``pixel``, k ≥ 2 →
                                               ``correlation_depth``                           ``replay`` with depth k
``max_depth``                                  (same)                      int     5           path depth, Mitsuba semantics (−1: ∞)
``rr_depth``                                   (same)                      int     5           Russian-roulette start depth
``hide_emitters``                              (same)                      bool    false       hide directly visible emitters
``m_reconnection_threshold``                   ``reconnection_threshold``  float   0.5         ``adaptive``: reconnect where both
                                                                                               surfaces are rougher than this α
                                                                                               (the original M06 key, §8.1)
–                                              ``n_times``                 int     2           correlated times per group
–                                              ``exposure_start``          float   0           scene time the exposure opens at, s
``is_doppler_integrator``,                     –                                               accepted for old files; no effect
``samples_per_pass``,
``block_size``, ``timeout``
=============================================  ==========================  ======  ==========  =========================================

A setting the file does not give takes the one default of :class:`~dopplertof.settings.RenderSettings`
(replay correlation, ``max_depth`` 5: paired tracing has no Russian roulette, so an
unbounded default would trace closed scenes to 64 bounces); camera keys left out follow
the original (no ``hetero_frequency`` and ``w_s = w_g``: homodyne). Any other key, or a
value of the wrong type, raises ``ValueError`` naming it (``mi.load_dict`` reports it
inside its own ``RuntimeError``). Every other setting of :class:`RenderSettings` may be
given by its own name.

Output of ``render`` (``mi.render``): a ``TensorXf`` of shape (H, W, C) whose channels are
listed by :func:`output_channels` (and the integrator's ``aov_names()``): first the D-ToF
measurement (1/T)∫ W f dt in the film's colour layout (R = G = B in RGB variants; signed),
then every output of :data:`dopplertof.outputs.OUTPUTS` with its standard error where it
has one (ground truth is 0 where no surface was hit). Only the
scene's first sensor and primal rendering (no derivatives) are supported.
"""

from __future__ import annotations

import importlib.abc
import importlib.util
import sys

import numpy as np

from .backend import SUPPORTED_VARIANTS
from .outputs import OUTPUTS
from .settings import PLUGIN_NAMES, RenderSettings, integrator_layer

# ----------------------------------------------------------------------------------------
# Rendering a Mitsuba scene


def output_channels(mono: bool | None = None, n_cameras: int = 1) -> list[str]:
    """Names of the channels of the plugin's output tensor, in order (module docstring):
    the first camera's measurement in the film's colour layout, then every output of
    :data:`dopplertof.outputs.OUTPUTS` and the standard errors, channel by channel.

    Parameters
    ----------
    mono : bool or None, default None
        One colour channel (``Y``) instead of ``R, G, B``; None: as the active Mitsuba
        variant renders (a ``*_mono`` variant: one).
    n_cameras : int, default 1
        Cameras rendered (one measurement channel and one standard error each).

    Returns
    -------
    list of str
    """
    if mono is None:
        import mitsuba as mi

        mono = mi.variant() is not None and not mi.is_rgb
    colours = ("Y",) if mono else ("R", "G", "B")
    names = [f"measurement.{c}" for c in colours]
    for o in OUTPUTS:
        if o.channels == "color":
            names += [f"{o.name}.{c}" for c in colours] + [f"{o.stderr_name}.{c}" for c in colours]
        elif o.channels == "cameras":
            for i in range(n_cameras):
                names += [f"{o.name}_{i}", f"{o.stderr_name}_{i}"]
        elif o.channels == 1:
            names.append(o.name)
        else:
            names += [f"{o.name}.{c}" for c in o.components]
    return names


def _first_sensor_only(static, sensor) -> None:
    sensors = static.sensors()
    index = sensor if isinstance(sensor, (int, np.integer)) else next((i for i, s in enumerate(sensors) if s is sensor), None)
    if index != 0:
        shown = "a sensor that is not part of the scene" if index is None else f"sensor {index}"
        raise ValueError(f"the dopplertof integrator renders the scene's first sensor only, got {shown}")


def _as_int(value) -> int:
    try:
        return int(value)
    except TypeError:  # a one-entry Dr.Jit array (mi.UInt32 seed)
        return int(value[0])


def render_image(settings: RenderSettings, scene, sensor=0, seed=0, spp=0) -> np.ndarray:
    """Render ``scene`` with :func:`dopplertof.render` and lay out the plugin's output.

    ``scene`` is an ``mi.Scene`` (static) or a :class:`DynamicScene`; ``spp`` 0 takes the
    sensor's sample count. Returns float32 (H, W, C), channels :func:`output_channels`.
    NaN ground truth (no hit) is written as 0, as Mitsuba films expect finite values.
    """
    from .render import render
    from .scene import DynamicScene

    dyn = scene if isinstance(scene, DynamicScene) else DynamicScene(static=scene, source="<mi.Scene>")
    _first_sensor_only(dyn.static, sensor)
    spp = _as_int(spp) or dyn.sensor.sampler().sample_count()
    result = render(dyn, settings=settings, spp=spp, seed=_as_int(seed))
    height, width = result.depth.shape

    def planes(image):
        image = np.asarray(image, dtype=np.float32)
        return [image] if image.ndim == 2 else [image[..., i] for i in range(image.shape[-1])]

    measurement = result.measurements[0] if len(settings.cameras) else np.zeros((height, width), np.float32)
    layers = [measurement] * (1 if result.intensity.ndim == 2 else result.intensity.shape[-1])
    for o in OUTPUTS:
        if o.channels == "cameras":
            for i in range(len(settings.cameras)):
                layers += [result.measurements[i], result.measurement_stderr[i]]
        elif o.kind == "estimate":
            layers += planes(getattr(result, o.name)) + planes(getattr(result, o.stderr_name))
        else:
            layers += planes(getattr(result, o.name))
    return np.nan_to_num(np.stack(layers, axis=-1)).astype(np.float32)


def _integrator_class():
    """The plugin class for the active variant (Mitsuba's base classes are per variant)."""
    import mitsuba as mi

    class DopplerToFIntegrator(mi.SamplingIntegrator):
        """D-ToF integrator plugin (see :mod:`dopplertof.plugin`)."""

        def __init__(self, props, name=PLUGIN_NAMES[0]):
            super().__init__(props)
            self.name = name
            here = f"<integrator type={name!r}{' id=' + repr(props.id()) if props.id() else ''}>"
            layer = integrator_layer({"type": name, **{k: props[k] for k in props.keys()}}, here)
            self.settings = RenderSettings.build(layer, where=here)

        def render(self, scene, sensor=0, seed=0, spp=0, develop=True, evaluate=True):
            if not develop:
                raise ValueError("the dopplertof integrator only supports develop=True")
            return mi.TensorXf(render_image(self.settings, scene, sensor, seed, spp))

        def aov_names(self):
            return output_channels(mono=not mi.is_rgb, n_cameras=len(self.settings.cameras))[3 if mi.is_rgb else 1 :]

        def to_string(self):
            camera = self.settings.cameras[0] if self.settings.cameras else None
            return f"DopplerToFIntegrator[type={self.name}, camera={camera}, max_depth={self.settings.max_depth}]"

    return DopplerToFIntegrator


_registered_variants: set = set()


def register() -> bool:
    """Register ``dopplertof`` and ``dopplertofpath`` for the active Mitsuba variant.

    Returns False when no supported variant is active (in another variant the two names
    load as an error saying which variants they render in).
    """
    import mitsuba as mi

    variant = mi.variant()
    if variant not in SUPPORTED_VARIANTS:
        if variant is not None and variant not in _registered_variants:  # say why, not 'Plugin "dopplertof" not found!'
            for name in PLUGIN_NAMES:
                mi.register_integrator(name, lambda props, name=name: _refuse_variant(name, variant))
            _registered_variants.add(variant)
        return False
    if variant not in _registered_variants:
        cls = _integrator_class()
        for name in PLUGIN_NAMES:
            mi.register_integrator(name, lambda props, name=name: cls(props, name))
        _registered_variants.add(variant)
    return True


def _refuse_variant(name: str, variant: str):
    raise ValueError(f"the {name} integrator renders in the Mitsuba variants {', '.join(SUPPORTED_VARIANTS)}, "
                     f"not in {variant!r} (no scalar or spectral variant): mi.set_variant('llvm_ad_rgb') first")


def _on_variant_change(old_variant, new_variant):
    register()


def register_on_variant_change() -> None:
    """Register now if a variant is active, and again whenever the variant changes, and
    make ``mi.render`` name :func:`dopplertof.render` when it is given a dynamic scene.

    Sets no variant itself.
    """
    import mitsuba as mi

    mi.detail.add_variant_callback(_on_variant_change)
    if not getattr(mi.render, "_dopplertof_checked", False):
        mi.render = _render_refusing_dynamic_scenes(mi.render)
    register()


def _render_refusing_dynamic_scenes(stock_render):
    """``mi.render`` unchanged, except that a :class:`~dopplertof.scene.DynamicScene` (which
    stock Mitsuba cannot trace: its bodies move) is a TypeError saying what to call instead
    of Mitsuba's bare ``assert isinstance(scene, mi.Scene)``."""
    import functools

    @functools.wraps(stock_render)
    def render(scene, *args, **kwargs):
        from .scene import DynamicScene

        if isinstance(scene, DynamicScene):
            raise TypeError(
                "mi.render cannot render a dopplertof scene (its bodies move at per-path times): "
                "use dopplertof.render(scene), or mi.render(scene.static) for the static part with stock Mitsuba"
            )
        return stock_render(scene, *args, **kwargs)

    render._dopplertof_checked = True
    return render


class _AfterMitsubaImport(importlib.abc.MetaPathFinder):
    """Runs :func:`register_on_variant_change` right after ``import mitsuba`` completes its
    module code, so that importing :mod:`dopplertof` need not import Mitsuba itself."""

    def find_spec(self, name, path=None, target=None):
        if name != "mitsuba":
            return None
        sys.meta_path.remove(self)  # find the real module with the other finders
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.loader is not None and hasattr(spec.loader, "exec_module"):
            exec_module = spec.loader.exec_module

            def exec_then_register(module):
                exec_module(module)
                register_on_variant_change()

            spec.loader.exec_module = exec_then_register
        return spec


def register_when_mitsuba_loads() -> None:
    """Called when :mod:`dopplertof` is imported: register now if Mitsuba is loaded, else
    as soon as it is (like mitransient, the plugins then exist for ``mi.load_dict``,
    ``mi.load_file`` and ``mi.render`` once a supported variant is set)."""
    if "mitsuba" in sys.modules:
        register_on_variant_change()
    elif not any(isinstance(f, _AfterMitsubaImport) for f in sys.meta_path):
        sys.meta_path.insert(0, _AfterMitsubaImport())
