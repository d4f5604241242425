"""Sensors: raw frames of coded taps, the noise chain of real silicon, presets.

* :class:`Sensor`, :class:`RawFrame` (:mod:`~dopplertof.sensors.frames`): a sensor is an
  ordered list of raw frames read through a pixel of 1, 2 or 4 taps;
  ``dopplertof.render(scene, sensor=S)`` renders every frame at once and gives ``raw``
  electrons, :meth:`Sensor.read_out` the digital numbers after the noise chain;
* :class:`Silicon` (:mod:`~dopplertof.sensors.noise`): quantum efficiency, demodulation
  contrast, ambient light, dark current, shot and read noise, full well, ADC, tap mismatch;
* :func:`preset` (:mod:`~dopplertof.sensors.presets`): real chips with sourced numbers,
  refusing schedules their hardware cannot capture;
* :mod:`~dopplertof.sensors.estimators`: measurements from a read-out, two-offset
  differential-heterodyne velocity, multi-frequency depth, each with its error (the
  ratio and the fit are :func:`dopplertof.reconstruct.velocity`).
"""

from . import estimators
from .frames import READOUT_MODES, TAP_LAYOUTS, RawFrame, Sensor
from .noise import Silicon
from .presets import PRESETS, Limits, preset

__all__ = ["RawFrame", "Sensor", "Silicon", "Limits", "PRESETS", "preset", "READOUT_MODES", "TAP_LAYOUTS"]
