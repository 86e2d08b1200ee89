"""The recursive formulation over kinematic trees (lagrgen.tree): which models are proven trees, and
that every model function gives the dense formulation's numbers on random trees (pin, slider and
telescopic joints, planar rigid bodies, 3-D particles, gravity as constant loads, springs,
dampers, forces with inputs, torques), on both backends; the choice between the formulations; the
generated C."""
import re
import subprocess

import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose

import lagrgen
from lagrgen.build import model_info
from lagrgen.toolchain import compiler_command
from lagrgen.codegen.c_model import standalone_files
from lagrgen.errors import MassMatrixError, ModelError
from lagrgen.lagrange import derived
from lagrgen.tree import RECURSIVE_FROM, analysed
from conftest import EXAMPLE_MODELS, example_model, load_example, random_point, state_function

t = sp.Symbol("t")


def random_tree(seed, dims=2, support=None, name=None):
    """A random tree of joints in absolute coordinates (each link's offset a function of its own
    coordinate), a mass at every joint, planar rigid bodies on some pins, gravity, a spring, a
    damper, a force with an input, a torque and a generalized force; hanging from `support`, a
    point moving with t (default: fixed)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, 8))
    model = lagrgen.Model(name or f"tree{seed}_{dims}d")
    q = model.coordinates([f"q{i}" for i in range(n)])
    masses = model.parameters(**{f"m{i}": float(rng.uniform(0.5, 2)) for i in range(3)})
    lengths = model.parameters(**{f"l{i}": float(rng.uniform(0.5, 1.5)) for i in range(n)})
    g, k, c = model.parameters(g=9.81, k=float(rng.uniform(1, 5)), c=0.3)
    force, = model.inputs(["f"])
    up = dims - 1                       # the vertical component
    points = [sp.zeros(dims, 1) if support is None else sp.Matrix(support)]
    for i in range(n):
        parent = points[int(rng.integers(0, len(points)))]
        kind = int(rng.integers(0, 3))
        if kind == 0:                   # pin: absolute angle
            direction = [sp.sin(q[i]), -sp.cos(q[i])] if dims == 2 else \
                [sp.sin(q[i]) * sp.Rational(3, 5), sp.sin(q[i]) * sp.Rational(4, 5), -sp.cos(q[i])]
            offset = lengths[i] * sp.Matrix(direction)
        elif kind == 1:                 # slider along a fixed direction
            offset = sp.Matrix([q[i], q[i] / 2] + ([q[i] / 3] if dims == 3 else []))
        else:                           # telescopic link at a fixed angle
            offset = (lengths[i] + q[i] / 2) * sp.Matrix([sp.Rational(3, 5), -sp.Rational(4, 5)]
                                                         + ([0] if dims == 3 else []))
        r = parent + offset
        m = masses[int(rng.integers(0, 3))]
        model.particle(m, r)
        model.potential_energy(m * g * r[up])
        if kind == 0 and dims == 2 and rng.uniform() < 0.5:
            model.rigid_body(masses[1] / 2, masses[2] * lengths[i] ** 2 / 12, parent + offset / 2,
                             q[i])
        points.append(r)
    a, b = (points[int(j)] for j in rng.choice(np.arange(1, n + 1), 2, replace=False))
    gap = ((a - b).T * (a - b))[0]
    model.spring(k, gap)
    model.damper(c, gap)
    model.force(sp.Matrix([force] + [sp.Integer(0)] * (dims - 1)), at=points[-1])
    model.torque(force * sp.cos(q[0]) / 3, q[1])
    model.generalized_force(q[n - 1], -c * q[n - 1].diff(t) * sp.cos(q[0]))
    return model


def random_state(mod, rng):
    n = mod.n_coordinates
    y = np.concatenate([rng.uniform(-1.2, 1.2, n), rng.uniform(-2, 2, n)])
    p = np.asarray(mod.defaults) * rng.uniform(0.7, 1.3, len(mod.defaults))
    return float(rng.uniform(0, 2)), y, p, rng.uniform(-1, 1, len(mod.inputs))


def functions_at(mod, point):
    """Every model function of an unconstrained model at one point, as a list of arrays (the
    directional derivatives along nine directions, more than one block of the recursion's solve,
    the first without a parameter direction, and their difference from J·dy + ∂ẏ/∂p·dp)."""
    tv, y, p, u = point
    n = mod.n_coordinates
    q, qd = y[:n], y[n:]
    rng = np.random.default_rng(n)
    dy, dp = rng.normal(size=(9, 2 * n)), rng.normal(size=(9, len(mod.parameters)))
    dp[0] = 0.0
    a = rng.normal(size=n)
    J, P = mod.jacobian(tv, y, p, u), mod.parameter_jacobian(tv, y, p, u)
    ydot, along = mod.directional_derivatives(tv, y, dy, dp, p, u)
    return [mod.mass_matrix(q, tv, p, u), mod.forcing(q, qd, tv, p, u), mod.rhs(tv, y, p, u),
            J, *mod.linear_terms(q, qd, tv, p, u), P, mod.outputs(tv, y, p, u),
            mod.power_terms(tv, y, p, u), ydot, along,
            along - dy @ J.T - dp @ P.T, *mod.residual_terms(q, qd, a, tv, p, u),
            mod.residual_parameter_jacobian(q, qd, a, tv, p, u)]


def assert_same_functions(a, b, points=3, seed=0):
    rng = np.random.default_rng(seed)
    for _ in range(points):
        point = random_state(a, rng)
        for x, z in zip(functions_at(a, point), functions_at(b, point)):
            assert_allclose(x, z, rtol=1e-10, atol=1e-10 * max(1.0, np.abs(z).max(initial=0)))


# -- which models are trees ------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(8))
def test_random_trees_are_proven_trees(seed):
    for dims in (2, 3):
        tree, reason = analysed(derived(random_tree(seed, dims).spec()))
        assert tree is not None, reason
        assert sorted(tree.coordinate) == list(range(tree.n))
        for k, p in enumerate(tree.parent):        # preorder: parents first, subtrees contiguous
            assert p < k and (p < 0 or k < tree.end[p] <= tree.end[p])


def relative_double_pendulum():
    model = lagrgen.Model("relative2")
    a, b = model.coordinates("a b")
    m, l, g = model.parameters(m=1.0, l=1.0, g=9.81)
    p1 = l * sp.Matrix([sp.sin(a), -sp.cos(a)])
    p2 = p1 + l * sp.Matrix([sp.sin(a + b), -sp.cos(a + b)])
    for point in (p1, p2):
        model.particle(m, point)
        model.potential_energy(m * g * point[1])
    return model


def overlapping():
    """x moves bodies 1 and 2, y bodies 2 and 3: neither set holds the other."""
    model = lagrgen.Model("overlap")
    x, y = model.coordinates("x y")
    model.particle(1, sp.Matrix([x, 0]))
    model.particle(1, sp.Matrix([x, y]))
    model.particle(1, sp.Matrix([0, y]))
    return model


def with_constraint():
    model = lagrgen.Model("constrained")
    x, y = model.coordinates("x y")
    model.particle(1, sp.Matrix([x, y]))
    model.constraint(x ** 2 + y ** 2 - 1)
    return model


def driven_joint():
    """A pendulum whose angle is measured from a link turning at a prescribed rate."""
    model = lagrgen.Model("driven_joint")
    a, = model.coordinates("a")
    model.particle(1.0, sp.Matrix([sp.sin(a + 2 * t), -sp.cos(a + 2 * t)]))
    return model


def screw():
    """A 3-D body that turns about z and slides along x by one coordinate: its axis moves with it."""
    from lagrgen import rotation
    model = lagrgen.Model("screw")
    a, b = model.coordinates("a b")
    model.rigid_body_3d(1.0, [0.1, 0.2, 0.3], [a, 0, 0], rotation.z(a) * rotation.x(b))
    return model


@pytest.mark.parametrize("make, reason", [
    (relative_double_pendulum, "move differently|depends on other coordinates"),
    (overlapping, "overlapping"),
    (with_constraint, "constraints"),
    (screw, "not fixed in the body above"),
    (driven_joint, r"\(or on t\)|t together with the coordinates"),
], ids=["relative angles", "overlapping", "constraint", "3-D body", "driven joint"])
def test_what_is_not_a_tree_keeps_the_dense_formulation(make, reason):
    model = make()
    tree, why = analysed(derived(model.spec()))
    assert tree is None and re.search(reason, why), why
    with pytest.raises(ModelError, match=f"formulation='recursive'.*({reason})"):
        lagrgen.build(model, backend="python", formulation="recursive")
    assert lagrgen.build(model, backend="python").formulation == "dense"


def perturbed_tree(seed):
    """A random chain or tree in which some offsets also depend on another coordinate, some
    planar bodies turn with a sum of coordinates, and one body may ride on a point driven by t:
    a tree or not, by chance (see test_detection_never_gives_a_wrong_number)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 6))
    model = lagrgen.Model(f"perturbed{seed}")
    q = model.coordinates([f"q{i}" for i in range(n)])
    m, g = model.parameters(m=1.3, g=9.81)
    points = [sp.zeros(2, 1)]
    for i in range(n):
        parent = points[int(rng.integers(0, len(points)))]
        kind, j = int(rng.integers(0, 5)), int(rng.integers(0, n))
        offset = [sp.Matrix([sp.sin(q[i]), -sp.cos(q[i])]), sp.Matrix([q[i], q[i] / 2]),
                  sp.Matrix([sp.sin(q[i] + q[j] / 3), -sp.cos(q[i])]),
                  sp.Matrix([q[i] * (1 + q[j] ** 2 / 5), sp.cos(q[i])]),
                  sp.Matrix([sp.cos(q[i]) ** 2, sp.sin(q[i]) * sp.cos(q[i])])][kind]
        r = parent + offset
        model.particle(m * (1 + sp.Rational(i, 3)), r)
        model.potential_energy(m * g * r[1])
        if rng.uniform() < 0.3:
            model.rigid_body(m / 3, m / 7, parent + offset / 2,
                             q[i] if rng.uniform() < 0.7 else q[i] + q[0])
        points.append(r)
    for i in range(n):
        model.particle(m / 5, sp.Matrix([q[i]]))
    if rng.uniform() < 0.3:
        model.particle(m, points[-1] + sp.Matrix([sp.sin(2 * t), 0]))
    return model


