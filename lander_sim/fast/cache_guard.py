"""Keep numba's on-disk cache honest across modules.

numba's ``cache=True`` checks only the source file of the cached function itself: a kernel that
calls a compiled function of *another* module (the closed loop calls ``lander_kernel.verlet_step``,
the Runge-Kutta kernels call ``lander_kernel._accelerations``) keeps its stale machine code after
that other file changes, and loading it even registers the stale callee in the process (seen: the
RK4 kernel then flew the rotor without its weight). :func:`invalidate_if_changed` drops a module's
cache files when any of its dependencies' sources changed since the cache was written.
"""
from __future__ import annotations

import hashlib
from pathlib import Path


def invalidate_if_changed(module_file: str, *dependency_files: str) -> None:
    """Remove ``module_file``'s numba cache (``__pycache__/<stem>.*.nbi/.nbc``) if the sources of
    ``dependency_files`` differ from those the cache was built against (a stamp file beside it)."""
    src = Path(module_file)
    cache = src.parent / "__pycache__"
    digest = hashlib.sha256()
    for dep in dependency_files:
        digest.update(Path(dep).read_bytes())
    stamp = cache / f"{src.stem}.deps-sha256"
    want = digest.hexdigest()
    try:
        if stamp.read_text() == want:
            return
    except OSError:
        pass
    try:
        cache.mkdir(exist_ok=True)
        for f in cache.glob(f"{src.stem}.*.nb[ic]"):
            f.unlink(missing_ok=True)
        stamp.write_text(want)
    except OSError:  # a read-only install: nothing was cached there either
        pass
