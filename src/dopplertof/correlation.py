"""How a partner path follows its primal: which random numbers a group of lanes shares.

Lanes of one group (the N correlated times of a pixel sample) draw from a group-shared
stream where a dimension is *correlated* and from their own stream elsewhere
(:mod:`dopplertof.integrator`). With ``correlation_depth = k`` (the original M3 code's
``path_correlation_depth``): k = 0 shares nothing, k = 1 shares the pixel (and aperture)
sample, and k ≥ 2 also shares the first k − 1 bounces.

==============  =====================================================================
mode            meaning
==============  =====================================================================
``none``        independent paths (only the times are paired): k = 0
``pixel``       same pixel sample, independent paths: k = 1
``replay``      random replay: the same random numbers for every bounce (k = ∞), or
                for the first ``correlation_depth − 1`` bounces
==============  =====================================================================

Each lane is an ordinary path sample at its own time, so every mode is unbiased.
"""

from __future__ import annotations

from dataclasses import dataclass

MODES = ("none", "pixel", "replay")
UNBOUNDED = 1 << 30


@dataclass(frozen=True)
class Correlation:
    """A correlation mode and its depth cut-off (see module docstring)."""

    mode: str = "replay"
    depth: int | None = None

    def __post_init__(self):
        if self.mode not in MODES:
            raise ValueError(f"unknown correlation {self.mode!r}; choose one of {', '.join(MODES)}")
        if self.depth is not None and (not isinstance(self.depth, int) or self.depth < 0):
            raise ValueError(f"correlation_depth must be a non-negative integer, got {self.depth!r}")

    @property
    def effective_depth(self) -> int:
        if self.mode == "none":
            return 0
        if self.mode == "pixel":
            return 1
        return UNBOUNDED if self.depth is None else self.depth

    def correlates_pixel(self) -> bool:
        return self.effective_depth >= 1

    def correlates_bounce(self, depth):
        """Is bounce ``depth`` (0 at the camera-ray hit) correlated?

        A Python bool where the answer is the same at every depth, else a per-lane Bool.
        """
        k = self.effective_depth
        if k <= 1 or k >= UNBOUNDED:
            return k >= UNBOUNDED
        return (depth + 1) < k
