"""Every render setting, once: its type, default, unit, validation and original name.

:class:`RenderSettings` is frozen and validated when built. The API
(:func:`dopplertof.render`), the command line, the Mitsuba plugin, ``animate`` and the
experiments all build it the same way, from *layers* of given values, later layers
winning (:meth:`RenderSettings.build`):

1. the scene (:func:`scene_layer`): its ``<integrator>`` (dict ``"integrator"``), the
   sampler's ``sample_count`` and ``seed`` and the sensor's shutter interval;
2. what the caller gives (keyword arguments, command-line options).

A layer that sets a setting discards what earlier layers said about the settings that
depend on it (``correlation_depth`` and ``reconnection_threshold`` follow
``correlation``; ``antithetic_shift`` and ``n_times`` follow ``time_sampling``;
``exposure`` follows ``cameras``), so ``--correlation reconnection`` on a file that asks
for replay to depth 3 is reconnection, not an error, and a caller's cameras set T over a
scene whose sensor has a shutter interval.

Each field of :class:`RenderSettings` declares its kind, unit, default, meaning and range
in its metadata; :meth:`RenderSettings.table` lists them (the docs' settings table,
docs/cli.md "Render settings", and the command-line help come from it).
"""

from __future__ import annotations

import dataclasses
import difflib
import warnings
from dataclasses import dataclass, field

import numpy as np

from .correlation import MODES, PAIRED, Correlation
from .modulation import ORIGINAL_CAMERA_KEYS, Camera, checked_exposure
from .timesampling import ANALYTIC, METHODS, group_cuts, stratifies, wrap_points
from .validation import checked

DEFAULT_EXPOSURE_S = 1.5e-3
DEFAULT_LANES_PER_PASS = 1 << 21
DEFAULT_CHECKPOINT_INTERVAL_S = 60.0
# The most paths per pixel one render takes: the strata tables index a pixel's groups in
# UInt32 (and a render of more would run for years); average several renders for more.
MAX_SPP = 1 << 31
PLUGIN_NAMES = ("dopplertof", "dopplertofpath")


