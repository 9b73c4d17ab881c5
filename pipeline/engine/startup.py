"""Start-up cost of the compiled kernels: numba's BLAS probe.

The first kernel a process calls, even one loaded from numba's cache, sets up numba's CPU
target, and that set-up asks whether a BLAS is present by importing
``scipy.linalg.cython_blas`` (``numba.np.linalg.ensure_blas``, run when ``numba.np.arraymath``
is imported). Python imports the parent package first, and ``scipy.linalg``'s ``__init__``
pulls in most of scipy's linear algebra and its array-API layer (``numpy.f2py`` among it):
0.11–0.12 s of every command and every sweep worker here, for a yes/no answer no ftsweep
kernel needs (none calls BLAS). :func:`preload_blas_probe` gives the probe the one extension
module it asks for, loaded on its own (2 ms), so the package is imported only by code that
uses it (a user's height-map splines, the Fresnel timestep optimiser). :func:`install` does it
at the moment numba's set-up imports the probing module, so a command that runs no kernel
(``--help``, ``catalogs``, ``select``) imports no scipy at all.

Measured on this project's 2-core VM (first call of a cached kernel after ``import numba``,
fresh interpreters, 3 runs each): 0.248–0.264 s without, 0.135–0.142 s with the preload.

The rest of that set-up is skipped where nothing is compiled (:func:`lazy_cache_loads`): a
kernel loaded from numba's cache is machine code already typed and lowered, yet numba sets up
its whole typing and lowering context before loading it (``Cache.load_overload`` calls
``refresh``), importing some forty implementation modules — string, list, set, random,
linear-algebra and CFFI support among them — which only a compilation reads. Measured here
(whole commands, alternating with and without, best of 5): a 5k-point predict 1.30 → 1.09 s,
the 950k-point one on one thread 2.53 → 2.39 s, on a VM twice as slow as the figures above.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.abc
import importlib.machinery
import importlib.util
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

PROBED = "scipy.linalg.cython_blas"
# numba's modules whose import runs the probe (numba.np.arraymath calls ensure_blas at import)
PROBING = frozenset({"numba.np.arraymath", "numba.np.linalg"})


def preload_blas_probe() -> bool:
    """Register scipy's ``cython_blas`` extension module under its own name, loaded from its
    file without running ``scipy.linalg``'s package ``__init__``, so numba's BLAS probe finds it
    in ``sys.modules``. True if it is registered (now or before); False where scipy or the
    file is missing or it cannot load (numba's own probe then runs as it would have).

    The module is the one ``scipy.linalg`` would load: importing ``scipy.linalg`` later runs
    its ``__init__`` as usual and ``from scipy.linalg import cython_blas`` gives this module;
    only the attribute ``scipy.linalg.cython_blas`` stays unset until something imports it
    through the package."""
    if PROBED in sys.modules or "scipy.linalg" in sys.modules:
        return PROBED in sys.modules
    try:
        scipy_spec = importlib.util.find_spec("scipy")
    except (ImportError, ValueError):
        return False
    if scipy_spec is None or not scipy_spec.submodule_search_locations:
        return False
    folder = os.path.join(next(iter(scipy_spec.submodule_search_locations)), "linalg")
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        file = os.path.join(folder, "cython_blas" + suffix)
        if os.path.isfile(file):
            break
    else:
        return False
    try:
        import scipy  # noqa: F401  (the package the module's name lives under)

        spec = importlib.util.spec_from_file_location(PROBED, file)
        if spec is None or spec.loader is None:
            return False
        module = importlib.util.module_from_spec(spec)
        sys.modules[PROBED] = module
        spec.loader.exec_module(module)
    except Exception:  # noqa: BLE001
        # whatever went wrong, leave no half-made module behind: numba then probes as usual
        sys.modules.pop(PROBED, None)
        return False
    return True


class _BeforeProbe(importlib.abc.MetaPathFinder):
    """An import hook that finds nothing itself: at the first import of a module of
    :data:`PROBING` it removes itself and runs :func:`preload_blas_probe` (numba, hence scipy's
    package, is imported by then), then lets the import proceed as usual (the finders after
    it keep their turn: see :func:`uninstall`)."""

    def find_spec(self, fullname: str, path: object = None, target: object = None) -> None:
        if fullname in PROBING:
            uninstall()
            preload_blas_probe()
        return None


_HOOK = _BeforeProbe()


def install() -> None:
    """Preload the probed module when numba's CPU target is first set up in this process
    (:func:`preload_blas_probe`), or now if that happened already (then it changes nothing),
    and load cached kernels without that set-up (:func:`lazy_cache_loads`, once numba's
    caching module is imported). Idempotent; called by the command line and by every sweep
    worker's warm-up."""
    from ftsweep import after_import

    after_import(_CACHING, lazy_cache_loads)
    if any(name in sys.modules for name in PROBING):
        return  # numba has probed already: nothing left to save
    if _HOOK not in sys.meta_path:
        sys.meta_path.insert(0, _HOOK)


def uninstall() -> None:
    """Remove the hook of :func:`install` (if present). ``sys.meta_path`` is given a new list
    rather than changed in place: the hook removes itself while the import system walks the
    list, and removing an entry then would make the walk skip the finder after it."""
    if _HOOK in sys.meta_path:
        sys.meta_path = [finder for finder in sys.meta_path if finder is not _HOOK]


_CACHING = "numba.core.caching"


def lazy_cache_loads() -> bool:
    """Load kernels from numba's cache without setting up numba's typing and lowering
    registries first; True if numba's cache loader now does so (now or before), False where
    this numba lacks the pieces relied on (it then loads as it always did).

    A cached kernel is machine code: loading it needs numba's runtime (NRT, the allocator its
    arrays use), the C helpers and math symbols the target context installs when created, and
    the pickled function descriptor; not the registries of implementations that typing and
    lowering consult. numba's loader sets the registries up anyway (``target_context.refresh``,
    ~0.2 s at a process's first kernel: CFFI's parser, string, list, set, random and
    linear-algebra support). Here the loader initialises the runtime, as the registries'
    set-up would, and loads; a compilation (a cache miss, a new signature, a user's own
    ``@njit``) still sets everything up first, in numba's compiler. A load that fails without
    the set-up is retried with it, as numba would have done."""
    from numba.core import caching
    from numba.core.runtime import nrt

    cache = caching.Cache
    if getattr(cache.load_overload, "_ftsweep_lazy", False):
        return True
    relied_on = (
        hasattr(cache, "_load_overload")
        and hasattr(cache, "_guard_against_spurious_io_errors")
        and hasattr(getattr(nrt, "rtsys", None), "initialize")
    )
    if not relied_on:
        return False
    full = cache.load_overload

    def load_overload(self: Any, sig: Any, target_context: Any) -> Any:
        try:
            nrt.rtsys.initialize(target_context)
            with self._guard_against_spurious_io_errors():
                return self._load_overload(sig, target_context)
        except Exception:  # noqa: BLE001
            return full(self, sig, target_context)

    load_overload._ftsweep_lazy = True  # type: ignore[attr-defined]
    cache.load_overload = load_overload  # type: ignore[method-assign]
    return True


class _Spent(Exception):
    """The time given to :func:`kernel_calls` ran out."""


def kernel_calls(run: Callable[[], Any], budget_s: float) -> list[tuple[Any, tuple[Any, ...]]]:
    """The compiled kernels ``run()`` calls from Python, each with the argument types numba
    would compile it for, in the order first called, found without compiling anything: during
    the call every kernel runs as the plain Python it is written in (its ``py_func``; the
    kernels it calls inside run so too), so give it a case small enough for that (a line or
    two). Stops once ``budget_s`` seconds are spent, with the kernels found so far; an error
    of ``run`` ends it the same way. The process's kernels are themselves again on return."""
    from numba.core.registry import CPUDispatcher
    from numba.core.typing.typeof import Purpose, typeof

    found: dict[tuple[int, tuple[Any, ...]], tuple[Any, tuple[Any, ...]]] = {}
    depth = [0]
    started = time.perf_counter()

    def as_python(kernel: Any, *args: Any) -> Any:
        if time.perf_counter() - started > budget_s:
            raise _Spent
        if depth[0] == 0:  # a kernel called inside another compiles with it
            types = tuple(typeof(a, Purpose.argument) for a in args)
            found.setdefault((id(kernel), types), (kernel, types))
        depth[0] += 1
        try:
            return kernel.py_func(*args)
        finally:
            depth[0] -= 1

    # on the class: every kernel, however it is reached (a module's name, a table of
    # families, a partial), runs as Python; removing it gives the compiled call back
    own = CPUDispatcher.__dict__.get("__call__")
    CPUDispatcher.__call__ = as_python  # type: ignore[method-assign, assignment]
    try:
        run()
    except Exception:  # noqa: BLE001 - _Spent, or a kernel that does not run as Python
        pass
    finally:
        if own is None:
            del CPUDispatcher.__call__
        else:
            CPUDispatcher.__call__ = own  # type: ignore[method-assign]
    return list(found.values())


def compile_shared(calls: list[tuple[Any, tuple[Any, ...]]], claims: str, wait_s: float) -> float:
    """Compile every kernel of ``calls`` (:func:`kernel_calls`) for its argument types together
    with the processes given the same ``claims`` folder, which share numba's cache: each takes
    the next kernel nobody is compiling (its claim, a file made only if absent, removed once
    the kernel is in the cache), so the kernels are compiled in parallel, each once; then it
    loads from the cache those the others compiled, waiting for one still claimed at most
    ``wait_s`` seconds (a process that died leaves its claim: the kernel is compiled here).
    Returns seconds. A kernel that fails to compile is left to the case that calls it."""
    t = time.perf_counter()
    folder = Path(claims)
    folder.mkdir(parents=True, exist_ok=True)
    # the largest first (longest-processing-time order): compile time follows the bytecode a
    # kernel compiles, its own and its kernels' (docs/performance.md, "A first run's compile,
    # shared"), so the last kernels taken are short and the processes finish together
    ordered = sorted(calls, key=lambda call: -_code_size(call[0].py_func, set()))
    others = [call for call in ordered if not _compile_claimed(call, folder)]
    deadline = time.monotonic() + wait_s
    for call in others:
        while _claim_of(call, folder).exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        _compile(call)  # from the cache now, unless its claimant is gone
    with contextlib.suppress(OSError):  # the last process to finish removes the folder
        folder.rmdir()
    return time.perf_counter() - t


def _code_size(function: Any, seen: set[int]) -> int:
    """Bytes of bytecode numba compiles for ``function``: its own and, once each, that of the
    kernels it calls (inlined or compiled with it)."""
    from numba.core.registry import CPUDispatcher

    if id(function) in seen:
        return 0
    seen.add(id(function))
    code = function.__code__
    called = (function.__globals__.get(name) for name in code.co_names)
    return len(code.co_code) + sum(
        _code_size(k.py_func, seen) for k in called if isinstance(k, CPUDispatcher)
    )


def _claim_of(call: tuple[Any, tuple[Any, ...]], folder: Path) -> Path:
    """The claim file of a kernel and argument types in ``folder``."""
    kernel, types = call
    key = f"{kernel.py_func.__module__}.{kernel.py_func.__qualname__}{types}"
    return folder / hashlib.sha256(key.encode()).hexdigest()[:32]


def _compile_claimed(call: tuple[Any, tuple[Any, ...]], folder: Path) -> bool:
    """Claim the kernel of ``call`` and compile it; False if another process holds its claim."""
    claim = _claim_of(call, folder)
    try:
        os.close(os.open(claim, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except FileExistsError:
        return False
    try:
        _compile(call)
    finally:
        claim.unlink(missing_ok=True)
    return True


def _compile(call: tuple[Any, tuple[Any, ...]]) -> None:
    """Compile a kernel for its argument types, or load it from numba's cache."""
    kernel, types = call
    with contextlib.suppress(Exception):  # the case that calls it reports its error
        kernel.compile(types)


def kernels_cached() -> bool:
    """Whether numba's cache holds this install's compiled kernels already (a run then starts
    at once): the index files of the envelope stage (``ftsweep.stages.envelope.arcs``) in the
    folder numba's ``UserProvidedCacheLocator`` gives its source under ``NUMBA_CACHE_DIR``
    (:mod:`ftsweep.caches`), so another install's kernels in the same cache do not count."""
    from numba.core.caching import UserProvidedCacheLocator

    import ftsweep.stages
    from ftsweep.caches import numba_cache_dir

    source = Path(ftsweep.stages.__file__).resolve().parent / "envelope" / "arcs.py"
    root = numba_cache_dir() / UserProvidedCacheLocator.get_suitable_cache_subpath(str(source))
    return root.is_dir() and any(root.glob("arcs.*.nbi"))
