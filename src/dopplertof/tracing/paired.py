"""Paired tracing: a primal path and its shifted partner in one lane (reconnection, adaptive).

Each lane traces one group of two correlated times: the *primal* path P1 at its own time
and its *partner* P2 at the other time, built from the same phases as the independent
tracer (:mod:`dopplertof.tracing.path`); what is paired is only the shift, its Jacobian,
the primal/partner MIS and the analytic integration. The shift is chosen per bounce:

* **replay**: P2 samples its BSDF with P1's random numbers (Jacobian 1);
* **reconnection**: P2 aims at P1's next vertex re-timed to P2's time, x₂' = M(t₂)M(t₁)⁻¹x₁'
  (same body-local point), with the solid-angle Jacobian dω₁/dω₂ = G₁/G₂, G = |cos θ'|/d²
  (rigid motion preserves area). An occluded reconnection ends P2.

``reconnection`` reconnects wherever both current vertices can (no delta lobe);
``adaptive`` only where both are rougher than the threshold
(:mod:`dopplertof.tracing.materials`) and replays elsewhere. The decision depends only on
the two current vertices, so the shift is its own inverse, which the MIS below needs.

Unbiasedness (the primal/partner MIS of the original §3.3, balance heuristic). Which member
of the pair is primal is a fair coin, so at every time t a path x is produced by four
techniques: primal or shifted, times NEE or BSDF sampling of its last vertex. With the
densities q of all four, each contribution is f(x)·W / Σq; the weights sum to one wherever
a technique can produce x, and a technique that cannot (the partner terminated, escaped or
its reconnection was occluded) has q = 0. Per path the code keeps β = f/p_primal and the
prefix ratio r = p_shift/p_primal, so Σq/p_primal = (p_own + p_light) + r·(p_shift + p_light)
for the last vertex (the light sample is shared, so its density is the same in both roles).
Russian roulette is off in paired tracing (its decisions would enter the densities); the
path ends at ``max_depth`` (``MAX_PAIRED_DEPTH`` for -1). Sphere emitters, which Mitsuba
samples by solid angle, are the one case where a shared light sample does not map to the
same light point.

The pair's sum of weighted contributions is one unbiased unit of the exposure average.

**Analytic mode** (``time_sampling="analytic"``, the original's M06 mode, biased): P1 at
the start of the exposure and its partner (replay or reconnection) at the end, no role
swap; each contribution is integrated in closed form over the exposure from its values at
the two ends (:meth:`~dopplertof.tracing.sink.Sink.add_analytic`: X and L linear in time
while P2 stays on P1's surfaces, else a linear fade between the two ends). Unlike the
original, P2 outlives P1 as a path of its own, so that contributions appearing during the
exposure count as those disappearing do, and an occluded reconnection lets P2 go on from
what it hit (the direction's density is the shift's whatever it hits). Biased per pixel wherever X or L are not linear in
time (occlusion changes, rotations); its bias per scene is measured by
``benchmarks/analytic_bias.py``.
"""

from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi

from .. import modulation
from ..timesampling import ANALYTIC, ANALYTIC_TIMES
from . import lanes
from .path import (
    camera_ray, emitter_hit, emitter_hit_length, extend, float64_distances, ground_truth, met_motion, next_hit, place_camera_ray, sample_emitter, segment_index, vertex_interaction,
)  # fmt: skip
from .sink import Sink

MAX_PAIRED_DEPTH = 64  # bound for max_depth = -1 (no Russian roulette in paired tracing)


def _geometry_term(p_from, p_to, n_to):
    """|cos θ at p_to| / distance² (converts solid angle at p_from to area at p_to)."""
    d = p_to - p_from
    dist2 = dr.squared_norm(d)
    return dr.abs(dr.dot(n_to, d)) * dr.rsqrt(dist2) / dist2


def _light_geometry(si, ds):
    """G at the light point for a shared light sample; 1 for delta and infinite emitters."""
    g = _geometry_term(si.p, ds.p, ds.n)
    return dr.select(ds.delta | ~dr.isfinite(g) | (g <= 0), 1.0, g)


