"""Precision maps: the Cramér–Rao bound of depth and velocity per pixel, and what an
estimator reaches.

A pixel's taps are independent with means μ_{k}(θ) and variances σ²_{k} from the noise
chain (:meth:`~dopplertof.sensors.Sensor.expected_electrons`,
:meth:`~dopplertof.sensors.noise.Silicon.tap_variance_e2`; shot, read and quantisation
noise, Gaussian approximation), θ = (s, L, L̇): the pixel's light scale s (a nuisance: the
reflectance is unknown), and a common change of every path's optical length L (m) and of
its rate L̇ (m/s) at the reference time t_ref. The Fisher information is

    F_ab = Σ_k (∂μ_k/∂θ_a)(∂μ_k/∂θ_b) / σ²_k,

and the bounds are √(F⁻¹)_LL / 2 for the depth (m) and √(F⁻¹)_L̇L̇ / 2 for the radial
velocity (m/s) (light at the camera: L = 2 d, L̇ = 2 v). The derivatives come from the
response record exactly (:mod:`dopplertof.design.record`): a camera's measurement is
c₀ Ī + Re Σ_m a_m e^{imψ} R(mf, mh), and shifting every path by δL + δL̇ (t − t_ref)
multiplies each term by e^{imk(δL + δL̇ (t − t_ref))}, so

    ∂M/∂L = Re Σ_m a_m e^{imψ} i m k R,
    ∂M/∂L̇ = Re Σ_m a_m e^{imψ} i m k [(t_w − t_ref) R + T_w R₁],

with t_w, T_w the camera's window and R₁ the first moments of a ``doppler=True`` record. A
tap at or above its full well carries no information and is left out. Where F is singular
(no light, or a schedule that cannot separate depth from velocity) the bound is infinite.

:func:`achieved_rmse` draws the noise chain ``draws`` times and runs an estimator of
:func:`dopplertof.reconstruct.velocity` on the read-outs: its spread about its noiseless
value is the precision it reaches (its model bias excluded), to set beside the bound.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from .record import Record, evaluate, readout_terms

# F normalised to unit diagonal is singular below this determinant: depth and velocity
# (or the scale) are then not separable from the frames.
SINGULAR_DETERMINANT = 1e-12
PARAMETERS = ("scale", "path_length_m", "path_rate_m_s")


@dataclass
class Precision:
    """Per-pixel precision of a sensor on a scene (:func:`crb`).

    Attributes
    ----------
    velocity_crb : float32 (H, W), m/s. Cramér–Rao bound of the radial velocity; inf where
        undetermined.
    depth_crb : float32 (H, W), m. Cramér–Rao bound of the depth at ``reference_time_s``.
    fisher : float64 (H, W, 3, 3). Fisher information of (s, L, L̇) (:data:`PARAMETERS`).
    reference_time_s : float, s. The time the depth refers to.
    moving : bool (H, W). Pixels whose ground-truth velocity is non-zero.
    """

    velocity_crb: np.ndarray
    depth_crb: np.ndarray
    fisher: np.ndarray
    reference_time_s: float
    moving: np.ndarray

    def summary(self) -> dict:
        """Mean and median bounds over the moving pixels where they are finite (m/s, m).

        Returns
        -------
        dict
        """
        out = {}
        for name in ("velocity_crb", "depth_crb"):
            values = getattr(self, name)[self.moving]
            values = values[np.isfinite(values)]
            out[f"{name}_mean"] = float(values.mean()) if values.size else float("nan")
            out[f"{name}_median"] = float(np.median(values)) if values.size else float("nan")
        out["moving_pixels"] = int(self.moving.sum())
        return out


def record_of(record_or_result, what: str) -> Record:
    """The record of a :class:`Record` or of a render made with ``record=``; ValueError otherwise.

    Parameters
    ----------
    record_or_result : Record or RenderResult
    what : str
        The caller, named in the error.

    Returns
    -------
    Record

    Raises
    ------
    ValueError
        Neither a record nor a render with one.
    """
    record = record_or_result if isinstance(record_or_result, Record) else getattr(record_or_result, "__dict__", {}).get("record")
    if not isinstance(record, Record):
        raise ValueError(f"{what}: needs a response record (dopplertof.render(..., record=dict(doppler=True)) or its .record), got {type(record_or_result).__name__}")
    return record


def derivatives(record: Record, camera, reference_time_s: float, where: str = "camera"):
    """(M, ∂M/∂L, ∂M/∂L̇), each (H, W) float64, of ``camera`` read out of ``record``
    (module docstring); ``record`` must hold the first moments (``doppler=True``).

    Parameters
    ----------
    record : Record
        With first moments (``doppler=True``).
    camera : Camera
    reference_time_s : float, s
        The time the depths refer to.
    where : str, default ``"camera"``
        Named in errors.

    Returns
    -------
    tuple of ndarray
        (M, ∂M/∂L, ∂M/∂L̇), each (H, W) float64; L in m, L̇ in m/s.

    Raises
    ------
    ValueError
        The record holds no first moments, or not the camera's window, frequency or beat.
    """
    w, constant, terms = readout_terms(record, camera, where)
    return contract(record, w, constant, terms, camera.wavenumber, reference_time_s, where)


def contract(record: Record, w: int, constant: float, terms, wavenumber: float, reference_time_s: float, where: str):
    """(M, ∂M/∂L, ∂M/∂L̇) of the weight c₀ + Re Σ a_m e^{imΔ} with ``terms`` located in window
    ``w`` of ``record`` as :func:`~dopplertof.design.record.readout_terms` gives them.

    Parameters
    ----------
    record : Record
    w : int
        The window's index.
    constant : float
        c₀.
    terms : list of tuple
        As :func:`~dopplertof.design.record.readout_terms` gives them.
    wavenumber : float, rad/m
        2π f / c of the camera's modulation.
    reference_time_s : float, s
        The time the depths refer to.
    where : str
        Named in errors.

    Returns
    -------
    tuple of ndarray
        (M, ∂M/∂L, ∂M/∂L̇), each (H, W) float64.

    Raises
    ------
    ValueError
        The record holds no first moments.
    """
    if record.moments is None:
        raise ValueError(f"{where}: the record holds no first moments; render it with record=dict(doppler=True, ...) for derivatives with respect to the velocity")
    start_s, exposure_s = record.windows[w]
    m = constant * record.luminance[w].astype(np.float64)
    d_length = np.zeros_like(m)
    d_rate = np.zeros_like(m)
    for order, coefficient, j, b in terms:
        r, r1 = record.phasors[w, j, b].astype(np.complex128), record.moments[w, j, b].astype(np.complex128)
        ik = 1j * order * wavenumber * coefficient
        m += (coefficient * r).real
        d_length += (ik * r).real
        d_rate += (ik * ((start_s - reference_time_s) * r + exposure_s * r1)).real
    return m, d_length, d_rate


def tap_terms(sensor, measurements, jacobians):
    """(∂μ (P, frames, taps, H, W), 1/σ² (frames, taps, H, W), μ) of a sensor's taps from its
    camera measurements (cameras, H, W) and their derivatives (P, cameras, H, W); taps at or
    above the full well get weight 0 (module docstring).

    Parameters
    ----------
    sensor : Sensor
    measurements : ndarray
        (cameras, H, W).
    jacobians : ndarray
        (P, cameras, H, W).

    Returns
    -------
    tuple of ndarray
    """
    raw = sensor.raw(measurements, clip=False)
    zero = sensor.expected_electrons(np.zeros_like(raw))
    mean_e = sensor.expected_electrons(np.maximum(raw, 0.0))
    weight = np.where(mean_e < sensor.noise.full_well_e, 1.0 / sensor.noise.tap_variance_e2(mean_e), 0.0)
    # The electrons are affine in the measurements: their derivatives are the linear part.
    d_e = np.stack([sensor.expected_electrons(sensor.raw(d, clip=False)) - zero for d in jacobians])
    return d_e, weight, mean_e


def fisher_information(sensor, measurements, jacobians) -> np.ndarray:
    """Fisher information (H, W, P, P) of P parameters from a sensor's camera measurements
    (cameras, H, W) and their derivatives (P, cameras, H, W), through the sensor's taps and
    noise chain (module docstring).

    Parameters
    ----------
    sensor : Sensor
    measurements : ndarray
        (cameras, H, W).
    jacobians : ndarray
        (P, cameras, H, W).

    Returns
    -------
    ndarray
        (H, W, P, P).
    """
    d_e, weight, _ = tap_terms(sensor, measurements, jacobians)
    return fisher_from_taps(d_e, weight)


def fisher_from_taps(d_e, weight) -> np.ndarray:
    """Σ_taps ∂μ_a ∂μ_b w (H, W, P, P) of :func:`tap_terms`' derivatives and weights.

    Parameters
    ----------
    d_e : ndarray
        (P, frames, taps, H, W) derivatives of the tap means (e⁻ per parameter unit).
    weight : ndarray
        (frames, taps, H, W) 1/σ² (e⁻⁻²).

    Returns
    -------
    ndarray
        (H, W, P, P).
    """
    return np.einsum("aftyx,bftyx,ftyx->yxab", d_e, d_e, weight)


def inverse_fisher(fisher: np.ndarray):
    """(F⁻¹, ok) per pixel: ok where F is regular (module docstring), F⁻¹ meaningless elsewhere.

    Parameters
    ----------
    fisher : ndarray
        (H, W, P, P).

    Returns
    -------
    tuple of (ndarray, ndarray)
        F⁻¹ (H, W, P, P) and ok (H, W) bool.
    """
    diagonal = np.einsum("...ii->...i", fisher)
    ok = np.all(diagonal > 0, axis=-1) & np.all(np.isfinite(fisher), axis=(-2, -1))
    scale = 1.0 / np.sqrt(np.where(ok[..., None], diagonal, 1.0))
    # normalised to a unit diagonal, so that the test of singularity does not depend on units
    normalised = np.where(ok[..., None, None], fisher * scale[..., :, None] * scale[..., None, :], np.eye(fisher.shape[-1]))
    ok &= np.linalg.det(normalised) > SINGULAR_DETERMINANT
    eye = np.broadcast_to(np.eye(fisher.shape[-1]), fisher.shape)
    inverse = np.linalg.inv(np.where(ok[..., None, None], normalised, eye)) * scale[..., :, None] * scale[..., None, :]
    return inverse, ok


def bounds(fisher: np.ndarray) -> np.ndarray:
    """√diag(F⁻¹) (H, W, P) per pixel; inf where F is singular (module docstring).

    Parameters
    ----------
    fisher : ndarray
        (H, W, P, P).

    Returns
    -------
    ndarray
        (H, W, P), in the parameters' units.
    """
    inverse, ok = inverse_fisher(fisher)
    return np.where(ok[..., None], np.sqrt(np.clip(np.einsum("...ii->...i", inverse), 0.0, None)), np.inf)


def crb(record_or_result, sensor, *, reference_time_s: float | None = None) -> Precision:
    """Per-pixel Cramér–Rao bounds of velocity and depth of ``sensor`` on a recorded scene.

    Parameters
    ----------
    record_or_result : :class:`~dopplertof.design.Record` with first moments, or the result
        of ``dopplertof.render(..., record=dict(doppler=True))``.
    sensor : :class:`dopplertof.Sensor`. Its frames must lie in the record (as for
        :func:`~dopplertof.design.evaluate`).
    reference_time_s : float, s, optional. The time the depth refers to; default the
        start of the record's first window.

    Returns
    -------
    Precision

    Raises
    ------
    ValueError
        Without a record holding first moments, or for frames the record cannot read out.
    """
    from ..sensors import Sensor

    record = record_of(record_or_result, "crb")
    if not isinstance(sensor, Sensor):
        raise ValueError(f"crb: 'sensor' must be a dopplertof.Sensor, got {sensor!r}")
    t_ref = reference_time(record, reference_time_s)
    m, d_length, d_rate = sensor_derivatives(record, sensor, t_ref, "crb")
    # ∂M/∂s = M: the scale multiplies every measurement, the mean light's too.
    fisher = fisher_information(sensor, m, [m, d_length, d_rate])
    sigma = bounds(fisher)
    return Precision((0.5 * sigma[..., 2]).astype(np.float32), (0.5 * sigma[..., 1]).astype(np.float32), fisher, t_ref, moving_pixels(record))


def reference_time(record: Record, reference_time_s) -> float:
    """The time depths refer to: ``reference_time_s``, default the first window's start.

    Parameters
    ----------
    record : Record
    reference_time_s : float or None, s
        None: the first window's start.

    Returns
    -------
    float
        s.
    """
    return record.windows[0][0] if reference_time_s is None else float(reference_time_s)


def moving_pixels(record: Record) -> np.ndarray:
    """Pixels (H, W) whose ground-truth radial velocity is finite and non-zero.

    Parameters
    ----------
    record : Record

    Returns
    -------
    ndarray
        (H, W) bool.
    """
    velocity = record.maps.get("velocity")
    if velocity is None:
        return np.zeros(record.luminance.shape[1:], bool)
    return np.isfinite(velocity) & (velocity != 0)


def sensor_derivatives(record: Record, sensor, t_ref: float, what: str):
    """(M, ∂M/∂L, ∂M/∂L̇), each (cameras, H, W), of every camera of ``sensor``.

    Parameters
    ----------
    record : Record
    sensor : Sensor
    t_ref : float, s
        The time the depths refer to.
    what : str
        The caller, named in errors.

    Returns
    -------
    tuple of ndarray
        (M, ∂M/∂L, ∂M/∂L̇), each (cameras, H, W).

    Raises
    ------
    ValueError
        What the record does not hold (:func:`derivatives`).
    """
    columns = [derivatives(record, c, t_ref, f"{what}: camera {i} ({c.label()})") for i, c in enumerate(sensor.cameras())]
    return tuple(np.stack(x) for x in zip(*columns))


def achieved_rmse(record_or_result, sensor, *, draws: int = 200, seed: int = 0, method: str = "auto") -> np.ndarray:
    """Per-pixel RMSE (H, W, m/s) of :func:`dopplertof.reconstruct.velocity` (``method``)
    over ``draws`` read-outs of ``sensor``, about its value on the noiseless measurements.

    Parameters
    ----------
    record_or_result : Record or RenderResult
        A response record, or a render made with ``record=``.
    sensor : Sensor
    draws : int, default 200
        Read-outs, ≥ 2.
    seed : int, default 0
        Seed of the read-outs' noise.
    method : str, default ``"auto"``
        The reconstruction method (``auto``, ``ratio``, ``fit``).

    Returns
    -------
    ndarray
        (H, W), m/s.

    Raises
    ------
    ValueError
        For ``draws`` < 2, a 1-tap sensor (its read-out gives no measurements), or what
        :func:`~dopplertof.design.evaluate` refuses.
    """
    from ..reconstruct import velocity
    from ..sensors.estimators import measurements_from_readout

    record = record_of(record_or_result, "achieved_rmse")
    if not isinstance(draws, int) or isinstance(draws, bool) or draws < 2:
        raise ValueError(f"achieved_rmse: 'draws' must be an integer >= 2, got {draws!r}")
    result = evaluate(record, sensor)
    clean = measurements_from_readout(sensor, _noiseless_dn(sensor, result.raw))
    # every determined pixel: the estimator's spread, not its validity threshold (which can mark them all invalid)
    every = dict(method=method, max_velocity_stderr=sys.float_info.max)
    reference = velocity(clean.measurements, clean.cameras, measurement_stderr=clean.stderr, **every).velocity
    squares = np.zeros(reference.shape)
    rng = np.random.SeedSequence(seed)
    for child in rng.spawn(draws):
        readout = measurements_from_readout(sensor, sensor.read_out(result, seed=child))
        estimate = velocity(readout.measurements, readout.cameras, measurement_stderr=readout.stderr, **every).velocity
        squares += (estimate - reference) ** 2
    return np.sqrt(squares / draws).astype(np.float32)


def _noiseless_dn(sensor, raw):
    """The read-out without noise, in DN (unrounded: the quantisation is noise)."""
    silicon = sensor.noise
    return sensor.expected_electrons(raw) / silicon.gain_e_per_dn + silicon.black_level_dn