def _setting(default, kind, unit, doc, *, choices=None, follows=None, minimum=None, maximum=None, beyond_maximum="", rule=None, optional=False):
    """A dataclass field with the setting's declaration in its metadata (``beyond_maximum``:
    what the refusal of a value above ``maximum`` says to do instead; ``rule``: value → what
    it must be, where it is not, else None)."""
    meta = dict(kind=kind, unit=unit, doc=doc, choices=choices, follows=follows, minimum=minimum, maximum=maximum,
                beyond_maximum=beyond_maximum, rule=rule, optional=optional)
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class RenderSettings:
    """All settings of one render (module docstring). Build with :meth:`build`."""

    spp: int = _setting(
        64, "int", "paths/pixel", "paths per pixel (a group of n_times correlated times uses n_times)", minimum=1,
        maximum=MAX_SPP, beyond_maximum="the most paths per pixel one render takes; average several renders (different seeds) for more",
    )  # fmt: skip
    seed: int = _setting(0, "int", "", "random seed: same seed, same image, whatever the pass split", minimum=0)
    cameras: tuple = _setting((), "cameras", "", "D-ToF camera configurations (dopplertof.Camera); none: intensity only")
    exposure: float | None = _setting(
        None, "float", "s", f"exposure T when no camera is given (default {DEFAULT_EXPOSURE_S})", follows="cameras", optional=True,
    )  # fmt: skip
    exposure_start: float = _setting(0.0, "float", "s", "scene time at which the exposure opens (of the cameras that give no exposure_start of their own)")
    max_depth: int = _setting(
        5, "int", "", "longest path, Mitsuba semantics (1 emitters only, 2 direct light, -1 unbounded)",
        rule=lambda depth: "must be >= 1 or -1 (unbounded)" if depth == 0 or depth < -1 else None,
    )  # fmt: skip
    rr_depth: int = _setting(5, "int", "", "depth at which Russian roulette starts", minimum=1)
    hide_emitters: bool = _setting(False, "bool", "", "hide directly visible emitters (as stock path)")
    time_sampling: str = _setting("antithetic", "str", "", "how path times are drawn", choices=METHODS + (ANALYTIC,))
    n_times: int | None = _setting(
        None, "int", "", "correlated times per group (default 1 for uniform with unpaired correlation, else 2)",
        minimum=1, follows="time_sampling", optional=True,
    )  # fmt: skip
    antithetic_shift: float | None = _setting(
        None, "float", "T", "antithetic shift a (default 0.5 for antithetic, 0 for antithetic_mirror)",
        follows="time_sampling", optional=True,
    )  # fmt: skip
    stratify_intervals: bool = _setting(True, "bool", "", "stratify each time interval over the pixel's groups, two groups per stratum")
    correlation: str = _setting("replay", "str", "", "how the paths of a group are correlated", choices=MODES)
    correlation_depth: int | None = _setting(
        None, "int", "", "replay cut-off: 0 none, 1 pixel, k: pixel + k-1 bounces (replay only; default: every bounce)",
        minimum=0, follows="correlation", optional=True,
    )  # fmt: skip
    reconnection_threshold: float | None = _setting(
        None, "float", "", "adaptive: reconnect where both surfaces are rougher than this GGX/Beckmann alpha (default 0.5)",
        minimum=0.0, follows="correlation", optional=True,
    )  # fmt: skip
    replicates: int = _setting(16, "int", "", "independent replicates per pixel that the standard errors are estimated from, where the times are not stratified (uniform, analytic, or stratify_intervals off; stratified times use their strata)", minimum=2)
    lanes_per_pass: int = _setting(DEFAULT_LANES_PER_PASS, "int", "lanes", "lanes per kernel launch: bounds the tracing memory whatever the film size", minimum=1024)

    # ------------------------------------------------------------------------------ build
    def __post_init__(self):
        for f in dataclasses.fields(self):
            object.__setattr__(self, f.name, _validated(f, getattr(self, f.name)))
        self._check_combination()

    @classmethod
    def build(cls, *layers: dict, where: str = "") -> "RenderSettings":
        """Settings from layers of given values (dicts of setting names), later ones winning.

        A layer that gives a setting drops the earlier layers' values of the settings that
        follow it (module docstring). Unknown names are a ValueError naming them.

        Parameters
        ----------
        *layers : dict
            Setting name → value, later layers winning.
        where : str, default ""
            Where the values come from (a file), named in errors.

        Returns
        -------
        RenderSettings

        Raises
        ------
        ValueError
            An unknown name, a value of the wrong type or out of range, or settings that
            contradict each other (naming the setting, after ``where``).
        """
        merged: dict = {}
        for layer in layers:
            unknown = [k for k in layer if k not in FIELDS]
            if unknown:
                raise _unknown(unknown[0], where)
            for name in layer:
                for dependent, f in FIELDS.items():
                    if f.metadata["follows"] == name and dependent not in layer:
                        merged.pop(dependent, None)
            merged.update(layer)
        try:
            return cls(**merged)
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}" if where else str(exc)) from None

    def replace(self, **changes) -> "RenderSettings":
        """A copy with ``changes`` applied as a new layer (dependent settings follow).

        Parameters
        ----------
        **changes
            Setting name → value.

        Returns
        -------
        RenderSettings

        Raises
        ------
        ValueError
            As for :meth:`build`.
        """
        given = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if getattr(self, f.name) != f.default}
        return RenderSettings.build(given, changes)

    def as_dict(self) -> dict:
        """JSON-friendly values (cameras as dicts).

        Returns
        -------
        dict
        """
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out["cameras"] = [c.as_dict() for c in self.cameras]
        return out

    # ------------------------------------------------------------------------------ derived
    @property
    def paired(self) -> bool:
        """Primal and partner traced in one lane (:mod:`dopplertof.tracing.paired`)."""
        return self.correlation in PAIRED or self.time_sampling == ANALYTIC

    @property
    def stratified(self) -> bool:
        """Times stratified over the pixel's groups (:func:`dopplertof.timesampling.stratifies`):
        the standard errors come from the strata, and ``replicates`` does not apply."""
        return stratifies(self.time_sampling, self.stratify_intervals)

    @property
    def wraps(self) -> tuple[float, ...]:
        """Where the stratified times wrap around the exposure's end: the strata are cut
        there (:func:`dopplertof.timesampling.wrap_points`)."""
        return wrap_points(self.time_sampling, self.group_size, self.shift)

    @property
    def group_size(self) -> int:
        """Correlated times per group (``n_times`` resolved)."""
        if self.n_times is not None:
            return self.n_times
        return 1 if self.time_sampling == "uniform" and self.correlation not in PAIRED else 2

    @property
    def shift(self) -> float:
        """The antithetic shift a in units of T, its default filled in: ``antithetic_shift``,
        else 0 for ``antithetic_mirror`` and 0.5 otherwise."""
        if self.antithetic_shift is not None:
            return self.antithetic_shift
        return 0.0 if self.time_sampling == "antithetic_mirror" else 0.5

    @property
    def threshold(self) -> float:
        """The GGX/Beckmann α above which ``adaptive`` reconnects: ``reconnection_threshold``,
        else 0.5."""
        return 0.5 if self.reconnection_threshold is None else self.reconnection_threshold

    @property
    def exposure_s(self) -> float:
        """The exposure T (s) of the reference window: the first camera's, else
        ``exposure``, else the default."""
        if self.cameras:
            return self.cameras[0].exposure
        return DEFAULT_EXPOSURE_S if self.exposure is None else self.exposure

    @property
    def windows(self) -> tuple["Window", ...]:
        """The capture schedule: the distinct exposure windows of the cameras, in the order
        of their first camera (the first is the *reference* window). A camera's window is
        (its ``exposure_start``, else this render's, its ``exposure``); without cameras,
        the one window (``exposure_start``, :attr:`exposure_s`)."""
        if not self.cameras:
            return (Window(self.exposure_start, self.exposure_s, (), ()),)
        members: dict = {}
        for index, camera in enumerate(self.cameras):
            members.setdefault(camera.window(self.exposure_start), []).append(index)
        return tuple(Window(start, length, tuple(self.cameras[i] for i in idx), tuple(idx)) for (start, length), idx in members.items())

    @property
    def scheduled_cameras(self) -> tuple[Camera, ...]:
        """The cameras with their window's start filled in (``exposure_start`` never None)."""
        return tuple(dataclasses.replace(c, exposure_start=c.window(self.exposure_start)[0]) for c in self.cameras)

    @property
    def correlation_spec(self) -> Correlation:
        """The path correlation as the tracer takes it: mode, replay depth and the
        reconnection threshold with their defaults filled in."""
        return Correlation(self.correlation, self.correlation_depth, self.threshold)

    def _check_combination(self):
        n = self.group_size
        if self.seed >= 1 << 32:
            raise ValueError(f"'seed' must be < 2**32, got {self.seed}")
        if self.time_sampling in ("antithetic_mirror", ANALYTIC) and n != 2:
            raise ValueError(f"{self.time_sampling} pairs exactly 2 times, got n_times={n}")
        if self.time_sampling == "antithetic" and n < 2:
            raise ValueError(f"antithetic needs n_times >= 2, got {n}")
        if not 0.0 <= self.shift <= 1.0:
            raise ValueError(f"'antithetic_shift' must be in [0, 1] (units of T), got {self.shift!r}")
        if self.antithetic_shift is not None and self.time_sampling not in ("antithetic", "antithetic_mirror"):
            raise ValueError(f"'antithetic_shift' applies to antithetic sampling, not {self.time_sampling}")
        if self.correlation_depth is not None and self.correlation != "replay":
            raise ValueError(f"'correlation_depth' applies to replay; {self.correlation!r} does not use it")
        if self.reconnection_threshold is not None and self.correlation != "adaptive":
            raise ValueError(f"'reconnection_threshold' applies to adaptive correlation, not {self.correlation!r}")
        if self.correlation in PAIRED and n != 2:
            raise ValueError(f"correlation={self.correlation!r} pairs two times (n_times=2), got n_times={n}")
        if self.spp % n:
            raise ValueError(f"spp={self.spp} must be a multiple of the {n} correlated times per group ({self.time_sampling}); "
                             "the spp is the render's (--spp, spp=), else the scene's <sampler> sample_count")
        groups = self.spp // n
        uncut = group_cuts(groups, self.wraps)[1]
        if self.stratified and groups >= 3 and uncut:
            warnings.warn(
                f"spp={self.spp} gives {groups} groups of {n} times: {self.time_sampling}'s times wrap around the exposure's end at "
                f"{', '.join(f'{w:g}' for w in uncut)} T, inside a stratum, so the standard errors at heterodyne cameras are less reliable "
                f"(an spp that puts those points between groups avoids it: for antithetic pairs at shift 0.5, a multiple of 4)", stacklevel=2,
            )  # fmt: skip
        if self.replicates != FIELDS["replicates"].default and self.stratified:
            warnings.warn(
                f"replicates={self.replicates} has no effect: time_sampling={self.time_sampling!r} with stratify_intervals stratifies the "
                f"times over the pixel's groups, two per stratum, and the standard errors come from the strata "
                f"(stratify_intervals=False for independent replicates)", stacklevel=2,
            )  # fmt: skip
        elif self.replicates != FIELDS["replicates"].default and self.replicates > groups:
            warnings.warn(
                f"replicates={self.replicates} exceeds the {groups} group(s) of correlated times per pixel (spp={self.spp} / n_times={n}): "
                f"the standard errors come from {groups} replicate(s){'' if groups >= 2 else ', so they are NaN'}", stacklevel=2,
            )  # fmt: skip
        if self.time_sampling == ANALYTIC:
            if self.correlation not in ("replay", "reconnection", "adaptive") or self.correlation_depth is not None:
                raise ValueError(f"analytic time integration needs a fully correlated partner (replay, reconnection or adaptive), got {self.correlation!r}")
            bad = [f"{c.label()} ({c.waveform}{'' if c.low_pass else ', full waveform'})" for c in self.cameras if not (c.low_pass and c.waveform == "sinusoidal")]
            if bad:
                raise ValueError(f"analytic time integration is implemented for the low-pass sinusoid only; cameras {', '.join(bad)} are not")
        # Cameras may differ in exposure: each (start, exposure) is a window of its own.
        exposures = sorted({c.exposure for c in self.cameras})
        if self.exposure is not None:
            checked_exposure("exposure", self.exposure)
            if exposures and exposures != [self.exposure]:
                raise ValueError(f"exposure={self.exposure!r} s differs from the cameras' exposure {', '.join(map(repr, exposures))} s")

    @staticmethod
    def table() -> list[tuple[str, str, str, str]]:
        """(name, unit, default, meaning) of every setting, for help texts and the docs.

        Returns
        -------
        list of tuple of (str, str, str, str)
        """
        return [(name, f.metadata["unit"], repr(f.default), f.metadata["doc"]) for name, f in FIELDS.items()]


