"""Sensor design: render a scene once, read out any sensor, know the best it can do.

* :mod:`~dopplertof.design.record`: ``dopplertof.render(scene, record=True).record`` keeps
  a scene's response on a declared frequency × beat grid; :func:`evaluate` reads the
  measurements and raw frames of any sensor in that band out of it, exactly;
* :mod:`~dopplertof.design.precision`: :func:`crb`, per-pixel Cramér–Rao bounds of velocity
  and depth from the record's exact derivatives and the sensor's noise chain, and
  :func:`achieved_rmse`, what an estimator reaches over noise draws;
* :mod:`~dopplertof.design.gradient`: :func:`gradient` of the raw frames and of the bounds
  with respect to phases, heterodyne offsets and Fourier code coefficients.
"""

from .gradient import Gradient, gradient
from .precision import Precision, achieved_rmse, crb
from .record import Record, RecordSpec, evaluate

__all__ = ["Record", "RecordSpec", "evaluate", "crb", "achieved_rmse", "Precision", "gradient", "Gradient"]
