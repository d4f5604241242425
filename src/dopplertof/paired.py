"""Paired tracing: a primal path and its shifted partner in one lane (reconnection, adaptive).

Each lane traces one group of two correlated times: the *primal* path P1 at its own time
and its *partner* P2 at the other time, obtained from P1 by a shift mapping chosen per
bounce:

* **replay**: P2 samples its BSDF with P1's random numbers (Jacobian 1);
* **reconnection**: P2 aims at P1's next vertex re-timed to P2's time, x₂' = M(t₂)M(t₁)⁻¹x₁'
  (same body-local point), with the solid-angle Jacobian dω₁/dω₂ = G₁/G₂, G = |cos θ'|/d²
  (rigid motion preserves area). An occluded reconnection ends P2.

``reconnection`` reconnects wherever both current vertices can (no delta lobe);
``adaptive`` only where both are rougher than ``threshold`` (diffuse = ∞, rough conductor,
dielectric or plastic = their mean α, anything with a delta lobe = 0) and replays
elsewhere. The decision depends only on the two current vertices, so the shift is its own
inverse, which the MIS below needs.

Unbiasedness (the primal/partner MIS of the original §3.3, balance heuristic). Which member
of the pair is primal is a fair coin, so at every time t a path x is produced by four
techniques: primal or shifted, times NEE or BSDF sampling of its last vertex. With the
densities q of all four, each contribution is f(x)·W / Σq; the weights sum to one wherever
a technique can produce x, and a technique that cannot (the partner terminated, escaped or
its reconnection was occluded) has q = 0. Per path the code keeps β = f/p_primal and the
prefix ratio r = p_shift/p_primal, so Σq/p_primal = (p_own + p_light) + r·(p_shift + p_light)
for the last vertex (the light sample is shared, so its density is the same in both roles).
Russian roulette is off in paired tracing (its decisions would enter the densities); the
path ends at ``max_depth``. Sphere emitters, which Mitsuba samples by solid angle, are the
one case where a shared light sample does not map to the same light point.

The pair's sum of weighted contributions is one unbiased unit of the exposure average.

**Analytic mode** (``time_sampling="analytic"``, the original's M06 mode, biased): P1 at
the start of the exposure and its partner (replay or reconnection) at the end, no role
swap. Each emitter contribution X and path length L are taken as linear in time between
the two, and the low-pass sinusoid is integrated in closed form,
(g₁/2)∫₀¹ cos(2πhu + ψ + kL(u))·X(u) du, with ψ included (the original omits it). Where
the partner has no matching contribution, X is held constant. Only for low-pass sinusoid
cameras. Biased wherever L or X are not linear in time (occlusion changes, rotations).
"""

from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi

from . import modulation, timesampling
from .modulation import TWO_PI
from .integrator import (
    _STREAM_OWN,
    _STREAM_PERM,
    _STREAM_SHARED,
    _accumulate,
    _aperture_point,
    _opaque_u32,
    _seeded_pcg,
    camera_ray,
    hit_distance64,
    lane_times,
    radial_velocities,
)

MAX_PAIRED_DEPTH = 64  # bound for max_depth = -1 (no Russian roulette in paired tracing)


def roughness_table(scene):
    """Per-BSDF roughness indexed by Dr.Jit registry id (mi.Float); see the module docstring."""
    import numpy as np

    values = {}
    for mi_scene in [scene.static] + [body.scene for body in scene.bodies]:
        for shape in mi_scene.shapes():
            bsdf = shape.bsdf()
            if bsdf is None:
                continue
            index = int(dr.reinterpret_array(mi.UInt32, mi.BSDFPtr(bsdf))[0])
            values[index] = _roughness(bsdf)
    table = np.zeros(max(values, default=0) + 1)
    for index, value in values.items():
        table[index] = value
    array = mi.Float(np.minimum(table, 1e30).astype(np.float32))
    dr.make_opaque(array)
    return array


def _roughness(bsdf) -> float:
    import numpy as np

    flags = bsdf.flags()
    if flags & int(mi.BSDFFlags.Delta):
        return 0.0
    if flags & int(mi.BSDFFlags.Glossy):
        params = mi.traverse(bsdf)
        alphas = [float(np.mean(np.asarray(params[k]))) for k in params.keys() if k.split(".")[-2 if k.endswith(".value") else -1].startswith("alpha")]
        return sum(alphas) / len(alphas) if alphas else 0.0
    return math.inf


def _geometry_term(p_from, p_to, n_to):
    """|cos θ at p_to| / distance² (converts solid angle at p_from to area at p_to)."""
    d = p_to - p_from
    dist2 = dr.squared_norm(d)
    return dr.abs(dr.dot(n_to, d)) * dr.rsqrt(dist2) / dist2