def test_detection_never_gives_a_wrong_number():
    """Whatever the detection accepts as a tree computes what the dense formulation does."""
    accepted = 0
    for seed in range(40):
        model = perturbed_tree(seed)
        if analysed(derived(model.spec()))[0] is None:
            continue
        accepted += 1
        dense = lagrgen.build(model, backend="python", formulation="dense")
        recursive = lagrgen.build(model, backend="python", formulation="recursive")
        rng = np.random.default_rng(seed)
        point = random_state(dense, rng)
        for a, b in zip(functions_at(recursive, point), functions_at(dense, point)):
            assert_allclose(a, b, rtol=1e-10, atol=1e-10 * max(1.0, np.abs(b).max(initial=0)))
    assert accepted >= 4


def test_the_formulation_is_chosen_by_size_and_can_be_forced():
    nlink = load_example("nlink_pendulum")
    assert lagrgen.build(nlink.make(3), backend="python").formulation == "dense"
    assert lagrgen.build(nlink.make(RECURSIVE_FROM), backend="python").formulation == "recursive"
    assert lagrgen.build(nlink.make(RECURSIVE_FROM), backend="python",
                         formulation="dense").formulation == "dense"
    assert lagrgen.build(nlink.make(3), backend="python",
                         formulation="recursive").formulation == "recursive"
    with pytest.raises(ModelError, match="unknown formulation"):
        lagrgen.build(nlink.make(3), backend="python", formulation="fast")


