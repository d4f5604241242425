"""Constant data the tracer reads, prepared once per render: per-BSDF tables, indexed by
the BSDF's Dr.Jit registry id, the film's filter sampler and the sensor's projection.

* ``roughness``: how rough a surface is for the adaptive shift (paired tracing): diffuse
  = ∞, rough conductor / dielectric / plastic = the mean of their α, anything with a delta
  lobe = 0.
* ``relative_ior``: η = n_inside / n_outside of a surface that refracts (``dielectric``,
  ``roughdielectric``), 1 elsewhere (``thindielectric``, ``null`` and ``mask`` pass light
  straight through; other transmitting BSDFs are refused: :func:`relative_ior`). Crossing
  it multiplies the index of the medium a path travels in by η entering, 1/η leaving;
  the optical length of a segment is that index times its length
  (:func:`dopplertof.tracing.path.segment_index`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..jitdata import jit_array

_REFRACTING = ("SmoothDielectric", "RoughDielectric")


@dataclass
class MaterialTables:
    """Per-BSDF tables the kernel gathers from (roughness for ``adaptive``, relative index
    of refraction for optical lengths), with the film's filter and the sensor's projection.

    Parameters
    ----------
    roughness : mi.Float
        Per-BSDF roughness.
    relative_ior : mi.Float
        Per-BSDF relative index of refraction (1 where it does not refract).
    film : FilterSampler or None, default None
    pinhole : tuple or None, default None
        The sensor's :func:`~dopplertof.tracing.path.pinhole_scales`.
    refracts : bool, default True
        Whether any BSDF refracts (else the indices are skipped).
    """
    roughness: object  # mi.Float indexed by BSDF id
    relative_ior: object  # mi.Float indexed by BSDF id
    film: object = None  # the FilterSampler of the scene's film (dopplertof.tracing.film)
    pinhole: tuple | None = None  # the sensor's projection scales for optical flow (path.pinhole_scales)
    refracts: bool = True  # some surface refracts: optical lengths need relative_ior (else the kernel skips it)

    @classmethod
    def of(cls, scene) -> "MaterialTables":
        """The tables of ``scene`` (a :class:`~dopplertof.DynamicScene`): every BSDF of the
        static scene and of the bodies, its film's filter and its sensor's projection.

        Parameters
        ----------
        scene : DynamicScene

        Returns
        -------
        MaterialTables

        Raises
        ------
        ValueError
            A transmissive BSDF nested in another, or a film filter with negative lobes.
        """
        import drjit as dr
        import mitsuba as mi

        rough, ior = {}, {}
        for mi_scene in scene.mitsuba_scenes():
            for shape in mi_scene.shapes():
                bsdf = shape.bsdf()
                if bsdf is None:
                    continue
                index = int(dr.reinterpret_array(mi.UInt32, mi.BSDFPtr(bsdf))[0])
                rough[index] = _roughness(bsdf)
                ior[index] = relative_ior(bsdf)
        size = max(rough, default=0) + 1
        arrays = []
        for values, fill in ((rough, 0.0), (ior, 1.0)):
            table = np.full(size, fill)
            for index, value in values.items():
                table[index] = value
            array = jit_array(mi.Float, np.minimum(table, 1e30), np.float32)
            dr.make_opaque(array)
            arrays.append(array)
        from .film import FilterSampler
        from .path import pinhole_scales

        if not scene.motions():  # nothing moves: no apparent motion, no projection needed
            pinhole = (0.0, 0.0)
        elif (pinhole := pinhole_scales(scene.sensor)) is not None:  # data, not code: another field of view reuses the kernel
            pinhole = tuple(dr.opaque(mi.Float, scale) for scale in pinhole)
        return cls(*arrays, film=FilterSampler(scene.sensor.film()), pinhole=pinhole, refracts=any(v != 1.0 for v in ior.values()))

    def gather(self, table, bsdf, active):
        """The entry of ``table`` (``roughness`` or ``relative_ior``) of each lane's BSDF
        pointer ``bsdf``, where ``active``.

        Parameters
        ----------
        table : mi.Float
            ``roughness`` or ``relative_ior``.
        bsdf : mi.BSDFPtr
        active : mi.Bool

        Returns
        -------
        mi.Float
        """
        import drjit as dr
        import mitsuba as mi

        return dr.gather(mi.Float, table, dr.reinterpret_array(mi.UInt32, bsdf), active)


def _roughness(bsdf) -> float:
    import mitsuba as mi

    flags = bsdf.flags()
    if flags & int(mi.BSDFFlags.Delta):
        return 0.0
    if flags & int(mi.BSDFFlags.Glossy):
        params = mi.traverse(bsdf)
        alphas = [float(np.mean(np.asarray(params[k]))) for k in params.keys() if k.split(".")[-2 if k.endswith(".value") else -1].startswith("alpha")]
        return sum(alphas) / len(alphas) if alphas else 0.0
    return math.inf


def relative_ior(bsdf) -> float:
    """η of a surface that refracts (``dielectric``, ``roughdielectric``), 1 for any other
    whose light passes straight through or not at all (``thindielectric``, ``null``,
    ``mask``: Mitsuba's null transmission).

    Parameters
    ----------
    bsdf : mi.BSDF

    Returns
    -------
    float

    Raises
    ------
    ValueError
        A BSDF that transmits light into the surface other than on its own as a dielectric
        (``principled`` with ``spec_trans`` > 0, a dielectric inside ``mask`` or
        ``blendbsdf``, diffuse transmission): the optical length through it is not known.
    """
    import mitsuba as mi

    name = bsdf.class_name()
    through = int(mi.BSDFFlags.DeltaTransmission) | int(mi.BSDFFlags.GlossyTransmission) | int(mi.BSDFFlags.DiffuseTransmission)
    if bsdf.flags() & through and name not in _REFRACTING:
        raise ValueError(
            f"BSDF {bsdf.id() or name!r} ({name}) transmits light through the surface, and the optical path length "
            "through it is not known here; a transmitting surface must be a dielectric or roughdielectric BSDF of its own "
            "(not inside mask, blendbsdf or twosided; principled with spec_trans 0); thindielectric, null and mask "
            "(around an opaque BSDF) pass light straight through and are fine"
        )
    if name not in _REFRACTING:
        return 1.0
    return float(np.asarray(mi.traverse(bsdf)["eta"]).ravel()[0])
