"""The one door to Mitsuba 3: find LLVM first, then import Mitsuba and pick a variant.

Every module that needs Mitsuba imports it with :func:`import_mitsuba` instead of ``import mitsuba``, so the LLVM
trap of ``shared/notes/mitsuba3.md`` is handled in one place; importing a module sets no variant (``mi.Float`` and
the rest are read when a function runs, in the variant active then). The variant is set where rendering starts, by
:func:`load_mitsuba` (:func:`convsss.register`, the commands, the scene loaders), and by the integrator's module,
whose class derives from the active variant's ``SamplingIntegrator``.
"""

import sys
from contextlib import contextmanager

from .errors import ConvsssError
from .llvm import ensure_llvm

#: The Mitsuba variants convsss runs in: Dr.Jit's JIT backends (the shading and the exitance lookups are Dr.Jit
#: kernels) with RGB colours (the profiles are RGB). Mitsuba's wheels have no non-AD ``llvm_rgb``/``cuda_rgb``;
#: ``scalar_*`` has no JIT, ``*_mono`` and ``*_spectral`` no RGB radiance.
SUPPORTED_VARIANTS = ("llvm_ad_rgb", "cuda_ad_rgb")
#: The variant set when none is active (runs on any CPU).
DEFAULT_VARIANT = "llvm_ad_rgb"


#: Threads Dr.Jit's pool keeps at least: Mitsuba's OpenEXR reader and writer wait on a pool task that never runs
#: with one (a process pinned to one CPU, ``taskset -c 0``, hung in every EXR write and envmap load: mitsuba3 #21).
MIN_THREADS = 2


def active_variant():
    """The Mitsuba variant set in this process, or None (Mitsuba not imported, or no variant set yet)."""
    mi = sys.modules.get("mitsuba")
    return mi.variant() if mi is not None else None


def import_mitsuba():
    """The ``mitsuba`` module, imported after a usable libLLVM was found for Dr.Jit (where one is), no variant set.

    Without a libLLVM of a usable version the import goes on (a CUDA variant may need none); :func:`load_mitsuba`
    says what to install when an LLVM variant is asked for."""
    if "mitsuba" not in sys.modules:
        try:
            ensure_llvm()
        except ConvsssError:
            pass
    import mitsuba as mi

    return mi


def load_mitsuba(variant=None):
    """Return the ``mitsuba`` module with a supported variant set (LLVM variants get a usable libLLVM first).

    ``variant`` None keeps the active variant, or sets :data:`DEFAULT_VARIANT` when none is active; a requested or
    active variant outside :data:`SUPPORTED_VARIANTS` is a :class:`~convsss.errors.ConvsssError`.
    """
    active = active_variant()
    chosen = variant or active or DEFAULT_VARIANT
    if chosen not in SUPPORTED_VARIANTS:
        whose = "requested" if variant else "active"
        raise ConvsssError(f"Mitsuba variant {chosen!r} ({whose}) is not supported: convsss renders in "
                           f"{' or '.join(SUPPORTED_VARIANTS)} (mitsuba.set_variant(...) or "
                           "convsss.register(variant=...))")
    if chosen.startswith("llvm"):
        ensure_llvm()
    import mitsuba as mi

    if active != chosen:
        try:
            mi.set_variant(chosen)
        except ImportError as error:  # cuda_ad_rgb without a GPU or its driver
            raise ConvsssError(f"Mitsuba variant {chosen!r} cannot start on this machine: "
                               f"{' '.join(str(error).split())[:200]}") from None
        import drjit as dr

        if dr.thread_count() < MIN_THREADS:
            dr.set_thread_count(MIN_THREADS)
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


def to_numpy3(v, dtype=None):
    """Dr.Jit 3-vectors (``Point3f``, ``Vector3f``, ``Normal3f``, ``Color3f``) of width N as an (N, 3) numpy array
    (in ``dtype`` when given; else Dr.Jit's own)."""
    import drjit as dr

    array = dr.ravel(v).numpy().reshape(-1, 3)
    return array if dtype is None else array.astype(dtype)


#: The alignment of the numpy buffers handed to Dr.Jit (:func:`aligned`), in bytes.
ALIGNMENT = 64


def aligned(array, dtype):
    """``array`` copied into a buffer aligned to :data:`ALIGNMENT` bytes. Dr.Jit reads a numpy array in place and
    writes the buffer's alignment into the kernel that reads it, so the same kernel of another run, whose buffer
    happened to sit elsewhere, missed the kernel cache and was compiled again (0.8 s for the shading's, issue 59)."""
    import numpy as np

    source = np.ascontiguousarray(array, dtype=dtype)
    raw = np.empty(source.nbytes + ALIGNMENT, dtype=np.uint8)
    offset = -raw.ctypes.data % ALIGNMENT
    out = raw[offset:offset + source.nbytes].view(source.dtype).reshape(source.shape)
    out[...] = source
    return out