# -- the same numbers ------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(6))
def test_recursive_python_backend_equals_dense(seed):
    for dims in (2, 3):
        model = random_tree(seed, dims)
        dense = lagrgen.build(model, backend="python", formulation="dense")
        recursive = lagrgen.build(model, backend="python", formulation="recursive")
        assert recursive.formulation == "recursive"
        assert_same_functions(recursive, dense, seed=seed)


def test_a_tree_on_a_moving_support_is_recursive():
    """The support's prescribed motion β(t) (every body of the tree moves with ∂r/∂t = β) is the
    roots' acceleration; the driven pendulum of the examples is such a tree."""
    support = [sp.cos(3 * t) / 4, sp.sin(2 * t) / 5]
    for model in (random_tree(4, support=support), load_example("driven_pendulum").model):
        dense = lagrgen.build(model, backend="python", formulation="dense")
        recursive = lagrgen.build(model, backend="python", formulation="recursive")
        assert recursive.explicit_time and dense.explicit_time
        assert_same_functions(recursive, dense, seed=4)


@pytest.fixture(scope="module")
def compiled(tmp_path_factory):
    """(recursive C, dense C, recursive Python) of one random tree on a moving support."""
    out = tmp_path_factory.mktemp("tree")
    model = random_tree(3, support=[sp.sin(t) / 3, sp.cos(2 * t) / 4])
    return (lagrgen.build(model, out_dir=out, formulation="recursive"),
            lagrgen.build(model, out_dir=out, formulation="dense"),
            lagrgen.build(model, backend="python", formulation="recursive"))


