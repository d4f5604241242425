"""Time-sampling strategies: normalised exposure times u ∈ [0, 1) from replayable numbers.

Samples of a pixel come in groups of ``N`` correlated times (an antithetic pair is N = 2);
``spp`` counts paths, so a pixel has ``G = spp / N`` groups. Sample ``s`` is member
``m = s mod N`` of group ``g = s // N``.

Further stratification (``stratify_intervals``, :func:`stratifies`) stratifies each
member's interval over *all* G groups of the pixel, with two groups per stratum: the
S = ⌊G/2⌋ strata are the pairs of groups (2s, 2s + 1) (with an odd G the last stratum
holds the last three groups), a stratum of n groups spans n/G of the interval, and the
groups of a stratum are jittered independently in it, so their differences estimate the
variance (:class:`dopplertof.passes.Reducer`): Var(μ̂) = Σ_s Q_s / G², with
Q_s = n_s/(n_s − 1) Σ_{g∈s} (x_g − x̄_s)² (d_s² for a pair), unbiased, S degrees of
freedom. :func:`dopplertof.tracing.lanes.stratum` gives each group its stratum, whose
place in the interval is rotated by a random whole number of pair strata per pixel (a
cyclic permutation of the pair strata; the three-group stratum of an odd G stays last), so
each group's time is uniform over the pair strata on its own and a render stopped before
its last pass (an interrupt, ``until_noise``) is unbiased too (for an odd G, but for the
last stratum's span); its standard error then leaves out the between-strata spread of the
strata not yet drawn. (A continuous rotation would let one stratum wrap around the
interval's end, where a heterodyne weight jumps: that stratum's variance, estimated from
one difference, then dominates the pixel's and the errors lose their calibration.)
Where the
times are not stratified, the groups are independent and the standard errors come from R
replicates (``replicates``). Each strategy is a function of

* ``r_shared``: a uniform number shared by the whole group,
* ``r_own``: a uniform number of this sample alone,
* the group's stratum (first group ``f``, ``n`` groups) among the G groups, rotated to
  ``f'``, ``m``, ``N``.

=====================  ==============================================================
name                   times of the members of a group
=====================  ==============================================================
``uniform``            independent: u = r_own
``stratified``         u = (m + r)/N; with ``stratify_intervals`` r = (f' + n·r_own)/G,
                       rotated per (pixel, member) (each interval stays stratified
                       while the members' strata decorrelate), else r = r_own
``antithetic``         u_m = frac(r + m·a) for N = 2 (shift ``a``, default ½), or
                       frac(r + m/N) for N > 2; r = (f' + n·r_shared)/G with
                       ``stratify_intervals`` (rotated per pixel) else r_shared
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


def stratifies(method: str, stratify_intervals: bool) -> bool:
    """Whether a render's times are stratified over the pixel's groups (module docstring):
    its standard errors then come from the strata, not from replicates.

    Parameters
    ----------
    method : str
        The time sampling (``time_sampling``).
    stratify_intervals : bool
        Further stratification on.

    Returns
    -------
    bool
        True for ``stratified``, ``antithetic`` and ``antithetic_mirror`` with
        ``stratify_intervals``.
    """
    return bool(stratify_intervals) and method in METHODS[1:]


def sample_times(method, r_shared, r_own, first, count, n_groups, member, n_times, shift, stratify_intervals, rotation):
    """Normalised times (``mi.Float64``) for each lane; see the module table.

    Parameters
    ----------
    method : str
        The time sampling.
    r_shared, r_own : mi.Float
        The group's and the lane's uniform numbers.
    first, count : mi.UInt32
        The group's stratum: its first group and its number of groups
        (:func:`dopplertof.tracing.lanes.stratum`).
    n_groups : int
        Groups G of the pixel.
    member : mi.UInt32
        The lane's index in its group.
    n_times : int
        Times per group N.
    shift : float, units of T
        The antithetic shift a.
    stratify_intervals : bool
        Further stratification on.
    rotation : mi.Float
        A uniform per pixel, and per member for ``stratified``: picks the rotation of the
        pair strata.

    Returns
    -------
    mi.Float64
        u in [0, 1), a multiple of :data:`TIME_QUANTUM`.

    Counts and shifts are opaque data, so another spp or shift reuses the kernel.
    """
    import drjit as dr
    import mitsuba as mi

    F = mi.Float64
    m = F(member)
    groups = F(n_groups)
    dr.make_opaque(groups)

    # the pair strata span the first `span` groups: all of an even G, an odd G but its last three
    span = F(n_groups if n_groups % 2 == 0 else max(n_groups - 3, 0))
    dr.make_opaque(span)
    placed = F(first) + 2.0 * dr.floor(F(rotation) * span * 0.5)
    placed = dr.select((F(first) < span) & (placed >= span), placed - span, placed)

    def stratum(r):  # r uniform in [0, 1) -> uniform in the group's rotated stratum
        return (placed + F(count) * F(r)) / groups

    if method == "uniform":
        u = F(r_own)
    elif method == "stratified":
        r = stratum(r_own) if stratify_intervals else F(r_own)
        u = (m + r) / n_times
    else:
        r = stratum(r_shared) if stratify_intervals else F(r_shared)
        step = F(shift if n_times == 2 else 1.0 / n_times)
        dr.make_opaque(step)
        if method == "antithetic":
            u = _frac(r + m * step)
        else:  # antithetic_mirror
            u = dr.select(member == 0, r, _frac(1.0 - r + step))
    u = dr.floor(u / TIME_QUANTUM) * TIME_QUANTUM
    return dr.minimum(u, 1.0 - TIME_QUANTUM)
