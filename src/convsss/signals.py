"""Ctrl-C and SIGTERM around Mitsuba's renders: a render stops on either, and Ctrl-C keeps working after it.

Mitsuba's render loop (``integrator_v.cpp``) installs a C-level SIGINT handler that asks the running render to wind
down (``Integrator.should_stop``), and it can stay installed after the render returns: from then on Ctrl-C raises no
``KeyboardInterrupt`` anywhere in the process (``convsss edit`` could not be stopped, issue 30). :func:`mitsuba_render`
puts Python's own handler back after each render and turns a render that Mitsuba wound down into a
``KeyboardInterrupt``, so that no partial image leaves it. :func:`terminate_as_interrupt` makes SIGTERM raise
:class:`Terminated` (a ``KeyboardInterrupt``), so that a command stopped by ``kill`` cleans up as on Ctrl-C.
"""

import signal
import threading
from contextlib import contextmanager


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where Python runs next (as Ctrl-C raises ``KeyboardInterrupt``)."""


def _main_thread():
    return threading.current_thread() is threading.main_thread()


@contextmanager
def mitsuba_render(integrator=None):
    """Run a Mitsuba render inside; afterwards Python's SIGINT handler is installed again (Mitsuba's may have replaced
    it) and, when ``integrator.should_stop()`` says Mitsuba wound the render down on Ctrl-C, ``KeyboardInterrupt`` is
    raised instead of returning its partial image; one that Dr.Jit wrapped in a ``RuntimeError`` comes out as
    itself."""
    previous = signal.getsignal(signal.SIGINT) if _main_thread() else None
    try:
        yield
    except RuntimeError as error:  # Ctrl-C in Python code that Dr.Jit ran for the render, wrapped by drjit.custom
        if isinstance(error.__cause__, KeyboardInterrupt):
            raise error.__cause__.with_traceback(None) from None
        raise
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    if integrator is not None and integrator.should_stop():
        raise KeyboardInterrupt


def terminate_as_interrupt():
    """From now on SIGTERM raises :class:`Terminated` in the main thread (call from it; elsewhere nothing changes)."""
    if not _main_thread():
        return

    def terminated(signum, frame):
        raise Terminated

    signal.signal(signal.SIGTERM, terminated)
