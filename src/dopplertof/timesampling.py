"""Time-sampling strategies: normalised exposure times u ∈ [0, 1) from replayable numbers.

Samples of a pixel come in groups of ``N`` correlated times (an antithetic pair is N = 2);
``spp`` counts paths, so a pixel has ``G = spp / N`` groups. Sample ``s`` is member
``m = s mod N`` of group ``g = s // N``. Each strategy is a function of

* ``r_shared``: a uniform number shared by the whole group,
* ``r_own``: a uniform number of this sample alone,
* ``g``, ``m``, ``G``, ``N`` and a per-(pixel, member) permutation key.

=====================  ==============================================================
name                   times of the members of a group
=====================  ==============================================================
``uniform``            independent: u = r_own
``stratified``         u = (m + r)/N; with ``stratify_intervals`` r = (π_m(g) + r_own)/G,
                       a per-interval stratification over the pixel's groups
                       (π_m a random permutation per pixel and interval), else r = r_own
``antithetic``         u_m = frac(r + m·a) for N = 2 (shift ``a``, default ½), or
                       frac(r + m/N) for N > 2; r = (g + r_shared)/G with
                       ``stratify_intervals`` else r_shared
``antithetic_mirror``  N = 2: u_0 = r, u_1 = frac(1 − r + a)
``analytic``           N = 2: u_0 = 0, u_1 = 1, integrated in closed form between them
                       (:mod:`dopplertof.paired`; biased)
=====================  ==============================================================

Times are rounded down to multiples of 2⁻²³ so that u + ½ is exact (DESIGN §3.5).
"""

from __future__ import annotations

METHODS = ("uniform", "stratified", "antithetic", "antithetic_mirror")
ANALYTIC = "analytic"  # not a sampling method: the biased closed-form mode
TIME_QUANTUM = 2.0**-23


def validate(method: str, n_times: int, shift: float) -> None:
    """Raise ValueError for an unknown method or inconsistent parameters."""
    if method not in METHODS + (ANALYTIC,):
        raise ValueError(f"unknown time sampling {method!r}; choose one of {', '.join(METHODS + (ANALYTIC,))}")
    if not isinstance(n_times, int) or n_times < 1:
        raise ValueError(f"n_times must be a positive integer, got {n_times!r}")
    if method in ("antithetic_mirror", ANALYTIC) and n_times != 2:
        raise ValueError(f"{method} pairs exactly 2 times, got n_times={n_times}")
    if method in ("antithetic", "antithetic_mirror", ANALYTIC) and n_times < 2:
        raise ValueError(f"{method} needs n_times >= 2, got {n_times}")
    if not (0.0 <= shift <= 1.0):
        raise ValueError(f"antithetic shift must be in [0, 1] (units of T), got {shift!r}")


def _frac(x):
    import drjit as dr

    return x - dr.floor(x)


def sample_times(method, r_shared, r_own, group, member, n_groups, n_times, shift, stratify_intervals, permutation_seed):
    """Normalised times (``mi.Float64``) for each lane; see the module table.

    ``r_shared``/``r_own`` are ``mi.Float`` uniforms, ``group``/``member`` ``mi.UInt32``,
    ``permutation_seed`` a ``mi.UInt32`` per (pixel, member) key.
    """
    import drjit as dr
    import mitsuba as mi

    F = mi.Float64
    m = F(member)
    groups = F(n_groups)  # counts and shifts as opaque data: another spp or shift reuses the kernel
    dr.make_opaque(groups)
    if method == "uniform":
        u = F(r_own)
    elif method == "stratified":
        if stratify_intervals:
            perm = mi.permute_kensler(group, n_groups, permutation_seed)  # takes a Python int
            r = (F(perm) + F(r_own)) / groups
        else:
            r = F(r_own)
        u = (m + r) / n_times
    else:
        r = (F(group) + F(r_shared)) / groups if stratify_intervals else F(r_shared)
        step = F(shift if n_times == 2 else 1.0 / n_times)
        dr.make_opaque(step)
        if method == "antithetic":
            u = _frac(r + m * step)
        else:  # antithetic_mirror
            u = dr.select(member == 0, r, _frac(1.0 - r + step))
    u = dr.floor(u / TIME_QUANTUM) * TIME_QUANTUM
    return dr.minimum(u, 1.0 - TIME_QUANTUM)
