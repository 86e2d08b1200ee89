"""The structured derivation (masses collected per kinematic product, parameter sums factored,
sin² + cos² folded) against a plain expanded Lagrange derivation in SymPy, on random multi-body
models at random states; and the build that compiles long kernels as several translation units."""
import subprocess

import numpy as np
import pytest
import symengine as se
import sympy as sp
from numpy.testing import assert_allclose

import lagrgen
from lagrgen.build import compiler_command, model_info
from lagrgen.codegen.c_model import standalone_files, translation_units
from conftest import load_example

t = sp.Symbol("t")


def random_model(seed):
    """A random planar model (tree of point masses on pin and slider joints, shared masses, a rigid
    body, a moving support, springs, gravity, an input force) and its plain SymPy T, V and Q."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 6))
    model = lagrgen.Model(f"random{seed}")
    q = model.coordinates([f"q{i}" for i in range(n)])
    masses = model.parameters(**{f"m{i}": float(rng.uniform(0.5, 2)) for i in range(3)})
    lengths = model.parameters(**{f"l{i}": float(rng.uniform(0.5, 2)) for i in range(n)})
    g, k, w = model.parameters(g=9.81, k=float(rng.uniform(1, 5)), w=1.3)
    force, = model.inputs(["f"])
    support = sp.Matrix([sp.sin(w * t) / 4, 0])
    points = [support]
    T, V = sp.Integer(0), sp.Integer(0)
    for b in range(int(rng.integers(n + 1, n + 4))):
        parent = points[int(rng.integers(0, len(points)))]
        a, c = (int(i) for i in rng.integers(0, n, 2))
        kind = int(rng.integers(0, 3))
        if kind == 0:
            angle = q[a]
        elif kind == 1:
            angle = q[a] + q[c] if a != c else 2 * q[a]
        else:
            angle = q[a] - q[c] / 2
        if kind == 2 and b % 2:
            r = parent + sp.Matrix([q[a], sp.Rational(1, 2) * q[c]])
        else:
            r = parent + lengths[a] * sp.Matrix([sp.sin(angle), -sp.cos(angle)])
        m = masses[int(rng.integers(0, 3))] * (1 if b % 3 else sp.Rational(3, 2))
        model.particle(m, r)
        v = r.diff(t)
        T += m * (v.T * v)[0] / 2
        V += m * g * r[1]
        points.append(r)
    for i in range(n):  # every coordinate gets inertia of its own (the tree may miss one)
        model.particle(masses[0] / 4, sp.Matrix([lengths[i] * sp.cos(q[i]), q[i] / 3]))
        r = sp.Matrix([lengths[i] * sp.cos(q[i]), q[i] / 3])
        v = r.diff(t)
        T += masses[0] / 4 * (v.T * v)[0] / 2
    model.rigid_body(masses[1], masses[2] * lengths[0] ** 2, points[-1], q[0] + q[n - 1])
    vb = points[-1].diff(t)
    T += masses[1] * (vb.T * vb)[0] / 2 + masses[2] * lengths[0] ** 2 * (q[0] + q[n - 1]).diff(t) ** 2 / 2
    model.potential_energy(V)
    model.potential_energy(k * (q[0] - q[1]) ** 2 / 2)
    V += k * (q[0] - q[1]) ** 2 / 2
    model.generalized_force(q[n - 1], force * sp.cos(q[0]))
    Q = [sp.Integer(0)] * n
    Q[n - 1] = force * sp.cos(q[0])
    return model, q, T, V, Q


def plain_lagrange(q, T, V, Q):
    """M = ∂²T/∂q̇∂q̇ᵀ and F = ∂L/∂q − (∂²L/∂q̇∂qᵀ)·q̇ − ∂²L/∂q̇∂t + Q, expanded, in SymPy."""
    qd = [c.diff(t) for c in q]
    L = sp.expand(T - V)
    dL_dqd = [L.diff(s) for s in qd]
    M = sp.Matrix([[d.diff(s) for s in qd] for d in dL_dqd])
    # d/dt ∂L/∂q̇ = M q̈ + (the rest): take the total derivative and drop the q̈ terms
    F = []
    for i, c in enumerate(q):
        total = dL_dqd[i].diff(t)
        rest = total.subs({s.diff(t): 0 for s in qd})
        F.append(L.diff(c) - rest + Q[i])
    return M, sp.Matrix(F)


@pytest.mark.parametrize("seed", range(6))
def test_structured_derivation_matches_plain_lagrange(seed):
    model, q, T, V, Q = random_model(seed)
    M_ref, F_ref = plain_lagrange(q, T, V, Q)
    mod = lagrgen.build(model, backend="python")
    params = [sp.Symbol(name) for name in mod.parameters]
    qs, qds = sp.symbols(f"x0:{len(q)}"), sp.symbols(f"v0:{len(q)}")
    fsym = sp.Symbol("fin")
    to_plain = {**{c.diff(t): s for c, s in zip(q, qds)}, **{c: s for c, s in zip(q, qs)}}
    spec = model.spec()
    to_plain.update({user: sym for user, sym in zip(spec.parameters, params)})
    to_plain.update({spec.inputs[0]: fsym})
    args = (t, qs, qds, params, fsym)
    M = sp.lambdify(args, M_ref.xreplace(to_plain), "numpy")
    F = sp.lambdify(args, F_ref.xreplace(to_plain), "numpy")
    rng = np.random.default_rng(100 + seed)
    for _ in range(4):
        tv = float(rng.uniform(0, 3))
        qv, qdv = rng.uniform(-2, 2, len(q)), rng.uniform(-2, 2, len(q))
        p = np.asarray(mod.defaults, dtype=float) * rng.uniform(0.7, 1.3, len(mod.defaults))
        u = rng.uniform(-1, 1, 1)
        assert_allclose(mod.mass_matrix(qv, tv, p, u), np.asarray(M(tv, qv, qdv, p, u[0]), float),
                        rtol=1e-11, atol=1e-11)
        assert_allclose(mod.forcing(qv, qdv, tv, p, u), np.asarray(F(tv, qv, qdv, p, u[0]),
                        float).ravel(), rtol=1e-10, atol=1e-10)


def test_chain_mass_sums_are_collected():
    """The n-link pendulum's M_ij is one product with one mass sum: L_i L_j cos(θ_i − θ_j)·Σ m_k
    (as sin·sin + cos·cos), and M_ii = L_i²·Σ m_k with sin² + cos² folded."""
    eq = load_example("nlink_pendulum").make(5).equations()
    p = eq.p
    assert eq.M[4][4] - p[9] ** 2 * p[4] == 0
    assert sp.expand(sp.sympify(eq.M[0][0]) - sp.sympify(p[5] ** 2 * sum(p[:5]))) == 0
    assert se.count_ops(eq.M[0][0]) <= 6
    m13 = sp.sympify(eq.M[1][3])
    q = sp.sympify(eq.q)
    expected = sp.sympify(p[6] * p[8] * (p[3] + p[4])) * (sp.sin(q[1]) * sp.sin(q[3])
                                                          + sp.cos(q[1]) * sp.cos(q[3]))
    assert sp.expand(m13 - expected) == 0
    assert se.count_ops(eq.M[1][3]) <= 11  # 4 trig calls, 6 products, 1 sum (+1 in Σm)


@pytest.fixture(scope="module")
def split_model(tmp_path_factory):
    """The 9-link pendulum, whose kernels are long enough to be compiled as several units."""
    model = load_example("nlink_pendulum").make(9, name="split9")
    return model, lagrgen.build(model, out_dir=tmp_path_factory.mktemp("split"), quiet=True)


def test_split_build_matches_python_backend(split_model):
    model, mod = split_model
    source = standalone_files(model_info(model.spec(), model.equations()),
                              model.equations())["split9_model.c"]
    assert translation_units(source) >= 1
    py = lagrgen.build(model, backend="python")
    rng = np.random.default_rng(5)
    p = np.asarray(mod.defaults, dtype=float)
    for _ in range(3):
        y = rng.uniform(-1, 1, 18)
        assert_allclose(mod.rhs(0.0, y, p), py.rhs(0.0, y, p), rtol=1e-11, atol=1e-11)
        assert_allclose(mod.jacobian(0.0, y, p), py.jacobian(0.0, y, p), rtol=1e-10, atol=1e-10)


def test_split_standalone_file_is_one_plain_c_unit(split_model, tmp_path):
    """The standalone model.c of a split model still compiles alone as strict C99, no warnings."""
    model, _ = split_model
    for name, text in standalone_files(model_info(model.spec(), model.equations()),
                                       model.equations()).items():
        (tmp_path / name).write_text(text)
    result = subprocess.run([*compiler_command(), "-std=c99", "-pedantic", "-Wall", "-Werror",
                             "-O0", "-c", str(tmp_path / "split9_model.c"), "-o",
                             str(tmp_path / "m.o")], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    symbols = subprocess.run(["nm", str(tmp_path / "m.o")], capture_output=True, text=True).stdout
    assert " T split9_rhs" in symbols and "part0" in symbols
    assert " T lg_" not in symbols  # the parts stay internal (static) in the one-file build
