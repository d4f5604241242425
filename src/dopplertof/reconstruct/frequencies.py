"""Two modulation frequencies (:mod:`dopplertof.reconstruct`, depth): the cameras of each
frequency are reconstructed on their own; their velocities are averaged, and their depths,
each known modulo its own c/(2 f), give the depth modulo c/(2 |f_1 − f_2|).

The phase of the depth at f is φ = 2π d/R (R = c/(2f)); the difference of the two phases,
2π d (1/R_fine − 1/R_coarse) modulo 2π, is the phase of the depth at the beat frequency
|f_1 − f_2|, whose range R_beat = c/(2 |f_1 − f_2|) is the larger. That coarse depth picks
the number of whole ranges R_fine to add to the finer depth. Noise in the coarse depth is
the phase noise magnified R_beat/R_fine times: where it is off by more than R_fine/4 from
the depth it selects, the choice is unsure and the depth is not given.
"""

from __future__ import annotations

import numpy as np

_SAME_FREQUENCY_RTOL = 1e-12  # cameras whose f_g agree to this are one group


def _frequency_groups(cameras: list) -> list[list[int]]:
    """Camera indices grouped by modulation frequency, in order of first appearance; one
    group when the frequencies cannot be read (the camera checks then say why)."""
    try:
        frequencies = [float(c.modulation_frequency) for c in cameras]
    except (AttributeError, TypeError, ValueError):
        return [list(range(len(cameras)))]
    groups: list[list[int]] = []
    for i, f in enumerate(frequencies):
        same = next((g for g in groups if abs(f - frequencies[g[0]]) <= _SAME_FREQUENCY_RTOL * abs(f)), None)
        if same is None:
            groups.append([i])
        else:
            same.append(i)
    return groups


def beat_range_m(range_a_m: float, range_b_m: float) -> float:
    """c/(2 |f_a − f_b|) (m) from the two ranges c/(2 f): the depth range of the pair.

    Parameters
    ----------
    range_a_m, range_b_m : float, m
        The ranges c/(2 f) of two modulation frequencies (different).

    Returns
    -------
    float
        m.
    """
    return range_a_m * range_b_m / abs(range_a_m - range_b_m)


def unwrap_depth(depth_a_m, range_a_m: float, depth_b_m, range_b_m: float) -> np.ndarray:
    """Depth (m) modulo :func:`beat_range_m` from two depths modulo their own ranges.

    Parameters
    ----------
    depth_a_m, depth_b_m : array_like, same shape
        Depths (m) modulo ``range_a_m`` and ``range_b_m``; NaN where unknown.
    range_a_m, range_b_m : float, m
        The two ranges c/(2 f) (different).

    Returns
    -------
    ndarray
        The depth in [0, R_beat), NaN where either depth is unknown or the coarse depth
        does not pick the number of fine ranges surely (module docstring).
    """
    (fine, r_fine), (coarse, r_coarse) = sorted(
        [(np.asarray(depth_a_m, dtype=np.float64), float(range_a_m)), (np.asarray(depth_b_m, dtype=np.float64), float(range_b_m))],
        key=lambda pair: pair[1],
    )
    r_beat = beat_range_m(r_fine, r_coarse)
    rough = np.mod(fine / r_fine - coarse / r_coarse, 1.0) * r_beat
    depth = np.mod(fine + np.round((rough - fine) / r_fine) * r_fine, r_beat)
    miss = np.abs(np.mod(depth - rough + 0.5 * r_beat, r_beat) - 0.5 * r_beat)
    return np.where(miss <= 0.25 * r_fine, depth, np.nan)


def inverse_variance_weights(velocities, stderrs) -> np.ndarray:
    """Weights (K, ...) summing to 1 per pixel over the K frequencies that give a velocity
    there (finite), ∝ 1/σ², or equal without errors (``stderrs`` None); 0 elsewhere.

    Parameters
    ----------
    velocities : sequence of array_like, m/s
        K velocity maps of one shape, NaN where unknown.
    stderrs : sequence of array_like or None, m/s
        Their standard errors; None: equal weights.

    Returns
    -------
    ndarray
        (K, ...) float64.
    """
    v = np.stack([np.asarray(x, dtype=np.float64) for x in velocities])
    known = np.isfinite(v)
    if stderrs is None:
        weight = known.astype(np.float64)
    else:
        s = np.stack([np.asarray(x, dtype=np.float64) for x in stderrs])
        with np.errstate(divide="ignore"):
            weight = np.where(known & np.isfinite(s) & (s > 0), 1.0 / (s * s), 0.0)
    total = weight.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total > 0, weight / total, 0.0)
