"""The D-ToF path tracer: one Dr.Jit symbolic loop per pass, every lane at its own time.

Each lane traces one path (NEE + BSDF sampling, power-heuristic MIS, Russian roulette)
through a :class:`~dopplertof.scene.DynamicScene` frozen at the lane's time
``t = t_start + u·T``. Every emitter contribution is added to the intensity and, for each
camera configuration, weighted by W(u, L) (:mod:`dopplertof.modulation`) with ``L`` the
optical path length of that light path, so all cameras come from the same paths.

Random numbers are replayable: two PCG32 streams per lane, seeded from
(seed, pixel, group) and (seed, pixel, sample); a draw takes the group's number where it
is correlated (:mod:`dopplertof.correlation`), so lanes of a group replay each other's
paths regardless of how the samples are split into passes. Where the correlation is the
same at every depth only the stream in use advances; a replay cut-off advances both.

The paired modes (``reconnection``, ``adaptive``) and analytic time integration trace a
primal path and its partner in one lane instead: :mod:`dopplertof.paired`.

Path lengths are accumulated in Float64 from Float64 vertices: each hit distance is
recomputed in Float64 against the hit surface's tangent plane in the body's frame, so the
length difference of two correlated paths is free of float32 cancellation (DESIGN §3.5).

=====================  ========  ==========================================================
parameter              default   meaning
=====================  ========  ==========================================================
``max_depth``          5         longest path (Mitsuba semantics: 1 = emitters only,
                                 2 = direct light); -1 = unbounded
``rr_depth``           5         depth at which Russian roulette starts
``hide_emitters``      False     hide directly visible emitters (camera rays pass
                                 through their surfaces, as in stock ``path``)
=====================  ========  ==========================================================
"""

from __future__ import annotations

from dataclasses import dataclass

import drjit as dr
import mitsuba as mi

from . import modulation

_STREAM_SHARED = 0x5EED0001
_STREAM_OWN = 0x5EED0002
_STREAM_PERM = 0x5EED0003


@dataclass
class LaneSetup:
    """Per-pass description of the lanes (host-side parameters of :func:`trace`)."""

    n_pixels: int
    width: int
    height: int
    samples_per_pixel_pass: int  # lanes per pixel in this pass
    first_sample: int  # global index of the pass's first sample in each pixel
    spp_total: int
    n_times: int  # correlated times per group (N)
    exposure_start_s: float
    exposure_s: float
    seed: int


def _opaque_u32(v):
    a = mi.UInt32(int(v) & 0xFFFFFFFF)
    dr.make_opaque(a)
    return a


def lane_times(setup, u):
    """Scene times (s, Float64) of normalised times ``u``; the exposure is opaque data, so
    another exposure window (an animation's next frame) reuses the kernel."""
    start = mi.Float64(setup.exposure_start_s)
    length = mi.Float64(setup.exposure_s)
    dr.make_opaque(start, length)
    return start + u * length


def _next_1d(rng_shared, rng_own, correlated):
    """One uniform: the group's stream where ``correlated``, else the lane's own.

    ``correlated`` is a Python bool when it is the same for every lane (only that stream
    advances) or a per-lane Bool (both advance, so each stays in step within its group).
    """
    if correlated is True:
        return rng_shared.next_float32()
    if correlated is False:
        return rng_own.next_float32()
    a = rng_shared.next_float32()
    b = rng_own.next_float32()
    return dr.select(correlated, a, b)


def _next_2d(rng_shared, rng_own, correlated):
    return mi.Point2f(_next_1d(rng_shared, rng_own, correlated), _next_1d(rng_shared, rng_own, correlated))


def _accumulate(radiance, measurements, bank, contrib, length_m, mask):
    """Add an emitter contribution to the intensity and, weighted by W(u, L), every camera."""
    radiance = dr.select(mask, radiance + contrib, radiance)
    if not bank.size:
        return radiance, measurements
    lum = mi.luminance(contrib) if mi.is_rgb else contrib[0]
    weights = bank.weights(length_m)
    return radiance, [dr.select(mask, m + w * lum, m) for m, w in zip(measurements, weights)]


