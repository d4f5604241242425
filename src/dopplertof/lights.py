"""Emitters at a lane's time: emitter sampling over static and moving emitters.

Emitters live in *groups*, each a Mitsuba scene in its own frame:

==========  ===============================================================================
group       emitters
==========  ===============================================================================
static      the static scene's (on static shapes, point, spot, environment, ...)
body        the area emitters on the shapes of a moving body, in the body's frame
light       a moving point or spot emitter, or a light attached to a moving camera
            (:class:`MovingLight`), in a scene of its own, in the light's frame
==========  ===============================================================================

Emitter sampling (next-event estimation) picks a group with probability proportional to
the sum of its emitters' sampling weights (Mitsuba's ``sampling_weight``); the group's
own ``sample_emitter_direction`` then picks one of its emitters in proportion to the same
weights, and a point on it, in the group's frame at the lane's time. So every emitter is
chosen as a static Mitsuba scene would choose it, and since the motions keep angles
(rigid for point and spot lights, at most an equal scale on every axis for bodies with
area emitters, which solid angles do not see; others are refused when the scene loads),
densities in the group's frame are those in the world. With only
the static group, the static scene is sampled directly, as before moving lights existed.
"""

from __future__ import annotations

from dataclasses import dataclass

NO_GEOMETRY = -1  # the body index of a group whose emitters cannot be hit (point, spot)


@dataclass
class MovingLight:
    """A point or spot emitter that moves: ``scene`` holds it in its local frame, placed in
    the world at time t by ``motion.pose(t)``; ``with_camera`` where it rides with the
    camera (an emitter in the sensor)."""

    name: str
    scene: object  # mi.Scene holding the emitter
    motion: object  # dopplertof.motion.Motion
    with_camera: bool = False


@dataclass(frozen=True)
class EmitterGroup:
    """Emitters sampled together (module docstring).

    ======  ========  ======================================================================
    scene   mi.Scene  holds the emitters, in the group's frame
    motion  Motion    places that frame in the world at a lane's time (None: static)
    body    int       hits on ``scene.bodies[body - 1]`` (0: static geometry) meet these
                      emitters; :data:`NO_GEOMETRY` for emitters no ray can hit
    weight  float     sum of the emitters' sampling weights
    ======  ========  ======================================================================
    """

    scene: object
    motion: object
    body: int
    weight: float


def _is_infinite(emitter) -> bool:
    """Whether ``emitter`` is infinitely distant (Mitsuba's ``EmitterFlags.Infinite``:
    environment maps, constant, directional and sun-sky emitters)."""
    import mitsuba as mi

    return mi.has_flag(emitter.flags(), mi.EmitterFlags.Infinite)


def _weight(mi_scene) -> float:
    return float(sum(e.sampling_weight() for e in mi_scene.emitters()))