def test_recursive_c_equals_dense_c_and_recursive_python(compiled):
    recursive, dense, python = compiled
    assert recursive.formulation == "recursive" and dense.formulation == "dense"
    assert_same_functions(recursive, dense, points=4, seed=1)
    assert_same_functions(recursive, python, points=4, seed=2)


def test_recursive_jacobians_match_finite_differences(compiled):
    mod = compiled[0]
    rng = np.random.default_rng(9)
    tv, y, p, u = random_state(mod, rng)
    J = mod.jacobian(tv, y, p, u)
    h = 1e-6
    fd = np.column_stack([(mod.rhs(tv, y + h * e, p, u) - mod.rhs(tv, y - h * e, p, u)) / (2 * h)
                          for e in np.eye(len(y))])
    assert_allclose(J, fd, rtol=1e-6, atol=1e-6 * np.abs(J).max())
    P = mod.parameter_jacobian(tv, y, p, u)
    fd = np.column_stack([(mod.rhs(tv, y, p + h * e, u) - mod.rhs(tv, y, p - h * e, u)) / (2 * h)
                          for e in np.eye(len(p))])
    assert_allclose(P, fd, rtol=1e-6, atol=1e-6 * np.abs(P).max())


def test_residual_parameter_jacobian_of_both_backends_and_formulations(compiled):
    """Issue 37.7: ∂r/∂p of the implicit form, by the recursion on both backends (the Python
    backend's recursive models called a dense kernel they do not have), equals the dense
    formulation's and the central differences of r."""
    recursive_c, dense_c, recursive_py = compiled
    model = random_tree(3, support=[sp.sin(t) / 3, sp.cos(2 * t) / 4])
    dense_py = lagrgen.build(model, backend="python", formulation="dense")
    rng = np.random.default_rng(37)
    tv, y, p, u = random_state(recursive_c, rng)
    n = recursive_c.n_coordinates
    q, qd, a = y[:n], y[n:], rng.normal(size=n)
    h = 1e-6
    fd = np.column_stack([(recursive_c.residual_terms(q, qd, a, tv, p + h * e, u)[0]
                           - recursive_c.residual_terms(q, qd, a, tv, p - h * e, u)[0]) / (2 * h)
                          for e in np.eye(len(p))])
    assert np.abs(fd).max() > 0.1
    for mod in (recursive_c, dense_c, recursive_py, dense_py):
        dr_dp = mod.residual_parameter_jacobian(q, qd, a, tv, p, u)
        assert_allclose(dr_dp, fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())
        assert_allclose(dr_dp, dense_c.residual_parameter_jacobian(q, qd, a, tv, p, u),
                        rtol=1e-10, atol=1e-10 * np.abs(fd).max())


def test_c_and_python_agree_on_every_example_recursively(tmp_path):
    """Every example is a kinematic tree; its recursive C and Python agree to ~1e-12."""
    rng = np.random.default_rng(17)
    for entry in EXAMPLE_MODELS:
        model = example_model(*entry)
        c = lagrgen.build(model, out_dir=tmp_path, formulation="recursive")
        py = lagrgen.build(model, backend="python", formulation="recursive")
        q, qd, tv, p, u = random_point(c, rng)
        y = np.concatenate([q, qd])
        for a, b in zip(functions_at(c, (tv, y, p, u)), functions_at(py, (tv, y, p, u))):
            assert_allclose(a, b, rtol=1e-12, atol=1e-12 * (1 + np.abs(b).max(initial=0)))


def test_a_singular_mass_matrix_is_reported_on_both_backends(compiled):
    recursive, _, python = compiled
    n = recursive.n_coordinates
    p = np.asarray(recursive.defaults, dtype=float).copy()
    p[:3] = 0.0                           # every mass zero: M = 0
    y = np.full(2 * n, 0.3)
    for mod in (recursive, python):
        with pytest.raises(MassMatrixError):
            mod.rhs(0.0, y, p)
        with pytest.raises(MassMatrixError):
            mod.jacobian(0.0, y, p)


