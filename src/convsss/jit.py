"""numba's ``njit`` and ``prange``, imported on the first call of a compiled function rather than at import.

Importing numba takes 0.15 s, which every ``convsss render`` paid although a render that walks (or shades with the
GPU) never runs a numba loop. The modules with compiled loops decorate them with :func:`njit` from here: before numba
is loaded it returns a :class:`Deferred` function that, on its first call, imports numba and puts numba's dispatcher
for every deferred function in place of the deferred one, in every module of convsss that holds it (numba resolves a
compiled function's calls to other compiled functions through its module's globals, so all of them must be numba's
by then). Once numba is loaded, :func:`njit` is numba's own.

Inside a compiled function ``prange`` must be numba's: ``from convsss.jit import prange`` gives a stand-in until
numba is loaded (``range`` in plain Python, as numba's is), which :func:`load` replaces, and numba's after.
"""

import sys
import threading

_DEFERRED = []
_LOCK = threading.Lock()


def _numba():
    return sys.modules.get("numba")


class Deferred:
    """A function to be compiled by ``numba.njit(**options)`` when first called."""

    def __init__(self, function, options):
        self.function, self.options, self.dispatcher = function, options, None
        self.__name__, self.__qualname__ = function.__name__, function.__qualname__
        self.__module__, self.__doc__, self.__wrapped__ = function.__module__, function.__doc__, function

    def __call__(self, *args, **kwargs):
        if self.dispatcher is None:
            load()
        return self.dispatcher(*args, **kwargs)

    def __repr__(self):
        return f"<deferred numba function {self.__module__}.{self.__qualname__}>"


class _Prange:
    """Stands for ``numba.prange`` until numba is loaded (``range`` when called from Python)."""

    def __call__(self, *args):
        return range(*args)


_PRANGE = _Prange()


def __getattr__(name):
    if name == "prange":
        return _PRANGE if _numba() is None else _numba().prange
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def njit(function=None, **options):
    """``numba.njit`` (bare or with options), its import deferred to the first call of a decorated function."""
    if function is None:
        return lambda f: njit(f, **options)
    if _numba() is not None and not _DEFERRED:
        return _numba().njit(**options)(function)
    deferred = Deferred(function, options)
    _DEFERRED.append(deferred)
    return deferred


def load():
    """Import numba; put its functions (and prange) in place of the deferred ones wherever convsss holds them."""
    import numba

    with _LOCK:
        _replace(numba)


def _replace(numba):
    for deferred in _DEFERRED:
        if deferred.dispatcher is None:
            deferred.dispatcher = numba.njit(**deferred.options)(deferred.function)
    for name, module in list(sys.modules.items()):
        if name.split(".")[0] != __package__ or name == __name__ or module is None:
            continue
        namespace = vars(module)
        for key, value in list(namespace.items()):
            if isinstance(value, Deferred):
                namespace[key] = value.dispatcher
            elif value is _PRANGE:
                namespace[key] = numba.prange
    _DEFERRED.clear()
