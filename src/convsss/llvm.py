"""Find a libLLVM that Dr.Jit's CPU backend can use, before ``import mitsuba``.

Dr.Jit loads libLLVM at run time. LLVM 14 is refused, and with LLVM 15/16 Dr.Jit 1.5 aborts the process on the
first ``dr.minimum`` (see ``shared/notes/mitsuba3.md``); LLVM >= 17 works. Dr.Jit's own search may pick an older
library first, so :func:`ensure_llvm` sets ``DRJIT_LIBLLVM_PATH`` to the newest suitable one, or stops with one line
that names the fix. An existing ``DRJIT_LIBLLVM_PATH`` is honoured as it is.
"""

import glob
import os
import re
import sys

from .errors import ConvsssError

MIN_VERSION = 17
ENV = "DRJIT_LIBLLVM_PATH"
SEARCH_DIRS = (
    "/usr/lib/x86_64-linux-gnu",
    "/usr/lib/aarch64-linux-gnu",
    "/usr/lib64",
    "/usr/lib",
    "/usr/local/lib",
    "/usr/lib/llvm-*/lib",
    "/opt/homebrew/opt/llvm/lib",
    "/usr/local/opt/llvm/lib",
)
FIX = f"run `apt-get install libllvm19` (Debian/Ubuntu) or set {ENV} to a libLLVM of version >= {MIN_VERSION}"


def llvm_version(path):
    """The major version in a libLLVM file name or its ``llvm-N`` folder, or None.

    >>> llvm_version('/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1'), llvm_version('/usr/lib/libLLVM-15.so.1')
    (19, 15)
    """
    name = os.path.basename(path)
    match = re.match(r"libLLVM(?:-|\.so\.|\.)(\d+)", name)
    if match:
        return int(match.group(1))
    match = re.search(r"llvm-(\d+)", path) or re.search(r"llvm@(\d+)", path)
    return int(match.group(1)) if match else None


def candidates(search_dirs=SEARCH_DIRS):
    """All libLLVM shared libraries in ``search_dirs`` (globs allowed), with their versions, newest first."""
    found = {}
    for pattern in search_dirs:
        for folder in glob.glob(pattern):
            for path in glob.glob(os.path.join(folder, "libLLVM*")):
                if (".so" in path or path.endswith(".dylib")) and os.path.isfile(path):
                    version = llvm_version(path)
                    if version is not None:
                        found[os.path.realpath(path)] = version
    return sorted(found.items(), key=lambda item: -item[1])


def find_libllvm(search_dirs=SEARCH_DIRS, environ=None):
    """Path of the libLLVM to use: ``$DRJIT_LIBLLVM_PATH`` if set, else the newest one of version >= 17."""
    environ = os.environ if environ is None else environ
    chosen = environ.get(ENV)
    if chosen:
        if not os.path.isfile(chosen):
            raise ConvsssError(f"{ENV}={chosen} does not exist: {FIX}")
        return chosen
    usable = [path for path, version in candidates(search_dirs) if version >= MIN_VERSION]
    if not usable:
        older = ", ".join(f"{v}" for _, v in candidates(search_dirs)) or "none"
        raise ConvsssError(f"no libLLVM >= {MIN_VERSION} found for Dr.Jit (versions seen: {older}): {FIX}")
    return usable[0]


def ensure_llvm(search_dirs=SEARCH_DIRS, environ=None):
    """Set ``DRJIT_LIBLLVM_PATH`` (if unset) so that a later ``import mitsuba`` finds a usable LLVM; return the path.

    Too late once Dr.Jit is imported: then the path is only checked.
    """
    environ = os.environ if environ is None else environ
    path = find_libllvm(search_dirs, environ)
    if "drjit" not in sys.modules:
        environ[ENV] = path
    return path
