"""Sensor design: render a scene once, read out any sensor, know the best it can do.

* :mod:`~dopplertof.design.record`: ``dopplertof.render(scene, record=True).record`` keeps
  a scene's response on a declared frequency × beat grid; :func:`evaluate` reads the
  measurements and raw frames of any sensor in that band out of it, exactly.
"""

from .record import Record, RecordSpec, evaluate

__all__ = ["Record", "RecordSpec", "evaluate"]
