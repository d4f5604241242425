"""Time-sampling strategies: normalised exposure times u ∈ [0, 1) from replayable numbers.

Samples of a pixel come in groups of ``N`` correlated times (an antithetic pair is N = 2);
``spp`` counts paths, so a pixel has ``G = spp / N`` groups. Sample ``s`` is member
``m = s mod N`` of group ``g = s // N``.

Further stratification (``stratify_intervals``, :func:`stratifies`) stratifies each
member's interval over *all* G groups of the pixel, two groups per stratum, jittered
independently in it, so that their differences estimate the variance
(:class:`dopplertof.passes.Reducer`): Var(μ̂) = Σ_s Q_s / G², with
Q_s = n_s/(n_s − 1) Σ_{g∈s} (x_g − x̄_s)² (d_s² for a pair), unbiased, about G/2 degrees
of freedom. A stratum of n groups spans n/G of the interval. The interval is first cut
where a member's time wraps around the exposure's end (:func:`wrap_points`: ½ for the
antithetic pair, where a contribution that differs between the exposure's ends jumps),
wherever the cut falls between groups; each piece is split into pairs of groups, the last
holding three where the piece has an odd number. (Without the cut, one stratum holds the
jump: its variance, estimated from one difference, dominates the pixel's and the errors
lose their calibration: z spread 1.8 on the moving plane at h = 1, G = 34.)
:class:`dopplertof.tracing.lanes.StrataLayout` lays the strata out and rotates them per
pixel. Where the times are not stratified, the groups are independent and the standard
errors come from R replicates (``replicates``). Each strategy is a function of

* ``r_shared``: a uniform number shared by the whole group,
* ``r_own``: a uniform number of this sample alone,
* the place of the group's stratum: its first group ``f`` (in units of 1/G of the
  interval) and its ``n`` groups, ``m``, ``N``.

=====================  ==============================================================
name                   times of the members of a group
=====================  ==============================================================
``uniform``            independent: u = r_own
``stratified``         u = (m + r)/N; with ``stratify_intervals`` r = (f + n·r_own)/G,
                       the strata placed per (pixel, member) (each interval stays
                       stratified while the members' strata decorrelate), else r = r_own
``antithetic``         u_m = frac(r + m·a) for N = 2 (shift ``a``, default ½), or
                       frac(r + m/N) for N > 2; r = (f + n·r_shared)/G with
                       ``stratify_intervals`` (placed per pixel) else r_shared
``antithetic_mirror``  N = 2: u_0 = r, u_1 = frac(1 − r + a)
``analytic``           N = 2: u_0 = 0, u_1 = 1, integrated in closed form between them
                       (:mod:`dopplertof.tracing.paired`; biased)
=====================  ==============================================================

Times are rounded down to multiples of 2⁻²³ so that u + ½ is exact (DESIGN §3.5).
"""

from __future__ import annotations

METHODS = ("uniform", "stratified", "antithetic", "antithetic_mirror")
ANALYTIC = "analytic"  # not a sampling method: the biased closed-form mode
ANALYTIC_TIMES = (0.0, 1.0)  # its members' normalised times u: the exposure's ends
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


def wrap_points(method: str, n_times: int, shift: float) -> tuple[float, ...]:
    """Where in (0, 1) the group's stratified number r makes a member's time wrap around
    the exposure's end: the strata are cut there (module docstring).

    Parameters
    ----------
    method : str
        The time sampling.
    n_times : int
        Times per group N.
    shift : float, units of T
        The antithetic shift a.

    Returns
    -------
    tuple of float
        In (0, 1): 1 − a for an antithetic pair, 1 − m/N for N > 2, a for the mirror
        (whose partner 1 − r + a wraps at r = a); none for the others.
    """
    if method == "antithetic":
        points = [1.0 - shift] if n_times == 2 else [1.0 - m / n_times for m in range(1, n_times)]
    elif method == "antithetic_mirror":
        points = [shift]
    else:
        points = []
    return tuple(sorted(p for p in points if 0.0 < p < 1.0))


def group_cuts(n_groups: int, wraps) -> tuple[list[int], list[float]]:
    """The ``wraps`` that fall between groups, as group counts, and those that do not.

    Parameters
    ----------
    n_groups : int
        Groups G of a pixel.
    wraps : sequence of float
        Points in (0, 1) (:func:`wrap_points`).

    Returns
    -------
    tuple of (list of int, list of float)
        The cuts c = w·G that are whole numbers; the wraps that are not.
    """
    whole = [abs(w * n_groups - round(w * n_groups)) <= 1e-9 * n_groups for w in wraps]
    return [round(w * n_groups) for w, ok in zip(wraps, whole) if ok], [w for w, ok in zip(wraps, whole) if not ok]


def sample_times(method, r_shared, r_own, first, count, n_groups, member, n_times, shift, stratify_intervals):
    """Normalised times (``mi.Float64``) for each lane; see the module table.

    Parameters
    ----------
    method : str
        The time sampling.
    r_shared, r_own : mi.Float
        The group's and the lane's uniform numbers.
    first, count : mi.UInt32
        The place of the group's stratum in units of 1/G of the interval, and its number
        of groups (:func:`dopplertof.tracing.lanes.stratum`).
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

    Returns
    -------
    mi.Float64
        u in [0, 1), a multiple of :data:`TIME_QUANTUM`; with ``analytic`` the exposure's
        ends, :data:`ANALYTIC_TIMES` (not sampled).

    Counts and shifts are opaque data, so another spp or shift reuses the kernel.
    """
    import drjit as dr
    import mitsuba as mi

    F = mi.Float64
    m = F(member)
    groups = F(n_groups)
    dr.make_opaque(groups)

    def stratum(r):  # r uniform in [0, 1) -> uniform in the group's stratum
        return (F(first) + F(count) * F(r)) / groups

    if method == ANALYTIC:  # the paired tracer's P1 and P2 (and the slices' members) at the ends
        return dr.select(member == 0, F(ANALYTIC_TIMES[0]), F(ANALYTIC_TIMES[1]))
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
