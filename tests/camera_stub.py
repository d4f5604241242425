"""A duck-typed camera for host-side tests (reconstruct, sensor).

Unlike :class:`dopplertof.Camera` it does not validate, so tests can hand the modules
invalid values (negative exposure, negative g0) and check that they reject them.
"""

from dataclasses import dataclass

T = 1.5e-3


@dataclass
class Cam:
    modulation_frequency: float = 30e6
    exposure: float = T
    heterodyne: float = 0.0
    phase: float = 0.0
    waveform: str = "sinusoidal"
    g1: float = 0.5
    g0: float = 0.5
    low_pass: bool = True