def _pair_times(setup, settings, seed, pixel, group, rng):
    """(u1, u2): the group's two normalised times, which of them is primal a fair coin."""
    r_shared = rng.next_float32()
    times = []
    for member in (0, 1):
        r_own = lanes.seeded_pcg(seed, lanes.STREAM_OWN, pixel, group * 2 + member).next_float32()
        times.append(lanes.sample_time(setup, settings, seed, pixel, group, member, r_shared, r_own))
    swap = rng.next_float32() < 0.5  # which member is primal (module docstring)
    return dr.select(swap, times[1], times[0]), dr.select(swap, times[0], times[1])


@dr.syntax
def trace_pair(scene, settings, setup, tables):
    """Trace one pass of pairs; the outputs of :func:`dopplertof.tracing.single.trace`,
    one entry per pair (``hits`` counts the members whose camera ray hit: 0, 1 or 2).

    Parameters
    ----------
    scene : DynamicScene
    settings : RenderSettings
    setup : LaneSetup
    tables : MaterialTables

    Returns
    -------
    dict
        Name → per-pair Dr.Jit array, not yet evaluated.
    """
    pixel, group_in_pass = lanes.pixel_and_index(setup, setup.samples // 2)
    group = group_in_pass + lanes.opaque_u32(setup.first_sample // 2)
    seed = lanes.opaque_u32(setup.seed)
    rng = lanes.seeded_pcg(seed, lanes.STREAM_SHARED, pixel, group)

    # ---------------------------------------------------------------- exposure times
    analytic = settings.time_sampling == ANALYTIC
    if dr.hint(analytic, mode="scalar"):  # the exposure's ends, P1 first
        u1, u2 = (mi.Float64(u) for u in ANALYTIC_TIMES)
    else:
        u1, u2 = _pair_times(setup, settings, seed, pixel, group, rng)
    time1, time2 = lanes.lane_times(setup, u1), lanes.lane_times(setup, u2)
    poses1, poses2 = scene.poses(time1), scene.poses(time2)
    poses1_64, poses2_64 = scene.poses(time1, precise=True), scene.poses(time2, precise=True)
    sink = Sink(settings.cameras)
    bank1, bank2 = sink.bank(u1), sink.bank(u2)

    # ---------------------------------------------------------------- camera vertices (one ray)
    ray, ray_weight, x0 = camera_ray(scene.sensor, tables.film, setup, pixel, time1, rng.next_float32, lambda: mi.Point2f(rng.next_float32(), rng.next_float32()))
    ray1, x0_1 = place_camera_ray(scene, ray, x0, time1)
    ray2, x0_2 = place_camera_ray(scene, ray, x0, time2)
    hit1 = next_hit(scene, ray1, time1, poses1, settings.hide_emitters)
    hit2 = next_hit(scene, ray2, time2, poses2, settings.hide_emitters)
    # Float64 distances where a member's path may differ from its partner's (path.float64_distances):
    # a path that met no moving body is the same path at both times.
    distances64 = float64_distances(scene, sink.needs_length)
    met1, precise1 = met_motion(distances64, mi.Bool(False), hit1)
    met2, precise2 = met_motion(distances64, mi.Bool(False), hit2)
    length1, x1, t1 = extend(scene, poses1_64, hit1, x0_1, ray1.d, mi.Float64(0), mi.Float(1), True, precise1)
    length2, x2, t2 = extend(scene, poses2_64, hit2, x0_2, ray2.d, mi.Float64(0), mi.Float(1), True, precise2)
    truth1, valid1 = ground_truth(scene, hit1, ray1.d, t1, time1, tables.pinhole)
    truth2, valid2 = ground_truth(scene, hit2, ray2.d, t2, time2, tables.pinhole)
    label = truth1.pop("instance_id")
    truth2.pop("instance_id")
    truth = {k: truth1[k] + truth2[k] for k in truth1}
    hits = dr.select(valid1, mi.Float(1), 0.0) + dr.select(valid2, mi.Float(1), 0.0)

    correlation = settings.correlation_spec
    threshold = mi.Float({"reconnection": 0.0, "adaptive": correlation.threshold}.get(correlation.mode, math.inf))
    dr.make_opaque(threshold)
    bsdf_ctx = mi.BSDFContext()
    max_depth = lanes.opaque_u32(MAX_PAIRED_DEPTH if settings.max_depth < 0 else settings.max_depth)  # data: another depth reuses the kernel
    hide_emitters = settings.hide_emitters
    # Which techniques a member's estimate combines: both roles (MIS), or in analytic mode
    # P1 as primal only and P2 as shifted only (two estimates at the exposure's ends).
    own_coef = (1.0, 0.0) if analytic else (1.0, 1.0)
    shift_coef = (0.0, 1.0) if analytic else (1.0, 1.0)
    opaque_cameras = [modulation.OpaqueCamera(c) for c in settings.cameras] if analytic else []

    # ---------------------------------------------------------------- loop state
    state = sink.empty()
    depth = mi.UInt32(0)
    si1, si2 = hit1.si, hit2.si
    body1, body2 = hit1.body, hit2.body
    ray1, ray2 = mi.Ray3f(ray1), mi.Ray3f(ray2)  # loop state: two objects, even where one ray was placed
    beta1, beta2 = mi.Spectrum(ray_weight), mi.Spectrum(ray_weight)
    index1, index2 = mi.Float(1), mi.Float(1)  # refractive index each member travels in
    r1, r2 = mi.Float(1), mi.Float(1)  # p_shift / p_primal of the prefix
    prev_it1, prev_it2 = dr.zeros(mi.Interaction3f), dr.zeros(mi.Interaction3f)
    prev_pdf1, prev_pdf2 = mi.Float(1), mi.Float(1)  # own BSDF pdf of the last direction
    prev_shift1, prev_shift2 = mi.Float(1), mi.Float(1)  # its density in the shifted role
    prev_r1, prev_r2 = mi.Float(1), mi.Float(1)
    prev_delta1, prev_delta2 = mi.Bool(True), mi.Bool(True)
    active1 = mi.Bool(True)  # P1's ray was traced: its hit (or escape) is to be shaded
    active2 = mi.Bool(True)  # the same for P2, which also needs P1 alive
    continuous = mi.Bool(True)  # analytic mode: P2's vertices so far lie on P1's surfaces
    tracing = mi.Bool(True)  # P1 alive; in analytic mode P1 or P2

    while dr.hint(
        tracing,
        label="dopplertof paired path",
        max_iterations=-1,
        exclude=[scene, correlation, bank1, bank2, poses1, poses2, poses1_64, poses2_64, tables, sink, bsdf_ctx, threshold, analytic, own_coef, shift_coef, opaque_cameras, distances64],
    ):
        valid1 = active1 & si1.is_valid()
        if dr.hint(analytic, mode="scalar"):
            # P2 outlives P1 as a path of its own (BSDF sampling with the shared numbers): its
            # contributions missing at the exposure's start fade in, as P1's lone ones fade out.
            valid2 = active2 & si2.is_valid()
            continuous &= (body1 == body2) & (si1.shape == si2.shape)
        else:
            active2 &= active1
            valid2 = active2 & valid1 & si2.is_valid()  # a shifted vertex needs its primal vertex

        # ---------------------------------------------------- emitter hit
        contributions = []
        members = (
            (si1, body1, time1, active1, prev_it1, prev_pdf1, prev_shift1, prev_r1, prev_delta1, beta1, length1, index1, x1, ray1),
            (si2, body2, time2, active2, prev_it2, prev_pdf2, prev_shift2, prev_r2, prev_delta2, beta2, length2, index2, x2, ray2),
        )
        for member, (si, body, time_s, act, prev_it, prev_pdf, prev_shift, prev_r, prev_delta, beta, length, index, x, ray) in enumerate(members):
            shown = act if not hide_emitters else act & (depth > 0)
            le, light_pdf, visible = emitter_hit(scene, si, body, prev_it, prev_delta, time_s, shown)
            denominator = own_coef[member] * (prev_pdf + light_pdf) + shift_coef[member] * prev_r * (prev_shift + light_pdf)
            weight = dr.select(denominator > 0, prev_pdf / denominator, 0.0)
            contributions.append((beta * le * weight, emitter_hit_length(scene, si, length, index, x, ray.d), visible))

        # ---------------------------------------------------- shift decision for this bounce
        bsdf1, bsdf2 = si1.bsdf(ray1), si2.bsdf(ray2)
        rough1 = tables.gather(tables.roughness, bsdf1, valid1)
        rough2 = tables.gather(tables.roughness, bsdf2, valid2)
        reconnect = valid2 & (rough1 > threshold) & (rough2 > threshold)
        r1_here = dr.select(valid2, r1, 0.0)  # no partner vertex: no shifted technique

        # ---------------------------------------------------- emitter sampling (one shared light sample)
        go_on = (depth + 1) < max_depth
        sample_em = mi.Point2f(rng.next_float32(), rng.next_float32())
        light1 = sample_emitter(scene, si1, bsdf1, bsdf_ctx, sample_em, time1, poses1, length1, index1, x1, tables, valid1 & go_on)
        light2 = sample_emitter(scene, si2, bsdf2, bsdf_ctx, sample_em, time2, poses2, length2, index2, x2, tables, valid2 & go_on)
        g1, g2 = _light_geometry(si1, light1.ds), _light_geometry(si2, light2.ds)
        pdf1 = dr.select(light1.ds.delta, 0.0, light1.bsdf_pdf)
        pdf2 = dr.select(light2.ds.delta, 0.0, light2.bsdf_pdf)
        shift_pdf1 = dr.select(reconnect, pdf2 * g2 / g1, pdf1)
        shift_pdf2 = dr.select(reconnect, pdf1 * g1 / g2, pdf2)
        for member, (light, pdf, shift_pdf, r, beta, act) in enumerate((
            (light1, pdf1, shift_pdf1, r1_here, beta1, light1.active),
            (light2, pdf2, shift_pdf2, r2, beta2, light2.active & valid2),
        )):
            light_pdf = dr.select(light.ds.delta, 1.0, light.ds.pdf)
            denominator = own_coef[member] * (light_pdf + pdf) + shift_coef[member] * r * (light_pdf + shift_pdf)
            weight = dr.select(denominator > 0, light_pdf / denominator, 0.0)
            contributions.append((beta * light.bsdf_value * light.weight * weight, light.length_m, act))

        # ---------------------------------------------------- accumulate
        if dr.hint(analytic, mode="scalar"):  # pairs (P1, P2): emitter hits, then NEE
            for k in (0, 2):
                state = sink.add_analytic(state, opaque_cameras, contributions[k], contributions[k + 1], continuous)
        else:
            for k, (contrib, length, mask) in enumerate(contributions):  # each member at its own time
                state = sink.add(state, (bank1, bank2)[k % 2], contrib, length, mask)

        # ---------------------------------------------------- BSDF sampling: P1, then P2 (replay)
        sample_1 = rng.next_float32()
        sample_2 = mi.Point2f(rng.next_float32(), rng.next_float32())
        next1 = valid1 & go_on
        bs1, bsdf_weight1 = bsdf1.sample(bsdf_ctx, si1, sample_1, sample_2, next1)
        next1 &= (bs1.pdf > 0) & (dr.max(mi.unpolarized_spectrum(bsdf_weight1)) > 0)
        ray1_next = si1.spawn_ray(si1.to_world(bs1.wo))
        hit1n = scene.intersect(ray1_next, time1, next1, poses=poses1)
        bs2, bsdf_weight2 = bsdf2.sample(bsdf_ctx, si2, sample_1, sample_2, valid2 & go_on)

        # ---------------------------------------------------- P2 by reconnection to P1's next vertex
        # An escaped P1 is reconnected at infinity: P2 leaves in the same world direction
        # (Jacobian 1), so the shift stays its own inverse for paths that leave the scene.
        reconnect &= next1
        at_infinity = reconnect & ~hit1n.si.is_valid()
        pose2 = scene.select_pose(poses2, hit1n.body)  # P1's next body at P2's time
        target2 = pose2.point_to_world(hit1n.p_local)
        origin2 = si2.spawn_ray_to(target2).o  # aim from the offset origin the ray will use
        d2 = dr.select(at_infinity, ray1_next.d, dr.normalize(target2 - origin2))
        value_r, pdf_r = bsdf2.eval_pdf(bsdf_ctx, si2, si2.to_local(d2), reconnect)
        ray2_next = dr.select(reconnect & ~at_infinity, mi.Ray3f(origin2, d2), si2.spawn_ray(dr.select(reconnect, d2, si2.to_world(bs2.wo))))
        next2 = valid2 & go_on & dr.select(reconnect, pdf_r > 0, bs2.pdf > 0)
        hit2n = scene.intersect(ray2_next, time2, next2, poses=poses2)
        expected = dr.norm(target2 - ray2_next.o)
        landed = hit2n.si.is_valid() & (hit2n.body == hit1n.body) & (dr.abs(hit2n.si.t - expected) <= 1e-4 * expected + 1e-5)
        landed = dr.select(at_infinity, ~hit2n.si.is_valid(), landed)
        if dr.hint(analytic, mode="scalar"):
            pass  # an occluded reconnection: P2 goes on from what it hit (an occlusion change, faded)
        else:
            next2 &= ~reconnect | landed  # the shift must be invertible for the MIS

        # ---------------------------------------------------- optical lengths and Jacobians
        index1_next = segment_index(index1, tables, bsdf1, next1, si1.wi, bs1.wo)
        wo2 = dr.select(reconnect, si2.to_local(d2), bs2.wo)
        index2_next = segment_index(index2, tables, bsdf2, next2, si2.wi, wo2)
        met1, precise1 = met_motion(distances64, met1, hit1n)
        met2, precise2 = met_motion(distances64, met2, hit2n)
        length1_next, x1n, _ = extend(scene, poses1_64, hit1n, x1, ray1_next.d, length1, index1_next, next1, precise1)
        length2_next, x2n, _ = extend(scene, poses2_64, hit2n, x2, ray2_next.d, length2, index2_next, next2, precise2)
        # A reconnected pair shares the body-local point: its lengths differ by the motion only.
        p_local64 = mi.Vector3d(hit1n.p_local)
        x1r = scene.select_pose(poses1_64, hit1n.body).point_to_world(p_local64)
        x2r = scene.select_pose(poses2_64, hit1n.body).point_to_world(p_local64)
        at_point = reconnect & ~at_infinity
        length1_next = dr.select(at_point & next1, length1 + mi.Float64(index1_next) * dr.norm(x1r - x1), length1_next)
        length2_next = dr.select(at_point & landed & next2, length2 + mi.Float64(index2_next) * dr.norm(x2r - x2), length2_next)
        x1n = dr.select(at_point, x1r, x1n)
        x2n = dr.select(at_point & landed, x2r, x2n)
        # The shift's Jacobian is that of the direction towards the target, whatever P2 hits.
        target_n2 = pose2.normal_to_world(hit1n.n_local)
        g1n = dr.select(at_infinity, 1.0, _geometry_term(si1.p, hit1n.si.p, hit1n.si.n))
        g2n = dr.select(at_infinity, 1.0, _geometry_term(si2.p, target2, target_n2))
        own_pdf2 = dr.select(reconnect, pdf_r, bs2.pdf)
        shift_n1 = dr.select(next2, dr.select(reconnect, pdf_r * g2n / g1n, bs1.pdf), 0.0)
        shift_n2 = dr.select(reconnect, bs1.pdf * g1n / g2n, bs2.pdf)
        weight2 = dr.select(reconnect, value_r / dr.maximum(pdf_r, 1e-30), bsdf_weight2)

        # ---------------------------------------------------- update
        prev_it1, prev_it2 = vertex_interaction(si1), vertex_interaction(si2)
        prev_pdf1, prev_pdf2 = bs1.pdf, own_pdf2
        prev_shift1, prev_shift2 = shift_n1, shift_n2
        prev_r1, prev_r2 = r1_here, r2
        prev_delta1 = mi.has_flag(bs1.sampled_type, mi.BSDFFlags.Delta)
        prev_delta2 = ~reconnect & mi.has_flag(bs2.sampled_type, mi.BSDFFlags.Delta)
        r1 = r1_here * shift_n1 / dr.select(bs1.pdf > 0, bs1.pdf, 1.0)
        r2 = r2 * shift_n2 / dr.select(own_pdf2 > 0, own_pdf2, 1.0)
        beta1 *= bsdf_weight1
        beta2 *= weight2
        index1, index2 = index1_next, index2_next
        length1, length2 = length1_next, length2_next
        x1, x2 = x1n, x2n
        si1, si2 = hit1n.si, hit2n.si
        body1, body2 = hit1n.body, hit2n.body
        ray1, ray2 = ray1_next, ray2_next
        depth += 1
        active1 = next1
        active2 = next2
        tracing = active1 | active2 if analytic else active1

    return sink.outputs(state, truth, hits, label)
