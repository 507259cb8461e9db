"""Every compile path of the package: numba options, specialised loops, user SDFs.

``kernel`` is ``numba.njit`` with the project defaults: cached on disk (turn off with
``DEM_JIT_CACHE=0``), IEEE arithmetic (no ``fastmath``) and numpy's error model, so a
division by zero gives ``inf``/``nan`` that the run loop detects instead of raising.
The threading layer is chosen here too: OpenMP where available, never TBB.

Numba checks a cached kernel against its own source file only, not against the
functions it inlines from other files: after an edit to a contact law or a detection
kernel (or an upgrade of the package) it would load a time loop compiled with the old
code. The cache therefore lives in a folder named after a hash of every source file of
the package, ``<NUMBA_CACHE_DIR or the package's __pycache__>/dem-<hash>``: a changed
file means a cold compile, never a stale kernel.

Builders
--------
:func:`branch_on` writes the law dispatch of :mod:`dem.contact.laws.dispatch`: an
inlined kernel with one branch per registered law.

Two things are compiled per scene rather than per package, both here:

* :func:`specialise`: a loop written once, compiled with some of the module-level
  kernels it calls replaced (the shape loop with the ADMM solver bound to a user's SDF).
* :func:`sdf_address` and :func:`call_sdf`: a user's ``@numba.njit`` SDF wrapped as a C
  function, and the call of that function by its address from compiled code, so that
  the solvers are compiled (and cached) once for every SDF, with the address a runtime
  argument.
"""

import hashlib
import importlib
import logging
import os
import pickle
import subprocess
import sys
import types as pytypes

import numba
import numpy as np
from llvmlite import ir as llvm_ir
from numba import carray, cfunc
from numba.core import types
from numba.extending import intrinsic, overload

CACHE = os.environ.get("DEM_JIT_CACHE", "1") != "0"

log = logging.getLogger(__name__)

#: seconds of a cold compile of each kernel family on the reference machine of
#: docs/performance.md (``benchmarks/cold_start.py``): the time loop of spheres and
#: disks with its measures, and the loop of level-set shapes
COMPILE_S = {"sphere": 50, "shape": 80}


def source_stamp():
    """A hash of the package's Python sources (names and contents), 16 hex digits."""
    root = os.path.dirname(os.path.abspath(__file__))
    h = hashlib.sha256()
    for folder, subfolders, files in os.walk(root):
        subfolders[:] = sorted(d for d in subfolders if d != "__pycache__")
        for name in sorted(f for f in files if f.endswith(".py")):
            path = os.path.join(folder, name)
            h.update(os.path.relpath(path, root).encode())
            with open(path, "rb") as f:
                h.update(f.read())
    return h.hexdigest()[:16]


if CACHE:
    _base = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(
        os.path.dirname(os.path.abspath(__file__)), "__pycache__")
    numba.config.CACHE_DIR = os.path.join(_base, "dem-" + source_stamp())

if "NUMBA_THREADING_LAYER" not in os.environ:
    numba.config.THREADING_LAYER = "omp"


#: numba's parallel options of a ``parallel=True`` kernel: the explicit ``prange`` loops
#: run on threads, and nothing else is parallelised. Numba's other conversions (array
#: expressions, ``a[:] = x``, reductions such as ``.max()`` become parallel loops of their
#: own, and adjacent loops are fused) find nothing worth a thread in these kernels, and
#: their passes cost a large part of a time loop's cold compile
#: (``benchmarks/loop_compile.py``).
PRANGE_ONLY = {"prange": True, "comprehension": False, "reduction": False,
               "inplace_binop": False, "setitem": False, "numpy": False, "stencil": False,
               "fusion": False}


def kernel(fn=None, *, parallel=False, inline=False, cache=True):
    """``numba.njit`` with project defaults; ``parallel=True`` only where a prange exists
    (and only the prange loops run in parallel: :data:`PRANGE_ONLY`).

    ``inline=True`` inlines the function into its callers at numba's IR level: for the
    small per-contact kernels (laws) called from hot loops, where a real call would pass
    every array as a dozen scalar arguments. Such a kernel may read from a state bundle
    (a named tuple of arrays) but must write only into arrays it takes as arguments:
    inlined into a ``prange`` loop, a write through ``bundle.field[...]`` is dropped by
    numba without an error (``tests/test_architecture.py``, ``bundle_writes``).

    ``cache=False`` keeps the function off the disk cache even where ``DEM_JIT_CACHE``
    allows it: for helpers that are only ever compiled into a cached caller (the ADMM
    solver's pieces), for functions that hold per-process objects (see
    :func:`specialise`), and for those specialised on a user's function passed as an
    argument (the mass properties of :class:`dem.shapes.CustomShape`), whose cache
    entries would miss in every new process.

    No module compiles with numba but through this one
    (``tests/test_architecture.py``, ``compile_paths``).
    """
    deco = numba.njit(cache=CACHE and cache, parallel=dict(PRANGE_ONLY) if parallel else False,
                      fastmath=False,
                      error_model="numpy", inline="always" if inline else "never")
    return deco if fn is None else deco(fn)


