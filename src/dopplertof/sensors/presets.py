"""Real sensors: their silicon, what their timing can do, and a default schedule.

:func:`preset` returns a :class:`~dopplertof.sensors.Sensor` whose ``limits``
(:class:`Limits`) refuse, with one message naming every violation, a raw frame the hardware
cannot capture: a frequency outside its range or off its step, a phase off its step, a
heterodyne offset on a chip that drives light and pixel from one clock, an integration time
beyond its limit, more raw frames than it sequences. Give your own schedule with
``preset(name, frames=[...])``; change the optics and scale (``wavelength_m``,
``f_number``, ``radiance_unit``, ``ambient_e_per_s``, …) with keyword arguments, which go to
the :class:`~dopplertof.sensors.noise.Silicon`.

Sources: the sensor-design reference (``shared/reference/sensor-design.md`` §2.3, §3) and
the documents it cites, named in each preset's docstring. Numbers no public source gave us
are marked **[unverified]** and left at the ideal defaults of
:class:`~dopplertof.sensors.noise.Silicon` (no read noise, no dark current, a deep well),
so that a preset never invents a noise figure (an unsourced ADC gain spans the full well); **[inference]** marks a value derived from a
sourced one.

The presets do not check the film size against the pixel array, nor the MLX75027's frame
duty limit (Σ integration / frame time < 0.4), which depends on a frame time we do not model.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from .frames import RawFrame, Sensor
from .noise import Silicon

_PHASE_TOLERANCE_RAD = 1e-9
_FREQUENCY_TOLERANCE = 1e-9  # relative, for frequencies on a step grid


@dataclass(frozen=True)
class Limits:
    """What a chip's timing can capture.

    Parameters
    ----------
    name : str. The chip, for messages.
    frequency_hz : (float, float). Lowest and highest modulation frequency, Hz.
    frequency_step_hz : float or None. Frequencies are multiples of it; None: continuous.
    phase_step_rad : float or None. Phases are multiples of it; None: any phase.
    heterodyne : bool. Whether light and pixel can run at different frequencies.
    max_exposure_s : float or None. Integration time per raw frame must be below it.
    max_frames : int or None. Raw frames per sequence.
    waveforms : tuple of str. Modulation the chip drives (``"code"``: any code).
    hint : str. What to use instead, appended to the message.
    """

    name: str
    frequency_hz: tuple
    frequency_step_hz: float | None = None
    phase_step_rad: float | None = None
    heterodyne: bool = False
    max_exposure_s: float | None = None
    max_frames: int | None = None
    waveforms: tuple = ("rectangular", "sinusoidal")
    hint: str = ""

    def violations(self, frame) -> list[str]:
        """Why this chip cannot capture ``frame`` (empty if it can).

        Parameters
        ----------
        frame : RawFrame

        Returns
        -------
        list of str
        """
        out = []
        f = frame.modulation_frequency
        low, high = self.frequency_hz
        if not low <= f <= high:
            out.append(f"modulation frequency {f:g} Hz outside {low:g} to {high:g} Hz")
        elif self.frequency_step_hz and abs(f / self.frequency_step_hz - round(f / self.frequency_step_hz)) > _FREQUENCY_TOLERANCE * f / self.frequency_step_hz:
            out.append(f"modulation frequency {f:g} Hz not a multiple of its {self.frequency_step_hz:g} Hz step")
        if self.phase_step_rad:
            steps = frame.phase / self.phase_step_rad
            if abs(steps - round(steps)) > _PHASE_TOLERANCE_RAD / self.phase_step_rad:
                out.append(f"phase {math.degrees(frame.phase):g} deg not a multiple of its {math.degrees(self.phase_step_rad):g} deg step")
        if frame.heterodyne != 0 and not self.heterodyne:
            out.append(f"heterodyne offset {frame.heterodyne / frame.exposure:g} Hz (light and pixel share one clock: no offset)")
        if self.max_exposure_s is not None and not frame.exposure < self.max_exposure_s:
            out.append(f"integration time {frame.exposure:g} s not below its {self.max_exposure_s:g} s per raw frame")
        if frame.waveform not in self.waveforms and "code" not in self.waveforms:
            out.append(f"waveform {frame.waveform!r} (it drives {', '.join(self.waveforms)})")
        return out

    def check(self, frames) -> None:
        """ValueError naming every violation of every frame, in one message.

        Parameters
        ----------
        frames : sequence of RawFrame

        Raises
        ------
        ValueError
            This chip cannot capture the frames (too many, or a frame it cannot take).
        """
        problems = []
        if self.max_frames is not None and len(frames) > self.max_frames:
            problems.append(f"{len(frames)} raw frames (at most {self.max_frames})")
        for index, frame in enumerate(frames):
            problems += [f"frame {index}: {v}" for v in self.violations(frame)]
        if problems:
            hint = f"; {self.hint}" if self.hint else ""
            raise ValueError(f"{self.name} cannot capture this schedule: {'; '.join(problems)}{hint}")


def _phases(n, step_rad, **frame):
    return [RawFrame(phase=k * step_rad, **frame) for k in range(n)]


def mlx75027(frames=None, **silicon) -> Sensor:
    """Melexis MLX75027: 640×480 BSI pixels of 10 µm, 2-tap CAPD, 4–100 MHz.

    Source: MLX75027 datasheet v1.0 (in ``rzw2/mlx75027_config@0501f11:doc/``; Features,
    Table 13, §7.3, §7.7, §7.11–7.14, §7.25, §9):

    * 2 taps in counter-phase; outputs A−B, A+B, raw A, raw B (§7.3); 12-bit ADC;
    * modulation 4–100 MHz in 1 MHz steps, set per frame; one PLL drives light and pixel
      (no heterodyne offset); 1–8 raw phases, phase shifts in 45° steps;
      integration < 1 ms per phase;
    * EQE 51 % at 850 nm, 28 % at 940 nm; demodulation contrast 85 % at 40 MHz, 78 % at
      100 MHz (held at 85 % below 40 MHz **[inference]**: contrast falls with frequency);
    * single-tap full well 160 ke⁻ (typical; 106 ke⁻ minimum); conversion gain 0.0106 DN/e⁻;
      pixel dark noise 83 e⁻ (taken as the read noise); dark current 51 ke⁻/s per tap
      (typical).

    Default schedule: 4 phases (0°, 90°, 180°, 270°) at 100 MHz, 300 µs each (the
    datasheet's 120 fps example); square-wave modulation. Black level **[unverified]**: 0.

    Parameters
    ----------
    frames : list of RawFrame or None, default None
        The schedule; None: the default one above.
    **silicon
        :class:`~dopplertof.sensors.noise.Silicon` parameters that replace the chip's.

    Returns
    -------
    Sensor

    Raises
    ------
    ValueError
        An unknown silicon parameter, or frames the chip cannot capture.
    """
    base = dict(
        pixel_pitch_m=10e-6, quantum_efficiency=((850e-9, 0.51), (940e-9, 0.28)),
        demodulation_contrast=((4e6, 0.85), (40e6, 0.85), (100e6, 0.78)), full_well_e=160e3,
        gain_e_per_dn=1 / 0.0106, read_noise_e=83.0, dark_current_e_per_s=51e3, adc_bits=12,
    )  # fmt: skip
    limits = Limits("MLX75027", (4e6, 100e6), 1e6, math.pi / 4, heterodyne=False, max_exposure_s=1e-3, max_frames=8,
                    waveforms=("rectangular",), hint="for D-ToF offsets and exposures use the 'dtof-prototype' preset")  # fmt: skip
    default = _phases(4, math.pi / 2, modulation_frequency=100e6, exposure=300e-6, waveform="rectangular")
    return _sensor("mlx75027", frames or default, 2, base, silicon, limits)


def opt8241(frames=None, **silicon) -> Sensor:
    """Texas Instruments OPT8241: 320×240 pixels of 15 µm, 2 mixer inputs, 10–100 MHz.

    Source: OPT8241 datasheet SBAS704B
    (https://www.digikey.cn/zh/htmldatasheets/production/1792947/0/0/1/opt8241.html;
    http://dtsheet.com/model/4185105):

    * modulation 10–100 MHz; demodulation contrast 45 % at 50 MHz (taken as flat over the
      range **[inference]**); responsivity 0.35 A/W at 850 nm, QE ≈ 51 %
      (0.35 × 1240/850, **[inference]**);
    * 2 taps (DMIX0/DMIX1, **[inference]**); 12-bit phase correlation output; "quads" of
      raw phases per frame.

    Frequency step, phase step and integration limit **[unverified]**: not restricted; one
    clock for light and pixel (no heterodyne offset). Full well, read noise, dark current
    **[unverified]**: ideal. Default schedule: 4 phases (quad) at 50 MHz, 1 ms each
    **[unverified]** integration.

    Parameters
    ----------
    frames : list of RawFrame or None, default None
        The schedule; None: the default one above.
    **silicon
        :class:`~dopplertof.sensors.noise.Silicon` parameters that replace the chip's.

    Returns
    -------
    Sensor

    Raises
    ------
    ValueError
        An unknown silicon parameter, or frames the chip cannot capture.
    """
    base = dict(pixel_pitch_m=15e-6, quantum_efficiency=0.51, demodulation_contrast=0.45, adc_bits=12)
    limits = Limits("OPT8241", (10e6, 100e6), heterodyne=False, waveforms=("rectangular", "sinusoidal"),
                    hint="for D-ToF offsets use the 'dtof-prototype' preset (OPT8241 with a DDS source)")  # fmt: skip
    return _sensor("opt8241", frames or _phases(4, math.pi / 2, modulation_frequency=50e6, exposure=1e-3, waveform="rectangular"), 2, base, silicon, limits)


def imx556(frames=None, **silicon) -> Sensor:
    """Sony IMX556 (DepthSense): 640×480 BSI CAPD pixels of 10 µm, global shutter, 2 taps.

    Sources: https://www.thinklucid.com/tech-briefs/sony-depthsense-how-it-works/ ;
    https://3da.medium.com/tof-understand-current-assisted-photonic-demodulator-capd-45ec3b599443
    (2 taps, junctions "180° out of phase").

    Frequency range, contrast, QE, full well, noise and ADC **[unverified]**: the frequency
    range is taken as the MLX75027's class, 4–100 MHz **[inference]**, the silicon ideal;
    one clock for light and pixel. Default schedule: 4 phases at 100 MHz, 500 µs
    **[unverified]**.

    Parameters
    ----------
    frames : list of RawFrame or None, default None
        The schedule; None: the default one above.
    **silicon
        :class:`~dopplertof.sensors.noise.Silicon` parameters that replace the chip's.

    Returns
    -------
    Sensor

    Raises
    ------
    ValueError
        An unknown silicon parameter, or frames the chip cannot capture.
    """
    limits = Limits("IMX556", (4e6, 100e6), heterodyne=False, hint="for D-ToF offsets use the 'dtof-prototype' preset")
    return _sensor("imx556", frames or _phases(4, math.pi / 2, modulation_frequency=100e6, exposure=500e-6, waveform="rectangular"), 2, dict(pixel_pitch_m=10e-6), silicon, limits)


# FLAT's Kinect v2 model (NVlabs/FLAT): modulation periods 2e4, 1e5 and 1.33e4 ps.
KINECT_V2_FREQUENCIES_HZ = (1 / 2e-8, 1 / 1e-7, 1 / 1.33e-8)


def kinect_v2(frames=None, **silicon) -> Sensor:
    """A Kinect-v2-like sensor: 512×424 pixels, 9 raw frames = 3 frequencies × 3 phases.

    Sources: libfreenect2#747 ("3 phases at 3 frequencies. 3x3=9"; phases 0, 2π/3, 4π/3);
    the raw packet's 11-bit samples (libfreenect2); frequencies from FLAT's model (periods
    2·10⁴, 10⁵ and 1.33·10⁴ ps: 50, 10 and ≈ 75.2 MHz; Microsoft's values **[unverified]**);
    "up to 130 MHz" (Payne et al., ISSCC 2014, title).

    Pixel pitch, QE, contrast, noise, exposure **[unverified]**: ideal silicon, 2 taps
    **[inference]**, 11-bit ADC, 1 ms per raw frame; frames one after another (each its own
    window, as a real capture). Light and pixel share a clock: no heterodyne offset.

    Parameters
    ----------
    frames : list of RawFrame or None, default None
        The schedule; None: the default one above.
    **silicon
        :class:`~dopplertof.sensors.noise.Silicon` parameters that replace the chip's.

    Returns
    -------
    Sensor

    Raises
    ------
    ValueError
        An unknown silicon parameter, or frames the chip cannot capture.
    """
    limits = Limits("Kinect v2", (1e6, 130e6), phase_step_rad=2 * math.pi / 3, heterodyne=False, max_frames=9, waveforms=("rectangular", "sinusoidal"))
    exposure = 1e-3
    default = [
        RawFrame(modulation_frequency=f, phase=p * 2 * math.pi / 3, exposure=exposure, exposure_start=(3 * i + p) * exposure, waveform="sinusoidal")
        for i, f in enumerate(KINECT_V2_FREQUENCIES_HZ) for p in range(3)
    ]  # fmt: skip
    return _sensor("kinect-v2", frames or default, 2, dict(adc_bits=11), silicon, limits)


def dtof_prototype(frames=None, **silicon) -> Sensor:
    """The D-ToF laboratory prototype: a PMD-type sensor (TI OPT8241) clocked by a DDS.

    Sources: Heide et al. 2015 and Shrestha et al. 2016 (a TI OPT8241 with an AD9959 DDS:
    0–200 MHz, 0.12 Hz and 0.02° resolution, so sub-Hz offsets and arbitrary phases;
    sensor-design reference §3); the silicon is :func:`opt8241`'s. The default schedule is
    the original D-ToF setting (Kim et al. 2023 code defaults): 30 MHz, T = 1.5 ms, a
    homodyne and a heterodyne frame at h = 1 (≈ 667 Hz), each at ψ = 0° and 90°, all in one
    window, sinusoidal modulation: the four frames velocity reconstruction needs (three
    cannot tell the brightness change of a moving surface from its Doppler shift).

    The DDS's 0.12 Hz / 0.02° steps are below what a render resolves, so frequencies, offsets
    and phases are not restricted to them.

    Parameters
    ----------
    frames : list of RawFrame or None, default None
        The schedule; None: the default one above.
    **silicon
        :class:`~dopplertof.sensors.noise.Silicon` parameters that replace the chip's.

    Returns
    -------
    Sensor

    Raises
    ------
    ValueError
        An unknown silicon parameter, or frames the chip cannot capture.
    """
    base = dict(pixel_pitch_m=15e-6, quantum_efficiency=0.51, demodulation_contrast=0.45, adc_bits=12)
    limits = Limits("D-ToF prototype (OPT8241 + AD9959)", (10e6, 100e6), heterodyne=True, waveforms=("code",))
    default = [
        RawFrame(modulation_frequency=30e6, exposure=1.5e-3, heterodyne=h, phase=p, waveform="sinusoidal")
        for h, p in ((0.0, 0.0), (0.0, math.pi / 2), (1.0, 0.0), (1.0, math.pi / 2))
    ]  # fmt: skip
    return _sensor("dtof-prototype", frames or default, 2, base, silicon, limits)


PRESETS = {"mlx75027": mlx75027, "opt8241": opt8241, "imx556": imx556, "kinect-v2": kinect_v2, "dtof-prototype": dtof_prototype}


def preset(name: str, frames=None, **silicon) -> Sensor:
    """The sensor ``name`` (one of :data:`PRESETS`), with its default schedule or ``frames``.

    Parameters
    ----------
    name : str. ``mlx75027``, ``opt8241``, ``imx556``, ``kinect-v2`` or ``dtof-prototype``.
    frames : list of :class:`~dopplertof.RawFrame`, optional. A schedule of your own,
        checked against the chip's limits.
    **silicon
        :class:`~dopplertof.sensors.noise.Silicon` parameters to change (optics, scale,
        ambient light, …).

    Returns
    -------
    Sensor

    Raises
    ------
    ValueError
        For an unknown name, a schedule the chip cannot capture (one message naming every
        violation), or a bad silicon parameter.
    """
    if name not in PRESETS:
        raise ValueError(f"unknown sensor preset {name!r}; choose one of {', '.join(PRESETS)}")
    return PRESETS[name](frames, **silicon)


def _sensor(name, frames, taps, base: dict, changes: dict, limits: Limits) -> Sensor:
    unknown = sorted(set(changes) - {f.name for f in dataclasses.fields(Silicon)})
    if unknown:
        raise ValueError(f"sensor preset {name!r}: unknown silicon parameter(s) {', '.join(map(repr, unknown))}")
    # built anew, not replaced: a gain left unsourced (None) then spans the changed well
    return Sensor(frames=list(frames), taps=taps, noise=Silicon(**{**base, **changes}), name=name, limits=limits)
