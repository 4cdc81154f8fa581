"""The one door to Mitsuba 3: find LLVM first, then import Mitsuba and pick a variant.

Every module that needs Mitsuba calls :func:`load_mitsuba` instead of ``import mitsuba``, so the LLVM trap of
``shared/notes/mitsuba3.md`` is handled in one place.
"""

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
