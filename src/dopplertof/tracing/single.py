"""One path per lane: the phases of :mod:`dopplertof.tracing.path` in a Dr.Jit loop.

Each lane traces one path (NEE + BSDF sampling, power-heuristic MIS, Russian roulette)
through the dynamic scene frozen at the lane's time ``t = t_start + u·T``. Every emitter
contribution goes to the intensity and, weighted by W(u, L), to every camera
(:mod:`dopplertof.tracing.sink`), L the optical length of that light path. Lanes of a
group replay each other's random numbers where the correlation mode says so
(:mod:`dopplertof.correlation`); where it is the same at every depth only the stream in
use advances, and a replay cut-off advances both.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

from . import lanes
from .path import camera_ray, emitter_hit, emitter_hit_length, extend, float64_distances, ground_truth, met_motion, next_hit, no_ground_truth, place_camera_ray, sample_emitter, segment_index, vertex_interaction
from .sink import Sink


def mis_weight(pdf_a, pdf_b):
    """Power heuristic (β = 2) for pdf_a against pdf_b; 0 where both vanish.

    Parameters
    ----------
    pdf_a, pdf_b : mi.Float

    Returns
    -------
    mi.Float
    """
    a2 = dr.square(pdf_a)
    w = a2 / (a2 + dr.square(pdf_b))
    return dr.select(dr.isfinite(w), w, 0.0)


@dr.syntax
def trace(scene, settings, setup, tables):
    """Trace one pass; per-lane outputs (:meth:`Sink.outputs`), not yet evaluated.

    Parameters
    ----------
    scene : DynamicScene
    settings : RenderSettings
    setup : LaneSetup
    tables : MaterialTables

    Returns
    -------
    dict
        Name → per-lane Dr.Jit array.
    """
    pixel, index_in_pass = lanes.pixel_and_index(setup, setup.samples)
    sample = index_in_pass + lanes.opaque_u32(setup.first_sample)
    n = setup.n_times
    group, member = sample // n, sample % n
    seed = lanes.opaque_u32(setup.seed)
    streams = lanes.Streams(
        lanes.seeded_pcg(seed, lanes.STREAM_SHARED, pixel, group), lanes.seeded_pcg(seed, lanes.STREAM_OWN, pixel, sample)
    )  # fmt: skip

    # ---------------------------------------------------------------- exposure time
    r_shared, r_own = streams.shared.next_float32(), streams.own.next_float32()
    u = lanes.sample_time(setup, settings, seed, pixel, group, member, r_shared, r_own)
    time_s = lanes.lane_times(setup, u)
    poses, poses64 = scene.poses(time_s), scene.poses(time_s, precise=True)

    # ---------------------------------------------------------------- camera vertex
    correlation = settings.correlation_spec
    grouped = n > 1  # a lone time has no partner to correlate with
    corr_pixel = grouped and correlation.correlates_pixel()
    ray, ray_weight, x0 = camera_ray(
        scene.sensor, tables.film, setup, pixel, time_s, lambda: streams.next_1d(corr_pixel), lambda: streams.next_2d(corr_pixel)
    )  # fmt: skip
    ray, x = place_camera_ray(scene, ray, x0, time_s)
    sink = Sink(settings.cameras, setup.grid)
    bank = sink.bank(u)
    distances64 = float64_distances(scene, sink.needs_length)

    bsdf_ctx = mi.BSDFContext()
    # Data, not literals: a render of another depth (a dataset's direct-light render) reuses the kernel.
    max_depth = lanes.opaque_u32(0xFFFFFFFF if settings.max_depth < 0 else settings.max_depth)
    rr_depth = lanes.opaque_u32(settings.rr_depth)
    hide_emitters = settings.hide_emitters

    # ---------------------------------------------------------------- loop state
    # The camera ray is traced in the loop, at depth 0: one ray query in the kernel, not two.
    state = sink.empty()
    truth, hit_mask = no_ground_truth()
    length = mi.Float64(0)  # optical length to the current vertex, m
    beta = mi.Spectrum(ray_weight)
    index = mi.Float(1)  # refractive index of the medium the path travels in
    prev_it = dr.zeros(mi.Interaction3f)
    prev_pdf = mi.Float(1)
    prev_delta = mi.Bool(True)
    depth = mi.UInt32(0)
    active = mi.Bool(True)
    met = mi.Bool(False)  # the path has met a moving body (path.met_motion)

    while dr.hint(active, label="dopplertof path", max_iterations=-1, exclude=[scene, settings, correlation, bank, poses, poses64, tables, sink, bsdf_ctx, distances64, grouped]):
        # ---------------------------------------------------- the vertex (at the lane's time)
        hit = next_hit(scene, ray, time_s, poses, hide_emitters, active, depth == 0)
        met, precise = met_motion(distances64, met, hit)
        length, x, distance_m = extend(scene, poses64, hit, x, ray.d, length, index, active, precise)
        si, body = hit.si, hit.body
        truth, hit_mask = dr.if_stmt(  # the camera ray's hit: ground truth (a branch: later bounces skip it)
            (truth, hit_mask), depth == 0, lambda *_: ground_truth(scene, hit, ray.d, distance_m, time_s, tables.pinhole), lambda *old: old,
            label="dopplertof path: ground truth",
        )  # fmt: skip

        # ---------------------------------------------------- emitter hit
        shown = active if not hide_emitters else active & (depth > 0)
        le, em_pdf, visible = emitter_hit(scene, si, body, prev_it, prev_delta, time_s, shown)
        length_le = emitter_hit_length(scene, si, length, index, x, ray.d)
        state = sink.add(state, bank, beta * mis_weight(prev_pdf, em_pdf) * le, length_le, visible)

        # ---------------------------------------------------- continue?
        go_on = active & si.is_valid() & ((depth + 1) < max_depth)
        bsdf = si.bsdf(ray)
        corr_bounce = grouped and correlation.correlates_bounce(depth)

        # ---------------------------------------------------- emitter sampling (NEE)
        light = sample_emitter(scene, si, bsdf, bsdf_ctx, streams.next_2d(corr_bounce), time_s, poses, length, index, x, tables, go_on)
        mis_em = dr.select(light.ds.delta, 1.0, mis_weight(light.ds.pdf, light.bsdf_pdf))
        state = sink.add(state, bank, beta * light.bsdf_value * light.weight * mis_em, light.length_m, light.active)

        # ---------------------------------------------------- BSDF sampling
        sample_1 = streams.next_1d(corr_bounce)
        sample_2 = streams.next_2d(corr_bounce)
        bs, bsdf_weight = bsdf.sample(bsdf_ctx, si, sample_1, sample_2, go_on)
        index_next = segment_index(index, tables, bsdf, go_on, si.wi, bs.wo)

        # ---------------------------------------------------- Russian roulette
        beta_next = beta * bsdf_weight
        beta_max = dr.max(mi.unpolarized_spectrum(beta_next))
        rr_active = depth >= rr_depth
        q = dr.minimum(beta_max * dr.square(index_next), 0.95)
        rr_sample = streams.next_1d(corr_bounce)
        survive = ~rr_active | (rr_sample < q)
        beta_next = dr.select(rr_active & survive, beta_next * dr.rcp(q), beta_next)
        go_on &= survive & (beta_max != 0) & (bs.pdf > 0)

        # ---------------------------------------------------- update
        ray = si.spawn_ray(si.to_world(bs.wo))
        prev_it = vertex_interaction(si)
        prev_pdf = bs.pdf
        prev_delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
        beta = beta_next
        index = index_next
        depth += 1
        active = go_on

    label = truth.pop("instance_id")
    return sink.outputs(state, truth, dr.select(hit_mask, mi.Float(1), 0.0), label, u)