def _ground_truth(scene, ray, members):
    """Camera-ray depth and velocities averaged over the members that hit, and their count."""
    sums = [mi.Float(0) for _ in range(4)]
    for hit, t64, time_s, poses in members:
        valid = hit.si.is_valid()
        ray_velocity, point_velocity = radial_velocities(scene, hit, ray.d, time_s, poses)
        for k, value in enumerate((mi.Float(1), mi.Float(t64), ray_velocity, point_velocity)):
            sums[k] += dr.select(valid, value, 0.0)
    per_hit = dr.rcp(dr.maximum(sums[0], 1.0))
    return sums[1] * per_hit, sums[2] * per_hit, sums[3] * per_hit, sums[0]


HIDDEN_EMITTER_LAYERS = 4  # hidden emitter surfaces a camera ray may pass through


def _camera_hit(scene, ray, time_s, poses, hide_emitters):
    """First hit of the camera ray; with ``hide_emitters`` it passes through emitter
    surfaces (as stock ``path``; at most ``HIDDEN_EMITTER_LAYERS`` of them)."""
    hit = scene.intersect(ray, time_s, True, poses=poses)
    for _ in range(HIDDEN_EMITTER_LAYERS if hide_emitters else 0):
        hidden = hit.si.is_valid() & (hit.si.emitter(scene.static) != None)  # noqa: E711 - Dr.Jit pointer test
        beyond = scene.intersect(hit.si.spawn_ray(ray.d), time_s, hidden, poses=poses)
        hit = dr.select(hidden, beyond, hit)
    return hit


def _light_geometry(si, ds):
    """G at the light point for a shared light sample; 1 for delta and infinite emitters."""
    g = _geometry_term(si.p, ds.p, ds.n)
    return dr.select(ds.delta | ~dr.isfinite(g) | (g <= 0), 1.0, g)


def _analytic_integral(cam, length1_m, length2_m, x1, x2):
    """(g₁/2)∫₀¹ cos(a u + b)(x1 + (x2 − x1)u) du, a = 2πh + k(L2 − L1), b = ψ + kL1 (Float64)."""
    a = TWO_PI * cam.heterodyne + cam.wavenumber * (length2_m - length1_m)
    b = modulation.wrap_phase(cam.phase + cam.wavenumber * length1_m)
    sin_b, cos_b = dr.sincos(b)
    sin_ab, cos_ab = dr.sincos(a + b)
    small = dr.abs(a) < 1e-4
    a_safe = dr.select(small, 1.0, a)
    constant = dr.select(small, cos_b - 0.5 * a * sin_b, (sin_ab - sin_b) / a_safe)  # ∫cos
    linear = dr.select(small, 0.5 * cos_b - a * sin_b / 3.0, sin_ab / a_safe + (cos_ab - cos_b) / dr.square(a_safe))  # ∫u cos
    return 0.5 * cam.g1 * (x1 * constant + (x2 - x1) * linear)


