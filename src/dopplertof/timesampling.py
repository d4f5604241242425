"""Time-sampling strategies: normalised exposure times u ∈ [0, 1) from replayable numbers.

Samples of a pixel come in groups of ``N`` correlated times (an antithetic pair is N = 2);
``spp`` counts paths, so a pixel has ``G = spp / N`` groups. Sample ``s`` is member
``m = s mod N`` of group ``g = s // N``. The groups form R independent *replicates*
(contiguous runs of groups, :mod:`dopplertof.tracing.lanes`), each stratified on its own,
so that the spread of the replicate means gives honest standard errors. Each strategy is
a function of

* ``r_shared``: a uniform number shared by the whole group,
* ``r_own``: a uniform number of this sample alone,
* ``g``, ``m``, ``G``, ``N`` and a per-(pixel, member) permutation key.

=====================  ==============================================================
name                   times of the members of a group
=====================  ==============================================================
``uniform``            independent: u = r_own
``stratified``         u = (m + r)/N; with ``stratify_intervals`` r = (π_m(j) + r_own)/S,
                       a per-interval stratification over the S groups of the lane's
                       replicate (j the group's index there, π_m a random cyclic
                       permutation per pixel, interval and replicate), else r = r_own
``antithetic``         u_m = frac(r + m·a) for N = 2 (shift ``a``, default ½), or
                       frac(r + m/N) for N > 2; r = (j + r_shared)/S with
                       ``stratify_intervals`` else r_shared
``antithetic_mirror``  N = 2: u_0 = r, u_1 = frac(1 − r + a)
``analytic``           N = 2: u_0 = 0, u_1 = 1, integrated in closed form between them
                       (:mod:`dopplertof.tracing.paired`; biased)
=====================  ==============================================================

Times are rounded down to multiples of 2⁻²³ so that u + ½ is exact (DESIGN §3.5).
"""

from __future__ import annotations

METHODS = ("uniform", "stratified", "antithetic", "antithetic_mirror")
ANALYTIC = "analytic"  # not a sampling method: the biased closed-form mode
TIME_QUANTUM = 2.0**-23


def _frac(x):
    import drjit as dr

    return x - dr.floor(x)


def sample_times(method, r_shared, r_own, stratum, n_strata, member, n_times, shift, stratify_intervals, rotation):
    """Normalised times (``mi.Float64``) for each lane; see the module table.

    ``r_shared``/``r_own`` are ``mi.Float`` uniforms; ``stratum`` (``mi.UInt32``) is the
    group's index among the ``n_strata`` groups (per-lane ``mi.UInt32``) of its replicate,
    which are stratified together; ``member`` (``mi.UInt32``) its index in the group;
    ``rotation`` a uniform per (pixel, member, replicate) that rotates the strata of a
    member's interval (a random cyclic permutation: each interval stays stratified while
    the members' strata decorrelate). Counts and shifts are opaque data, so another spp
    or shift reuses the kernel.
    """
    import drjit as dr
    import mitsuba as mi

    F = mi.Float64
    m = F(member)
    strata = F(n_strata)
    if method == "uniform":
        u = F(r_own)
    elif method == "stratified":
        if stratify_intervals:
            rotated = F(stratum) + dr.floor(F(rotation) * strata)
            rotated = dr.select(rotated >= strata, rotated - strata, rotated)
            r = (rotated + F(r_own)) / strata
        else:
            r = F(r_own)
        u = (m + r) / n_times
    else:
        r = (F(stratum) + F(r_shared)) / strata if stratify_intervals else F(r_shared)
        step = F(shift if n_times == 2 else 1.0 / n_times)
        dr.make_opaque(step)
        if method == "antithetic":
            u = _frac(r + m * step)
        else:  # antithetic_mirror
            u = dr.select(member == 0, r, _frac(1.0 - r + step))
    u = dr.floor(u / TIME_QUANTUM) * TIME_QUANTUM
    return dr.minimum(u, 1.0 - TIME_QUANTUM)
