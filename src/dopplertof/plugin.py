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
turns into render settings through the same :func:`render_settings`.

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
``path_correlation_depth``                     ``correlation``,            int     0           0 → ``none``, 1 → ``pixel``, k ≥ 2 →
                                               ``correlation_depth``                           ``replay`` with depth k
``max_depth``                                  (same)                      int     −1          path depth, Mitsuba semantics (−1: ∞)
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

These are the original's defaults, not :func:`dopplertof.render`'s: no path correlation,
unbounded depth, homodyne. Any other key, or a value of the wrong type, raises
``ValueError`` naming it (``mi.load_dict`` reports it inside its own ``RuntimeError``).

Output of ``render`` (``mi.render``): a ``TensorXf`` of shape (H, W, C) whose channels are
listed by :func:`output_channels` (and the integrator's ``aov_names()``): first the D-ToF
measurement (1/T)∫ W f dt in the film's colour layout (R = G = B in RGB variants; signed),
then the intensity image, the measurement's standard error, depth (m) and radial velocity
(m/s, positive receding; depth and velocity are 0 where no surface was hit). Only the
scene's first sensor and primal rendering (no derivatives) are supported.
"""

from __future__ import annotations

import dataclasses
import difflib
import math

import numpy as np

from .backend import SUPPORTED_VARIANTS
from .correlation import Correlation
from .modulation import Camera
from .timesampling import validate as validate_time_sampling

PLUGIN_NAMES = ("dopplertof", "dopplertofpath")

# key -> expected Python type ("int" accepts integral numbers, "float" any real number)
_ORIGINAL_KEYS = {
    "time": "float",
    "w_g": "float",
    "w_s": "float",
    "hetero_frequency": "float",
    "sensor_phase_offset": "float",
    "hetero_offset": "float",
    "g_1": "float",
    "g_0": "float",
    "wave_function_type": "str",
    "low_frequency_component_only": "bool",
    "time_sampling_method": "str",
    "antithetic_shift": "float",
    "use_stratified_sampling_for_each_interval": "bool",
    "path_correlation_depth": "int",
    "max_depth": "int",
    "rr_depth": "int",
    "hide_emitters": "bool",
    "m_reconnection_threshold": "float",  # M06 (reference §8.1); the prefix is the original's
}
# Keys of the original's (or Mitsuba's) integrator that change nothing here.
_IGNORED_KEYS = {"is_doppler_integrator": "bool", "samples_per_pass": "int", "block_size": "int", "timeout": "float"}
# SI name -> (type, the original names it replaces)
_SI_KEYS = {
    "exposure": ("float", ("time", "w_s")),
    "modulation_frequency": ("float", ("w_g", "w_s")),
    "heterodyne": ("float", ("hetero_frequency", "w_s")),
    "phase": ("float", ("sensor_phase_offset", "hetero_offset")),
    "g1": ("float", ("g_1",)),
    "g0": ("float", ("g_0",)),
    "waveform": ("str", ("wave_function_type",)),
    "low_pass": ("bool", ("low_frequency_component_only",)),
    "time_sampling": ("str", ("time_sampling_method",)),
    "stratify_intervals": ("bool", ("use_stratified_sampling_for_each_interval",)),
    "correlation": ("str", ("path_correlation_depth",)),
    "correlation_depth": ("int", ("path_correlation_depth",)),
    "n_times": ("int", ()),
    "exposure_start": ("float", ()),
    "reconnection_threshold": ("float", ("m_reconnection_threshold",)),
}
_CAMERA_SI_KEYS = ("exposure", "modulation_frequency", "heterodyne", "phase", "g1", "g0", "waveform", "low_pass")
# Settings any Mitsuba integrator may carry: taken from a scene's foreign <integrator> too.
_GENERIC_KEYS = ("max_depth", "rr_depth", "hide_emitters")
ORIGINAL_DEFAULT_MAX_DEPTH = -1
DEFAULT_RECONNECTION_THRESHOLD = Correlation.threshold  # M06's default too (0.5)


# ----------------------------------------------------------------------------------------
# Parameters -> keyword arguments of dopplertof.render


def _checked(key: str, value, kind: str, where: str):
    """``value`` as a Python ``kind`` ("int", "float", "bool", "str"), or ValueError."""
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
    article = "an" if kind == "int" else "a"
    noun = {"int": "integer", "float": "finite number", "bool": "boolean", "str": "string"}[kind]
    raise ValueError(f"{where}: {key!r} must be {article} {noun}, got {value!r}")


def _unknown_key_error(key: str, where: str) -> ValueError:
    known = sorted({*_ORIGINAL_KEYS, *_IGNORED_KEYS, *_SI_KEYS})
    close = difflib.get_close_matches(key, known, n=1)
    hint = f"; did you mean {close[0]!r}?" if close else f"; known parameters: {', '.join(known)}"
    return ValueError(f"{where}: unknown parameter {key!r}{hint}")


def _camera(p: dict, where: str) -> Camera:
    """The camera: the original names through :meth:`Camera.from_original`, then SI names."""
    camera = Camera.from_original({k: v for k, v in p.items() if k in _ORIGINAL_KEYS}, where)
    si = {k: p[k] for k in _CAMERA_SI_KEYS if k in p}
    try:
        return dataclasses.replace(camera, **si)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None


def _correlation(p: dict, where: str) -> tuple[str, int | None]:
    """(mode, depth) from ``path_correlation_depth`` (0 none, 1 pixel, k ≥ 2 replay to k)."""
    if "correlation" in p or "correlation_depth" in p:
        return p.get("correlation", "replay"), p.get("correlation_depth")
    depth = p.get("path_correlation_depth", 0)
    if depth < 0:
        raise ValueError(f"{where}: 'path_correlation_depth' must be >= 0, got {depth}")
    if depth == 0:
        return "none", None
    if depth == 1:
        return "pixel", None
    return "replay", depth


def _depths(p: dict, where: str, default_max_depth: int) -> dict:
    max_depth = p.get("max_depth", default_max_depth)
    if max_depth == 0 or max_depth < -1:
        raise ValueError(f"{where}: 'max_depth' must be >= 1 or -1 (unbounded), got {max_depth}")
    rr_depth = p.get("rr_depth", 5)
    if rr_depth < 1:
        raise ValueError(f"{where}: 'rr_depth' must be >= 1, got {rr_depth}")
    return {"max_depth": max_depth, "rr_depth": rr_depth, "hide_emitters": p.get("hide_emitters", False)}


def render_settings(params: dict, where: str = "integrator") -> dict:
    """Keyword arguments of :func:`dopplertof.render` from integrator parameters.

    Parameters
    ----------
    params : dict
        The parameters of a ``dopplertof`` / ``dopplertofpath`` integrator (module table;
        an optional ``"type"`` entry names the plugin). For another integrator type (e.g.
        a scene file's stock ``path``) only ``max_depth``, ``rr_depth`` and
        ``hide_emitters`` are taken, and only where given.
    where : str
        Prefix of error messages (the file and element, for instance).

    Returns
    -------
    dict with ``cameras`` (one :class:`Camera`), ``time_sampling``, ``n_times``,
    ``antithetic_shift``, ``stratify_intervals``, ``correlation``, ``correlation_depth``,
    ``reconnection_threshold``, ``max_depth``, ``rr_depth``, ``hide_emitters`` and
    ``exposure_start``.

    Raises
    ------
    ValueError
        An unknown key, a value of the wrong type or range, or an SI name given together
        with the original name it replaces; the message names the key.
    """
    plugin_type = params.get("type", PLUGIN_NAMES[0])
    params = {k: v for k, v in params.items() if k != "type"}
    if plugin_type not in PLUGIN_NAMES:
        given = {k: _checked(k, params[k], _ORIGINAL_KEYS[k], where) for k in _GENERIC_KEYS if k in params}
        checked = _depths(given, where, ORIGINAL_DEFAULT_MAX_DEPTH)
        return {k: checked[k] for k in given}

    p = {}
    for key, value in params.items():
        if key in _ORIGINAL_KEYS:
            p[key] = _checked(key, value, _ORIGINAL_KEYS[key], where)
        elif key in _SI_KEYS:
            p[key] = _checked(key, value, _SI_KEYS[key][0], where)
            clash = [k for k in _SI_KEYS[key][1] if k in params]
            if clash:
                raise ValueError(f"{where}: give either {key!r} or {clash[0]!r}, not both")
        elif key in _IGNORED_KEYS:
            _checked(key, value, _IGNORED_KEYS[key], where)
        else:
            raise _unknown_key_error(key, where)

    method = p.get("time_sampling", p.get("time_sampling_method", "antithetic"))
    shift = p.get("antithetic_shift", 0.5 if method == "antithetic" else 0.0)
    n_times = p.get("n_times", 2)
    correlation, correlation_depth = _correlation(p, where)
    threshold = p.get("reconnection_threshold", p.get("m_reconnection_threshold", DEFAULT_RECONNECTION_THRESHOLD))
    try:
        validate_time_sampling(method, n_times, shift)
        Correlation(correlation, correlation_depth, threshold)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
    return {
        "cameras": [_camera(p, where)],
        "time_sampling": method,
        "n_times": n_times,
        "antithetic_shift": shift,
        "stratify_intervals": p.get("stratify_intervals", p.get("use_stratified_sampling_for_each_interval", True)),
        "correlation": correlation,
        "correlation_depth": correlation_depth,
        "reconnection_threshold": threshold,
        **_depths(p, where, ORIGINAL_DEFAULT_MAX_DEPTH),
        "exposure_start": p.get("exposure_start", 0.0),
    }


# ----------------------------------------------------------------------------------------
# Rendering a Mitsuba scene


def output_channels(mono: bool = False) -> list[str]:
    """Names of the channels of the plugin's output tensor, in order (module docstring)."""
    colours = ("Y",) if mono else ("R", "G", "B")
    return [f"measurement.{c}" for c in colours] + [f"intensity.{c}" for c in colours] + ["measurement_stderr", "depth", "velocity"]


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


def render_image(settings: dict, scene, sensor=0, seed=0, spp=0) -> np.ndarray:
    """Render ``scene`` with :func:`dopplertof.render` and lay out the plugin's output.

    ``scene`` is an ``mi.Scene`` (static) or a :class:`DynamicScene`; ``spp`` 0 takes the
    sensor's sample count. Returns float32 (H, W, C), channels :func:`output_channels`.
    """
    from .render import render
    from .scene import DynamicScene

    dyn = scene if isinstance(scene, DynamicScene) else DynamicScene(static=scene, source="<mi.Scene>")
    _first_sensor_only(dyn.static, sensor)
    spp = _as_int(spp) or dyn.sensor.sampler().sample_count()
    result = render(dyn, spp=spp, seed=_as_int(seed), **settings)
    intensity = result.intensity if result.intensity.ndim == 3 else result.intensity[..., None]
    measurement = np.repeat(result.measurements[0][..., None], intensity.shape[-1], axis=-1)
    extra = [result.measurement_stderr[0], np.nan_to_num(result.depth), np.nan_to_num(result.velocity)]
    return np.concatenate([measurement, intensity, np.stack(extra, axis=-1)], axis=-1).astype(np.float32)


def _integrator_class():
    """The plugin class for the active variant (Mitsuba's base classes are per variant)."""
    import mitsuba as mi

    class DopplerToFIntegrator(mi.SamplingIntegrator):
        """D-ToF integrator plugin (see :mod:`dopplertof.plugin`)."""

        def __init__(self, props, name=PLUGIN_NAMES[0]):
            super().__init__(props)
            self.name = name
            here = f"<integrator type={name!r}{' id=' + repr(props.id()) if props.id() else ''}>"
            self.settings = render_settings({"type": name, **{k: props[k] for k in props.keys()}}, here)

        def render(self, scene, sensor=0, seed=0, spp=0, develop=True, evaluate=True):
            if not develop:
                raise ValueError("the dopplertof integrator only supports develop=True")
            return mi.TensorXf(render_image(self.settings, scene, sensor, seed, spp))

        def aov_names(self):
            return output_channels(mono=not mi.is_rgb)[3 if mi.is_rgb else 1:]

        def to_string(self):
            camera = self.settings["cameras"][0]
            return f"DopplerToFIntegrator[type={self.name}, camera={camera}, max_depth={self.settings['max_depth']}]"

    return DopplerToFIntegrator


_registered_variants: set = set()


def register() -> bool:
    """Register ``dopplertof`` and ``dopplertofpath`` for the active Mitsuba variant.

    Returns False (and registers nothing) when no supported variant is active.
    """
    import mitsuba as mi

    variant = mi.variant()
    if variant not in SUPPORTED_VARIANTS:
        return False
    if variant not in _registered_variants:
        cls = _integrator_class()
        for name in PLUGIN_NAMES:
            mi.register_integrator(name, lambda props, name=name: cls(props, name))
        _registered_variants.add(variant)
    return True


def _on_variant_change(old_variant, new_variant):
    register()


def register_on_variant_change() -> None:
    """Register now if a variant is active, and again whenever the variant changes.

    Called when :mod:`dopplertof` is imported; sets no variant itself.
    """
    import mitsuba as mi

    mi.detail.add_variant_callback(_on_variant_change)
    register()