def _pair_times(rng, seed, pixel, group, setup, time_sampling):
    """(u1, u2): the group's two normalised times, which of them is primal a fair coin."""
    r_time_shared = rng.next_float32()
    n_groups = max(setup.spp_total // 2, 1)
    times = []
    for member in (0, 1):
        r_own = _seeded_pcg(seed, _STREAM_OWN, pixel, group * 2 + member).next_float32()
        perm_seed = mi.sample_tea_32(seed ^ _STREAM_PERM, pixel * 2 + member, 4)[0]
        args = (r_time_shared, r_own, group, mi.UInt32(member), n_groups, 2, time_sampling.shift, time_sampling.stratify_intervals, perm_seed)
        times.append(timesampling.sample_times(time_sampling.method, *args))
    swap = rng.next_float32() < 0.5  # which member is primal (module docstring)
    return dr.select(swap, times[1], times[0]), dr.select(swap, times[0], times[1])


@dr.syntax
def trace_pair(scene, setup, cameras, time_sampling, correlation, max_depth=5, hide_emitters=False, roughness=None):
    """Trace one pass of pairs; same outputs as :func:`dopplertof.integrator.trace`, one
    entry per pair (``hit`` counts the members whose camera ray hit: 0, 1 or 2)."""
    lane = dr.arange(mi.UInt32, setup.n_pixels * (setup.samples_per_pixel_pass // 2))
    groups_pass = _opaque_u32(setup.samples_per_pixel_pass // 2)
    pixel = lane // groups_pass
    group = lane % groups_pass + _opaque_u32(setup.first_sample // 2)
    seed = _opaque_u32(setup.seed)
    rng = _seeded_pcg(seed, _STREAM_SHARED, pixel, group)

    # ---------------------------------------------------------------- exposure times
    analytic = time_sampling.method == timesampling.ANALYTIC
    if dr.hint(analytic, mode="scalar"):  # the exposure's ends, P1 first
        u1, u2 = mi.Float64(0.0), mi.Float64(1.0)
    else:
        u1, u2 = _pair_times(rng, seed, pixel, group, setup, time_sampling)
    time1, time2 = lane_times(setup, u1), lane_times(setup, u2)
    poses1, poses2 = scene.poses(time1), scene.poses(time2)
    poses1_64, poses2_64 = scene.poses(time1, precise=True), scene.poses(time2, precise=True)
    bank1, bank2 = modulation.CameraBank(cameras, u1), modulation.CameraBank(cameras, u2)

    # ---------------------------------------------------------------- camera rays (shared)
    sensor = scene.sensor
    ray, ray_weight = camera_ray(sensor, setup, pixel, time1, rng.next_float32, lambda: mi.Point2f(rng.next_float32(), rng.next_float32()))
    x0 = _aperture_point(sensor, ray)
    hit1 = _camera_hit(scene, ray, time1, poses1, hide_emitters)
    hit2 = _camera_hit(scene, ray, time2, poses2, hide_emitters)
    t1_64, x1 = hit_distance64(scene, poses1_64, hit1, x0, ray.d)
    t2_64, x2 = hit_distance64(scene, poses2_64, hit2, x0, ray.d)

    depth_gt, velocity_gt, point_velocity_gt, hits = _ground_truth(scene, ray, ((hit1, t1_64, time1, poses1), (hit2, t2_64, time2, poses2)))

    if roughness is None:
        roughness = roughness_table(scene)
    threshold = mi.Float({"reconnection": 0.0, "adaptive": correlation.threshold}.get(correlation.mode, math.inf))
    dr.make_opaque(threshold)
    bsdf_ctx = mi.BSDFContext()
    static = scene.static
    max_depth_u = MAX_PAIRED_DEPTH if max_depth < 0 else max_depth

    # ---------------------------------------------------------------- loop state
    depth = mi.UInt32(0)
    si1, si2 = hit1.si, hit2.si
    ray1, ray2 = mi.Ray3f(ray), mi.Ray3f(ray)
    beta1, beta2 = mi.Spectrum(ray_weight), mi.Spectrum(ray_weight)
    r1, r2 = mi.Float(1), mi.Float(1)  # p_shift / p_primal of the prefix
    length1, length2 = t1_64, t2_64  # Float64 optical path lengths to the current vertices
    prev_p1, prev_p2 = mi.Point3f(ray.o), mi.Point3f(ray.o)
    prev_pdf1, prev_pdf2 = mi.Float(1), mi.Float(1)  # own BSDF pdf of the last direction
    prev_shift1, prev_shift2 = mi.Float(1), mi.Float(1)  # its density in the shifted role
    prev_r1, prev_r2 = mi.Float(1), mi.Float(1)
    prev_delta1, prev_delta2 = mi.Bool(True), mi.Bool(True)
    radiance = mi.Spectrum(0)
    measurements = [mi.Float(0) for _ in cameras]
    # Which techniques a member's estimate combines: both roles (MIS), or in analytic mode
    # P1 as primal only and P2 as shifted only (two estimates at the exposure's ends).
    own_coef = (1.0, 0.0) if analytic else (1.0, 1.0)
    shift_coef = (0.0, 1.0) if analytic else (1.0, 1.0)
    opaque_cameras = [modulation.OpaqueCamera(c) for c in cameras] if analytic else []
    active1 = mi.Bool(True)  # P1's ray was traced: its hit (or escape) is to be shaded
    active2 = mi.Bool(True)  # the same for P2, which also needs P1 alive

    while dr.hint(
        active1,
        label="dopplertof paired path",
        max_iterations=-1,
        exclude=[scene, correlation, bank1, bank2, poses1, poses2, poses1_64, poses2_64, static, bsdf_ctx, roughness, threshold, analytic, own_coef, shift_coef, opaque_cameras],
    ):
        active2 &= active1
        valid1 = active1 & si1.is_valid()
        valid2 = active2 & valid1 & si2.is_valid()  # a shifted vertex needs its primal vertex

        # ---------------------------------------------------- emitter hit
        contributions = []
        for member, (si, act, prev_p, prev_pdf, prev_shift, prev_r, prev_delta, beta, length) in enumerate((
            (si1, active1, prev_p1, prev_pdf1, prev_shift1, prev_r1, prev_delta1, beta1, length1),
            (si2, active2, prev_p2, prev_pdf2, prev_shift2, prev_r2, prev_delta2, beta2, length2),
        )):
            emitter = si.emitter(static)
            visible = act & (emitter != None)  # noqa: E711 - Dr.Jit pointer test
            prev_it = dr.zeros(mi.Interaction3f)
            prev_it.p = prev_p
            ds = mi.DirectionSample3f(static, si, prev_it)
            light_pdf = dr.select(prev_delta | (depth == 0), 0.0, static.pdf_emitter_direction(prev_it, ds, ~prev_delta))
            denominator = own_coef[member] * (prev_pdf + light_pdf) + shift_coef[member] * prev_r * (prev_shift + light_pdf)
            le = emitter.eval(si, visible)
            weight = dr.select(denominator > 0, prev_pdf / denominator, 0.0)
            contributions.append((beta * le * weight, dr.select(si.is_valid(), length, length + 1e6), visible))

        # ---------------------------------------------------- shift decision for this bounce
        bsdf1, bsdf2 = si1.bsdf(ray1), si2.bsdf(ray2)
        rough1 = dr.gather(mi.Float, roughness, dr.reinterpret_array(mi.UInt32, bsdf1), valid1)
        rough2 = dr.gather(mi.Float, roughness, dr.reinterpret_array(mi.UInt32, bsdf2), valid2)
        reconnect = valid2 & (rough1 > threshold) & (rough2 > threshold)
        r1_here = dr.select(valid2, r1, 0.0)  # no partner vertex: no shifted technique

        # ---------------------------------------------------- emitter sampling (one shared light sample)
        go_on = (depth + 1) < max_depth_u
        sample_em = mi.Point2f(rng.next_float32(), rng.next_float32())
        nee = []
        for si, bsdf, act, x, time_s, poses in ((si1, bsdf1, valid1 & go_on, x1, time1, poses1), (si2, bsdf2, valid2 & go_on, x2, time2, poses2)):
            act &= mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
            ds, em_weight = static.sample_emitter_direction(si, sample_em, False, act)
            act &= ds.pdf != 0
            act &= ~scene.occluded(si.spawn_ray_to(ds.p), time_s, act, poses=poses)
            value, pdf = bsdf.eval_pdf(bsdf_ctx, si, si.to_local(ds.d), act)
            g = _light_geometry(si, ds)
            nee.append((ds, em_weight, value, dr.select(ds.delta, 0.0, pdf), g, act, x))
        (ds1, emw1, val1, pdf1, g1, act_em1, xe1), (ds2, emw2, val2, pdf2, g2, act_em2, xe2) = nee
        shift_pdf1 = dr.select(reconnect, pdf2 * g2 / g1, pdf1)
        shift_pdf2 = dr.select(reconnect, pdf1 * g1 / g2, pdf2)
        for member, (ds, emw, val, pdf, shift_pdf, r, beta, length, x, act) in enumerate((
            (ds1, emw1, val1, pdf1, shift_pdf1, r1_here, beta1, length1, xe1, act_em1),
            (ds2, emw2, val2, pdf2, shift_pdf2, r2, beta2, length2, xe2, act_em2 & valid2),
        )):
            light_pdf = dr.select(ds.delta, 1.0, ds.pdf)
            denominator = own_coef[member] * (light_pdf + pdf) + shift_coef[member] * r * (light_pdf + shift_pdf)
            weight = dr.select(denominator > 0, light_pdf / denominator, 0.0)
            contributions.append((beta * val * emw * weight, length + dr.norm(mi.Vector3d(ds.p) - x), act))

        # ---------------------------------------------------- accumulate
        if dr.hint(analytic, mode="scalar"):  # pairs (P1, P2): emitter hits, then NEE
            for k in (0, 2):
                (x1c, l1c, m1c), (x2c, l2c, m2c) = contributions[k], contributions[k + 1]
                both = m1c & m2c
                x2c = dr.select(both, x2c, x1c)  # no partner value: hold X constant
                l2c = dr.select(both, l2c, l1c)
                radiance = dr.select(m1c, radiance + 0.5 * (x1c + x2c), radiance)
                lum1 = mi.luminance(x1c) if mi.is_rgb else x1c[0]
                lum2 = mi.luminance(x2c) if mi.is_rgb else x2c[0]
                for i in range(len(opaque_cameras)):
                    w = _analytic_integral(opaque_cameras[i], l1c, l2c, mi.Float64(lum1), mi.Float64(lum2))
                    measurements[i] = dr.select(m1c, measurements[i] + mi.Float(w), measurements[i])
        else:
            for k, (contrib, length, mask) in enumerate(contributions):  # each member at its own time
                radiance, measurements = _accumulate(radiance, measurements, (bank1, bank2)[k % 2], contrib, length, mask)

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
        pose2_target = scene.select_pose(poses2, hit1n.body)
        target2 = pose2_target.point_to_world(hit1n.p_local)
        origin2 = si2.spawn_ray_to(target2).o  # aim from the offset origin the ray will use
        d2 = dr.select(at_infinity, ray1_next.d, dr.normalize(target2 - origin2))
        value_r, pdf_r = bsdf2.eval_pdf(bsdf_ctx, si2, si2.to_local(d2), reconnect)
        ray2_next = dr.select(reconnect & ~at_infinity, mi.Ray3f(origin2, d2), si2.spawn_ray(dr.select(reconnect, d2, si2.to_world(bs2.wo))))
        next2 = valid2 & go_on & dr.select(reconnect, pdf_r > 0, bs2.pdf > 0)
        hit2n = scene.intersect(ray2_next, time2, next2, poses=poses2)
        expected = dr.norm(target2 - ray2_next.o)
        landed = hit2n.si.is_valid() & (hit2n.body == hit1n.body) & (dr.abs(hit2n.si.t - expected) <= 1e-4 * expected + 1e-5)
        landed = dr.select(at_infinity, ~hit2n.si.is_valid(), landed)
        next2 &= ~reconnect | landed

        # ---------------------------------------------------- Float64 vertices and Jacobians
        t1n, x1n = hit_distance64(scene, poses1_64, hit1n, x1, ray1_next.d)
        t2n, x2n = hit_distance64(scene, poses2_64, hit2n, x2, ray2_next.d)
        # A reconnected pair shares the body-local point: its lengths differ by the motion only.
        p_local64 = mi.Vector3d(hit1n.p_local)
        x1r = scene.select_pose(poses1_64, hit1n.body).point_to_world(p_local64)
        x2r = scene.select_pose(poses2_64, hit1n.body).point_to_world(p_local64)
        at_point = reconnect & ~at_infinity
        x1n = dr.select(at_point, x1r, x1n)
        x2n = dr.select(at_point, x2r, x2n)
        t1n = dr.select(at_point, dr.norm(x1r - x1), t1n)
        t2n = dr.select(at_point, dr.norm(x2r - x2), t2n)
        g1n = dr.select(at_infinity, 1.0, _geometry_term(si1.p, hit1n.si.p, hit1n.si.n))
        g2n = dr.select(at_infinity, 1.0, _geometry_term(si2.p, hit2n.si.p, hit2n.si.n))
        own_pdf2 = dr.select(reconnect, pdf_r, bs2.pdf)
        shift_n1 = dr.select(next2, dr.select(reconnect, pdf_r * g2n / g1n, bs1.pdf), 0.0)
        shift_n2 = dr.select(reconnect, bs1.pdf * g1n / g2n, bs2.pdf)
        weight2 = dr.select(reconnect, value_r / dr.maximum(pdf_r, 1e-30), bsdf_weight2)

        # ---------------------------------------------------- update
        prev_p1, prev_p2 = si1.p, si2.p
        prev_pdf1, prev_pdf2 = bs1.pdf, own_pdf2
        prev_shift1, prev_shift2 = shift_n1, shift_n2
        prev_r1, prev_r2 = r1_here, r2
        prev_delta1 = mi.has_flag(bs1.sampled_type, mi.BSDFFlags.Delta)
        prev_delta2 = ~reconnect & mi.has_flag(bs2.sampled_type, mi.BSDFFlags.Delta)
        r1 = r1_here * shift_n1 / dr.select(bs1.pdf > 0, bs1.pdf, 1.0)
        r2 = r2 * shift_n2 / dr.select(own_pdf2 > 0, own_pdf2, 1.0)
        beta1 *= bsdf_weight1
        beta2 *= weight2
        length1 = dr.select(next1, length1 + t1n, length1)
        length2 = dr.select(next2, length2 + t2n, length2)
        x1, x2 = x1n, x2n
        si1, si2 = hit1n.si, hit2n.si
        ray1, ray2 = ray1_next, ray2_next
        depth += 1
        active1 = next1
        active2 = next2

    return {
        "intensity": radiance,
        "measurements": measurements,
        "hit": hits,
        "depth": depth_gt,
        "velocity": velocity_gt,
        "point_velocity": point_velocity_gt,
    }
