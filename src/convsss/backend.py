"""The one door to Mitsuba 3: find LLVM first, then import Mitsuba and pick a variant.

Every module that needs Mitsuba calls :func:`load_mitsuba` instead of ``import mitsuba``, so the LLVM trap of
``shared/notes/mitsuba3.md`` is handled in one place.
"""

from contextlib import contextmanager

from .llvm import ensure_llvm

DEFAULT_VARIANT = "llvm_ad_rgb"


def load_mitsuba(variant=DEFAULT_VARIANT):
    """Return the ``mitsuba`` module with ``variant`` set (LLVM variants get a usable libLLVM first)."""
    if variant.startswith("llvm"):
        ensure_llvm()
    import mitsuba as mi

    if mi.variant() != variant:
        mi.set_variant(variant)
    return mi


@contextmanager
def ordered_kernels():
    """Run the Dr.Jit kernels launched inside, and everything pending at the end, on the calling thread alone.

    Lanes that scatter-add to the same address add in the order the threads happen to run, which changes float
    sums from run to run; one thread adds them in lane order, so the result is bit-identical whatever the thread
    count. Scatter-adds stay atomic (no per-thread copies of their targets, whose number would change with the
    thread count). Yields the thread count outside. No image file may be read or written inside: Mitsuba's
    OpenEXR I/O hangs without worker threads.
    """
    import drjit as dr

    threads, expand = dr.thread_count(), dr.expand_threshold()
    dr.set_expand_threshold(0)
    dr.set_thread_count(1)
    try:
        yield threads
        dr.eval()
    finally:
        dr.set_thread_count(threads)
        dr.set_expand_threshold(expand)