FIELDS = {f.name: f for f in dataclasses.fields(RenderSettings)}


def _parameters_section() -> str:
    """The numpy-style parameter table of :class:`RenderSettings`, from the declarations."""
    lines = ["Parameters", "----------"]
    for name, unit, default, meaning in RenderSettings.table():
        meta = FIELDS[name].metadata
        kind = "sequence of dopplertof.Camera" if meta["kind"] == "cameras" else meta["kind"]
        choices = f" ({', '.join(meta['choices'])})" if meta["choices"] else ""
        bounds = [f">= {meta['minimum']}"] * (meta["minimum"] is not None) + [f"<= {meta['maximum']}"] * (meta["maximum"] is not None)
        limits = f" ({', '.join(bounds)})" if bounds else ""
        lines += [f"{name} : {kind}{', ' + unit if unit else ''}, default {default}", f"    {meaning}{choices}{limits}."]
    return "\n".join("    " + line for line in lines)


RenderSettings.__doc__ = f"""{RenderSettings.__doc__}

{_parameters_section()}

    Examples
    --------
    >>> import dopplertof as dt
    >>> settings = dt.RenderSettings.build({{"spp": 256, "correlation": "adaptive"}})
    >>> settings.spp, settings.time_sampling, settings.threshold
    (256, 'antithetic', 0.5)
    >>> dt.RenderSettings.build({{"spp": 0}})
    Traceback (most recent call last):
    ...
    ValueError: 'spp' must be >= 1, got 0
    """


