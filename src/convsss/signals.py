"""Ctrl-C and SIGTERM around Mitsuba's renders: a render stops on either, and Ctrl-C keeps working after it.

Mitsuba's render loop (``integrator_v.cpp``) installs a C-level SIGINT handler that asks the running render to wind
down (``Integrator.should_stop``), and it can stay installed after the render returns: from then on Ctrl-C raises no
``KeyboardInterrupt`` anywhere in the process (``convsss edit`` could not be stopped, issue 30). :func:`mitsuba_render`
puts Python's own handler back after each render and turns a render that Mitsuba wound down into a
``KeyboardInterrupt``, so that no partial image leaves it. :func:`terminate_as_interrupt` makes SIGTERM raise
:class:`Terminated` (a ``KeyboardInterrupt``), so that a command stopped by ``kill`` cleans up as on Ctrl-C; one
stuck in compiled code, where Python cannot raise it, still ends :data:`GRACE` seconds later (exit 143; a later write
into the same folder removes the temporaries it left, :func:`convsss.files.remove_stale_temporaries`).
"""

import os
import signal
import threading
import time
from contextlib import contextmanager

#: Seconds a process that got SIGTERM has to stop by itself before it is ended at once.
GRACE = 10.0
#: The exit code of a process ended by SIGTERM (128 + 15).
TERMINATED = 143
_WATCHED = False


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where Python runs next (as Ctrl-C raises ``KeyboardInterrupt``)."""


def _main_thread():
    return threading.current_thread() is threading.main_thread()


@contextmanager
def mitsuba_render(integrator=None):
    """Run a Mitsuba render inside; afterwards Python's SIGINT handler is installed again (Mitsuba's may have replaced
    it) and, when ``integrator.should_stop()`` says Mitsuba wound the render down on Ctrl-C, ``KeyboardInterrupt`` is
    raised instead of returning its partial image; one (or a :class:`Terminated`) that Dr.Jit wrapped in
    one ``RuntimeError`` per symbolic loop or branch it was raised inside, comes out as itself."""
    previous = signal.getsignal(signal.SIGINT) if _main_thread() else None
    try:
        yield
    except RuntimeError as error:  # Ctrl-C in Python code that Dr.Jit ran for the render, wrapped once per level
        cause = error.__cause__  # of drjit.custom, dr.while_loop and dr.if_stmt it was raised inside
        while isinstance(cause, RuntimeError):
            cause = cause.__cause__
        if isinstance(cause, KeyboardInterrupt):
            raise cause.with_traceback(None) from None
        raise
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    if integrator is not None and integrator.should_stop():
        raise KeyboardInterrupt


def terminate_as_interrupt():
    """From now on SIGTERM raises :class:`Terminated` in the main thread, and ends the process :data:`GRACE` seconds
    later if it has not stopped (call from the main thread; elsewhere, or a second time, nothing changes)."""
    global _WATCHED
    if not _main_thread() or _WATCHED:
        return
    _WATCHED = True

    def terminated(signum, frame):
        raise Terminated

    signal.signal(signal.SIGTERM, terminated)
    # Python runs a handler only between bytecodes; its C-level handler also writes the signal's number into the
    # wakeup fd at once, which a watchdog thread reads.
    read, write = os.pipe()
    os.set_blocking(write, False)
    signal.set_wakeup_fd(write, warn_on_full_buffer=False)

    def watchdog():
        while signal.SIGTERM not in os.read(read, 64):
            pass
        time.sleep(GRACE)
        os._exit(TERMINATED)

    threading.Thread(target=watchdog, name="sigterm-watchdog", daemon=True).start()
