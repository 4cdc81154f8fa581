"""Ctrl-C and SIGTERM (convsss.signals): Ctrl-C still raises KeyboardInterrupt after a render in the process (Mitsuba's
handler had stayed installed, issue 30 defect 7), and SIGTERM stops a command as Ctrl-C does."""

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

SRC = str(Path(__file__).resolve().parents[1] / "src")

AFTER_RENDER = textwrap.dedent("""
    import os, signal, threading, time
    import convsss
    from convsss.editor import EditSession
    from convsss.pipeline.integrator import register
    from convsss.scene.quick import demo_mesh, quick_scene

    mi = register()
    EditSession(mi.load_dict(quick_scene(demo_mesh(), convsss.material("wholemilk"), 20.0, 16, 16, 1)))
    threading.Timer(0.2, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
    try:
        time.sleep(30)
        print("not interrupted")
    except KeyboardInterrupt:
        print("interrupted")
""")


def _python(code, timeout=120):
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, "PYTHONPATH": SRC})


@pytest.mark.slow
def test_ctrl_c_raises_keyboard_interrupt_after_a_render():
    result = _python(AFTER_RENDER)
    assert result.stdout.strip() == "interrupted", result.stdout + result.stderr


def test_sigterm_raises_terminated_a_keyboard_interrupt():
    code = textwrap.dedent("""
        import os, signal
        from convsss.signals import Terminated, terminate_as_interrupt
        terminate_as_interrupt()
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            print("not terminated")
        except Terminated as error:
            print("terminated", isinstance(error, KeyboardInterrupt))
    """)
    assert _python(code).stdout.strip() == "terminated True"


def test_an_interrupt_that_drjit_wrapped_comes_out_as_itself():
    from convsss.signals import mitsuba_render

    with pytest.raises(KeyboardInterrupt):
        with mitsuba_render():
            try:
                raise KeyboardInterrupt
            except KeyboardInterrupt as error:
                raise RuntimeError("drjit.custom(...): error while performing a custom operation") from error
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_termination_that_drjit_wrapped_twice_comes_out_as_itself():
    """SIGTERM inside a dr.if_stmt inside a dr.while_loop: two RuntimeErrors around it (the CI failure of 2026-12-04:
    `convsss render` ended with a traceback and exit 1 instead of `terminated` and 143)."""
    from convsss.signals import Terminated, mitsuba_render

    with pytest.raises(Terminated):
        with mitsuba_render():
            try:
                try:
                    raise Terminated
                except Terminated as error:
                    raise RuntimeError("dr.if_stmt(): encountered an exception (see above).") from error
            except RuntimeError as error:
                raise RuntimeError("dr.while_loop(): encountered an exception (see above).") from error


def test_a_runtime_error_that_wraps_no_interrupt_is_raised_as_it_is():
    from convsss.signals import mitsuba_render

    with pytest.raises(RuntimeError, match="while_loop"):
        with mitsuba_render():
            try:
                raise ValueError("a bug")
            except ValueError as error:
                raise RuntimeError("dr.while_loop(): encountered an exception (see above).") from error


@pytest.mark.slow
def test_sigterm_ends_a_process_stuck_in_compiled_code():
    """A process stuck in C (where Python cannot raise Terminated: the helper who reproduced issue 30 found a hung
    convsss that ignored `timeout`'s SIGTERM) still ends, GRACE seconds later, with exit 143."""
    import time

    from convsss.signals import GRACE

    # The main thread blocks SIGTERM after the watchdog starts (which keeps it unblocked) and sleeps: Python never
    # runs the handler there, as in a long C call; the watchdog thread receives the signal.
    code = textwrap.dedent("""
        import signal, time
        from convsss.signals import terminate_as_interrupt
        terminate_as_interrupt()
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM})
        print("stuck", flush=True)
        time.sleep(120)
    """)
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": SRC})
    try:
        assert proc.stdout.readline().strip() == "stuck"
        # Signal it once its main thread sleeps in C: between its print and the sleep, a bytecode boundary would run
        # the handler there (the watchdog thread took the signal, but the main thread runs Python's handlers).
        deadline = time.perf_counter() + 30
        while "sleep" not in Path(f"/proc/{proc.pid}/wchan").read_text() and time.perf_counter() < deadline:
            time.sleep(0.01)
        start = time.perf_counter()
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=GRACE + 60) == 143
        assert time.perf_counter() - start >= GRACE - 1
    finally:
        proc.kill()
