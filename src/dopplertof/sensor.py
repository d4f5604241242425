"""Physically based noise for D-ToF measurements, applied to the raw taps (pure numpy).

:class:`SensorModel` is the older post-process model of one rendered camera read by a
2-tap pixel, kept for the scripts written against it. It is an alias onto
:class:`dopplertof.sensors.Silicon` (the one home of a pixel's physics and noise chain):
its parameters become a ``Silicon`` (:attr:`SensorModel.silicon`, table below), its taps
are :func:`dopplertof.sensors.frames.tap_electrons` with demodulation contrast 1, and they
go through ``Silicon.digitize``. New code should use :class:`dopplertof.Sensor` (raw
frames, 1/2/4 taps, contrast, dark current, tap mismatch, presets).

A differential 2-tap pixel steers the photo-electrons generated during the exposure into
tap A with weight (1 + s(t))/2 and into tap B with weight (1 − s(t))/2, s being the
sensor modulation. With κ = ``electrons_per_unit × quantum_efficiency`` photo-electrons per
second per unit of rendered radiance, the expected tap charges are

    N_A = κ T (g0 I + m)/2 + q T,     N_B = κ T (g0 I − m)/2 + q T,

where I is the standard intensity (luminance) image, g0 I the time-averaged incident
radiance, m the rendered D-ToF measurement (the exposure average of the correlation with s)
and q the ambient (plus dark-current) electrons per second and tap. So
(N_A − N_B)/(κ T) = m and N_A + N_B = κ T g0 I + 2 q T: the ambient light cancels in the
difference but adds shot noise.

Noise chain per tap (EMVA-1288 style):

1. Poisson shot noise on the tap's total electrons (``shot_noise=False`` uses the mean);
2. full-well saturation: the collected charge is clipped at ``full_well_e``;
3. Gaussian read noise, σ = ``read_noise_e`` electrons;
4. ADC: DN = round(electrons / ``gain_e_per_dn`` + ``black_level_dn``), clipped to
   [0, 2^``adc_bits`` − 1].

:meth:`SensorModel.taps_to_measurement` inverts the chain back to measurement units,
m̂ = (DN_A − DN_B) · gain / (κ T); the black level and the ambient light cancel. Feed m̂ to
:mod:`dopplertof.reconstruct` to see how noise propagates into velocity.

Parameters of :class:`SensorModel`:

===========================  ======================  ========  =================================
name                         unit                    default   meaning
===========================  ======================  ========  =================================
``electrons_per_unit``       e⁻ / (s · radiance)     required  photo-electrons per second per unit
                                                               of rendered radiance reaching the
                                                               pixel (light power, optics, fill
                                                               factor): sets the signal level
``quantum_efficiency``       –                       1.0       multiplies ``electrons_per_unit``
``ambient_electrons_per_s``  e⁻ / s per tap          0.0       ambient light and dark current
``read_noise_e``             e⁻ rms                  3.0       Gaussian read noise per tap
``full_well_e``              e⁻                      20000     tap charge capacity
``adc_bits``                 bits                    12        ADC resolution
``gain_e_per_dn``            e⁻ / DN                 5.0       conversion gain (5 e⁻/DN puts the
                                                               default full well at 4000 DN)
``black_level_dn``           DN                      0.0       ADC offset; > 0 keeps read noise
                                                               on dark taps from clipping at 0
``shot_noise``               –                       True      draw Poisson shot noise
===========================  ======================  ========  =================================

The camera configuration supplies the exposure T (``exposure``, s) and the light's DC
offset g0 (``g0``, default 0.5). A signal charge below zero (possible only when a noisy
render has |m| > g0 I) is clipped to zero before the ambient charge is added, as
:class:`dopplertof.Sensor` does.

How the parameters map onto :class:`~dopplertof.sensors.Silicon`
(``Silicon.with_electrons_per_unit_s``): ``electrons_per_unit`` → the silicon's radiance
scale (its ``electrons_per_unit_s`` is ``electrons_per_unit × quantum_efficiency``),
``quantum_efficiency`` → ``quantum_efficiency``, ``ambient_electrons_per_s`` (per tap) →
``ambient_e_per_s`` = 2 × it (per pixel: each of the two taps takes half), and
``read_noise_e``, ``full_well_e``, ``adc_bits``, ``gain_e_per_dn``, ``black_level_dn``,
``shot_noise`` → the same names; demodulation contrast 1, no dark current, no tap
mismatch. Out-of-range values are refused by ``Silicon`` with its message (naming the
parameter and value); ``electrons_per_unit`` and ``ambient_electrons_per_s`` by this class.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .sensors.frames import tap_electrons
from .sensors.noise import Silicon
from .validation import checked_in_range

LUMINANCE_WEIGHTS_REC709 = (0.2126, 0.7152, 0.0722)
"""Rec. 709 / sRGB weights of R, G, B in the luminance, as used by the original scripts."""


def luminance(rgb) -> np.ndarray:
    """Luminance Y = 0.2126 R + 0.7152 G + 0.0722 B of a linear RGB image.

    Parameters
    ----------
    rgb : array_like, shape (..., 3)
        Linear RGB values; the last axis holds the channels.

    Returns
    -------
    ndarray, shape (...)
        Luminance, in the units of the input.

    Raises
    ------
    ValueError
        If the last axis does not have length 3.
    """
    rgb = np.asarray(rgb, dtype=np.float64)
    if rgb.ndim == 0 or rgb.shape[-1] != 3:
        raise ValueError(f"rgb must have shape (..., 3), got shape {rgb.shape}")
    return rgb @ np.asarray(LUMINANCE_WEIGHTS_REC709)


def _exposure_s(camera) -> float:
    exposure = float(getattr(camera, "exposure", np.nan))
    if not (np.isfinite(exposure) and exposure > 0):
        raise ValueError(f"camera exposure must be a finite number > 0 s, got {exposure!r}")
    return exposure


def _light_offset(camera) -> float:
    g0 = float(getattr(camera, "g0", 0.5))
    if not (np.isfinite(g0) and g0 >= 0):
        raise ValueError(f"camera g0 must be a finite number >= 0, got {g0!r}")
    return g0


def _as_generator(rng) -> np.random.Generator:
    if isinstance(rng, np.random.Generator):
        return rng
    return np.random.default_rng(rng)


@dataclass(frozen=True)
class SensorModel:
    """Differential 2-tap ToF pixel: expected taps, noise, saturation and ADC; an alias onto
    :class:`dopplertof.sensors.Silicon` (module docstring: the model, the parameter table
    and how it maps).

    Parameters
    ----------
    electrons_per_unit : float, e⁻ / (s · radiance). Required, > 0.
    quantum_efficiency : float. In (0, 1]; default 1.0.
    ambient_electrons_per_s : float, e⁻/s per tap. >= 0; default 0.0.
    read_noise_e : float, e⁻ rms. Default 3.0.
    full_well_e : float, e⁻. Default 20000.
    adc_bits : int. Default 12.
    gain_e_per_dn : float, e⁻/DN. Default 5.0.
    black_level_dn : float, DN. Default 0.0.
    shot_noise : bool. Default True.

    Attributes
    ----------
    silicon : :class:`~dopplertof.sensors.Silicon`. The same pixel as a ``Silicon``.

    Raises
    ------
    ValueError
        On construction, naming the parameter and value, if a value is out of range
        (negative noise, non-positive full well or gain, quantum efficiency outside (0, 1],
        ...).
    """

    electrons_per_unit: float
    quantum_efficiency: float = 1.0
    ambient_electrons_per_s: float = 0.0
    read_noise_e: float = 3.0
    full_well_e: float = 20_000.0
    adc_bits: int = 12
    gain_e_per_dn: float = 5.0
    black_level_dn: float = 0.0
    shot_noise: bool = True

    def __post_init__(self):
        checked_in_range("electrons_per_unit", self.electrons_per_unit, above=0, where="SensorModel")
        ambient = checked_in_range("ambient_electrons_per_s", self.ambient_electrons_per_s, at_least=0, where="SensorModel")
        silicon = Silicon.with_electrons_per_unit_s(
            self.electrons_per_unit, quantum_efficiency=self.quantum_efficiency, ambient_e_per_s=2.0 * ambient,
            read_noise_e=self.read_noise_e, full_well_e=self.full_well_e, adc_bits=self.adc_bits, gain_e_per_dn=self.gain_e_per_dn,
            black_level_dn=self.black_level_dn, shot_noise=self.shot_noise,
        )  # fmt: skip
        # not a dataclass field: dataclasses.asdict(model) stays the old parameter set
        object.__setattr__(self, "silicon", silicon)

    @property
    def max_dn(self) -> int:
        """Largest ADC output, 2^adc_bits − 1 (DN)."""
        return self.silicon.max_dn

    def electrons_per_unit_exposure(self, camera) -> float:
        """κ T: photo-electrons per unit of rendered radiance over one exposure (e⁻).

        Parameters
        ----------
        camera : camera configuration. Supplies ``exposure`` (s).

        Returns
        -------
        float
            ``silicon.electrons_per_unit_s × exposure`` = electrons_per_unit × QE × T.
        """
        return self.silicon.electrons_per_unit_s * _exposure_s(camera)

    def expected_taps(self, intensity, measurement, camera) -> tuple[np.ndarray, np.ndarray]:
        """Mean tap charges, no noise.

        Parameters
        ----------
        intensity : array_like, shape (...)
            Standard intensity (luminance) image, rendered radiance units.
        measurement : array_like, broadcastable with ``intensity``
            Rendered D-ToF measurement of ``camera`` (radiance units × g1/2).
        camera : camera configuration
            Supplies ``exposure`` (s) and ``g0``.

        Returns
        -------
        tap_a_e, tap_b_e : ndarray, broadcast shape
            Expected electrons in taps A and B: max(κT(g0 I ± m)/2, 0) + q T.

        Raises
        ------
        ValueError
            If the camera's exposure is not > 0 or its g0 not >= 0.
        """
        intensity = np.asarray(intensity, dtype=np.float64)
        measurement = np.asarray(measurement, dtype=np.float64)
        light = _light_offset(camera) * intensity
        signal = tap_electrons(self.electrons_per_unit_exposure(camera), light, measurement, taps=2)
        # unmodulated light splits evenly between two counter-phase taps of a zero-mean s
        ambient_e = 0.5 * self.silicon.ambient_e_per_s * _exposure_s(camera)
        tap_a, tap_b = (np.maximum(tap, 0.0) + ambient_e for tap in signal)
        return tap_a, tap_b

    def sample_taps(self, intensity, measurement, camera, rng=None):
        """Noisy, saturated, quantised tap values.

        Parameters
        ----------
        intensity, measurement, camera
            As in :meth:`expected_taps`.
        rng : numpy.random.Generator or int or None
            Random generator, or a seed for ``numpy.random.default_rng``.

        Returns
        -------
        tap_a_dn, tap_b_dn : ndarray of int64, broadcast shape
            ADC outputs in [0, 2^adc_bits − 1] (DN).
        """
        rng = _as_generator(rng)
        tap_a_e, tap_b_e = self.expected_taps(intensity, measurement, camera)
        return self.silicon.digitize(tap_a_e, rng), self.silicon.digitize(tap_b_e, rng)

    def taps_to_measurement(self, tap_a_dn, tap_b_dn, camera) -> np.ndarray:
        """Measurement from the taps, m̂ = (DN_A − DN_B) · gain / (κ T).

        Black level and ambient light cancel in the difference, so nothing is subtracted.
        Without noise the error is at most one LSB of the difference, gain/(κ T)
        (half an LSB per tap).

        Parameters
        ----------
        tap_a_dn, tap_b_dn : array_like
            Tap values (DN).
        camera : camera configuration
            Supplies ``exposure`` (s).

        Returns
        -------
        ndarray
            Measurement in rendered units (radiance × g1/2), float64.
        """
        difference_dn = np.asarray(tap_a_dn, dtype=np.float64) - np.asarray(tap_b_dn, np.float64)
        return difference_dn * self.silicon.gain_e_per_dn / self.electrons_per_unit_exposure(camera)

    def measurement_std(self, intensity, measurement, camera) -> np.ndarray:
        """Theoretical standard deviation of :meth:`taps_to_measurement` of noisy taps.

        Shot noise of both taps (their sum, κT g0 I + 2qT), read noise of both taps and the
        uniform quantisation noise (gain²/12 per tap); saturation and clipping ignored.

        Parameters
        ----------
        intensity : array_like
            The intensity (rendered radiance units) of the pixels.
        measurement : array_like
            Their D-ToF measurement (same units), broadcast with ``intensity``.
        camera : Camera
            Its exposure T and g₀.

        Returns
        -------
        ndarray, broadcast shape
            Standard deviation in measurement units.
        """
        tap_a_e, tap_b_e = self.expected_taps(intensity, measurement, camera)
        variance_e = self.silicon.tap_variance_e2(tap_a_e) + self.silicon.tap_variance_e2(tap_b_e)
        return np.sqrt(variance_e) / self.electrons_per_unit_exposure(camera)

    def noisy_measurements(self, intensity, measurements, cameras: Sequence, seed=None):
        """The full chain for every camera: taps, noise, ADC, back to measurements.

        Parameters
        ----------
        intensity : array_like, shape (...)
            Standard intensity (luminance) image (see :func:`luminance`), shared by all
            cameras.
        measurements : array_like, shape (n_cameras, ...)
            Rendered measurements, one image per camera.
        cameras : sequence of n_cameras camera configurations
        seed : int or numpy.random.SeedSequence or None
            Each camera gets an independent stream spawned from it; the same seed gives
            the same output.

        Returns
        -------
        ndarray, shape (n_cameras, ...)
            Noisy measurements in rendered units.

        Raises
        ------
        ValueError
            If the number of measurement images differs from the number of cameras.
        """
        cameras = list(cameras)
        measurements = np.asarray(measurements, dtype=np.float64)
        if measurements.ndim == 0 or measurements.shape[0] != len(cameras):
            raise ValueError(
                f"measurements must have shape (n_cameras, ...) with n_cameras = "
                f"{len(cameras)}, got shape {measurements.shape}"
            )
        seed_sequence = seed if isinstance(seed, np.random.SeedSequence) else (
            np.random.SeedSequence(seed)
        )
        streams = [np.random.default_rng(s) for s in seed_sequence.spawn(len(cameras))]
        noisy = [
            self.taps_to_measurement(*self.sample_taps(intensity, m, camera, rng), camera)
            for m, camera, rng in zip(measurements, cameras, streams)
        ]
        return np.stack(noisy)
