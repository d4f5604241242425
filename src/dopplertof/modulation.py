"""Camera configurations and the modulation weight W(t, L) of a D-ToF measurement.

A D-ToF pixel is the exposure average (1/T)∫ W(t, L) f dt of the path throughput f
weighted by the product of the sensor and light modulations (DESIGN §3.7). With
``u = t/T`` the normalised time and ``k = 2π f_g / c`` (rad per metre of optical path):

* low-pass (default): ``W = (g1/2) · Λ(2π h u + ψ + k L)``
* full waveform:     ``W = s(ω_s t + ψ) · [g1 · g(ω_g t − k L) + g0]``, ω_s = ω_g + 2π h/T

Codes as data (:mod:`dopplertof.codes`): a camera given ``light_code`` and ``sensor_code``
(sampled chips or Fourier coefficients) has ``waveform="code"``; its low-pass weight is
``W = g1 · C(Δ) + g0 · s̄`` with C the exact cross-correlation of the two codes, Δ the phase
above and s̄ the sensor code's mean (zero for the named waveforms, whose C is Λ/2), and its
full weight is the product above with s and g the codes. ``light_bandwidth`` (Hz) removes
the light code's harmonics above it (an ideal low-pass source: a finite rise time).

Every phase is computed in Float64 and wrapped with a floor-based modulo, so negative
phases (negative ``h`` or ``ψ``, early times in full-waveform mode) are right.

Waveforms (θ wrapped to [0, 2π), c = min(θ/π, 2 − θ/π) ∈ [0, 1]):

===============  ==========================  =================================
name             s(θ) = g(θ), full waveform  Λ(θ), low-pass
===============  ==========================  =================================
sinusoidal       cos θ                       cos θ
rectangular      sign(cos θ) = ±1            2 − 4c
triangular       1 − 2c                      (2/3)(4c³ − 6c² + 1)
trapezoidal      sensor sign(cos θ), light   clamp(4 − 8c, −2, 2)
                 4·[c < 1/4] (mean 1)
===============  ==========================  =================================
"""

from __future__ import annotations

import difflib
import math
import warnings
from dataclasses import dataclass
from functools import cached_property

from . import codes as _codes
from .validation import parse_bool

import numpy as np

SPEED_OF_LIGHT_M_S = 299_792_458.0
TWO_PI = 2.0 * math.pi
WAVEFORMS = ("sinusoidal", "rectangular", "triangular", "trapezoidal")
CODE_WAVEFORM = "code"  # the waveform of a camera given light_code and sensor_code
# Beyond these the Float64 phase arithmetic loses the path length (k·L at 1 THz and 1 km is
# 2e7 rad, still resolving 1e-8 rad); no D-ToF sensor comes near them.
MAX_MODULATION_FREQUENCY_HZ = 1e12
MAX_HETERODYNE = 1e9
# Below this the modulation wavelength c/f_g exceeds 3 km and a scene's phase hardly
# changes: no D-ToF sensor modulates so slowly, so it warns (MHz given as Hz, say).
SUSPICIOUS_MODULATION_FREQUENCY_HZ = 1e5
# D-ToF exposures are microseconds to milliseconds. Longer than a minute is a unit mistake
# (the time grid, 2^-23 T, would be coarser than 7 µs), and a T of 1e300 s overflows the
# scene times t = start + u T.
MAX_EXPOSURE_S = 60.0
# Longer than this a D-ToF exposure is likely milliseconds given as seconds; it warns.
SUSPICIOUS_EXPOSURE_S = 0.1
# A phase beyond two turns is likely degrees given as radians (90 for pi/2); it warns.
SUSPICIOUS_PHASE_RAD = 4.0 * math.pi


def checked_exposure(name: str, value_s: float, where: str = "") -> float:
    """``value_s`` if it is an exposure T in (0, :data:`MAX_EXPOSURE_S`] seconds, else
    ValueError naming ``name`` (and ``where``) and the value."""
    from .validation import checked

    value_s = checked(name, value_s, "float", where)
    if not 0.0 < value_s <= MAX_EXPOSURE_S:
        prefix = f"{where}: " if where else ""
        raise ValueError(f"{prefix}{name!r} must be in (0, {MAX_EXPOSURE_S:g}] s, got {value_s!r}")
    return value_s


