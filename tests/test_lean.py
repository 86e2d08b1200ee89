"""Lean generated code for robots (issue 43) and long chains (issue 45 item 1): the traced
straight-line recursions (`lagrgen.trace`, `lagrgen.lean3d`) against the generic loops, the
Python backend and Pinocchio; a URDF chain of more than 200 joints builds and is right."""
import numpy as np
import pytest

import lagrgen
from lagrgen import lean3d
from lagrgen.trace import Printer, Tape

from test_robots import ARM, QUADRUPED, relative

pytestmark = pytest.mark.filterwarnings("ignore::lagrgen.URDFWarning")


# -- the tape --------------------------------------------------------------------------------------
def test_the_tape_folds_numbers_and_shares_what_it_forms_twice():
    t = Tape()
    x, y = t.leaf("q[0]"), t.leaf("q[1]")
    assert t.mul(x, 0.0) == 0.0 and t.add(x, 0.0) == x and t.mul(1.0, x) == x
    assert t.mul(-1.0, x) == t.neg(x) and t.sub(x, x) == 0.0
    assert t.add(2.0, 3.0) == 5.0 and t.mul(t.add(1.0, 1.0), 4.0) == 8.0
    d = t.sub(x, y)
    assert t.sub(y, x) == t.neg(d)                 # y − x is −(x − y): one node
    assert t.mul(x, y) == t.mul(y, x) and t.mul(t.neg(x), y) == t.neg(t.mul(x, y))
    before = len(t.nodes)
    assert t.add(t.mul(x, y), d) == t.add(d, t.mul(y, x)) and len(t.nodes) == before + 1
    nodes = t.needed([t.add(t.mul(x, y), d)])
    assert t.flops(nodes) == 3                     # x·y, x − y and their sum
    text = "\n".join(Printer(t).statements(nodes))
    assert "const double" in text and "q[0] * q[1]" in text


# -- both code paths, both backends ---------------------------------------------------------------
@pytest.fixture(scope="module")
def arms(tmp_path_factory):
    """The seven-joint arm built with the traced code and with the loops only (C), and with the
    Python backend; with its inertial parameters (traced as leaves p[j])."""
    model = lagrgen.from_urdf(ARM, parameters="inertial", name="arm_lean")
    lean = lagrgen.build(model, out_dir=tmp_path_factory.mktemp("lean"), quiet=True)
    saved = lean3d.LEAN_MAX_JOINTS
    lean3d.LEAN_MAX_JOINTS = 0
    try:
        loops = lagrgen.build(model, out_dir=tmp_path_factory.mktemp("loops"), quiet=True)
    finally:
        lean3d.LEAN_MAX_JOINTS = saved
    return lean, loops, lagrgen.build(model, backend="python")


def test_a_small_robot_gets_traced_code_and_a_long_chain_the_loops(tmp_path):
    from lagrgen.build import export_c
    source = next(f for f in export_c(lagrgen.from_urdf(ARM, name="arm_c"), tmp_path)
                  if f.suffix == ".c").read_text()
    assert "LG_FN LG_PART_FN int lg_lean_qdd(" in source and "#define LG_LEAN_QDD 1" in source
    assert source.count("/* traced */") == 2       # q̈ and the node records: units of their own
    assert "#define LG_LEAN_NODES 1" in source
    assert "flops (" in source                     # the legend says how many, per joint
    chain = tmp_path / "chain.urdf"
    chain.write_text(chain_urdf(lean3d.LEAN_MAX_JOINTS + 1))
    long_source = next(f for f in export_c(lagrgen.from_urdf(chain, name="chain_c"),
                                           tmp_path / "chain") if f.suffix == ".c").read_text()
    assert "#define LG_LEAN_QDD 0" in long_source and "#define LG_TREE_JOINTS 1" in long_source