def specialise(py_func, *, parallel=False, **bind):
    """Compile ``py_func`` as :func:`kernel` does, with the globals ``bind`` replaced.

    A loop factory writes its loop once, calling module-level kernels by their global
    names; a scene that needs another kernel in one of those places (the shape loop's
    ``_ADMM``, bound to the ADMM solver of a user's SDF) gets the same code compiled
    over ``{**py_func.__globals__, **bind}``. Numba reads globals once, at compile time,
    so the binding holds for the life of the returned dispatcher.

    Caching: numba keys its disk cache on a function's code, the values of its closure
    cells and the signature, not on its globals, so two bindings of one function would
    share (and overwrite) one cache entry; and a bound object may be valid in this
    process only (a kernel holding the address of a user's compiled SDF). A function
    whose globals are really replaced is therefore compiled with ``cache=False``.
    Names bound to the object they already hold are no replacement: with nothing else
    bound the function compiles exactly as ``kernel(py_func, parallel=parallel)``, and
    caches as any kernel does.

    Examples
    --------
    >>> SCALE = 2.0
    >>> def scaled(x):
    ...     return SCALE * x
    >>> scaled(3.0), specialise(scaled, SCALE=10.0)(3.0)
    (6.0, 30.0)
    """
    own = py_func.__globals__
    bind = {k: v for k, v in bind.items() if k not in own or own[k] is not v}
    if not bind:
        return kernel(py_func, parallel=parallel)
    fn = pytypes.FunctionType(py_func.__code__, {**own, **bind}, py_func.__name__,
                              py_func.__defaults__, py_func.__closure__)
    return kernel(fn, parallel=parallel, cache=False)


def branch_on(name, params, cases, fallback, doc=""):
    """An inlined kernel ``name(code, *params)`` that calls ``cases[code](*params)``.

    ``cases`` maps each integer code to a compiled function, ``fallback`` is called for
    any other code. The function is written with one branch per case and no more:
    numba types and lowers every branch of a function inlined into a caller (its dead
    branch pruning runs before inlining), so a fixed chain of spare branches costs
    compile time in every loop that inlines it; a caller whose ``code`` is a constant
    gets the other branches folded away by LLVM. The cases are the new function's own
    globals, read when a caller compiles (a disk-cached caller is keyed on the package
    sources, :func:`source_stamp`, so the cases must come from them).
    """
    if not all(str(x).isidentifier() for x in (name, *params)):
        raise ValueError(f"branch_on: names must be identifiers, got {name!r}, {params!r}")
    args = ", ".join(params)
    lines = [f"def {name}(code, {args}):"]
    scope = {"_fallback": fallback}
    for code, fn in sorted(cases.items()):
        scope[f"_case_{int(code)}"] = fn
        lines.append(f"    if code == {int(code)}:")
        lines.append(f"        return _case_{int(code)}({args})")
    lines.append(f"    return _fallback({args})")
    namespace = {}
    exec(compile("\n".join(lines), f"<dem._jit.branch_on {name}>", "exec"), scope, namespace)
    fn = namespace[name]
    fn.__doc__ = doc
    # never compiled on its own (it has no source file to cache by): inlined only
    return kernel(fn, inline=True, cache=False)


# --------------------------------------------------------------------------- user SDFs
#: parameters of a user SDF: ``sdf(x, y, z, p)`` reads ``p[0] .. p[N_SDF_PARAMS - 1]``
N_SDF_PARAMS = 4
#: the C signature of a wrapped user SDF: ``double f(double x, double y, double z,
#: double *p)``
SDF_SIGNATURE = types.float64(types.float64, types.float64, types.float64,
                              types.CPointer(types.float64))
_WRAPPERS = {}


def sdf_address(sdf):
    """The ``fn`` argument that hands the user's SDF to compiled solvers.

    ``sdf`` is a ``@numba.njit`` function ``sdf(x, y, z, p) -> float`` (``p`` a (4,)
    float64 array). It is wrapped once per process in a C function of
    :data:`SDF_SIGNATURE` (kept alive here, for every call through its address) and
    its address is returned as an int64, to be passed on to :func:`call_sdf`. Under
    ``NUMBA_DISABLE_JIT`` the function itself is returned: :func:`call_sdf` then calls
    it directly.
    """
    if numba.config.DISABLE_JIT:
        return sdf
    if sdf not in _WRAPPERS:
        @cfunc(SDF_SIGNATURE, error_model="numpy")
        def wrapper(x, y, z, p):
            return sdf(x, y, z, carray(p, N_SDF_PARAMS))

        _WRAPPERS[sdf] = wrapper
    return np.int64(_WRAPPERS[sdf].address)


def call_sdf(fn, x, y, z, p):
    """The user's SDF at ``(x, y, z)`` with parameters ``p`` (a (4,) float64 array):
    ``fn`` is :func:`sdf_address`'s answer, an address in compiled code (the C function
    called through it) and the Python function when interpreted."""
    return fn(x, y, z, p)