@dataclass(frozen=True)
class Window:
    """One exposure window of a capture schedule (:attr:`RenderSettings.windows`): its
    cameras share paths, traced at times in [start_s, start_s + exposure_s].

    Parameters
    ----------
    start_s : float, s
        When the window opens.
    exposure_s : float, s
        Its length T.
    cameras : tuple of Camera
        Its cameras.
    indices : tuple of int
        Their positions in the render's ``cameras``.
    """

    start_s: float
    exposure_s: float
    cameras: tuple  # the window's cameras, in the render's order
    indices: tuple  # their positions in RenderSettings.cameras


def _validated(f, value):
    meta = f.metadata
    if value is None and meta["optional"]:
        return None
    if meta["kind"] == "cameras":
        cameras = tuple(value) if isinstance(value, (list, tuple)) else None
        if cameras is None or not all(isinstance(c, Camera) for c in cameras):
            raise ValueError(f"'cameras' must be a list of dopplertof.Camera, got {value!r}")
        return cameras
    value = checked(f.name, value, meta["kind"])
    if meta["choices"] and value not in meta["choices"]:
        raise ValueError(f"unknown {f.name} {value!r}; choose one of {', '.join(meta['choices'])}")
    if meta["minimum"] is not None and value < meta["minimum"]:
        raise ValueError(f"{f.name!r} must be >= {meta['minimum']}, got {value!r}")
    if meta["maximum"] is not None and value > meta["maximum"]:
        raise ValueError(f"{f.name}={value!r} exceeds its maximum {meta['maximum']}: {meta['beyond_maximum']}")
    broken = meta["rule"](value) if meta["rule"] is not None else None
    if broken:
        raise ValueError(f"{f.name!r} {broken}, got {value!r}")
    return value