def test_the_traced_functions_are_units_of_their_own_where_they_are_called():
    """A robot's module compiles its traced q̈ and node records apart from unit 0 (side by side);
    a unit compiled on first use without the rhs (the residual's Hessian) keeps q̈ static in
    unit 0, where the compiler drops it, and compiles the node records apart."""
    from lagrgen.build import derived, model_info
    from lagrgen.codegen.c_model import model_source, traced_unit_numbers, translation_units
    from lagrgen.functions import MODEL_UNIT, functions_of
    model = lagrgen.from_urdf(ARM, name="arm_units")
    spec = model.spec()
    equations = derived(spec)
    info = model_info(spec, equations, formulation="recursive")
    whole = model_source(info, equations, functions=functions_of(MODEL_UNIT))
    assert traced_unit_numbers(whole) == {1, 2} and translation_units(whole) == 2
    assert "LG_FN LG_PART_FN int lg_lean_qdd(double t" in whole
    hessian = model_source(info, equations, functions=functions_of("hessian"))
    assert traced_unit_numbers(hessian) == {1} and translation_units(hessian) == 1
    assert "LG_FN static int lg_lean_qdd(double t" in hessian
    assert "LG_FN LG_PART_FN int lg_tree_nodes(double t" in hessian
    pivots = "LG_FN LG_PART_FN int lg_lean_pivots(double t, const double *q, const double *p)"
    assert whole.count(pivots + ";") == 1 and whole.count(pivots + "\n{") == 1


def test_a_traced_functions_callees_are_declared_as_the_template_defines_them():
    """The prototype a traced function's unit declares for a function it calls is read off
    the template's definition, so the two cannot disagree; a name the template does not define
    is an error."""
    from lagrgen.codegen.c_model import read_template
    from lagrgen.codegen.tree_code import template_prototypes
    template = read_template("tree3d.c.in")
    declared, = template_prototypes(template, ["lg_lean_pivots"])
    assert declared.endswith(");") and declared[:-1] + "\n{" in template
    assert template_prototypes("LG_FN static int f(int a,\n    int b)\n{\n}\n", ["f"]) == \
        ("LG_FN static int f(int a,\n    int b);",)
    with pytest.raises(ValueError, match="no function lg_nowhere"):
        template_prototypes(template, ["lg_nowhere"])


def test_the_traced_code_and_the_loops_agree(arms):
    lean, loops, python = arms
    n = lean.n_coordinates
    rng = np.random.default_rng(3)
    p = lean.defaults * rng.uniform(0.9, 1.1, len(lean.defaults))
    for _ in range(3):
        y, u = rng.uniform(-1.5, 1.5, 2 * n), rng.uniform(-2, 2, n)
        for mod in (loops, python):
            assert relative(lean.rhs(0.0, y, p=p, u=u), mod.rhs(0.0, y, p=p, u=u)) < 1e-12
            assert relative(lean.jacobian(0.0, y, p=p, u=u),
                            mod.jacobian(0.0, y, p=p, u=u)) < 1e-11
            assert relative(lean.mass_matrix(y[:n], p=p), mod.mass_matrix(y[:n], p=p)) < 1e-13
            assert relative(lean.outputs(0.0, y, p=p, u=u), mod.outputs(0.0, y, p=p, u=u)) < 1e-12
    h = 1e-6
    J = lean.jacobian(0.0, y, p=p, u=u)
    fd = np.column_stack([(lean.rhs(0, y + h * e, p=p, u=u) - lean.rhs(0, y - h * e, p=p, u=u))
                          / (2 * h) for e in np.eye(2 * n)])
    assert relative(J, fd) < 1e-6


def test_a_mass_matrix_that_is_not_positive_definite_is_said_by_the_traced_code(tmp_path):
    model = lagrgen.from_urdf(ARM, parameters="inertial", name="arm_singular")
    mod = lagrgen.build(model, out_dir=tmp_path, quiet=True)
    p = np.array(mod.defaults)
    p[[i for i, name in enumerate(mod.parameters) if name.startswith(("m", "I"))]] = 0.0
    with pytest.raises(lagrgen.MassMatrixError):
        mod.rhs(0.0, np.zeros(2 * mod.n_coordinates), p=p)


