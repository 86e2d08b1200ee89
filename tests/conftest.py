"""Shared helpers: loading the example files, building each model once per test module and backend,
random evaluation points, and numeric evaluation of SymPy expressions written in a model's symbols.

`BACKENDS` lists the backends every backend-aware fixture runs over. Tests import the installed
lagrgen (the README's `pip install .`), whose runtime extension is compiled.
"""
import functools
import importlib
import importlib.util
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
import lagrgen  # noqa: E402

BACKENDS = ["python", "c"]

#: SciPy's release series that lagrgen's native engine is a port of (native/README.md).
SCIPY_PORTED = (1, 17)


#: The head of a script a test interrupts with SIGINT (`str.format` with the compiled model's
#: `directory` and module `name`): imports the model as `mod` and keeps when SIGINT came in `hit`.
INTERRUPTED_HEAD = """
import importlib, signal, sys, time
import numpy as np
sys.path.insert(0, {directory!r})
import lagrgen
mod = importlib.import_module({name!r})
hit = []
def on_sigint(signum, frame):
    hit.append(time.monotonic())
    raise KeyboardInterrupt
signal.signal(signal.SIGINT, on_sigint)
"""


def interrupted_script(mod, body):
    """The text of a script that runs `body` (already formatted) on the compiled model `mod` and
    can be interrupted (`INTERRUPTED_HEAD`)."""
    import os
    return INTERRUPTED_HEAD.format(directory=os.path.dirname(mod.__file__), name=mod.__name__) \
        + body


def benchmark(name):
    """A module of benchmarks/ (their Pinocchio and MuJoCo comparisons, the robots' folder)."""
    import sys
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        return importlib.import_module(name)
    finally:
        sys.path.pop(0)


def robots_dir():
    """The robots folder of the example-robot-data package, or None when it is not installed."""
    import importlib.metadata
    try:
        files = importlib.metadata.files("example-robot-data") or ()
    except importlib.metadata.PackageNotFoundError:
        return None
    for f in files:
        if str(f).endswith("robots/solo_description/robots/solo12.urdf"):
            return Path(f.locate()).parents[2]
    return None


def counts_close(ours, ref, rel=0.05, slack=3):
    """True when solver counts (an int or a tuple of ints: nfev, njev, ...) agree within `rel`
    relative plus `slack`. The native engine takes SciPy's steps, but a last-bit difference of
    OpenBLAS's sums (another CPU, another SciPy build) can flip one accept/reject or event
    decision; outside SciPy's ported release series the counts may drift a little more."""
    import scipy
    ported = tuple(int(x) for x in scipy.__version__.split(".")[:2]) == SCIPY_PORTED
    rel = rel if ported else 4 * rel
    pairs = zip(ours, ref) if isinstance(ours, tuple) else [(ours, ref)]
    return all(abs(a - b) <= rel * max(a, b) + slack for a, b in pairs)

#: (file stem, attribute) of every Model defined by the example files.
EXAMPLE_MODELS = [
    ("double_pendulum", "model"),
    ("two_mass_chain", "absolute"),
    ("two_mass_chain", "relative"),
    ("driven_pendulum", "model"),
    ("rolling_chain", "model"),
    ("cart_pendulum", "model"),
    ("nlink_pendulum", "model"),
]