def _seeded_pcg(seed_u32, stream, key_a, key_b):
    v0, v1 = mi.sample_tea_32(seed_u32 ^ stream, key_a, 4)
    rng = mi.PCG32()
    w0, w1 = mi.sample_tea_32(v0 ^ key_b, v1, 4)
    rng.seed(w0, w1)
    return rng


def _aperture_point(sensor, ray):
    """Float64 point where the camera ray leaves the aperture (the camera plane z = 0).

    Mitsuba's perspective cameras start rays at the near-clip plane; optical path lengths
    and depths are measured from the aperture instead.
    """
    to_world = sensor.world_transform()
    eye = to_world.translation()
    forward = dr.normalize(to_world @ mi.Vector3f(0, 0, 1))
    back = dr.dot(ray.o - eye, forward) / dr.dot(ray.d, forward)
    return mi.Vector3d(ray.o) - mi.Vector3d(ray.d) * mi.Float64(back)


def hit_distance64(scene, poses64, hit, x_prev, direction):
    """Float64 distance from ``x_prev`` (mi.Vector3d) along ``direction`` to ``hit``, and the point.

    Recomputed against the hit primitive's plane in the body's frame, so two correlated
    paths hitting the same primitive at different times differ by the motion alone.
    """
    pose64 = scene.select_pose(poses64, hit.body)
    d64 = dr.normalize(mi.Vector3d(direction))
    o_local = pose64.point_to_local(x_prev)
    d_local = pose64.vector_to_local(d64)
    n_local = mi.Vector3d(hit.n_local)
    t64 = dr.dot(n_local, mi.Vector3d(hit.plane_local) - o_local) / dr.dot(n_local, d_local)
    t64 = dr.select(dr.isfinite(t64) & (t64 > 0), t64, mi.Float64(hit.si.t))
    return t64, x_prev + d64 * t64


def radial_velocities(scene, hit, direction, time_s, poses):
    """(ray-fixed d/dt of the hit distance, v·d̂ of the hit point), m/s, for unit ``direction``."""
    si = hit.si
    v_surface = scene.surface_velocity(si.p, hit.body, time_s, poses=poses) if scene.bodies else mi.Vector3f(0)
    ray_fixed_rate = dr.dot(si.n, v_surface) / dr.dot(si.n, direction)
    return dr.select(dr.isfinite(ray_fixed_rate), ray_fixed_rate, 0.0), dr.dot(v_surface, direction)


