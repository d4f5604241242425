"""The D-ToF path tracer, written once (DESIGN §5.1).

=============  ===========================================================================
module         owns
=============  ===========================================================================
``lanes``      which pixel, group, member and replicate a lane is; its replayable random
               streams; its exposure time
``film``       the film position of a camera sample, drawn from the film's
               reconstruction filter
``materials``  per-BSDF tables the paired shift and the optical length need (roughness,
               relative index of refraction)
``path``       the phases of a bounce: camera vertex (+ ground truth), extending the
               Float64 optical length by η·d, emitter hit, emitter sampling
``sink``       the per-lane outputs: intensity and the modulation weight W(u, L) of every
               camera, ground truth
``single``     :func:`trace`: one path per lane, the phases in a loop (power-heuristic MIS,
               Russian roulette)
``paired``     :func:`trace_pair`: a primal path and its shifted partner per lane
               (reconnection, adaptive, analytic)
=============  ===========================================================================

:func:`trace_pass` runs one pass with the tracer the settings ask for;
:func:`interrupts_unwrapped` lets an interrupt raised while Dr.Jit traced leave as itself.
"""

from __future__ import annotations

import contextlib


def trace_pass(scene, settings, setup, tables):
    """Per-lane outputs of one pass (:class:`~dopplertof.tracing.sink.Sink` layout).

    Parameters
    ----------
    scene : DynamicScene
    settings : RenderSettings
    setup : LaneSetup
        The pass's pixels, samples and exposure window.
    tables : MaterialTables
        Of ``scene``.

    Returns
    -------
    dict
        Name → per-lane Dr.Jit array, not yet evaluated.
    """
    if settings.paired:
        from .paired import trace_pair as trace
    else:
        from .single import trace
    return trace(scene, settings, setup, tables)


@contextlib.contextmanager
def interrupts_unwrapped():
    """Let a KeyboardInterrupt raised while Dr.Jit traced a loop leave as itself.

    A signal handled while Dr.Jit traces a loop body (the path loop, the pass's reduction)
    raises there, and Dr.Jit hands it on wrapped in a RuntimeError; whoever stops on a
    KeyboardInterrupt (a render, a dataset's SIGTERM) must see it as one. Other errors leave
    unchanged.
    """
    try:
        yield
    except RuntimeError as exc:
        interrupt = _interrupt_in(exc)
        if interrupt is None:
            raise
        raise interrupt from None


def _interrupt_in(exc: BaseException) -> KeyboardInterrupt | None:
    """The KeyboardInterrupt in ``exc``'s chain of causes and contexts, if any."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None
