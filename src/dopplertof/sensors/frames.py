"""A ToF sensor as a list of raw frames read through a pixel of 1, 2 or 4 taps.

A :class:`RawFrame` is one exposure of the chip: a :class:`~dopplertof.Camera` (its
modulation frequency, heterodyne offset, phase, codes, integration time and start) whose
heterodyne offset may also be given in Hz. A :class:`Sensor` holds the ordered frames, the
tap layout and the :class:`~dopplertof.sensors.noise.Silicon`.

Taps. The photo-charge of a pixel is steered into its taps by the demodulation s (the
frame's sensor waveform or code, |s| ≤ 1) with the demodulation contrast c = c(f) of the
silicon at the frame's frequency:

=====  ==========================================  ===========================================
taps   share of the charge                         raw electrons (noiseless)
=====  ==========================================  ===========================================
1      A: (1 + c s)/2 (the rest drained)           A = κT (D + c M)/2
2      A: (1 + c s)/2, B: (1 − c s)/2 (counter-     A, B = κT (D ± c M)/2
       phase)
4      tap j: (1 + c s(θ + jπ/2))/4, j = 0 … 3      A_j = κT (D + c M_j)/4
=====  ==========================================  ===========================================

with κ the silicon's photo-electrons per second per unit of rendered radiance
(:attr:`~dopplertof.sensors.noise.Silicon.electrons_per_unit_s`, QE included), T the frame's
exposure, M the frame's rendered measurement (the exposure average of s times the light),
M_j that of the frame with its phase advanced by jπ/2, and D the exposure average of the
light reaching the pixel: (g1 ḡ + g0) Ī, with ḡ the light waveform's mean and Ī the
luminance averaged over the frame's window. So A + B = κT D (the frame's exposure-weighted
intensity in electrons) and A − B = c κT M. A 4-tap layout needs a demodulation without
harmonics at multiples of 4 (the four shares sum to 1): refused otherwise.

Rendering (:func:`dopplertof.render` with ``sensor=``): :meth:`Sensor.cameras` are the
frames (and, for 4 taps, their three phase-shifted copies) plus one camera per exposure
window that measures Ī (constant weight 1); cameras of one window share paths, so one
render gives every frame. The result's ``raw`` (frames, taps, H, W) holds the noiseless
signal electrons; :meth:`Sensor.read_out` adds ambient light, dark current, the fixed
pattern, shot and read noise, the full well and the ADC
(:mod:`dopplertof.sensors.noise`), for every frame at once.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..codes import fourier
from ..modulation import Camera
from ..validation import checked, checked_in_range
from .noise import Silicon

TAP_LAYOUTS = (1, 2, 4)
READOUT_MODES = ("raw", "A-B", "A+B", "A", "B")
_CONSTANT = fourier([1.0, 0.0])


@dataclass(frozen=True)
class RawFrame(Camera):
    """One raw frame of a sensor: a :class:`~dopplertof.Camera` (same parameters, same
    defaults) whose heterodyne offset is given as ``heterodyne`` (h, beat cycles per
    exposure) or ``heterodyne_hz`` (Hz, h = ``heterodyne_hz`` × ``exposure``), default 0
    (homodyne).

    Parameters
    ----------
    heterodyne : float or None. h; None: from ``heterodyne_hz``, else 0.
    heterodyne_hz : float or None, Hz. The sensor-minus-light frequency offset.
    modulation_frequency, exposure, phase, waveform, g1, g0, low_pass, exposure_start, light_code, sensor_code, light_bandwidth
        As :class:`~dopplertof.Camera`'s: same units (Hz, s, rad) and defaults.

    Examples
    --------
    >>> import dopplertof as dt
    >>> frame = dt.RawFrame(modulation_frequency=30e6, exposure=1.5e-3, heterodyne_hz=667.0)
    >>> round(frame.heterodyne, 4)                          # h = 667 Hz × 1.5 ms
    1.0005
    """

    heterodyne: float | None = None
    heterodyne_hz: float | None = None

    def __post_init__(self):
        if self.heterodyne_hz is not None:
            hz = checked("heterodyne_hz", self.heterodyne_hz, "float", "RawFrame")
            exposure = checked("exposure", self.exposure, "float", "RawFrame")
            h = hz * exposure
            # dataclasses.replace passes both back: consistent values are the same frame
            if self.heterodyne is not None and not math.isclose(checked("heterodyne", self.heterodyne, "float", "RawFrame"), h, rel_tol=1e-12, abs_tol=1e-15):
                raise ValueError(f"RawFrame: give heterodyne (h={self.heterodyne!r}) or heterodyne_hz ({hz!r} Hz), not both")
            object.__setattr__(self, "heterodyne", h)
            object.__setattr__(self, "heterodyne_hz", hz)
        elif self.heterodyne is None:
            object.__setattr__(self, "heterodyne", 0.0)
        super().__post_init__()

    def label(self) -> str:
        """Short text naming this frame: its modulation frequency (Hz), then the
        :meth:`Camera.label <dopplertof.Camera.label>`.

        Returns
        -------
        str
        """
        return f"f={self.modulation_frequency:g},{super().label()}"


def tap_electrons(kappa_t, light, signal, taps: int) -> list:
    """Noiseless signal charge of each tap (the module docstring's table), unclipped.

    Parameters
    ----------
    kappa_t : float, e⁻ per rendered unit. κT: the silicon's photo-electrons per second per
        unit of radiance times the frame's exposure.
    light : ndarray. D, the exposure average of the light reaching the pixel (rendered units).
    signal : ndarray, or (4 taps) a sequence of the four ndarrays. c M (c M_j): the frame's
        measurement(s) times the demodulation contrast.
    taps : int. 1, 2 or 4.

    Returns
    -------
    list of ndarray
        One charge array (e⁻) per tap: κT(D ± cM)/2, or κT(D + cM_j)/4 for 4 taps.
    """
    if taps == 4:
        return [0.25 * kappa_t * (light + s) for s in signal]
    tap_a = 0.5 * kappa_t * (light + signal)
    return [tap_a] if taps == 1 else [tap_a, 0.5 * kappa_t * (light - signal)]


def mean_light_camera(start_s, exposure_s) -> Camera:
    """The camera that measures a window's mean luminance Ī (constant weight 1).

    Parameters
    ----------
    start_s : float, s
        When the window opens.
    exposure_s : float, s
        Its length.

    Returns
    -------
    Camera
    """
    return Camera(exposure=exposure_s, exposure_start=start_s, heterodyne=0.0, g1=0.0, g0=1.0, light_code=_CONSTANT, sensor_code=_CONSTANT)


def _sensor_range(frame: Camera) -> tuple[float, float]:
    return frame.sensor_code.extremes() if frame.coded else (-1.0, 1.0)  # every named sensor waveform spans [-1, 1]


@dataclass(frozen=True)
class Sensor:
    """A ToF sensor: an ordered list of raw frames, a tap layout and its silicon.

    Parameters
    ----------
    frames : sequence of :class:`RawFrame` (or :class:`~dopplertof.Camera`), at least one.
    taps : int. 1, 2 (counter-phase A/B) or 4 taps per pixel. Default 2.
    noise : :class:`~dopplertof.sensors.noise.Silicon`. The pixel's physics; default an
        ideal pixel (``Silicon()``).
    name : str. What it is (a preset's name), for metadata. Default ``"custom"``.
    limits : :class:`~dopplertof.sensors.presets.Limits` or None. What the chip's timing
        can capture (a preset's); None: anything.

    Raises
    ------
    ValueError
        Naming the frame, for what ``limits`` refuse, a demodulation outside [−1, 1], a
        4-tap layout whose shares do not sum to 1, or a frequency outside the silicon's
        contrast table.

    Examples
    --------
    >>> import dopplertof as dt
    >>> sensor = dt.sensors.preset("dtof-prototype")       # 4 frames read by 2 taps
    >>> result = dt.render(dt.scenes.cornell_box(resolution=16), sensor=sensor, spp=8, max_depth=2)
    >>> result.raw.shape                                    # (frames, taps, H, W), electrons
    (4, 2, 16, 16)
    >>> sensor.read_out(result, seed=1, mode="A-B").shape   # digital numbers
    (4, 16, 16)
    """

    frames: tuple
    taps: int = 2
    noise: Silicon = dataclasses.field(default_factory=Silicon)
    name: str = "custom"
    limits: object = None

    def __post_init__(self):
        frames = tuple(self.frames) if isinstance(self.frames, (list, tuple)) else None
        if not frames or not all(isinstance(f, Camera) for f in frames):
            raise ValueError(f"Sensor: 'frames' must be a non-empty list of dopplertof.RawFrame, got {self.frames!r}")
        object.__setattr__(self, "frames", frames)
        taps = checked("taps", self.taps, "int", "Sensor")
        if taps not in TAP_LAYOUTS:
            raise ValueError(f"Sensor: 'taps' must be one of {', '.join(map(str, TAP_LAYOUTS))}, got {self.taps!r}")
        object.__setattr__(self, "taps", taps)
        if not isinstance(self.noise, Silicon):
            raise ValueError(f"Sensor: 'noise' must be a dopplertof.sensors.Silicon, got {self.noise!r}")
        object.__setattr__(self, "name", checked("name", self.name, "str", "Sensor"))
        if self.limits is not None:
            self.limits.check(frames)
        for index, frame in enumerate(frames):
            low, high = _sensor_range(frame)
            if low < -1.0 - 1e-12 or high > 1.0 + 1e-12:
                raise ValueError(f"Sensor: frame {index} ({frame.label()}): its demodulation spans [{low:g}, {high:g}]; a tap pixel steers charge with s in [-1, 1]")
            if taps == 4 and frame.coded and frame.sensor_code.shifted_sum(4) > 1e-9:
                raise ValueError(f"Sensor: frame {index} ({frame.label()}): a 4-tap pixel needs a demodulation without mean or harmonics at multiples of 4 (its four shares must sum to 1)")
            try:
                self.noise.contrast(frame.modulation_frequency)
            except ValueError as exc:
                raise ValueError(f"Sensor: frame {index} ({frame.label()}): {exc}") from None

    # ------------------------------------------------------------------ rendering
    def cameras(self) -> list[Camera]:
        """What a render traces: every frame (and its 4-tap phase shifts), then one
        constant-weight camera per exposure window (the window's mean luminance).

        Returns
        -------
        list of Camera
        """
        out = list(self.frames)
        if self.taps == 4:
            out += [dataclasses.replace(f, phase=f.phase + j * math.pi / 2) for j in (1, 2, 3) for f in self.frames]
        for start, exposure in self._windows():
            out.append(mean_light_camera(start, exposure))
        return out

    @property
    def frame_cameras(self) -> int:
        """How many of :meth:`cameras` are frames (and 4-tap phase copies): the rest
        measure the windows' mean luminance."""
        return len(self.frames) * (4 if self.taps == 4 else 1)

    def _windows(self) -> list[tuple]:
        """Distinct (exposure_start, exposure) of the frames, in order (None: the render's start)."""
        return list(dict.fromkeys((f.exposure_start, f.exposure) for f in self.frames))

    def raw(self, measurements, clip: bool = True) -> np.ndarray:
        """Noiseless signal electrons (frames, taps, H, W) from the measurements of
        :meth:`cameras` (a render's ``measurements``, in that order; module docstring).

        ``clip=False``: the linear map itself, in float64 and unclipped (applied to the
        derivatives of the measurements it gives the electrons' derivatives).

        Parameters
        ----------
        measurements : array_like
            (len(cameras()), H, W), as above.
        clip : bool, default True
            Clip the electrons at zero.

        Returns
        -------
        ndarray
            (frames, taps, H, W), e⁻.

        Raises
        ------
        ValueError
            ``measurements`` of another shape.
        """
        # clipped electrons are float32: computing them so halves the memory traffic
        m = np.asarray(measurements, dtype=np.float32 if clip else np.float64)
        n_frames, windows = len(self.frames), self._windows()
        expected = self.frame_cameras + len(windows)
        if m.ndim < 1 or m.shape[0] != expected:
            raise ValueError(f"Sensor.raw: expected the {expected} measurements of Sensor.cameras(), got shape {m.shape}")
        mean_luminance = m[self.frame_cameras:]
        raw = np.empty((n_frames, self.taps, *m.shape[1:]), m.dtype)
        for index, frame in enumerate(self.frames):
            kappa_t = self.noise.electrons_per_unit_s * frame.exposure
            contrast = self.noise.contrast(frame.modulation_frequency)
            light = (frame.g1 * frame.light_mean + frame.g0) * mean_luminance[windows.index((frame.exposure_start, frame.exposure))]
            signal = [contrast * m[index + j * n_frames] for j in range(4)] if self.taps == 4 else contrast * m[index]
            raw[index] = tap_electrons(kappa_t, light, signal, self.taps)
        if not clip:
            return raw
        # A noisy render can make |M| exceed D where little light arrives: no charge is negative.
        return np.maximum(raw, 0.0, out=raw)

    def with_signal(self, measurements, electrons: float, percentile: float = 99.0) -> "Sensor":
        """This sensor with its silicon's radiance scale (``radiance_unit``) set so that all
        taps of its first frame together collect ``electrons`` at the ``percentile`` pixel:
        the light level of a render stated in electrons (a dataset's photon level, a
        benchmark's full well). The rest of the silicon is unchanged.

        Parameters
        ----------
        measurements : array_like. The measurements of :meth:`cameras` (a render's).
        electrons : float, e⁻. > 0.
        percentile : float. In (0, 100]; default 99 (the brightest pixels may exceed it).

        Returns
        -------
        Sensor
            A copy; itself scaled by 1 where the frame collects nothing (a black image).

        Raises
        ------
        ValueError
            For ``electrons`` or ``percentile`` out of range, or measurements of another shape.
        """
        electrons = checked_in_range("electrons", electrons, above=0, where="Sensor.with_signal")
        percentile = checked_in_range("percentile", percentile, above=0, at_most=100, where="Sensor.with_signal")
        collected = np.asarray(self.raw(measurements)[0], dtype=np.float64).sum(axis=0)
        finite = collected[np.isfinite(collected)]
        level = float(np.percentile(finite, percentile)) if finite.size else 0.0
        scale = electrons / level if level > 0 else 1.0
        return dataclasses.replace(self, noise=dataclasses.replace(self.noise, radiance_unit=self.noise.radiance_unit * scale))

    # ------------------------------------------------------------------ read-out
    def expected_electrons(self, raw) -> np.ndarray:
        """Mean tap charge (frames, taps, H, W) before the full well: signal with the tap
        gain mismatch, plus its share of the ambient light and the dark current.

        Parameters
        ----------
        raw : ndarray
            (frames, taps, H, W) signal electrons, as :meth:`raw` gives them.

        Returns
        -------
        ndarray
            (frames, taps, H, W), e⁻.
        """
        raw = np.asarray(raw, dtype=np.float64)
        gain, _ = self.noise.pattern(raw.shape[1:])
        column = (-1, *([1] * (raw.ndim - 1)))
        exposure = np.array([f.exposure for f in self.frames]).reshape(column)
        # Unmodulated light splits as the taps' mean shares: (1 ± c s̄)/2, (1 + c s̄)/4.
        mean_share = np.array([[self._share(f, tap) for tap in range(self.taps)] for f in self.frames]).reshape(*column[:1], self.taps, *column[2:])
        ambient = self.noise.ambient_e_per_s * exposure * mean_share
        return gain * (raw + ambient) + self.noise.dark_current_e_per_s * exposure

    def _share(self, frame, tap: int) -> float:
        """The mean share of a pixel's charge that ``tap`` collects in ``frame``."""
        modulated = self.noise.contrast(frame.modulation_frequency) * frame.sensor_mean
        if self.taps == 4:
            return 0.25 * (1.0 + modulated)
        return 0.5 * (1.0 + modulated if tap == 0 else 1.0 - modulated)

    def read_out(self, result, seed=None, mode: str = "raw") -> np.ndarray:
        """Digital numbers of a render's frames after the noise chain (module docstring).

        Parameters
        ----------
        result : RenderResult of ``dopplertof.render(scene, sensor=self)``, or its ``raw``
            array (frames, taps, H, W) in electrons.
        seed : int or numpy.random.SeedSequence or None. Same seed, same numbers.
        mode : str. ``"raw"``: every tap (frames, taps, H, W); with 2 taps ``"A-B"``,
            ``"A+B"``, ``"A"``, ``"B"`` (frames, H, W), as real chips output them (``"A"``
            also with 1 tap). Differences and sums are of DN, black level included.

        Returns
        -------
        ndarray of int64 (DN).

        Raises
        ------
        ValueError
            For a seed that is not a whole number >= 0 (or a SeedSequence), an unknown mode,
            a mode the tap layout lacks, ``raw`` of another shape, or frames without a finite charge (an interrupted render's untraced windows).
        """
        if mode not in READOUT_MODES:
            raise ValueError(f"Sensor.read_out: unknown mode {mode!r}; choose one of {', '.join(READOUT_MODES)}")
        if mode != "raw" and not (self.taps == 2 or (self.taps == 1 and mode == "A")):
            raise ValueError(f"Sensor.read_out: mode {mode!r} needs a 2-tap pixel; this sensor has {self.taps} tap(s): use mode='raw'")
        raw = getattr(result, "raw", result)
        raw = np.asarray(raw, dtype=np.float64)
        if raw.ndim < 2 or raw.shape[:2] != (len(self.frames), self.taps):
            raise ValueError(f"Sensor.read_out: raw must have shape ({len(self.frames)}, {self.taps}, ...), got {raw.shape}")
        empty = [i for i in range(len(raw)) if not np.all(np.isfinite(raw[i]))]
        if empty:
            raise ValueError(f"Sensor.read_out: raw frames {empty} hold no charge estimate (NaN: a render stopped before their window was traced); finish the render first")
        if not (seed is None or isinstance(seed, np.random.SeedSequence)):
            seed = checked("seed", seed, "int", "Sensor.read_out")
            if seed < 0:
                raise ValueError(f"Sensor.read_out: 'seed' must be >= 0, got {seed}")
        _, offset = self.noise.pattern(raw.shape[1:])
        rng = np.random.default_rng(seed)
        dn = self.noise.digitize(self.expected_electrons(raw), rng, offset_e=offset)
        if mode == "raw":
            return dn
        return {"A-B": lambda: dn[:, 0] - dn[:, 1], "A+B": lambda: dn[:, 0] + dn[:, 1], "A": lambda: dn[:, 0], "B": lambda: dn[:, 1]}[mode]()
