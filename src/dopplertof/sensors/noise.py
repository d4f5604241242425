"""The noise chain of a ToF pixel's taps, from photons to digital numbers (pure numpy).

:class:`Silicon` holds a pixel's physics; :func:`digitize` is the chain every tap goes
through (also :class:`dopplertof.sensor.SensorModel`'s):

1. photo-electrons: rendered radiance → photons on the pixel (camera equation:
   irradiance E = π L / (4 N²) for an f-number N, times the pixel area and fill factor, over
   the photon energy h c / λ) × the quantum efficiency at the source wavelength λ; the
   tap's share of them follows the demodulation contrast c(f) at the raw frame's
   modulation frequency (:mod:`dopplertof.sensors.frames`);
2. fixed pattern: each tap of each pixel has a gain (1 + δg) and an offset δo, drawn once
   per sensor from ``pattern_seed`` (``tap_gain_mismatch``, ``tap_offset_mismatch_e`` rms);
3. ambient light (photo-electrons per second on the pixel, unmodulated: each tap takes
   its mean share, (1 ± c s̄)/2 of a 2-tap pixel, (1 + c s̄)/4 of a 4-tap one, s̄ the
   demodulation's mean, 0 for the named waveforms) and dark current (electrons per second
   and tap) add to the mean;
4. Poisson shot noise on the tap's total (``shot_noise=False``: the mean);
5. full-well saturation: the charge is clipped at ``full_well_e``;
6. Gaussian read noise (``read_noise_e`` rms) and the offset mismatch;
7. ADC: DN = round(e⁻ / ``gain_e_per_dn`` + ``black_level_dn``), clipped to
   [0, 2^``adc_bits`` − 1].

Its variance, unsaturated: shot (mean e⁻) + read² + gain²/12 (quantisation), in e⁻²
(:meth:`Silicon.tap_variance_e2`).

Parameters of :class:`Silicon`:

===========================  ===================  ==========  ==========================================
name                         unit                 default     meaning
===========================  ===================  ==========  ==========================================
``pixel_pitch_m``            m                    10e-6       pixel side (its area collects light)
``fill_factor``              –                    1.0         light-collecting fraction of the area
``f_number``                 –                    1.0         the lens's N (camera equation)
``wavelength_m``             m                    850e-9      the source's wavelength λ
``radiance_unit``            W m⁻² sr⁻¹           1.0         radiance of one rendered unit at λ
``quantum_efficiency``       – or ((λ m, QE),…)   1.0         QE, or a table over λ (linear in λ)
``demodulation_contrast``    – or ((f Hz, c),…)   1.0         c, or a table over f (linear in f)
``ambient_e_per_s``          e⁻/s per pixel       0.0         ambient photo-electrons (after QE)
``dark_current_e_per_s``     e⁻/s per tap         0.0         dark current
``read_noise_e``             e⁻ rms               0.0         read noise per tap
``full_well_e``              e⁻                   1e5         tap capacity
``gain_e_per_dn``            e⁻/DN                None        inverse conversion gain; None: the
                                                              ADC spans the full well
                                                              (full_well_e / (2^bits − 1), set
                                                              at construction)
``adc_bits``                 bits                 16          ADC resolution
``black_level_dn``           DN                   0.0         ADC offset
``tap_gain_mismatch``        – rms                0.0         per-tap, per-pixel gain spread
``tap_offset_mismatch_e``    e⁻ rms               0.0         per-tap, per-pixel offset spread
``pattern_seed``             –                    0           seed of the fixed pattern
``shot_noise``               –                    True        draw Poisson shot noise
===========================  ===================  ==========  ==========================================

The defaults are an ideal pixel (no noise but the shot noise, no quantisation worth
noting); :mod:`dopplertof.sensors.presets` holds real ones.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass

import numpy as np

from ..validation import checked, checked_in_range

PLANCK_J_S = 6.626_070_15e-34
SPEED_OF_LIGHT_M_S = 299_792_458.0
MAX_ADC_BITS = 32


def digitize(expected_e, rng: np.random.Generator, *, full_well_e, read_noise_e, gain_e_per_dn, black_level_dn, max_dn, shot_noise=True, offset_e=0.0):
    """Steps 4–7 of the chain (module docstring) for taps with mean charge ``expected_e``.

    Parameters
    ----------
    expected_e : ndarray. Mean electrons per tap (≥ 0).
    rng : numpy.random.Generator. Draws the shot noise, then the read noise.
    full_well_e, read_noise_e, gain_e_per_dn, black_level_dn : float. As in :class:`Silicon`.
    max_dn : int. Largest ADC output.
    shot_noise : bool. Draw Poisson shot noise (else the mean).
    offset_e : float or ndarray. Offset added after the well (the taps' offset mismatch), e⁻.

    Returns
    -------
    ndarray of int64
        DN in [0, max_dn], the shape of ``expected_e``.

    Raises
    ------
    ValueError
        If ``expected_e`` is not finite.
    """
    expected_e = np.asarray(expected_e, dtype=np.float64)
    if not np.all(np.isfinite(expected_e)):
        raise ValueError("the expected tap charge must be finite electrons (NaN: a frame without samples)")
    if shot_noise:
        # Above a few full wells the draw saturates anyway; the cap keeps Poisson finite.
        cap = 4.0 * full_well_e + 1e3
        electrons = rng.poisson(np.minimum(expected_e, cap)).astype(np.float64)
    else:
        electrons = expected_e.copy()
    electrons = np.minimum(electrons, full_well_e)
    if read_noise_e > 0:
        electrons = electrons + rng.normal(0.0, read_noise_e, size=electrons.shape)
    dn = np.rint((electrons + offset_e) / gain_e_per_dn + black_level_dn)
    return np.clip(dn, 0, max_dn).astype(np.int64)


def _table(name, value, unit):
    """A scalar, or ((x, y), …) pairs sorted by x, as a validated tuple; None stays None."""
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        if not (math.isfinite(value) and 0 < value <= 1):
            raise ValueError(f"Silicon: {name!r} must be in (0, 1], got {value!r}")
        return float(value)
    try:
        pairs = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        pairs = None
    if pairs is None or pairs.ndim != 2 or pairs.shape[1] != 2 or pairs.shape[0] < 1:
        raise ValueError(f"Silicon: {name!r} must be a number in (0, 1] or a table of ({unit}, value) pairs, got {value!r}")
    if not np.all(np.isfinite(pairs)) or np.any(pairs[:, 1] <= 0) or np.any(pairs[:, 1] > 1) or np.any(pairs[:, 0] <= 0):
        raise ValueError(f"Silicon: {name!r} needs positive {unit} and values in (0, 1], got {value!r}")
    if np.any(np.diff(pairs[:, 0]) <= 0):
        raise ValueError(f"Silicon: {name!r} must list strictly increasing {unit}, got {value!r}")
    return tuple((float(x), float(y)) for x, y in pairs)


def _interpolate(name, table, x, unit):
    if isinstance(table, float):
        return table
    xs, ys = np.array(table).T
    if not xs[0] <= x <= xs[-1]:
        raise ValueError(f"{name} is tabulated for {xs[0]:g} to {xs[-1]:g} {unit}, not {x:g} {unit}")
    return float(np.interp(x, xs, ys))


@dataclass(frozen=True)
class Silicon:
    """The physics of a ToF pixel's taps (module docstring, parameter table).

    Raises
    ------
    ValueError
        On construction, naming the parameter and value, for anything out of range.
    """

    pixel_pitch_m: float = 10e-6
    fill_factor: float = 1.0
    f_number: float = 1.0
    wavelength_m: float = 850e-9
    radiance_unit: float = 1.0
    quantum_efficiency: float | tuple = 1.0
    demodulation_contrast: float | tuple = 1.0
    ambient_e_per_s: float = 0.0
    dark_current_e_per_s: float = 0.0
    read_noise_e: float = 0.0
    full_well_e: float = 1e5
    gain_e_per_dn: float | None = None
    adc_bits: int = 16
    black_level_dn: float = 0.0
    tap_gain_mismatch: float = 0.0
    tap_offset_mismatch_e: float = 0.0
    pattern_seed: int = 0
    shot_noise: bool = True

    def __post_init__(self):
        ranges = {
            "pixel_pitch_m": dict(above=0),
            "fill_factor": dict(above=0, at_most=1),
            "f_number": dict(above=0),
            "wavelength_m": dict(above=0, below=1e-3, unit="m"),
            "radiance_unit": dict(above=0),
            "ambient_e_per_s": dict(at_least=0),
            "dark_current_e_per_s": dict(at_least=0),
            "read_noise_e": dict(at_least=0),
            "full_well_e": dict(above=0),
            "tap_gain_mismatch": dict(at_least=0, below=0.5),
            "tap_offset_mismatch_e": dict(at_least=0),
        }
        for name, bounds in ranges.items():
            object.__setattr__(self, name, checked_in_range(name, getattr(self, name), where="Silicon", **bounds))
        object.__setattr__(self, "adc_bits", checked_in_range("adc_bits", self.adc_bits, at_least=1, at_most=MAX_ADC_BITS, kind="int", where="Silicon"))
        if self.gain_e_per_dn is None:
            object.__setattr__(self, "gain_e_per_dn", self.full_well_e / self.max_dn)
        object.__setattr__(self, "gain_e_per_dn", checked_in_range("gain_e_per_dn", self.gain_e_per_dn, above=0, where="Silicon"))
        object.__setattr__(self, "black_level_dn", checked_in_range("black_level_dn", self.black_level_dn, at_least=0, below=self.max_dn, where="Silicon"))
        object.__setattr__(self, "pattern_seed", checked_in_range("pattern_seed", self.pattern_seed, at_least=0, kind="int", where="Silicon"))
        object.__setattr__(self, "shot_noise", checked("shot_noise", self.shot_noise, "bool", "Silicon"))
        object.__setattr__(self, "quantum_efficiency", _table("quantum_efficiency", self.quantum_efficiency, "wavelength m"))
        object.__setattr__(self, "demodulation_contrast", _table("demodulation_contrast", self.demodulation_contrast, "frequency Hz"))
        self.qe  # a QE table must cover the source's wavelength

    @classmethod
    def with_electrons_per_unit_s(cls, electrons_per_unit_s: float, **parameters) -> "Silicon":
        """The silicon whose pixel turns one rendered unit of radiance into
        ``electrons_per_unit_s`` photo-electrons per second before the quantum efficiency:
        its ``radiance_unit`` solved from the camera equation (module docstring) and its
        optics. How a signal level given in electrons (``dopplertof.sensor.SensorModel``'s
        ``electrons_per_unit``, a dataset's ``sensor.signal_electrons``) becomes a silicon.

        Parameters
        ----------
        electrons_per_unit_s : float, e⁻ / (s · rendered radiance unit). > 0.
        **parameters
            Every other :class:`Silicon` parameter (not ``radiance_unit``), as in the
            constructor.

        Returns
        -------
        Silicon
            With :attr:`electrons_per_unit_s` = ``electrons_per_unit_s`` × :attr:`qe`
            (to rounding).

        Raises
        ------
        ValueError
            If ``electrons_per_unit_s`` is not a finite number > 0, ``radiance_unit`` is
            given, or a parameter is out of range.
        """
        target = checked_in_range("electrons_per_unit_s", electrons_per_unit_s, above=0, where="Silicon")
        if "radiance_unit" in parameters:
            raise ValueError("Silicon.with_electrons_per_unit_s: give electrons_per_unit_s or radiance_unit, not both")
        unit = cls(**parameters)
        per_radiance_unit = unit.electrons_per_unit_s / (unit.qe * unit.radiance_unit)
        return dataclasses.replace(unit, radiance_unit=target / per_radiance_unit)

    @property
    def max_dn(self) -> int:
        """Largest ADC output, 2^adc_bits − 1 (DN)."""
        return (1 << int(self.adc_bits)) - 1

    @property
    def qe(self) -> float:
        """Quantum efficiency at the source wavelength."""
        return _interpolate("Silicon: quantum_efficiency", self.quantum_efficiency, self.wavelength_m, "m")

    def contrast(self, modulation_frequency_hz: float) -> float:
        """Demodulation contrast at a modulation frequency (ValueError outside its table).

        Parameters
        ----------
        modulation_frequency_hz : float, Hz

        Returns
        -------
        float

        Raises
        ------
        ValueError
            A frequency outside the ``demodulation_contrast`` table.
        """
        return _interpolate("Silicon: demodulation_contrast", self.demodulation_contrast, modulation_frequency_hz, "Hz")

    @property
    def electrons_per_unit_s(self) -> float:
        """Photo-electrons per second on the pixel per unit of rendered radiance (QE applied)."""
        irradiance_w_m2 = math.pi * self.radiance_unit / (4.0 * self.f_number**2)
        power_w = irradiance_w_m2 * self.pixel_pitch_m**2 * self.fill_factor
        photon_j = PLANCK_J_S * SPEED_OF_LIGHT_M_S / self.wavelength_m
        return power_w / photon_j * self.qe

    def pattern(self, shape) -> tuple[np.ndarray, np.ndarray]:
        """The fixed pattern for taps of ``shape`` (taps, H, W): gain factors and offsets (e⁻).

        Parameters
        ----------
        shape : tuple of int
            (taps, H, W).

        Returns
        -------
        tuple of (ndarray, ndarray)
            Gain factors and offsets (e⁻), drawn from ``pattern_seed``.
        """
        if self.tap_gain_mismatch == 0 and self.tap_offset_mismatch_e == 0:
            return np.ones(shape), np.zeros(shape)
        rng = np.random.default_rng(self.pattern_seed)
        gain = 1.0 + self.tap_gain_mismatch * rng.standard_normal(shape)
        return gain, self.tap_offset_mismatch_e * rng.standard_normal(shape)

    def tap_variance_e2(self, mean_e) -> np.ndarray:
        """Variance of a tap (e⁻²) with mean charge ``mean_e`` below the full well: shot +
        read² + quantisation gain²/12 (the fixed pattern is not noise: it repeats).

        Parameters
        ----------
        mean_e : array_like, e⁻

        Returns
        -------
        ndarray
            e⁻².
        """
        mean_e = np.asarray(mean_e, dtype=np.float64)
        return (mean_e if self.shot_noise else np.zeros_like(mean_e)) + self.read_noise_e**2 + self.gain_e_per_dn**2 / 12.0

    def digitize(self, expected_e, rng, offset_e=0.0) -> np.ndarray:
        """:func:`digitize` with this silicon's well, read noise and ADC.

        Parameters
        ----------
        expected_e : array_like, e⁻
            Mean tap charges.
        rng : numpy.random.Generator
            Draws the shot noise, then the read noise.
        offset_e : float or ndarray, e⁻, default 0
            Offset added after the well (the taps' offset mismatch).

        Returns
        -------
        ndarray
            Digital numbers.

        Raises
        ------
        ValueError
            A charge that is not finite.
        """
        return digitize(
            expected_e, rng, full_well_e=self.full_well_e, read_noise_e=self.read_noise_e, gain_e_per_dn=self.gain_e_per_dn,
            black_level_dn=self.black_level_dn, max_dn=self.max_dn, shot_noise=self.shot_noise, offset_e=offset_e,
        )  # fmt: skip