@functools.lru_cache(maxsize=None)
def load_example(stem):
    """Import examples/<stem>.py by path and return the module."""
    path = EXAMPLES / f"{stem}.py"
    spec = importlib.util.spec_from_file_location(f"lagrgen_example_{stem}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def example_model(stem, attr="model"):
    """The Model object `attr` defined by examples/<stem>.py."""
    return getattr(load_example(stem), attr)


def double_integrator(name):
    """A unit mass pushed by a force F: m·ẍ = F (m = 1)."""
    model = lagrgen.Model(name)
    x, = model.coordinates("x")
    m, = model.parameters(m=1.0)
    F, = model.inputs("F")
    model.particle(m, sp.Matrix([x]))
    model.generalized_force(x, F)
    return model


def damped_oscillator(name, **extra):
    """m·ẍ + c·ẋ + k·x = F (m = 1, k = 4, c = 0.3), with the parameters `extra` in no equation."""
    model = lagrgen.Model(name)
    x, = model.coordinates("x")
    m, k, c = model.parameters(m=1.0, k=4.0, c=0.3)
    if extra:
        model.parameters(**extra)
    F, = model.inputs("F")
    model.particle(m, sp.Matrix([x]))
    model.spring(k, x)
    model.damper(c, x)
    model.generalized_force(x, F)
    return model


def example_id(entry):
    stem, attr = entry
    return stem if attr == "model" else f"{stem}.{attr}"


@pytest.fixture(scope="module", params=BACKENDS)
def backend(request):
    """The backend name; every fixture built on it runs once per entry of BACKENDS."""
    return request.param


@pytest.fixture(scope="module", params=[None])
def formulation(request):
    """The `formulation` option of `build` (None: lagrgen's own choice). A module runs its tests on
    both formulations by overriding this fixture with `FORMULATIONS` as its params."""
    return request.param


#: Both formulations, for the modules that check every model on each (`formulation` fixture).
FORMULATIONS = ["dense", "recursive"]


@pytest.fixture(scope="module")
def build(backend, formulation, tmp_path_factory):
    """A function Model -> built model that builds each Model at most once in the test module, in
    the module's `formulation`; with "recursive", a model that is not a kinematic tree is skipped
    (saying why: lagrgen.tree.analysed)."""
    out_dir = tmp_path_factory.mktemp(f"gen_{backend}")
    cache = {}

    def build_once(model):
        if id(model) not in cache:
            if formulation == "recursive":
                skip_unless_tree(model)
            cache[id(model)] = (model, lagrgen.build(model, backend=backend, out_dir=out_dir,
                                                     formulation=formulation))
        return cache[id(model)][1]
    return build_once


@pytest.fixture(scope="module")
def compile_factory(compile_once):
    """A function (factory of a Model) -> compiled model, each factory's model compiled at most
    once in the module."""
    cache = {}

    def get(factory):
        if factory not in cache:
            cache[factory] = compile_once(factory())
        return cache[factory]
    return get


def skip_unless_tree(model):
    """pytest.skip unless `model` is a kinematic tree (the recursive formulation applies)."""
    from lagrgen.lagrange import derived
    from lagrgen.tree import analysed
    tree, reason = analysed(derived(model.spec()))
    if tree is None:
        pytest.skip(f"{model.name} is not a kinematic tree: {reason}")


@pytest.fixture(scope="session")
def dask_client():
    """One Dask LocalCluster of two worker processes for the session (its start-up is the cost)."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=":0",
                                  silence_logs=40) as cluster, distributed.Client(cluster) as c:
        yield c


@pytest.fixture(scope="module")
def compile_once(tmp_path_factory):
    """A function Model -> compiled model that compiles each Model at most once in the module."""
    out_dir = tmp_path_factory.mktemp("gen_c_once")
    cache = {}

    def build_once(model):
        if id(model) not in cache:
            cache[id(model)] = (model, lagrgen.build(model, out_dir=out_dir))
        return cache[id(model)][1]
    return build_once


def random_point(mod, rng, t_range=(0.0, 2.0)):
    """A random (q, qd, t, p, u): parameters are the defaults scaled by factors in [0.5, 1.5]."""
    n = mod.n_coordinates
    q = rng.uniform(-1.5, 1.5, n)
    qd = rng.uniform(-2.0, 2.0, n)
    t = rng.uniform(*t_range)
    p = np.asarray(mod.defaults) * rng.uniform(0.5, 1.5, len(mod.parameters))
    u = rng.uniform(-2.0, 2.0, len(mod.inputs))
    return q, qd, t, p, u


def state_function(expr, t, q, qd, params, inputs):
    """Return f(q, qd, t, p, u) evaluating `expr`, written in q_i(t), dq_i/dt, t, the parameter
    symbols `params` and the input functions `inputs`, with NumPy (p, u in the orders given)."""
    n = len(q)
    Q = sp.symbols(f"_q0:{n}")
    QD = sp.symbols(f"_qd0:{n}")
    U = sp.symbols(f"_u0:{len(inputs)}")
    T = sp.Symbol("_t")
    rules = {**dict(zip(qd, QD)), **dict(zip(q, Q)), **dict(zip(inputs, U)), t: T}
    plain = sp.sympify(expr).xreplace(rules)
    left = plain.atoms(sp.Derivative, sp.core.function.AppliedUndef)
    assert not left, f"unexpected functions of t left in {plain}: {left}"
    f = sp.lambdify([Q, QD, T, tuple(params), U], plain, "numpy")
    return lambda q, qd, t, p, u: np.array(f(list(q), list(qd), t, list(p), list(u)), dtype=float)


_FMI2_CALLBACKS = []


@pytest.fixture
def fmi2_callbacks():
    """FMI 2 callbacks that live as long as the process, with FMPy's logger proxy pointed at them
    for this test (the proxy is one global pointer, which an earlier `simulate_fmu(logger=...)`
    leaves dangling: an FMU that logs through FMPy's default callbacks may then crash). The
    messages logged collect in `.messages`."""
    from ctypes import byref
    from fmpy import calloc, free
    from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                           fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)
    from fmpy.logging import addLoggerProxy
    if not _FMI2_CALLBACKS:
        messages = []
        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(lambda *args: messages.append(args[-1]))
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        _FMI2_CALLBACKS.append((callbacks, messages))
    callbacks, messages = _FMI2_CALLBACKS[0]
    callbacks.messages = messages
    addLoggerProxy(byref(callbacks))
    return callbacks


def nlp_derivatives(prob, seed=0):
    """(J, J by central differences, H lower, H by differences of ∇L, gradient, its differences)
    of the problem's NLP at a random point with random multipliers."""
    tr = prob.transcription("exact").bound(0.77)
    L = tr.layout
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1, 1, L.size)
    if L.free:
        x[L.T_index] = 1.3
    x[L.p_start:L.p_start + len(L.unknown)] = rng.uniform(0.5, 1.5, len(L.unknown))
    eps = 1e-6
    E = np.eye(L.size)
    J = np.zeros((tr.n_constraints, L.size))
    np.add.at(J, (tr.jac_rows, tr.jac_cols), tr.jacobian(x))
    Jn = np.array([(tr.constraints(x + eps * e) - tr.constraints(x - eps * e)) / (2 * eps)
                   for e in E]).T
    lam, sigma = rng.uniform(-1, 1, tr.n_constraints), 0.7

    def lagrangian_gradient(z):
        jac = tr.jacobian(z)
        return sigma * tr.gradient(z) + np.bincount(tr.jac_cols, jac * lam[tr.jac_rows],
                                                    minlength=L.size)
    H = np.zeros((L.size, L.size))
    np.add.at(H, (tr.hess_rows, tr.hess_cols), tr.hessian(x, lam, sigma))
    Hn = np.array([(lagrangian_gradient(x + eps * e) - lagrangian_gradient(x - eps * e))
                   / (2 * eps) for e in E]).T
    g = tr.gradient(x)
    gn = np.array([(tr.objective(x + eps * e) - tr.objective(x - eps * e)) / (2 * eps)
                   for e in E])
    return J, Jn, H, np.tril(Hn), g, gn


def native_free_mode_pair(mod, monkeypatch, *args, **kwargs):
    """The same native hybrid solve with its free mode (the model's own rhs between contacts)
    and without it (rhs address 0: every mode by the mode equations), checked to agree: the
    same transitions to 1e-9 s, states to 1e-8 (two ways of computing q̈ over a whole run),
    forces to 1e-7, and not bit for bit (the free mode was taken). Returns (free, general)."""
    from lagrgen.native import _ode
    solve_hybrid, addresses = _ode.solve_hybrid, []

    def recorded(*a, **options):
        addresses.append(options["rhs"])
        return solve_hybrid(*a, **options)

    monkeypatch.setattr(_ode, "solve_hybrid", recorded)
    free = lagrgen.simulate(mod, *args, engine="native", **kwargs)
    monkeypatch.setattr(_ode, "solve_hybrid",
                        lambda *a, **options: recorded(*a, **{**options, "rhs": 0}))
    general = lagrgen.simulate(mod, *args, engine="native", **kwargs)
    monkeypatch.setattr(_ode, "solve_hybrid", solve_hybrid)
    assert addresses[0] != 0 and addresses[1] == 0
    assert free.success and general.success, (free.message, general.message)
    assert [tr[1:] for tr in free.transitions] == [tr[1:] for tr in general.transitions]
    np.testing.assert_allclose([tr[0] for tr in free.transitions],
                               [tr[0] for tr in general.transitions], rtol=0, atol=1e-9)
    np.testing.assert_allclose(free.y, general.y, rtol=0, atol=1e-8)
    np.testing.assert_allclose(free.contact_forces, general.contact_forces, rtol=0, atol=1e-7)
    assert np.abs(free.y - general.y).max() > 0
    return free, general
