"""How a partner path follows its primal: which random numbers a group of lanes shares.

Lanes of one group (the N correlated times of a pixel sample) draw from a group-shared
stream where a dimension is *correlated* and from their own stream elsewhere
(:mod:`dopplertof.tracing.lanes`). With ``correlation_depth = k`` (the original M3 code's
``path_correlation_depth``): k = 0 shares nothing, k = 1 shares the pixel (and aperture)
sample, and k ≥ 2 also shares the first k − 1 bounces.

==============  =====================================================================
mode            meaning
==============  =====================================================================
``none``        independent paths (only the times are paired): k = 0
``pixel``       same pixel sample, independent paths: k = 1
``replay``      random replay: the same random numbers for every bounce (k = ∞), or
                for the first ``correlation_depth − 1`` bounces
``reconnection`` paired tracing (:mod:`dopplertof.tracing.paired`): the partner aims at the
                primal's next vertex re-timed to its own time, wherever both current
                vertices have no delta lobe (replay there)
``adaptive``    paired tracing, reconnecting only where both current surfaces are rougher
                than ``threshold`` (mean GGX/Beckmann α; diffuse = ∞), replay elsewhere
==============  =====================================================================

In ``none``, ``pixel`` and ``replay`` each lane is an ordinary path sample at its own
time; the paired modes weight primal and partner by MIS. Every mode is unbiased.
"""

from __future__ import annotations

from dataclasses import dataclass

MODES = ("none", "pixel", "replay", "reconnection", "adaptive")
PAIRED = ("reconnection", "adaptive")
UNBOUNDED = 1 << 30


@dataclass(frozen=True)
class Correlation:
    """A correlation mode and its depth cut-off (see module docstring); built from a
    validated :class:`~dopplertof.settings.RenderSettings` (``correlation_spec``)."""

    mode: str = "replay"
    depth: int | None = None
    threshold: float = 0.5  # adaptive: roughness (α) above which a bounce reconnects

    @property
    def paired(self) -> bool:
        """Traced as primal + partner in one lane (:mod:`dopplertof.tracing.paired`)."""
        return self.mode in PAIRED

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