def check_layer(layer: dict, where: str) -> None:
    """ValueError (prefixed with ``where``) for a value of a settings layer that no render
    could take (its kind, choices, range, rule), before the other layers meet it: what
    :meth:`RenderSettings.build` checks of each setting on its own, not their combination.

    Parameters
    ----------
    layer : dict
        Setting name → value (a scene's ``<integrator>``: :func:`integrator_layer`).
    where : str
        Named in the error.
    """
    for name, value in layer.items():
        if name in FIELDS:
            try:
                _validated(FIELDS[name], value)
            except ValueError as exc:
                raise ValueError(f"{where}: {exc}") from None


def checked_checkpoint_interval(value) -> float:
    """Seconds between a render's checkpoints, checked: a finite number >= 0, else ValueError.

    Not a :class:`RenderSettings` field: how often the sums are saved changes nothing in
    the result, so a render may be resumed with another interval.

    Parameters
    ----------
    value : float
        A checkpoint is written after the first pass that ends at least this long after
        the previous one (0: after every pass). Default
        :data:`DEFAULT_CHECKPOINT_INTERVAL_S` (60 s).

    Returns
    -------
    float
        Seconds.

    Raises
    ------
    ValueError
        Not a finite number >= 0.
    """
    seconds = checked("checkpoint_interval_s", value, "float")
    if seconds < 0:
        raise ValueError(f"'checkpoint_interval_s' must be >= 0 seconds, got {value!r}")
    return seconds


def _unknown(key: str, where: str, known=None) -> ValueError:
    known = sorted(known if known is not None else FIELDS)
    close = difflib.get_close_matches(key, known, n=1)
    hint = f"; did you mean {close[0]!r}?" if close else f"; known: {', '.join(known)}"
    return ValueError(f"{where + ': ' if where else ''}unknown setting {key!r}{hint}")


