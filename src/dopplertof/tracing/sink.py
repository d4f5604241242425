"""Where a path's contributions go: the intensity and, weighted by W(u, L), every camera.

The per-lane accumulators are loop state, so they travel as a plain tuple
``(intensity, [measurement per camera])`` that :meth:`Sink.add` returns anew (Dr.Jit
tracks PyTrees, not attributes of Python objects). :meth:`Sink.outputs` lays the
per-lane results out under the names of :data:`dopplertof.outputs.OUTPUTS`.
"""

from __future__ import annotations

from .. import modulation


class Sink:
    """The cameras of a render and how contributions reach them."""

    def __init__(self, cameras):
        self.cameras = list(cameras)

    def empty(self):
        """Zero contributions: the intensity and one value per camera."""
        import mitsuba as mi

        return mi.Spectrum(0), [mi.Float(0) for _ in self.cameras]

    def bank(self, u):
        """The cameras' weights for lanes at normalised time ``u``."""
        return modulation.CameraBank(self.cameras, u)

    @property
    def needs_length(self) -> bool:
        """Float64 optical lengths are needed only where a camera weighs them."""
        return bool(self.cameras)

    def add(self, state, bank, contrib, length_m, mask):
        """``state`` plus an emitter contribution with optical length ``length_m`` (Float64)."""
        import drjit as dr

        radiance, measurements = state
        radiance = dr.select(mask, radiance + contrib, radiance)
        if not self.cameras:
            return radiance, measurements
        lum = _luminance(contrib)
        return radiance, [dr.select(mask, m + w * lum, m) for m, w in zip(measurements, bank.weights(length_m))]

    def add_analytic(self, state, cameras, first, second):
        """The original's analytic mode (:mod:`dopplertof.tracing.paired`): a contribution
        X and length L at the exposure's start (``first``) and end (``second``), each a
        (X, L, mask), taken as linear in time in between and integrated in closed form. A
        start without a matching end holds X and L constant."""
        import drjit as dr
        import mitsuba as mi

        radiance, measurements = state
        (x1, l1, m1), (x2, l2, m2) = first, second
        both = m1 & m2
        x2 = dr.select(both, x2, x1)
        l2 = dr.select(both, l2, l1)
        radiance = dr.select(m1, radiance + 0.5 * (x1 + x2), radiance)
        lum1, lum2 = mi.Float64(_luminance(x1)), mi.Float64(_luminance(x2))
        measurements = [
            dr.select(m1, m + mi.Float(modulation.analytic_integral(cam, l1, l2, lum1, lum2)), m) for m, cam in zip(measurements, cameras)
        ]
        return radiance, measurements

    @staticmethod
    def outputs(state, truth: dict, hits, label):
        """Per-lane outputs: estimates, truth sums (value × hit), hit count, label."""
        radiance, measurements = state
        return {"intensity": radiance, "measurements": measurements, "hits": hits, "instance_id": label, **truth}


def _luminance(contrib):
    import mitsuba as mi

    return mi.luminance(contrib) if mi.is_rgb else contrib[0]