@pytest.mark.parametrize("path, base", [(ARM, "fixed"), (QUADRUPED, "floating")])
def test_robots_equal_pinocchio(path, base, tmp_path):
    pin = pytest.importorskip("pinocchio")
    model = lagrgen.from_urdf(path, joint_dynamics=False, base=base, name=f"pin_{base}")
    mod = lagrgen.build(model, out_dir=tmp_path, quiet=True)
    n = mod.n_coordinates
    if base == "fixed":
        pm = pin.buildModelFromUrdf(str(path))
    else:     # lagrgen's base: x, y, z, then roll, pitch, yaw as Rz·Ry·Rx
        chain = pin.JointModelComposite()
        for joint in (pin.JointModelPX(), pin.JointModelPY(), pin.JointModelPZ(),
                      pin.JointModelRZ(), pin.JointModelRY(), pin.JointModelRX()):
            chain.addJoint(joint)
        pm = pin.buildModelFromUrdf(str(path), chain)
    order = list(range(n)) if base == "fixed" else [0, 1, 2, 5, 4, 3] + list(range(6, n))
    data = pm.createData()
    for y, _ in [(np.random.default_rng(s).uniform(-1, 1, 2 * n), None) for s in range(3)]:
        q, v = y[:n][order], y[n:][order]
        qdd = pin.aba(pm, data, q, v, np.zeros(n))
        assert relative(mod.rhs(0.0, y)[n:][order], qdd) < 1e-10
        M = pin.crba(pm, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        assert relative(mod.mass_matrix(y[:n])[np.ix_(order, order)], M) < 1e-10
        if base == "fixed":
            pin.computeABADerivatives(pm, data, q, v, np.zeros(n))
            J = mod.jacobian(0.0, y)
            assert relative(J[n:, :n], data.ddq_dq) < 1e-10
            assert relative(J[n:, n:], data.ddq_dv) < 1e-10


# -- a long chain (issue 45 item 1) --------------------------------------------------------------
def chain_urdf(n, seed=0):
    """A 3-D chain of n revolute joints: random masses, centres, inertias, placements; axes
    cycling through z, y, x."""
    rng = np.random.default_rng(seed)
    parts = [f'<?xml version="1.0"?><robot name="chain{n}">', '<link name="l0"/>']
    for k in range(1, n + 1):
        c, d, xyz, rpy = (rng.uniform(-0.05, 0.05, 3), rng.uniform(0.015, 0.025, 3),
                          rng.uniform(-0.1, 0.1, 3) + [0, 0, 0.2], rng.uniform(-0.5, 0.5, 3))
        parts.append(
            f'<link name="l{k}"><inertial><origin xyz="{c[0]} {c[1]} {c[2]}"/><mass '
            f'value="{rng.uniform(0.5, 2.0)}"/><inertia ixx="{d[0]}" ixy="0.001" ixz="0" '
            f'iyy="{d[1]}" iyz="-0.001" izz="{d[2]}"/></inertial></link><joint name="j{k}" '
            f'type="revolute"><parent link="l{k - 1}"/><child link="l{k}"/><origin '
            f'xyz="{xyz[0]} {xyz[1]} {xyz[2]}" rpy="{rpy[0]} {rpy[1]} {rpy[2]}"/><axis '
            f'xyz="{("0 0 1", "0 1 0", "1 0 0")[k % 3]}"/><limit lower="-3" upper="3" '
            'effort="100" velocity="5"/></joint>')
    return "".join(parts) + "</robot>"


@pytest.fixture(scope="module")
def long_chain(tmp_path_factory):
    folder = tmp_path_factory.mktemp("long_chain")
    path = folder / "chain.urdf"
    path.write_text(chain_urdf(230))
    model = lagrgen.from_urdf(path, joint_dynamics=False, name="chain230")
    return path, lagrgen.build(model, out_dir=folder, quiet=True), \
        lagrgen.build(model, backend="python")


def test_a_chain_of_more_than_200_joints_builds_and_is_right(long_chain):
    path, mod, python = long_chain
    n = mod.n_coordinates
    assert n == 230 and mod.formulation == "recursive"
    rng = np.random.default_rng(2)
    y = np.concatenate([rng.uniform(-1, 1, n), rng.uniform(-0.5, 0.5, n)])
    assert relative(mod.rhs(0.0, y), python.rhs(0.0, y)) < 1e-9     # two algorithms, 230 joints
    out = mod.outputs(0.0, y)
    assert relative(out, python.outputs(0.0, y)) < 1e-12
    T, V, E = (out[mod.output_names.index(k)] for k in
               ("kinetic_energy", "potential_energy", "total_energy"))
    M = mod.mass_matrix(y[:n])
    assert T == pytest.approx(0.5 * y[n:] @ M @ y[n:], rel=1e-11)      # T = ½·q̇ᵀ·M·q̇
    assert E == pytest.approx(T + V, rel=1e-14)
    # −∂V/∂q is the forcing at rest (gravity alone); V by central differences, a few joints
    h, F = 1e-6, mod.forcing(y[:n], np.zeros(n))
    V_at = lambda q: mod.outputs(0.0, np.concatenate([q, np.zeros(n)]))[   # noqa: E731
        mod.output_names.index("potential_energy")]
    for j in (0, 57, 229):
        e = np.zeros(n)
        e[j] = h
        assert -(V_at(y[:n] + e) - V_at(y[:n] - e)) / (2 * h) == \
            pytest.approx(F[j], rel=1e-6, abs=1e-6 * np.abs(F).max())
    J = mod.jacobian(0.0, y)
    for j in (0, 100, n + 3, 2 * n - 1):
        e = np.zeros(2 * n)
        e[j] = h
        column = (mod.rhs(0.0, y + e) - mod.rhs(0.0, y - e)) / (2 * h)
        assert relative(J[:, j], column) < 1e-5


def test_the_long_chain_equals_pinocchio(long_chain):
    pin = pytest.importorskip("pinocchio")
    path, mod, _ = long_chain
    n = mod.n_coordinates
    pm = pin.buildModelFromUrdf(str(path))
    data = pm.createData()
    y = np.random.default_rng(4).uniform(-1, 1, 2 * n)
    assert relative(mod.rhs(0.0, y)[n:], pin.aba(pm, data, y[:n], y[n:], np.zeros(n))) < 1e-10
    M = pin.crba(pm, data, y[:n])
    assert relative(mod.mass_matrix(y[:n]), np.triu(M) + np.triu(M, 1).T) < 1e-10


@pytest.mark.parametrize("path, base", [(ARM, "fixed"), (QUADRUPED, "floating")])
def test_the_bounds_of_the_diagonal_of_m_hold_everywhere(path, base):
    """lean3d.diagonal_bounds: the traced q̈ compares each pivot with 1e-3 of a bound of M_kk over
    every q to decide whether M's pivots are noted (NearSingularMassMatrixWarning): the bound
    must hold at any q, and be finite for the joints of a robot's revolute chains."""
    from lagrgen import tree
    from lagrgen.lagrange import derived
    model = lagrgen.from_urdf(path, base=base, name=f"bounds_{base}")
    structure = tree.analyse(derived(model.spec()))
    bounds = np.array(lean3d.diagonal_bounds(structure.joints, structure.parent))
    assert np.all(np.isfinite(bounds)) and np.all(bounds > 0)
    mod = lagrgen.build(model, backend="python")
    rng = np.random.default_rng(8)
    order = list(structure.coordinate)
    for _ in range(20):
        M = mod.mass_matrix(rng.uniform(-np.pi, np.pi, mod.n_coordinates))
        assert np.all(np.diag(M)[order] <= bounds * (1 + 1e-12))