# ----------------------------------------------------------------------------------------
# The original code's integrator parameters (reference §8.2) -> a layer of settings

# Camera keys (modulation.ORIGINAL_CAMERA_KEYS) go through Camera.from_original;
# original key -> (type, our setting)
_ORIGINAL_KEYS = {
    "time_sampling_method": ("str", "time_sampling"),
    "antithetic_shift": ("float", "antithetic_shift"),
    "use_stratified_sampling_for_each_interval": ("bool", "stratify_intervals"),
    "path_correlation_depth": ("int", None),  # -> correlation (+ correlation_depth)
    "max_depth": ("int", "max_depth"),
    "rr_depth": ("int", "rr_depth"),
    "hide_emitters": ("bool", "hide_emitters"),
    "m_reconnection_threshold": ("float", "reconnection_threshold"),  # M06 (§8.1); the prefix is the original's
}
# SI camera names -> the original names they replace
_CAMERA_SI_KEYS = {
    "exposure": ("time", "w_s"), "modulation_frequency": ("w_g", "w_s"), "heterodyne": ("hetero_frequency", "w_s"),
    "phase": ("sensor_phase_offset", "hetero_offset"), "g1": ("g_1",), "g0": ("g_0",),
    "waveform": ("wave_function_type",), "low_pass": ("low_frequency_component_only",),
}  # fmt: skip
_CAMERA_SI_KINDS = {"waveform": "str", "low_pass": "bool"}
# Keys that change nothing here (the original's or Mitsuba's scheduling knobs).
_NO_EFFECT_KEYS = {"is_doppler_integrator": "bool", "samples_per_pass": "int", "block_size": "int", "timeout": "float"}
# Stock Mitsuba integrators that estimate the same radiance as our path tracer, and the
# keys of theirs we honour; any other stock integrator computes something else.
STOCK_PATH_INTEGRATORS = ("path", "volpath", "volpathmis", "prb", "prb_basic", "prbvolpath")
_GENERIC_KEYS = ("max_depth", "rr_depth", "hide_emitters")
# What a stock path tracer does with a key its file leaves out (Mitsuba 3.9's defaults: the
# C++ integrators' max_depth is unbounded, the Python prb family's 6), which a file naming
# that integrator asks for: not dopplertof's own defaults.
STOCK_PATH_DEFAULTS = {
    kind: {"max_depth": -1 if kind in ("path", "volpath", "volpathmis") else 6, "rr_depth": 5, "hide_emitters": False} for kind in STOCK_PATH_INTEGRATORS
}
STOCK_OTHER_INTEGRATORS = ("direct", "aov", "depth", "moment", "stokes", "ptracer", "direct_projective", "prb_projective", "adjoint")