@dataclass(frozen=True)
class Camera:
    """One D-ToF camera configuration (SI units).

    Parameters
    ----------
    modulation_frequency : float, Hz. Light modulation f_g, in (0, 1e12]; below 100 kHz
        (a wavelength over 3 km) it warns. Default 30 MHz.
    exposure : float, s. Exposure T, in (0, 60] s (:data:`MAX_EXPOSURE_S`). Default 1.5 ms.
    heterodyne : float. h, beat cycles per exposure (0 homodyne, 1 "perfect" heterodyne).
        Default 1: a camera given no h is heterodyne (``h=0`` for a homodyne one).
    phase : float, rad. Sensor phase offset ψ. Default 0.
    waveform : str. One of ``sinusoidal``, ``rectangular``, ``triangular``, ``trapezoidal``.
        Default ``sinusoidal``.
    g1, g0 : float. Light modulation amplitude (> 0; >= 0 with codes) and DC offset (>= 0; g0 enters
        full-waveform only, and, for codes, the low-pass weight as g0 s̄). Default 0.5 each.
    low_pass : bool. Low-pass (correlation) model if True, else the full waveform product.
        Default True.
    light_code, sensor_code : array_like or :class:`dopplertof.codes.Code`, optional.
        One period of the light modulation g and of the sensor demodulation s as sampled
        chips (1-D, N >= 8 samples, binary or not) or Fourier coefficients
        (:func:`dopplertof.codes.fourier`); both or neither. With them ``waveform`` is
        ``"code"`` (module docstring).
    light_bandwidth : float or None, Hz. The source's modulation bandwidth, harmonics of
        the light code above it removed; for codes and for the rectangular and trapezoidal
        waveforms, which it turns into their exact chip codes
        (:func:`dopplertof.codes.named`; ``waveform`` keeps its name). None: unlimited.
    exposure_start : float or None, s of scene time. When this configuration's exposure
        opens; None: the render's ``exposure_start``. Its window is
        [exposure_start, exposure_start + exposure]: configurations with the same window
        share paths, each other window is traced with its own (a capture schedule, such as
        four phase images one after another; docs/reconstruction.md, "Capture schedules").

    Examples
    --------
    >>> import math, dopplertof as dt
    >>> camera = dt.Camera(heterodyne=1.0, phase=math.pi / 2)   # 30 MHz, T = 1.5 ms
    >>> camera.label(), round(camera.beat_frequency, 1)          # h / T in Hz
    ('h=1,psi=1.5708', 666.7)
    """

    modulation_frequency: float = 30e6
    exposure: float = 1.5e-3
    heterodyne: float = 1.0
    phase: float = 0.0
    waveform: str = "sinusoidal"
    g1: float = 0.5
    g0: float = 0.5
    low_pass: bool = True
    exposure_start: float | None = None
    light_code: _codes.Code | None = None
    sensor_code: _codes.Code | None = None
    light_bandwidth: float | None = None

    def __post_init__(self):
        from .validation import checked

        self._check_codes()
        for name in ("modulation_frequency", "exposure", "heterodyne", "phase", "g1", "g0"):
            object.__setattr__(self, name, checked(name, getattr(self, name), "float", "Camera"))
        if self.exposure_start is not None:
            object.__setattr__(self, "exposure_start", checked("exposure_start", self.exposure_start, "float", "Camera"))
        object.__setattr__(self, "waveform", checked("waveform", self.waveform, "str", "Camera"))
        object.__setattr__(self, "low_pass", checked("low_pass", self.low_pass, "bool", "Camera"))
        if not 0 < self.modulation_frequency <= MAX_MODULATION_FREQUENCY_HZ:
            raise ValueError(f"Camera: modulation_frequency must be in (0, {MAX_MODULATION_FREQUENCY_HZ:g}] Hz, got {self.modulation_frequency!r}")
        if abs(self.heterodyne) > MAX_HETERODYNE:
            raise ValueError(f"Camera: |heterodyne| must be <= {MAX_HETERODYNE:g} beat cycles per exposure, got {self.heterodyne!r}")
        if self.modulation_frequency < SUSPICIOUS_MODULATION_FREQUENCY_HZ:
            warnings.warn(
                f"Camera: modulation_frequency={self.modulation_frequency:g} Hz, a wavelength of {SPEED_OF_LIGHT_M_S / self.modulation_frequency:.3g} m; "
                "the unit is Hz (30 MHz is 30e6)", stacklevel=3,
            )  # fmt: skip
        checked_exposure("exposure", self.exposure, "Camera")
        if self.exposure > SUSPICIOUS_EXPOSURE_S:
            warnings.warn(f"Camera: exposure={self.exposure:g} s; the unit is s (1.5 ms is 1.5e-3)", stacklevel=3)
        if abs(self.phase) > SUSPICIOUS_PHASE_RAD:
            warnings.warn(f"Camera: phase={self.phase:g} rad, more than two turns; the unit is rad (90 degrees is pi/2 = 1.5708)", stacklevel=3)
        # A coded camera's light may be pure DC (g1 = 0, the code's mean through g0): the
        # sensor model's mean-light frames are such cameras.
        if self.g1 < 0 or (self.g1 == 0 and not self.coded):
            bound = ">= 0 with codes" if self.coded else "> 0"
            raise ValueError(f"Camera: 'g1' (light modulation amplitude) must be {bound}, got {self.g1!r}")
        if self.g0 < 0:
            raise ValueError(f"Camera: 'g0' (light DC offset) must be >= 0, got {self.g0!r}")
        if self.waveform not in WAVEFORMS and not (self.waveform == CODE_WAVEFORM and self.coded):
            hint = " (give light_code and sensor_code)" if self.waveform == CODE_WAVEFORM else ""
            raise ValueError(f"Camera: unknown waveform {self.waveform!r}; choose one of {', '.join(WAVEFORMS)}{hint}")
        if self.light_bandwidth is not None:
            object.__setattr__(self, "light_bandwidth", checked("light_bandwidth", self.light_bandwidth, "float", "Camera"))
            if not self.coded:
                raise ValueError(
                    f"Camera: light_bandwidth applies to cameras with light_code and sensor_code and to the {' and '.join(_codes.NAMED_CODES)} "
                    f"waveforms, not the {self.waveform} one"
                )  # fmt: skip
            if self.light_bandwidth < self.modulation_frequency:
                raise ValueError(f"Camera: light_bandwidth={self.light_bandwidth!r} Hz is below the modulation frequency {self.modulation_frequency!r} Hz: no modulation reaches the scene")
            if self.light_bandwidth // self.modulation_frequency > _codes.MAX_HARMONICS:
                raise ValueError(f"Camera: light_bandwidth={self.light_bandwidth!r} Hz passes more than {_codes.MAX_HARMONICS} harmonics; leave it None (unlimited)")

    def _check_codes(self):
        given = [n for n in ("light_code", "sensor_code") if getattr(self, n) is not None]
        band_limited_named = self.light_bandwidth is not None and self.waveform in _codes.NAMED_CODES
        if not given:
            if band_limited_named:  # a named waveform through a source of finite bandwidth: its exact chips, band-limited
                light, sensor = _codes.named(self.waveform)
                object.__setattr__(self, "light_code", light)
                object.__setattr__(self, "sensor_code", sensor)
            return
        if len(given) == 1:
            raise ValueError(f"Camera: give both light_code and sensor_code, or neither (got only {given[0]})")
        for name in given:
            object.__setattr__(self, name, _codes.as_code(getattr(self, name), name))
        if band_limited_named and (self.light_code, self.sensor_code) == _codes.named(self.waveform):
            return  # the codes it was given above (as_dict of such a camera)
        if self.waveform not in ("sinusoidal", CODE_WAVEFORM):  # "sinusoidal" is the default
            raise ValueError(f"Camera: waveform={self.waveform!r} and light_code/sensor_code exclude each other")
        object.__setattr__(self, "waveform", CODE_WAVEFORM)

    def as_dict(self) -> dict:
        """The parameters of a :class:`Camera` (a :class:`~dopplertof.RawFrame`'s too),
        JSON-friendly; ``Camera(**camera.as_dict())`` is the same camera.

        Returns
        -------
        dict
        """
        from dataclasses import fields

        out = {f.name: getattr(self, f.name) for f in fields(Camera)}
        for name in ("light_code", "sensor_code"):
            if out[name] is not None:
                out[name] = out[name].as_dict()
        return out

    @property
    def coded(self) -> bool:
        """Whether the modulation is given as codes (``light_code``, ``sensor_code``)."""
        return self.light_code is not None

    @property
    def light_mean(self) -> float:
        """ḡ, the light waveform's mean over a period (1 for the trapezoid's pulse, 0 for
        the other named waveforms)."""
        if self.coded:
            return self.light.mean
        return 1.0 if self.waveform == "trapezoidal" else 0.0

    @property
    def sensor_mean(self) -> float:
        """s̄, the demodulation's mean over a period (0 for every named waveform)."""
        return self.sensor_code.mean if self.coded else 0.0

    @cached_property
    def light(self) -> _codes.Code:
        """The light code as it leaves the source (``light_bandwidth`` applied)."""
        if self.light_bandwidth is None:
            return self.light_code
        return _codes.band_limited(self.light_code, int(self.light_bandwidth // self.modulation_frequency))

    @cached_property
    def correlation(self) -> _codes.PeriodicFunction:
        """C(Δ) of a coded camera's sensor and (band-limited) light codes."""
        return _codes.correlation(self.sensor_code, self.light)

    @property
    def wavenumber(self) -> float:
        """k = 2π f_g / c, rad per metre of optical path."""
        return TWO_PI * self.modulation_frequency / SPEED_OF_LIGHT_M_S

    @property
    def beat_frequency(self) -> float:
        """Sensor minus light modulation frequency, h / T (Hz)."""
        return self.heterodyne / self.exposure

    def label(self) -> str:
        """Short text naming this camera in file names and tables, e.g. ``h=1,psi=1.5708``
        (with ``,start=…`` in s when it has an ``exposure_start``).

        Returns
        -------
        str
        """
        start = "" if self.exposure_start is None else f",start={self.exposure_start:g}"
        return f"h={self.heterodyne:g},psi={self.phase:g}{start}"

    def window(self, default_start_s: float = 0.0) -> tuple[float, float]:
        """(start, length) of its exposure window (s); ``default_start_s`` where
        ``exposure_start`` is None (a render's: its ``exposure_start``).

        Parameters
        ----------
        default_start_s : float, s, default 0
            The start where ``exposure_start`` is None.

        Returns
        -------
        tuple of (float, float)
            Seconds.
        """
        start = default_start_s if self.exposure_start is None else self.exposure_start
        return float(start), self.exposure

    @classmethod
    def from_original(cls, params: dict, where: str = "integrator") -> "Camera":
        """A Camera from the original code's parameter names (MHz frequencies).

        Accepts ``time``, ``w_g`` (MHz), ``w_s`` (MHz), ``g_1``, ``g_0``, ``hetero_frequency``,
        ``hetero_offset`` (fraction of 2π, overrides ``sensor_phase_offset``),
        ``sensor_phase_offset`` (rad), ``wave_function_type``,
        ``low_frequency_component_only`` (:data:`ORIGINAL_CAMERA_KEYS`); any other key is a
        ValueError naming it (a misspelt ``hetero_frequency`` gave a homodyne camera). Values may be
        given as text (as in a scene file), parsed strictly: a boolean is ``true``/``false``
        (``yes``/``no``, ``1``/``0``, ``on``/``off``), anything else is a ValueError naming
        the key.

        Parameters
        ----------
        params : dict
            The original parameter names and values.
        where : str, default ``"integrator"``
            Where the values come from, named in errors (a file's element).

        Returns
        -------
        Camera

        Raises
        ------
        ValueError
            A value that does not parse or is out of range, naming the key.
        """
        from .validation import checked_or_text

        unknown = sorted(set(params) - set(ORIGINAL_CAMERA_KEYS))
        if unknown:
            named = [f"{k!r}" + "".join(f" (did you mean {c!r}?)" for c in difflib.get_close_matches(k, ORIGINAL_CAMERA_KEYS, n=1)) for k in unknown]
            raise ValueError(f"{where}: unknown camera key{'s' if len(unknown) > 1 else ''} {', '.join(named)}; the keys are {', '.join(ORIGINAL_CAMERA_KEYS)}")

        def get(key, kind, default):
            return checked_or_text(key, params.get(key, default), kind, where)

        exposure = get("time", "float", 1.5e-3)
        f_g = get("w_g", "float", 30.0) * 1e6
        if "hetero_frequency" in params:
            h = get("hetero_frequency", "float", None)
        else:  # the original's w_s, converted without float32 cancellation
            h = (get("w_s", "float", get("w_g", "float", 30.0)) * 1e6 - f_g) * exposure
        if "hetero_offset" in params:
            psi = TWO_PI * get("hetero_offset", "float", None)
        else:
            psi = get("sensor_phase_offset", "float", 0.0)
        values = dict(
            modulation_frequency=f_g,
            exposure=exposure,
            heterodyne=h,
            phase=psi,
            waveform=get("wave_function_type", "str", "sinusoidal"),
            g1=get("g_1", "float", 0.5),
            g0=get("g_0", "float", 0.5),
            low_pass=get("low_frequency_component_only", "bool", True),
        )
        try:
            return cls(**values)
        except ValueError as exc:
            unit = " (w_g and w_s are in MHz: w_g=30 is 30 MHz)" if "modulation_frequency" in str(exc) and "w_g" in params else ""
            raise ValueError(f"{where}: {exc}{unit}") from None


# The original code's camera parameters and their kinds (:meth:`Camera.from_original`).
ORIGINAL_CAMERA_KEYS = {
    "time": "float", "w_g": "float", "w_s": "float", "hetero_frequency": "float", "sensor_phase_offset": "float",
    "hetero_offset": "float", "g_1": "float", "g_0": "float", "wave_function_type": "str",
    "low_frequency_component_only": "bool",
}  # fmt: skip


# ----------------------------------------------------------------------------------------
# Cameras from text (command line)

_CAMERA_KEYS = {
    "h": "heterodyne",
    "heterodyne": "heterodyne",
    "psi": "phase",
    "phase": "phase",
    "f": "modulation_frequency",
    "frequency": "modulation_frequency",
    "T": "exposure",
    "exposure": "exposure",
    "waveform": "waveform",
    "g1": "g1",
    "g0": "g0",
    "low_pass": "low_pass",
    "start": "exposure_start",
    "exposure_start": "exposure_start",
}


def parse_camera(text: str, exposure: float | None = None) -> Camera:
    """A :class:`Camera` from ``"h=1,psi=0,f=30e6,waveform=sinusoidal"``.

    ``psi`` accepts radians or degrees with a ``deg`` suffix (``psi=90deg``); ``f`` is Hz;
    ``T`` and ``start`` (its ``exposure_start``: when its window opens) are seconds.
    """
    kwargs: dict = {}
    items = [p.strip() for p in text.split(",")]
    if not any(items):
        raise ValueError(f"camera {text!r}: empty; give key=value pairs such as 'h=1,psi=90deg'")
    for item in filter(None, items):
        if "=" not in item:
            raise ValueError(f"camera {text!r}: expected key=value, got {item!r}")
        key, value = (s.strip() for s in item.split("=", 1))
        if key not in _CAMERA_KEYS:
            raise ValueError(f"camera {text!r}: unknown key {key!r}; use {', '.join(sorted(set(_CAMERA_KEYS)))}")
        name = _CAMERA_KEYS[key]
        if name in kwargs:
            raise ValueError(f"camera {text!r}: {key!r} given twice")
        if name == "waveform":
            kwargs[name] = value
        elif name == "low_pass":
            kwargs[name] = parse_bool(value, f"camera {text!r}: 'low_pass'")
        else:
            try:
                kwargs[name] = math.radians(float(value[:-3])) if name == "phase" and value.endswith("deg") else float(value)
            except ValueError:
                raise ValueError(f"camera {text!r}: {key}={value!r} is not a number") from None
    if exposure is not None:
        kwargs.setdefault("exposure", exposure)
    try:
        return Camera(**kwargs)
    except ValueError as exc:
        raise ValueError(f"camera {text!r}: {exc}") from None



# ----------------------------------------------------------------------------------------
# Waveforms, generic over numpy and Dr.Jit arrays


def _ops(x):
    """(floor, minimum, maximum, cos, select) for numpy or Dr.Jit arrays."""
    if isinstance(x, np.ndarray) or np.isscalar(x):
        return np.floor, np.minimum, np.maximum, np.cos, np.where
    import drjit as dr

    return dr.floor, dr.minimum, dr.maximum, dr.cos, dr.select


def wrap_phase(theta):
    """θ − 2π⌊θ/2π⌋ ∈ [0, 2π) (floor-based; correct for negative θ)."""
    floor = _ops(theta)[0]
    return theta - TWO_PI * floor(theta * (1.0 / TWO_PI))


def _distance_to_peak(theta):
    """c = min(a, 2 − a), a = wrapped θ/π: normalised distance to the nearest 2πk."""
    minimum = _ops(theta)[1]
    a = wrap_phase(theta) * (1.0 / math.pi)
    return minimum(a, 2.0 - a)


def lowpass_waveform(theta, waveform: str):
    """Λ(θ): the correlation of sensor and light waveforms (table in module docstring)."""
    floor, minimum, maximum, cos, select = _ops(theta)
    if waveform == "sinusoidal":
        return cos(wrap_phase(theta))
    c = _distance_to_peak(theta)
    if waveform == "rectangular":
        return 2.0 - 4.0 * c
    if waveform == "triangular":
        return (2.0 / 3.0) * (4.0 * c * c * c - 6.0 * c * c + 1.0)
    if waveform == "trapezoidal":
        return minimum(maximum(4.0 - 8.0 * c, -2.0), 2.0)
    raise ValueError(f"unknown waveform {waveform!r}; choose one of {', '.join(WAVEFORMS)}")


def sensor_waveform(theta, waveform: str):
    """Sensor modulation s(θ) for full-waveform mode (zero mean over a period)."""
    floor, minimum, maximum, cos, select = _ops(theta)
    if waveform == "sinusoidal":
        return cos(wrap_phase(theta))
    c = _distance_to_peak(theta)
    if waveform in ("rectangular", "trapezoidal"):
        return select(c < 0.5, 1.0, -1.0) + 0.0 * c
    if waveform == "triangular":
        return 1.0 - 2.0 * c
    raise ValueError(f"unknown waveform {waveform!r}; choose one of {', '.join(WAVEFORMS)}")


def light_waveform(theta, waveform: str):
    """Light modulation g(θ) for full-waveform mode.

    Equal to :func:`sensor_waveform` except ``trapezoidal``: a pulse of amplitude 4 and a
    quarter-period width (mean 1), whose correlation with the square sensor is the
    trapezoid clamp(2 − 4c, −1, 1) of the low-pass model.
    """
    if waveform == "trapezoidal":
        floor, minimum, maximum, cos, select = _ops(theta)
        c = _distance_to_peak(theta)
        return select(c < 0.25, 4.0, 0.0) + 0.0 * c
    return sensor_waveform(theta, waveform)


def lowpass_phase(camera: Camera, u, path_length_m):
    """Phase (rad) of the low-pass weight: 2π h u + ψ + k L. Float64 in, Float64 out."""
    return TWO_PI * camera.heterodyne * u + camera.phase + camera.wavenumber * path_length_m


def weight(camera: Camera, u, path_length_m):
    """W(t, L) at normalised time ``u = t/T`` and optical path length ``L`` (m).

    ``u`` and ``path_length_m`` should be Float64 (Dr.Jit or numpy); the result has the
    same type. See :func:`full_weight` for ``low_pass=False``.
    """
    if camera.low_pass:
        return lowpass_weight(camera, lowpass_phase(camera, u, path_length_m))
    return full_weight(camera, u, path_length_m)


def lowpass_weight(camera: Camera, phase):
    """The low-pass weight at slow phase Δ = 2π h u + ψ + k L (rad): (g1/2)Λ(Δ), or
    g1 C(Δ) + g0 s̄ for a coded camera (numpy or Dr.Jit Float64)."""
    if camera.coded:
        return camera.g1 * camera.correlation(phase) + camera.g0 * camera.sensor_mean
    return (0.5 * camera.g1) * lowpass_waveform(phase, camera.waveform)


def full_weight(camera: Camera, u, path_length_m):
    """Full-waveform weight s(ω_s t + ψ) · [g1 g(ω_g t − k L) + g0].

    The carrier phase ω_g t = 2π f_g T u is reduced modulo 2π in Float64 before it is
    combined (f_g T u reaches ~5e4 cycles at 30 MHz and 1.5 ms).
    """
    cycles = camera.modulation_frequency * camera.exposure * u
    floor = _ops(cycles)[0]
    carrier = TWO_PI * (cycles - floor(cycles))  # ω_g t mod 2π
    if getattr(camera, "coded", False):
        sensor = camera.sensor_code(carrier + TWO_PI * camera.heterodyne * u + camera.phase)
        light = camera.light(carrier - camera.wavenumber * path_length_m)
        return sensor * (camera.g1 * light + camera.g0)
    sensor = sensor_waveform(carrier + TWO_PI * camera.heterodyne * u + camera.phase, camera.waveform)
    light = light_waveform(carrier - camera.wavenumber * path_length_m, camera.waveform)
    return sensor * (camera.g1 * light + camera.g0)


# ----------------------------------------------------------------------------------------
# Per-lane evaluation for the integrator (Dr.Jit)


class OpaqueCamera:
    """A camera whose numeric parameters are opaque Dr.Jit Float64 scalars (no recompiles)."""

    def __init__(self, camera: Camera):
        import drjit as dr
        import mitsuba as mi

        def opaque(v):
            a = mi.Float64(float(v))
            dr.make_opaque(a)
            return a

        self.waveform = camera.waveform
        self.low_pass = camera.low_pass
        for name in ("heterodyne", "phase", "wavenumber", "g1", "g0", "modulation_frequency", "exposure"):
            setattr(self, name, opaque(getattr(camera, name)))


class CameraBank:
    """W(u, L) of several cameras for lanes whose normalised time ``u`` is fixed.

    A path contributes several times (every NEE and emitter hit) at one time ``u``, so the
    time part of each low-pass phase, 2π h u + ψ, is wrapped once per lane here. For the
    sinusoid the contribution then needs cos(a + kL) = cos a cos kL − sin a sin kL: one
    Float64 ``sincos(kL)`` per contribution shared by every camera with the same
    modulation frequency, plus two multiply-adds per camera. All phase arithmetic stays
    in Float64 (DESIGN §3.5).
    """

    def __init__(self, cameras, u):
        import drjit as dr

        self.size = len(cameras)
        self._terms = []
        wavenumbers = {}  # host k (rad/m) -> opaque Float64, shared by cameras
        for camera in cameras:
            cam = OpaqueCamera(camera)
            k_key = camera.wavenumber
            cam.wavenumber = wavenumbers.setdefault(k_key, cam.wavenumber)
            if camera.coded and not camera.low_pass:
                cycles = cam.modulation_frequency * cam.exposure * u
                carrier = TWO_PI * (cycles - dr.floor(cycles))  # ω_g t mod 2π, as full_weight
                sensor = camera.sensor_code.periodic()
                light = camera.light.periodic()
                sensor_w = sensor.drjit(carrier + TWO_PI * cam.heterodyne * u + cam.phase, sensor.opaque())
                self._terms.append(("code_full", cam, carrier, sensor_w, light, light.opaque()))
                continue
            if not camera.low_pass:
                self._terms.append(("full", cam, u))
                continue
            time_phase = wrap_phase(TWO_PI * cam.heterodyne * u + cam.phase)
            amplitude = 0.5 * cam.g1
            if camera.coded:
                corr = camera.correlation
                offset = cam.g0 * camera.sensor_mean
                if corr.harmonics is not None:  # e^{iΔ} = e^{i(2πhu + ψ)} e^{ikL}: the second shared
                    sin_a, cos_a = dr.sincos(time_phase)
                    self._terms.append(("code_harmonics", k_key, cam, corr, corr.opaque(), cos_a, sin_a, offset))
                else:
                    self._terms.append(("code_table", cam, corr, corr.opaque(), time_phase, offset))
            elif camera.waveform == "sinusoidal":
                sin_a, cos_a = dr.sincos(time_phase)
                self._terms.append(("sin", k_key, cam.wavenumber, amplitude * cos_a, amplitude * sin_a))
            else:
                self._terms.append(("lowpass", cam, time_phase, amplitude))

    def weights(self, path_length_m):
        """Float32 weights W (one per camera) for Float64 optical path lengths (m)."""
        import drjit as dr
        import mitsuba as mi

        trig = {}

        def sincos_kl(k_key, k):
            if k_key not in trig:
                trig[k_key] = dr.sincos(k * path_length_m)
            return trig[k_key]

        out = []
        for term in self._terms:
            kind = term[0]
            if kind == "sin":
                _, k_key, k, c, s = term
                sin_kl, cos_kl = sincos_kl(k_key, k)
                w = c * cos_kl - s * sin_kl
            elif kind == "code_harmonics":
                _, k_key, cam, corr, constants, cos_a, sin_a, offset = term
                sin_kl, cos_kl = sincos_kl(k_key, cam.wavenumber)
                z = (cos_a * cos_kl - sin_a * sin_kl, sin_a * cos_kl + cos_a * sin_kl)
                w = cam.g1 * corr.drjit(None, constants, z) + offset
            elif kind == "code_table":
                _, cam, corr, constants, time_phase, offset = term
                w = cam.g1 * corr.drjit(time_phase + cam.wavenumber * path_length_m, constants) + offset
            elif kind == "code_full":
                _, cam, carrier, sensor_w, light, constants = term
                w = sensor_w * (cam.g1 * light.drjit(carrier - cam.wavenumber * path_length_m, constants) + cam.g0)
            elif kind == "lowpass":
                _, cam, time_phase, amplitude = term
                w = amplitude * lowpass_waveform(time_phase + cam.wavenumber * path_length_m, cam.waveform)
            else:
                _, cam, u = term
                w = full_weight(cam, u, path_length_m)
            out.append(mi.Float(w))
        return out


def analytic_integral(cam: OpaqueCamera, length1_m, length2_m, x1, x2):
    """(g₁/2)∫₀¹ cos(a u + b)(x1 + (x2 − x1)u) du, a = 2πh + k(L2 − L1), b = ψ + kL1 (Float64).

    The low-pass sinusoid weight integrated over the exposure for a contribution X and a
    path length L linear in time between their values at the start (1) and end (2): the
    original's analytic mode, with ψ (which the original omits).
    """
    import drjit as dr

    a = TWO_PI * cam.heterodyne + cam.wavenumber * (length2_m - length1_m)
    b = wrap_phase(cam.phase + cam.wavenumber * length1_m)
    sin_b, cos_b = dr.sincos(b)
    sin_ab, cos_ab = dr.sincos(a + b)
    small = dr.abs(a) < 1e-4
    a_safe = dr.select(small, 1.0, a)
    constant = dr.select(small, cos_b - 0.5 * a * sin_b, (sin_ab - sin_b) / a_safe)  # ∫cos
    linear = dr.select(small, 0.5 * cos_b - a * sin_b / 3.0, sin_ab / a_safe + (cos_ab - cos_b) / dr.square(a_safe))  # ∫u cos
    return 0.5 * cam.g1 * (x1 * constant + (x2 - x1) * linear)