class Emitters:
    """The emitter groups of a :class:`~dopplertof.scene.DynamicScene` and the two queries
    of a path tracer: :meth:`sample` (next-event estimation) and :meth:`pdf_hit` (the
    density with which it would have produced a direction that hit an emitter)."""

    def __init__(self, scene):
        groups = [EmitterGroup(scene.static, None, 0, _weight(scene.static))]
        groups += [EmitterGroup(b.scene, b.motion, k + 1, _weight(b.scene)) for k, b in enumerate(scene.bodies) if b.scene.emitters()]
        groups += [EmitterGroup(light.scene, light.motion, NO_GEOMETRY, _weight(light.scene)) for light in scene.lights]
        self.static = scene.static
        self.only_static = len(groups) == 1
        # Infinitely distant emitters (environment, directional) are static (others are refused).
        self.has_infinite = any(_is_infinite(e) for e in scene.static.emitters())
        self._far_reference = None
        self.groups = [g for g in groups if g.weight > 0]
        self.total = sum(g.weight for g in self.groups)

    def sample(self, it, sample, time_s, active):
        """(ds, weight, p64): a light sample seen from ``it`` (world) at ``time_s``
        (mi.Float64, s), with ``sample`` (mi.Point2f): Mitsuba's direction sample and
        emitter weight (Le/p) in the world, and the light point in Float64."""
        import drjit as dr
        import mitsuba as mi

        if self.only_static:
            ds, weight = self.static.sample_emitter_direction(it, sample, False, active)
            return ds, weight, mi.Vector3d(ds.p)
        x = sample.x * self.total
        ds_out, weight_out, p_out = dr.zeros(mi.DirectionSample3f), dr.zeros(mi.Spectrum), dr.zeros(mi.Vector3d)
        start = 0.0
        for k, g in enumerate(self.groups):
            last = k == len(self.groups) - 1
            chosen = active & (x >= start) & ((x < start + g.weight) | last)
            rescaled = mi.Point2f(dr.clip((x - start) / g.weight, 0.0, dr.one_minus_epsilon(mi.Float)), sample.y)
            if g.motion is None:
                ds, weight = g.scene.sample_emitter_direction(it, rescaled, False, chosen)
                p64 = mi.Vector3d(ds.p)
            else:
                pose, pose64 = g.motion.pose(time_s), g.motion.pose(time_s, precise=True)
                ds, weight = g.scene.sample_emitter_direction(_to_local(it, pose), rescaled, False, chosen)
                p64 = pose64.point_to_world(mi.Vector3d(ds.p))
                ds.p = pose.point_to_world(ds.p)
                ds.n = dr.normalize(pose.vector_to_world(ds.n))
                ds.d = dr.normalize(pose.vector_to_world(ds.d))
            fraction = g.weight / self.total
            ds.pdf *= fraction
            weight *= 1.0 / fraction
            ds_out = dr.select(chosen, ds, ds_out)
            weight_out = dr.select(chosen, weight, weight_out)
            p_out = dr.select(chosen, p64, p_out)
            start += g.weight
        return ds_out, weight_out, p_out

    def far_reference(self):
        """(centre, radius) of the static scene's bounding sphere (mi.Point3d, mi.Float64,
        opaque): where :func:`dopplertof.tracing.path.plane_wave_leg_m` measures the plane
        waves of infinitely distant emitters from (the origin and 0 for a scene with no
        static shape). Fixed per scene, whatever the bodies do."""
        import drjit as dr
        import mitsuba as mi

        if self._far_reference is None:
            box = self.static.bbox()
            centre, radius = (0.0, 0.0, 0.0), 0.0
            if box.valid():
                sphere = box.bounding_sphere()
                centre, radius = (float(sphere.center.x), float(sphere.center.y), float(sphere.center.z)), float(sphere.radius)
            self._far_reference = (mi.Point3d(*(dr.opaque(mi.Float64, v) for v in centre)), dr.opaque(mi.Float64, radius))
        return self._far_reference

    def pdf_hit(self, prev_it, si, body, time_s, active):
        """Density (solid angle at ``prev_it``) with which :meth:`sample` produces the
        emitter point ``si`` on ``body`` (a :class:`~dopplertof.scene.Hit`'s index; an
        escaped ray's ``si`` is invalid and meets the static scene's environment)."""
        import drjit as dr
        import mitsuba as mi

        if self.only_static:
            ds = mi.DirectionSample3f(self.static, si, prev_it)
            return self.static.pdf_emitter_direction(prev_it, ds, active)
        pdf = mi.Float(0.0)
        for g in self.groups:
            if g.body == NO_GEOMETRY:
                continue
            mask = active & (body == g.body)
            if g.motion is None:
                ds = mi.DirectionSample3f(g.scene, si, prev_it)
                pdf_g = g.scene.pdf_emitter_direction(prev_it, ds, mask)
            else:
                pose = g.motion.pose(time_s)
                si_local = mi.SurfaceInteraction3f(si)
                si_local.p = pose.point_to_local(si.p)
                si_local.n = dr.normalize(pose.vector_to_local(si.n))
                si_local.sh_frame = mi.Frame3f(dr.normalize(pose.vector_to_local(si.sh_frame.n)))  # a position sample's normal
                it_local = _to_local(prev_it, pose)
                pdf_g = g.scene.pdf_emitter_direction(it_local, mi.DirectionSample3f(g.scene, si_local, it_local), mask)
            pdf = dr.select(mask, pdf_g * (g.weight / self.total), pdf)
        return pdf


def _to_local(it, pose):
    """The point and normal of interaction ``it`` in the frame of ``pose``."""
    import drjit as dr
    import mitsuba as mi

    return mi.Interaction3f(it.t, it.time, it.wavelengths, pose.point_to_local(it.p), dr.normalize(pose.vector_to_local(it.n)))