def camera_ray(sensor, setup, pixel, time_s, next_1d, next_2d):
    """The camera ray of ``pixel`` (film jitter, aperture and wavelength from the draws)."""
    pixel_xy = mi.Point2f(mi.Float(pixel % setup.width), mi.Float(pixel // setup.width))
    jitter = next_2d()
    aperture = next_2d()
    wavelength_sample = next_1d()
    film_pos = (pixel_xy + jitter) / mi.ScalarVector2f(setup.width, setup.height)
    return sensor.sample_ray(mi.Float(time_s), wavelength_sample, film_pos, aperture)


def _mis_weight(pdf_a, pdf_b):
    """Power heuristic (β = 2) for pdf_a against pdf_b; 0 where both vanish."""
    a2 = dr.square(pdf_a)
    w = a2 / (a2 + dr.square(pdf_b))
    return dr.select(dr.isfinite(w), w, 0.0)


@dr.syntax
def trace(scene, setup: LaneSetup, cameras, time_sampling, correlation, max_depth=5, rr_depth=5, hide_emitters=False):
    """Trace one pass; returns a dict of per-lane Dr.Jit arrays (not yet evaluated).

    Keys: ``intensity`` (mi.Color3f / Float), ``measurements`` (list of mi.Float, one per
    camera), ``hit`` (mi.Float 0/1), ``depth`` (m), ``velocity`` (m/s, ray-fixed
    d/dt of the hit distance), ``point_velocity`` (m/s, v·d̂ of the hit point).
    """
    from . import timesampling

    n_lanes = setup.n_pixels * setup.samples_per_pixel_pass
    lane = dr.arange(mi.UInt32, n_lanes)
    spp_pass = _opaque_u32(setup.samples_per_pixel_pass)  # data, not code: any spp reuses the kernel
    pixel = lane // spp_pass
    sample = lane % spp_pass + _opaque_u32(setup.first_sample)
    group = sample // setup.n_times
    member = sample % setup.n_times
    seed = _opaque_u32(setup.seed)

    rng_shared = _seeded_pcg(seed, _STREAM_SHARED, pixel, group)
    rng_own = _seeded_pcg(seed, _STREAM_OWN, pixel, sample)

    # ---------------------------------------------------------------- exposure time
    r_time_shared = rng_shared.next_float32()
    r_time_own = rng_own.next_float32()
    perm_seed = mi.sample_tea_32(seed ^ _STREAM_PERM, pixel * setup.n_times + member, 4)[0]
    u = timesampling.sample_times(
        time_sampling.method,
        r_time_shared,
        r_time_own,
        group,
        member,
        max(setup.spp_total // setup.n_times, 1),
        setup.n_times,
        time_sampling.shift,
        time_sampling.stratify_intervals,
        perm_seed,
    )
    time_s = lane_times(setup, u)
    poses = scene.poses(time_s)
    poses64 = scene.poses(time_s, precise=True)

    # ---------------------------------------------------------------- camera ray
    sensor = scene.sensor
    grouped = setup.n_times > 1  # a lone time has no partner to correlate with
    corr_pixel = grouped and correlation.correlates_pixel()
    ray, ray_weight = camera_ray(
        sensor, setup, pixel, time_s, lambda: _next_1d(rng_shared, rng_own, corr_pixel), lambda: _next_2d(rng_shared, rng_own, corr_pixel)
    )

    bank = modulation.CameraBank(cameras, u)
    track_length = bool(cameras)  # Float64 path lengths only where a camera needs them
    bsdf_ctx = mi.BSDFContext()
    static = scene.static
    max_depth_u = 0xFFFFFFFF if max_depth < 0 else max_depth

    # ---------------------------------------------------------------- loop state
    depth = mi.UInt32(0)
    beta = mi.Spectrum(ray_weight)
    radiance = mi.Spectrum(0)
    measurements = [mi.Float(0) for _ in cameras]
    eta = mi.Float(1)
    path_length = mi.Float64(0)
    x_prev = _aperture_point(sensor, ray)  # Float64 position of the previous vertex
    prev_si = dr.zeros(mi.SurfaceInteraction3f)
    prev_bsdf_pdf = mi.Float(1)
    prev_bsdf_delta = mi.Bool(True)
    first_depth = mi.Float(0)
    first_velocity = mi.Float(0)
    first_point_velocity = mi.Float(0)
    first_hit = mi.Bool(False)
    active = mi.Bool(True)

    while dr.hint(active, label="dopplertof path", max_iterations=-1, exclude=[scene, correlation, bank, poses, poses64, static, bsdf_ctx, track_length, grouped]):
        # ---------------------------------------------------- intersect (at the lane's time)
        hit = scene.intersect(ray, time_s, active, poses=poses)
        si = hit.si
        valid = active & si.is_valid()

        # ---------------------------------------------------- Float64 path length
        if dr.hint(track_length, mode="scalar"):
            t64, x_hit = hit_distance64(scene, poses64, hit, x_prev, ray.d)
        else:  # intensity only: float32 is plenty for the depth
            t64 = mi.Float64(dr.norm(si.p - mi.Point3f(x_prev)))
            x_hit = mi.Vector3d(si.p)
        path_length = dr.select(valid, path_length + t64 * mi.Float64(eta), path_length)

        # ---------------------------------------------------- hidden emitters
        # As stock `path`: a camera ray passes through a hidden emitter's surface.
        emitter = si.emitter(static)
        pass_through = mi.Bool(False)
        if dr.hint(hide_emitters, mode="scalar"):
            pass_through = valid & (depth == 0) & (emitter != None)  # noqa: E711 - Dr.Jit pointer test

        # ---------------------------------------------------- ground truth at the camera ray
        at_camera = valid & (depth == 0) & ~pass_through
        ray_velocity, point_velocity = radial_velocities(scene, hit, ray.d, time_s, poses)
        first_depth = dr.select(at_camera, mi.Float(t64), first_depth)
        first_velocity = dr.select(at_camera, ray_velocity, first_velocity)
        first_point_velocity = dr.select(at_camera, point_velocity, first_point_velocity)
        first_hit |= at_camera

        # ---------------------------------------------------- emitter hit
        visible_emitter = active & (emitter != None) & ~pass_through  # noqa: E711 - Dr.Jit pointer test
        ds = mi.DirectionSample3f(static, si, prev_si)
        em_pdf = dr.select(prev_bsdf_delta, 0.0, static.pdf_emitter_direction(prev_si, ds, ~prev_bsdf_delta))
        mis_bsdf = _mis_weight(prev_bsdf_pdf, em_pdf)
        le = emitter.eval(si, visible_emitter)
        length_hit = dr.select(si.is_valid(), path_length, path_length + 1e6)
        radiance, measurements = _accumulate(radiance, measurements, bank, beta * mis_bsdf * le, length_hit, visible_emitter)

        # ---------------------------------------------------- continue?
        active_next = valid & ~pass_through & ((depth + 1) < max_depth_u)
        bsdf = si.bsdf(ray)
        corr_bounce = grouped and correlation.correlates_bounce(depth)

        # ---------------------------------------------------- emitter sampling (NEE)
        active_em = active_next & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
        sample_em = _next_2d(rng_shared, rng_own, corr_bounce)
        ds_em, em_weight = static.sample_emitter_direction(si, sample_em, False, active_em)
        active_em &= ds_em.pdf != 0
        shadow_ray = si.spawn_ray_to(ds_em.p)
        active_em &= ~scene.occluded(shadow_ray, time_s, active_em, poses=poses)
        wo_em = si.to_local(ds_em.d)
        bsdf_val_em, bsdf_pdf_em = bsdf.eval_pdf(bsdf_ctx, si, wo_em, active_em)
        mis_em = dr.select(ds_em.delta, 1.0, _mis_weight(ds_em.pdf, bsdf_pdf_em))
        length_em = path_length + dr.norm(mi.Vector3d(ds_em.p) - x_hit)
        radiance, measurements = _accumulate(radiance, measurements, bank, beta * bsdf_val_em * em_weight * mis_em, length_em, active_em)

        # ---------------------------------------------------- BSDF sampling
        sample_1 = _next_1d(rng_shared, rng_own, corr_bounce)
        sample_2 = _next_2d(rng_shared, rng_own, corr_bounce)
        bs, bsdf_weight = bsdf.sample(bsdf_ctx, si, sample_1, sample_2, active_next)

        # ---------------------------------------------------- update
        beta = dr.select(pass_through, beta, beta * bsdf_weight)
        eta = dr.select(pass_through, eta, eta * bs.eta)
        prev_si = dr.select(pass_through, prev_si, dr.detach(si, True))
        prev_bsdf_pdf = dr.select(pass_through, prev_bsdf_pdf, bs.pdf)
        prev_bsdf_delta = dr.select(pass_through, prev_bsdf_delta, mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta))
        ray = si.spawn_ray(dr.select(pass_through, ray.d, si.to_world(bs.wo)))
        x_prev = x_hit

        # ---------------------------------------------------- Russian roulette
        beta_max = dr.max(mi.unpolarized_spectrum(beta))
        rr_active = depth >= rr_depth
        q = dr.minimum(beta_max * dr.square(eta), 0.95)
        rr_sample = _next_1d(rng_shared, rng_own, corr_bounce)
        survive = ~rr_active | (rr_sample < q)
        beta = dr.select(rr_active & survive, beta * dr.rcp(q), beta)
        active_next &= survive & (beta_max != 0) & (bs.pdf > 0)

        depth = dr.select(active & ~pass_through, depth + 1, depth)
        active = active_next | pass_through

    return {
        "intensity": radiance,
        "measurements": measurements,
        "hit": dr.select(first_hit, mi.Float(1), mi.Float(0)),
        "depth": first_depth,
        "velocity": first_velocity,
        "point_velocity": first_point_velocity,
    }
