"""What a camera set can determine (:mod:`dopplertof.reconstruct`, brightness): the ranks
of the model's Jacobian at a generic point, and the cameras to add when velocity is not."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np

from .model import _CameraSet, _design_columns, _kernel


_PROBE_DOPPLER_PHASE = 0.123  # rad: a generic a at which a camera set's ranks are judged


def _probe_jacobian(cams: _CameraSet) -> np.ndarray:
    """∂m/∂(Re Z, Im Z, β, a), shape (n_cameras, 4), at a generic point (a = 0.123 rad,
    β = 0, arg Z = 0.7 rad), each column scaled to unit norm: its ranks decide what a
    camera set can determine whatever the data."""
    a, z = np.array([_PROBE_DOPPLER_PHASE]), np.exp(0.7j)
    c1, c2 = _design_columns(a, cams)
    columns = [c1[:, 0], c2[:, 0]]
    for wrt in ("beta", "a"):
        columns.append(cams.half_g1 * (z * _kernel(a, cams, 0.0, wrt)[:, 0]).real)
    jac = np.stack(columns, axis=1)
    norms = np.linalg.norm(jac, axis=0)
    return jac / np.where(norms > 0, norms, 1.0)


def _rank(matrix: np.ndarray) -> int:
    return 0 if matrix.size == 0 else int(np.linalg.matrix_rank(matrix, tol=1e-8))


def _determines_doppler(cams: _CameraSet) -> bool:
    """Whether ∂m/∂a is independent of the amplitude, depth-phase and brightness columns."""
    jac = _probe_jacobian(cams)
    return _rank(jac) > _rank(jac[:, :3])


def _with_cameras(cams: _CameraSet, added) -> _CameraSet:
    """``cams`` plus cameras (h, ψ) in the first camera's window, with the mean g1."""
    h, psi = (np.array([c[i] for c in added], dtype=np.float64) for i in (0, 1))
    return dataclasses.replace(
        cams,
        heterodyne=np.concatenate([cams.heterodyne, h]),
        phase_rad=np.concatenate([cams.phase_rad, psi]),
        half_g1=np.concatenate([cams.half_g1, np.full(len(added), np.mean(cams.half_g1))]),
        waveforms=cams.waveforms + ("sinusoidal",) * len(added),
        window_offset=np.concatenate([cams.window_offset, np.zeros(len(added))]),
    )


def _phase_spec(psi_rad: float) -> str:
    """A phase offset as ``--camera`` takes it."""
    degrees = float(np.degrees(psi_rad))
    return f"psi={'0' if degrees == 0 else f'{degrees:g}deg'}"


def _camera_spec(h: float, psi_rad: float) -> str:
    """A camera as ``--camera`` takes it."""
    return f"h={h:g},{_phase_spec(psi_rad)}"


def _what_to_add(cams: _CameraSet) -> str:
    """The first one or two cameras (homodyne first, ψ in quadrature steps) after which the
    set determines the Doppler shift, as ``--camera`` specs."""
    heterodynes = [0.0, 1.0] + sorted(set(cams.heterodyne.tolist()) - {0.0, 1.0})
    phases = cams.phase_rad[0] + 0.5 * np.pi * np.arange(4)  # quadrature steps from the first camera's ψ
    singles = [(h, psi) for h in heterodynes for psi in np.mod(phases, 2.0 * np.pi)]
    for count in (1, 2):
        for added in itertools.combinations(singles, count):
            if _determines_doppler(_with_cameras(cams, added)):
                return " and ".join(_camera_spec(h, psi) for h, psi in added)
    return "homodyne and heterodyne cameras at ψ = 0 and 90deg"


def _velocity_identifiable(cams: _CameraSet) -> str | None:
    """Why the set cannot determine the Doppler phase, or None if it can (generically).

    The unknowns per pixel are four: amplitude and depth phase (Z), the Doppler phase a and
    the brightness slope β (module docstring, brightness). Velocity is determined when the
    measurements respond to a in a way that Z and β cannot imitate.
    """
    if len(np.unique(np.round(cams.heterodyne, 12))) < 2:
        return (
            f"all cameras have the same heterodyne ratio h = {cams.heterodyne.tolist()}; the "
            "Doppler shift only changes their common scale, so velocity is not determined: add "
            "cameras with a different h (e.g. h = 1 next to h = 0)"
        )
    if _determines_doppler(cams):
        return None
    cameras = ", ".join(_camera_spec(h, psi) for h, psi in zip(cams.heterodyne, cams.phase_rad))
    return (
        f"the cameras {cameras} cannot determine velocity: a moving surface changes its "
        "brightness during the exposure (1/d²: by −2vT/d, as large as the Doppler phase "
        "itself), and these measurements cannot tell that change from a Doppler shift (amplitude, "
        "depth phase, Doppler shift and brightness change are four unknowns per pixel); "
        f"add {_what_to_add(cams)}"
    )


def _column_rank(c1: np.ndarray, c2: np.ndarray) -> int:
    """Rank of the (n_cameras, 2) design matrix of one Doppler phase."""
    basis = np.concatenate([c1, c2], axis=1)
    scale = np.abs(basis).max()
    return 0 if scale == 0 else int(np.linalg.matrix_rank(basis, tol=1e-9 * scale))