def integrator_layer(params: dict, where: str = "integrator") -> dict:
    """A settings layer from a scene's ``<integrator>`` parameters (with ``"type"``).

    ``dopplertof``/``dopplertofpath`` take the original M3 names (reference §8.2) and the
    SI names (an SI name together with the original one it replaces is an error); the
    original names accepted are listed in docs/scene-format.md. A stock path-tracing integrator
    (:data:`STOCK_PATH_INTEGRATORS`) gives ``max_depth``, ``rr_depth`` and
    ``hide_emitters``, each Mitsuba's default where the file leaves it out
    (:data:`STOCK_PATH_DEFAULTS`: ``<integrator type="path"/>`` is unbounded, as in
    Mitsuba), and nothing else: Mitsuba's scheduling keys (``samples_per_pass``,
    ``block_size``, ``timeout``) change nothing, D-ToF keys on it are an error naming them.
    Any other integrator type is an error.

    Parameters
    ----------
    params : dict
        The ``<integrator>``'s parameters, with ``"type"``; values may be text.
    where : str, default ``"integrator"``
        Where they come from, named in errors.

    Returns
    -------
    dict
        A settings layer.

    Raises
    ------
    ValueError
        An unknown or contradictory key, a value that does not parse, or an integrator
        type other than D-ToF or stock path tracing.
    """
    params = dict(params)
    kind = params.pop("type", PLUGIN_NAMES[0])
    if kind not in PLUGIN_NAMES:
        if kind not in STOCK_PATH_INTEGRATORS:
            what = "a stock Mitsuba integrator that computes something other than path-traced radiance" if kind in STOCK_OTHER_INTEGRATORS else "an unknown integrator type"
            raise ValueError(
                f"{where}: <integrator type={kind!r}> is {what}; use type 'dopplertof' (or the original 'dopplertofpath') or one of {', '.join(STOCK_PATH_INTEGRATORS)}"
            )
        foreign = sorted(k for k in params if k not in _GENERIC_KEYS and k not in _NO_EFFECT_KEYS)
        if foreign:
            raise ValueError(f"{where}: <integrator type={kind!r}> does not take {', '.join(map(repr, foreign))}; D-ToF parameters belong to <integrator type=\"dopplertof\">")
        return {**STOCK_PATH_DEFAULTS[kind], **{k: checked(k, params[k], _ORIGINAL_KEYS[k][0], where) for k in _GENERIC_KEYS if k in params}}

    layer: dict = {}
    camera_params: dict = {}
    for key, value in params.items():
        if key in ORIGINAL_CAMERA_KEYS:
            camera_params[key] = checked(key, value, ORIGINAL_CAMERA_KEYS[key], where)
        elif key in _CAMERA_SI_KEYS:
            clash = [k for k in _CAMERA_SI_KEYS[key] if k in params]
            if clash:
                raise ValueError(f"{where}: give either {key!r} or {clash[0]!r}, not both")
        elif key in _ORIGINAL_KEYS:
            kind_, name = _ORIGINAL_KEYS[key]
            value = checked(key, value, kind_, where)
            if name is not None:
                if name != key and name in params:
                    raise ValueError(f"{where}: give either {name!r} or {key!r}, not both")
                layer[name] = value
        elif key in _NO_EFFECT_KEYS:
            checked(key, value, _NO_EFFECT_KEYS[key], where)
        elif key in FIELDS and key != "cameras":
            layer[key] = value
        else:
            raise _unknown(key, where, [*FIELDS, *ORIGINAL_CAMERA_KEYS, *_ORIGINAL_KEYS, *_CAMERA_SI_KEYS, *_NO_EFFECT_KEYS])
    if "path_correlation_depth" in params:
        if "correlation" in params or "correlation_depth" in params:
            raise ValueError(f"{where}: give either 'correlation'/'correlation_depth' or 'path_correlation_depth', not both")
        depth = checked("path_correlation_depth", params["path_correlation_depth"], "int", where)
        if depth < 0:
            raise ValueError(f"{where}: 'path_correlation_depth' must be >= 0, got {depth}")
        layer["correlation"] = {0: "none", 1: "pixel"}.get(depth, "replay")
        if depth >= 2:
            layer["correlation_depth"] = depth
    if "m_reconnection_threshold" in params and layer.get("correlation") != "adaptive":
        if layer["reconnection_threshold"] < 0:
            raise ValueError(f"{where}: 'm_reconnection_threshold' must be >= 0, got {layer['reconnection_threshold']!r}")
        layer.pop("reconnection_threshold")  # the M06 key travels with every mode; only adaptive uses it
    camera = Camera.from_original(camera_params, where)
    si = {k: checked(k, params[k], _CAMERA_SI_KINDS.get(k, "float"), where) for k in _CAMERA_SI_KEYS if k in params}
    try:
        layer["cameras"] = (dataclasses.replace(camera, **si),)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
    # Validate the file's own combination now; its spp comes from the sampler, later.
    RenderSettings.build(layer, {"spp": 2 * (layer.get("n_times") or 2)}, where=where)
    return layer