@intrinsic
def _call_address(typingctx, address, x, y, z, p):
    """Call the C function ``double f(double, double, double, double*)`` at ``address``."""
    sig = types.float64(address, x, y, z, p)

    def codegen(context, builder, signature, args):
        double = llvm_ir.DoubleType()
        fnty = llvm_ir.FunctionType(double, [double, double, double, double.as_pointer()])
        fn = builder.inttoptr(args[0], fnty.as_pointer())
        return builder.call(fn, args[1:])

    return sig, codegen


@intrinsic
def _as_pointer(typingctx, address):
    """An integer address as a ``float64*``."""
    sig = types.CPointer(types.float64)(address)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(signature.return_type))

    return sig, codegen


@overload(call_sdf, jit_options={"cache": False})
def _call_sdf_compiled(fn, x, y, z, p):
    def impl(fn, x, y, z, p):
        return _call_address(fn, x, y, z, _as_pointer(p.ctypes.data))
    return impl


def set_threads(n):
    """Set the number of numba threads used by parallel kernels (1 .. NUMBA_NUM_THREADS)."""
    numba.set_num_threads(int(n))


def get_threads():
    """Number of numba threads parallel kernels use now."""
    return numba.get_num_threads()


_announced = set()

#: ``DEM_COMPILE_APART=0`` compiles the time loops in this process (see :func:`prepare`)
APART = os.environ.get("DEM_COMPILE_APART", "1") != "0"


def recipe(dispatcher, factory, *args, **kwargs):
    """Mark ``dispatcher`` as made by ``factory(*args, **kwargs)``, a module-level
    function whose arguments are plain values (numbers, strings, tuples):
    :func:`prepare` may then compile it in a child process. Returns the dispatcher."""
    dispatcher.dem_recipe = (factory.__module__, factory.__qualname__, args, kwargs)
    return dispatcher


def prepare(dispatcher, args, family):
    """Make sure ``dispatcher`` is compiled for ``args`` before its first call.

    Where the loop is not in the disk cache (a first run, or the first after an edit
    or upgrade), say so once per process and family (on a terminal to stderr, else
    logged at INFO; under MPI only rank 0 speaks), and, for a dispatcher with a
    :func:`recipe`, compile it in a child process that writes the disk cache, from
    which this process then loads it.

    Why a child: numba keeps every intermediate object of a ``parallel=True``
    compilation alive for the life of the process (numba issue 5667). A time loop
    leaves 1.5-3 GB behind that way, so a process that compiled a few variants (a
    test session, a notebook that tries 2D and 3D, with and without rolling) grew
    past the memory of a laptop; loaded from the cache, a loop costs a few MB. If the
    child fails, the loop compiles here, as numba would, and raises any error here.
    ``DEM_COMPILE_APART=0`` turns the child off.
    """
    if numba.config.DISABLE_JIT or not CACHE:
        return
    try:
        sig = tuple(dispatcher.typeof_pyval(a) for a in args)
    except Exception:  # numba raises its own error at the call
        return
    if sig in dispatcher.overloads or _cached(dispatcher, sig):
        return
    if family not in _announced:
        _announced.add(family)
        if os.environ.get("PMI_RANK", "0") == "0":
            msg = (f"compiling the {family} kernels: first run only, about "
                   f"{COMPILE_S[family]} s")
            if sys.stderr.isatty():
                print(f"dem: {msg}", file=sys.stderr, flush=True)
            else:
                log.info(msg)
    made = getattr(dispatcher, "dem_recipe", None)
    if made is None or not APART:
        return
    # the child must not join an MPI job: drop the process manager's variables
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("PMI_", "PMIX_", "HYDRA_", "MPICH_", "OMPI_"))}
    done = subprocess.run([sys.executable, "-c", "import dem._jit as j; j._compile_child()"],
                          input=pickle.dumps((numba.config.CACHE_DIR, made, sig)),
                          env=env, capture_output=True)
    if done.returncode != 0 or not _cached(dispatcher, sig):
        log.info("the %s kernels did not compile in a child process (exit %d): "
                 "compiling here\n%s", family, done.returncode,
                 done.stderr.decode(errors="replace")[-2000:])


def _compile_child():
    """The child of :func:`prepare`: compile one loop for one signature (from stdin)."""
    numba.config.CACHE_DIR, (module, name, args, kwargs), sig = pickle.load(sys.stdin.buffer)
    factory = getattr(importlib.import_module(module), name)
    factory(*args, **kwargs).compile(sig)


def _cached(dispatcher, sig):
    """True if ``dispatcher`` has ``sig`` in its disk cache, or has no disk cache."""
    try:  # numba's cache layout (0.5x-0.6x)
        cache = dispatcher._cache
        key = cache._index_key(sig, dispatcher.targetctx.codegen())
        return key in cache._cache_file._load_index()
    except AttributeError:  # not cached, or another numba: nothing to do
        return True
