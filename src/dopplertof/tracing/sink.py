"""Where a path's contributions go: the intensity and, weighted by W(u, L), every camera.

The per-lane accumulators are loop state, so they travel as a plain tuple
``(intensity, [measurement per camera])`` that :meth:`Sink.add` returns anew (Dr.Jit
tracks PyTrees, not attributes of Python objects). :meth:`Sink.outputs` lays the
per-lane results out under the names of :data:`dopplertof.outputs.OUTPUTS`.
"""

from __future__ import annotations

from .. import modulation


class Sink:
    """The cameras of a render and how contributions reach them.

    Parameters
    ----------
    cameras : sequence of Camera
    """

    def __init__(self, cameras):
        self.cameras = list(cameras)

    def empty(self):
        """Zero contributions: the intensity and one value per camera."""
        import mitsuba as mi

        return mi.Spectrum(0), [mi.Float(0) for _ in self.cameras]

    def bank(self, u):
        """The cameras' weights for lanes at normalised time ``u``.

        Parameters
        ----------
        u : mi.Float64
            Normalised times.

        Returns
        -------
        list
            Each camera's weight per lane.
        """
        return modulation.CameraBank(self.cameras, u)

    @property
    def needs_length(self) -> bool:
        """Float64 optical lengths are needed only where a camera weighs them."""
        return bool(self.cameras)

    def add(self, state, bank, contrib, length_m, mask):
        """``state`` plus an emitter contribution with optical length ``length_m`` (Float64).

        Parameters
        ----------
        state : tuple
            (intensity, [per-camera values]).
        bank : list
            :meth:`bank` of the lanes' times.
        contrib : mi.Spectrum
        length_m : mi.Float64
            m.
        mask : mi.Bool

        Returns
        -------
        tuple
            The new state.
        """
        import drjit as dr

        radiance, measurements = state
        radiance = dr.select(mask, radiance + contrib, radiance)
        if not self.cameras:
            return radiance, measurements
        lum = _luminance(contrib)
        return radiance, [dr.select(mask, m + w * lum, m) for m, w in zip(measurements, bank.weights(length_m))]

    def add_analytic(self, state, cameras, first, second, continuous):
        """The analytic mode (:mod:`dopplertof.tracing.paired`): a contribution X with optical
        length L at the exposure's start (``first``) and end (``second``), each a
        (X, L, mask), integrated in closed form over the exposure under a model of X(t)
        and L(t) between them:

        * where both ends are present and the partner path lies on the primal's surfaces
          (``continuous``: one path moving), X and L are linear in time;
        * otherwise (the contribution is missing at one end: shadowed, the partner path
          gone; or the paths reach different surfaces: an occlusion change) the start's
          contribution fades linearly out and the end's in, each at its own L: the
          expectation over a switch at a uniformly distributed time.

        The original ramped a contribution missing at the end to zero (L held) and dropped
        one missing at the start; holding it constant was this package's earlier rule. Both
        are further from the unbiased estimate (README, ``benchmarks/analytic_bias.py``).

        Parameters
        ----------
        state : tuple
            (intensity, [per-camera values]).
        cameras : sequence of Camera
        first, second : tuple
            (X, L, mask) at the exposure's start and end; L in m.
        continuous : mi.Bool
            Where the partner path lies on the primal's surfaces.

        Returns
        -------
        tuple
            The new state.
        """
        import drjit as dr
        import mitsuba as mi

        radiance, measurements = state
        (x1, l1, m1), (x2, l2, m2) = first, second
        x1, x2 = dr.select(m1, x1, 0.0), dr.select(m2, x2, 0.0)
        l1, l2 = dr.select(m1, l1, l2), dr.select(m2, l2, l1)  # a missing end's length is unused: keep it finite
        present = m1 | m2
        linear = m1 & m2 & continuous
        radiance = dr.select(present, radiance + 0.5 * (x1 + x2), radiance)
        lum1, lum2 = mi.Float64(_luminance(x1)), mi.Float64(_luminance(x2))
        out = []
        for m, cam in zip(measurements, cameras):
            moving = modulation.analytic_integral(cam, l1, l2, lum1, lum2)
            fading = modulation.analytic_integral(cam, l1, l1, lum1, 0.0) + modulation.analytic_integral(cam, l2, l2, 0.0, lum2)
            out.append(dr.select(present, m + mi.Float(dr.select(linear, moving, fading)), m))
        return radiance, out

    @staticmethod
    def outputs(state, truth: dict, hits, label):
        """Per-lane outputs: estimates, truth sums (value × hit), hit count, label.

        Parameters
        ----------
        state : tuple
            (intensity, [per-camera values]).
        truth : dict
            Ground-truth sums.
        hits : mi.UInt32
        label : mi.UInt32
            Instance id.

        Returns
        -------
        dict
        """
        radiance, measurements = state
        return {"intensity": radiance, "measurements": measurements, "hits": hits, "instance_id": label, **truth}


def _luminance(contrib):
    import mitsuba as mi

    return mi.luminance(contrib) if mi.is_rgb else contrib[0]