def float32_decimal(value) -> float:
    """The shortest decimal that rounds to the float32 ``value``, as a float.

    Mitsuba keeps shutter times in float32; read back as they are, a file's 0.0015 s
    would be 0.001500000013 s.

    Parameters
    ----------
    value : float

    Returns
    -------
    float
    """
    return float(str(np.float32(value)))


def scene_camera(layer: dict) -> Camera:
    """The camera a scene's settings layer (:func:`scene_layer`) implies: its first
    camera, else the default camera with the layer's exposure (the sensor's shutter).

    The base of the camera sets that ``animate`` and the experiments make when the caller
    gives none.

    Parameters
    ----------
    layer : dict
        A settings layer (:func:`scene_layer`).

    Returns
    -------
    Camera
    """
    if layer.get("cameras"):
        return layer["cameras"][0]
    return Camera() if layer.get("exposure") is None else Camera(exposure=layer["exposure"])


def shutter_interval(scene) -> tuple[float, float] | None:
    """(opening time, length) in s of the scene's sensor shutter, as written in the file
    (:func:`float32_decimal`); None where the sensor has none (zero length).

    Parameters
    ----------
    scene : DynamicScene

    Returns
    -------
    tuple of float, or None
    """
    from decimal import Decimal

    sensor = scene.sensor
    open_f32, length_f32 = np.float32(sensor.shutter_open()), np.float32(sensor.shutter_open_time())
    if not length_f32 > 0:
        return None
    # Mitsuba keeps the length as the float32 difference close - open (0.0025 - 0.001 is
    # 0.0014999999): the file's length is the difference of the decimals it wrote.
    open_s, close_s = float32_decimal(open_f32), float32_decimal(open_f32 + length_f32)
    return open_s, float(Decimal(repr(close_s)) - Decimal(repr(open_s)))


def scene_layer(scene, where: str | None = None) -> dict:
    """The settings a :class:`~dopplertof.scene.DynamicScene` asks for: its integrator's,
    its sampler's ``sample_count`` (spp) and ``seed``, and its sensor's shutter interval.

    A shutter interval (``shutter_open``, ``shutter_close``) is the exposure window: it
    sets ``exposure_start`` and T; an ``<integrator>`` exposure that contradicts it is an
    error.

    Parameters
    ----------
    scene : DynamicScene
    where : str or None, default None
        Where the scene comes from (its file), named in errors.

    Returns
    -------
    dict
        A settings layer.

    Raises
    ------
    ValueError
        An ``<integrator>`` that contradicts the shutter, or bad ``<integrator>``
        parameters (:func:`integrator_layer`).
    """
    where = where or f"{scene.source}"
    layer = integrator_layer(scene.integrator_params, f"{where}: <integrator>") if scene.integrator_params else {}
    if scene.spp_hint is not None:
        layer["spp"] = scene.spp_hint
    if scene.seed_hint is not None:
        layer["seed"] = scene.seed_hint
    if (shutter := shutter_interval(scene)) is not None:
        open_s, length_s = shutter
        cameras = layer.get("cameras", ())
        given_t = [k for k in ("time", "exposure") if k in scene.integrator_params]
        # Mitsuba keeps shutter times in float32: agreeing means agreeing to a few of its ulps.
        tolerance = 4.0 * float(np.spacing(np.float32(abs(open_s) + length_s)))
        if cameras and given_t and abs(cameras[0].exposure - length_s) > tolerance:
            raise ValueError(
                f"{where}: the sensor's shutter is open for {length_s!r} s but the <integrator> exposure "
                f"{given_t[0]!r} is {cameras[0].exposure!r} s; make them agree or remove one"
            )
        if cameras and not given_t:
            layer["cameras"] = tuple(dataclasses.replace(c, exposure=length_s) for c in cameras)
        elif not cameras:
            layer["exposure"] = length_s
        if "exposure_start" in scene.integrator_params and scene.integrator_params["exposure_start"] != open_s:
            raise ValueError(f"{where}: the sensor's shutter opens at {open_s!r} s but the <integrator> exposure_start is {scene.integrator_params['exposure_start']!r} s")
        layer["exposure_start"] = open_s
    return layer