def test_both_formulations_integrate_alike(tmp_path):
    model = load_example("nlink_pendulum").make(8)
    y0 = np.r_[np.full(8, 0.5), np.zeros(8)]
    ends = []
    for formulation in ("dense", "recursive"):
        mod = lagrgen.build(model, out_dir=tmp_path, formulation=formulation)
        sol = lagrgen.simulate(mod, (0.0, 2.0), y0, method="Radau", rtol=1e-10, atol=1e-10)
        assert sol.success
        ends.append(sol.y[:, -1])
    assert_allclose(ends[0], ends[1], rtol=1e-7, atol=1e-8)


def plain_lagrange(model):
    """M and F of `model` by a plain SymPy derivation from its records: T = Σ ½·m·|ṙ|², V, the
    dampers' R and the virtual work of its forces (independent of lagrgen's derivation)."""
    spec = model.spec()
    q, qd = list(spec.coordinates), list(spec.qd)
    T = sum(m * (r.diff(t).T * r.diff(t))[0] / 2 for m, r in spec.particles)
    V = sum(spec.potential)
    R = sum(c * sp.diff(length, t) ** 2 / 2 for c, length in spec.dampers)
    plain = {**{v: sp.Symbol(f"v{i}") for i, v in enumerate(qd)},
             **{c: sp.Symbol(f"x{i}") for i, c in enumerate(q)}}
    back = {s: c for c, s in plain.items()}
    Tp, Vp, Rp = (sp.expand(sp.sympify(e).xreplace(plain)) for e in (T, V, R))
    xs, vs = [plain[c] for c in q], [plain[v] for v in qd]
    M = sp.Matrix([[sp.diff(Tp, a, b) for b in vs] for a in vs])
    F = []
    for i, (x, v) in enumerate(zip(xs, vs)):
        dT = sp.diff(Tp, v)
        Q = sum((sp.Matrix(vec).dot(sp.Matrix(at).diff(q[i])) for vec, at in spec.virtual_work),
                sp.Integer(0))
        F.append(sp.diff(Tp, x) - sum(sp.diff(dT, y) * w for y, w in zip(xs, vs))
                 - sp.diff(Vp, x) - sp.diff(Rp, v) + sp.sympify(Q).xreplace(plain))
    return (M.xreplace(back), sp.Matrix(F).xreplace(back))


def test_recursive_equals_a_plain_sympy_derivation():
    model = random_tree(27)        # 4 coordinates: telescopic links, pins, two rigid bodies
    mod = lagrgen.build(model, backend="python", formulation="recursive")
    spec = model.spec()
    M, F = plain_lagrange(model)
    args = (t, spec.coordinates, spec.qd, spec.parameters, spec.inputs)
    f_M, f_F = state_function(M, *args), state_function(F, *args)
    rng = np.random.default_rng(4)
    for _ in range(3):
        tv, y, p, u = random_state(mod, rng)
        n = mod.n_coordinates
        q, qd = y[:n], y[n:]
        assert_allclose(mod.mass_matrix(q, tv, p, u), f_M(q, qd, tv, p, u), rtol=1e-11,
                        atol=1e-11)
        assert_allclose(mod.forcing(q, qd, tv, p, u), np.ravel(f_F(q, qd, tv, p, u)),
                        rtol=1e-10, atol=1e-10)


# -- the generated code ----------------------------------------------------------------------------
def recursive_c(model):
    eq = derived(model.spec())
    info = model_info(model.spec(), eq, "recursive")
    return standalone_files(info, eq)[f"{model.name}_model.c"]


def test_recursive_c_is_readable_plain_c_and_grows_like_n(tmp_path):
    nlink = load_example("nlink_pendulum")
    sizes = {n: len(recursive_c(nlink.make(n))) for n in (10, 20, 40)}
    assert sizes[40] / sizes[20] < 2.3 and sizes[20] / sizes[10] < 2.3, sizes
    model = random_tree(5)
    eq = derived(model.spec())
    for name, text in standalone_files(model_info(model.spec(), eq, "recursive"), eq).items():
        (tmp_path / name).write_text(text)
    text = (tmp_path / f"{model.name}_model.c").read_text()
    assert "#define LG_RECURSIVE 1" in text and "lg_tree_factor" in text
    assert re.search(r"/\* node 1: coordinate q\d, (below q\d|a root); carries (a planar mass|a 1-D "
                     r"mass or inertia) of m\d", text)
    assert "const double x0 = " in text
    result = subprocess.run([*compiler_command(), "-std=c99", "-pedantic", "-Wall", "-Wextra",
                             "-Werror", "-c", str(tmp_path / f"{model.name}_model.c"), "-o",
                             str(tmp_path / "m.o")], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr[-2000:]
