"""The paper's experiments, each writing CSV tables and PNG plots to a folder.

=================  =========================================================================
experiment         what it measures
=================  =========================================================================
``time-sampling``  error (MAE, RMSE, relative, PSNR) of every time sampling × correlation
                   mode against a high-spp reference over an h × ψ grid; averaged over ψ
                   versus h (paper Fig. 12) — :func:`run_time_sampling`
``shifts``         the same error for antithetic and mirrored antithetic sampling over the
                   shift a ∈ [0, 1] (units of T) and h (paper Fig. 15) — :func:`run_shifts`
``velocity``       velocity reconstructed from homodyne/heterodyne pairs at ψ = 0, 90°
                   against the ground truth, with and without sensor noise —
                   :func:`run_velocity`
``paper-fig12``    Figs. 12, 9 and 15 with the original scripts' protocol (:mod:`.paper`):
``paper-fig9``     ω_r and ψ over 11 values each, 1024 spp, a 131 072-spp reference —
``paper-fig15``    :func:`run_fig12`, :func:`run_fig9`, :func:`run_shifts`
=================  =========================================================================

From the command line: ``dopplertof experiment <name> SCENE`` (:mod:`.cli`). References
are cached by everything that determines them (:class:`ReferenceCache`), so a rerun does
not render them again.
"""

import importlib

# Loaded on first use: the command line imports this package at start-up, and plotting
# (matplotlib) would slow down every ``dopplertof`` command.
_EXPORTS = {
    "Estimator": "common",
    "ExperimentScene": "common",
    "ReferenceCache": "common",
    "default_cache_dir": "common",
    "image_errors": "common",
    "open_scene": "common",
    "SweepSettings": "sweeps",
    "run_shifts": "sweeps",
    "run_time_sampling": "sweeps",
    "run_velocity": "velocity",
    "run_fig12": "paper",
    "run_fig9": "paper",
    "velocity_errors": "velocity",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
