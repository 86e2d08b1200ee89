"""Optimal motions of robots (issue 42): the residual's exact second derivatives from the recursion
of a three-dimensional tree (and from duals on the Python backend), against finite differences of
its first derivatives and between the backends; the collocation NLP of a URDF robot laid out from
its structure alone, its Hessian against finite differences."""
import time

import numpy as np
import pytest
import sympy as sp

import lagrgen
from conftest import example_model, nlp_derivatives
from lagrgen.collocation.refine import DiscretizationWarning
from test_robots import ARM, QUADRUPED, SMALL


@pytest.fixture(scope="module")
def out_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("robot_motions")


@pytest.fixture(scope="module")
def small(out_dir, tmp_path_factory):
    """A three-joint robot with a skew revolute joint, a prismatic and a continuous one, joint
    damping, and a floating quadruped: both backends of each."""
    path = tmp_path_factory.mktemp("urdf") / "small.urdf"
    path.write_text(SMALL)
    built = {}
    for key, model in (("small", lagrgen.from_urdf(path, name="motions_small")),
                       ("quadruped", lagrgen.from_urdf(QUADRUPED, name="motions_quadruped",
                                                       base="floating"))):
        built[key] = (model, lagrgen.build(model, out_dir=out_dir),
                      lagrgen.build(model, backend="python"))
    return built


def residual_gradient(mod, z, mu):
    """∇_z(Σ mu_i·r_i) from the model's exact first derivatives (residual_terms)."""
    n, m = mod.n_coordinates, mod.n_constraints
    q, qd, a, u = z[:n], z[n:2 * n], z[2 * n:3 * n + m], z[3 * n + m:]
    _, dr_dy, dr_da, dr_du = mod.residual_terms(q, qd, a, 0.2, None, u)
    return np.concatenate([mu @ dr_dy, mu @ dr_da, mu @ dr_du])


def point(mod, seed):
    n, m, k = mod.n_coordinates, mod.n_constraints, len(mod.inputs)
    rng = np.random.default_rng(seed)
    return rng.uniform(-1, 1, 3 * n + m + k), rng.uniform(-1, 1, n + m)


def hessian_at(mod, z, mu):
    n, m = mod.n_coordinates, mod.n_constraints
    return mod.residual_hessian(z[:n], z[n:2 * n], z[2 * n:3 * n + m], mu, 0.2, None,
                                z[3 * n + m:])


def differenced(mod, z, mu, eps=1e-6):
    return np.array([(residual_gradient(mod, z + eps * e, mu)
                      - residual_gradient(mod, z - eps * e, mu)) / (2 * eps)
                     for e in np.eye(z.size)]).T


@pytest.mark.parametrize("key", ["small", "quadruped"])
def test_the_recursions_second_derivatives_are_exact(small, key):
    """The second-order derivatives of the inverse dynamics (contracted with the weights) plus the
    joint dampers' equal the differences of the exact first derivatives, on a skew, prismatic and
    continuous joint and on an 18-coordinate floating quadruped; C and NumPy agree to round-off."""
    model, mod, py = small[key]
    assert mod.formulation == py.formulation == "recursive"
    for seed in range(2):
        z, mu = point(mod, seed)
        H = hessian_at(mod, z, mu)
        assert H.shape == (z.size, z.size)
        assert np.array_equal(H, H.T)
        Hn = differenced(mod, z, mu)
        assert np.abs(H - Hn).max() < 1e-7 * (1 + np.abs(Hn).max())
        assert np.abs(hessian_at(py, z, mu) - H).max() < 1e-12 * (1 + np.abs(H).max())


@pytest.mark.parametrize("backend", ["c", "python"])
def test_dense_second_derivatives_are_exact_with_constraints(out_dir, backend):
    """A constrained model (the pendulum in Cartesian coordinates with its rod a constraint):
    the symbolic kernel (C) and the duals over the first-derivative kernels (Python) give the
    Hessian of the residual's rows and constraint rows."""
    model = example_model("cartesian_pendulum")
    mod = lagrgen.build(model, out_dir=out_dir, backend=backend)
    assert mod.n_constraints
    z, mu = point(mod, 3)
    H = hessian_at(mod, z, mu)
    Hn = differenced(mod, z, mu)
    assert np.abs(H - Hn).max() < 1e-7 * (1 + np.abs(Hn).max())


def test_a_robots_collocation_hessian_matches_finite_differences(small):
    """The NLP of a URDF robot's move within its limits, with an effort integrand: its structure
    from the tree alone (no symbolic equations), its Jacobian and Lagrangian Hessian against
    differences, every nonzero inside the structure."""
    model, mod, _ = small["small"]
    prob = lagrgen.Collocation(mod, nodes=3, duration=1.0, scheme="hermite-simpson")
    prob.minimize(integral=sum(u ** 2 for u in model.input_functions)
                  + model.q[0].diff(model.t) ** 2 * sp.cos(model.q[1]))
    tr = prob.transcription("exact")
    assert tr.recursive
    J, Jn, H, Hn, grad, gradn = nlp_derivatives(prob, seed=2)
    assert np.abs(J - Jn).max() < 1e-7 * (1 + np.abs(Jn).max())
    assert np.abs(Jn[J == 0]).max(initial=0) < 1e-7
    assert np.abs(H - Hn).max() < 1e-6 * (1 + np.abs(Hn).max())
    assert np.abs(Hn[H == 0]).max(initial=0) < 1e-6
    assert np.abs(grad - gradn).max() < 1e-7 * (1 + np.abs(gradn).max())


def test_the_arms_least_effort_move_never_forms_dense_equations(out_dir, monkeypatch):
    """The seven-joint arm from rest to rest within its limits, refined to mesh_tol 1e-5 (four
    meshes; the default 1e-6 takes five and ~40 s), with the exact Hessian from the recursion: no step forms the dense symbolic equations (they
    would take minutes), the answer is within its tolerance and limits."""
    model = lagrgen.from_urdf(ARM, name="motions_arm", joint_dynamics=False)
    mod = lagrgen.build(model, out_dir=out_dir)

    def refuse(*args):
        raise AssertionError("dense symbolic equations formed for a recursive model")
    monkeypatch.setattr(lagrgen.lagrange, "dense_equations", refuse)
    n = mod.n_coordinates
    lower, upper, velocity = (np.array([mod.limits[c][i] for c in mod.coordinates])
                              for i in (0, 1, 2))
    middle, half = (lower + upper) / 2, (upper - lower) / 2
    prob = lagrgen.Collocation(mod, nodes=21, duration=1.5).bound_limits()
    prob.initial(q=middle, qd=np.zeros(n))
    prob.final(q=middle + 0.3 * half * np.linspace(1, -1, n), qd=np.zeros(n))
    prob.minimize(integral=sum(u ** 2 for u in model.input_functions))
    res = prob.solve(progress=False, mesh_tol=1e-5)
    assert res.success, res.message
    assert res.error <= 1e-5 and len(res.meshes) > 1
    q, qd = res.y[:n], res.y[n:]
    tol = 1e-7
    assert np.all(q >= lower[:, None] - tol) and np.all(q <= upper[:, None] + tol)
    assert np.all(np.abs(qd) <= velocity[:, None] + tol)


# -- the structured SQP and re-planning ---------------------------------------------------------
@pytest.fixture(scope="module")
def swing(out_dir):
    """opty's compound pendulum swung up by a torque too weak to lift it directly."""
    model = lagrgen.Model("motions_swing")
    th, = model.coordinates("theta")
    m, g, d = model.parameters(m=1.0, g=9.81, d=1.0)
    T, = model.inputs("T")
    model.kinetic_energy(th.diff(model.t) ** 2 / 2)
    model.potential_energy(-m * g * d * sp.cos(th))
    model.torque(T, th)
    return model, lagrgen.build(model, out_dir=out_dir)


def swing_problem(mod, T, nodes=41, limit=6.0):
    prob = lagrgen.Collocation(mod, nodes=nodes, duration=3.0)
    prob.bound("T", -limit, limit).bound("theta_dot", -4.0, 4.0)
    prob.initial(q=[0.0], qd=[0.0]).final(q=[np.pi], qd=[0.0])
    return prob.minimize(integral=T ** 2)


def swing_near_optimum(swing, seed):
    """(IPOPT's result, the bound transcription, a point 1e-2 off its solution, the random
    generator) of the swing-up on 9 nodes."""
    model, mod = swing
    prob = swing_problem(mod, model.input_functions[0], nodes=9)
    res = prob.solve(progress=False, mesh_tol=None, solver="ipopt")
    tr = prob.transcription("exact").bound(3.0)
    rng = np.random.default_rng(seed)
    return res, tr, np.clip(res.x + 1e-2 * rng.standard_normal(res.x.size), tr.lo, tr.hi), rng


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_the_structured_qp_is_the_kkt_solution(swing):
    """One QP of the SQP (accelerations eliminated point by point, states interval by interval,
    the Riccati recursion, bounds by the active set) equals the solve of the whole KKT system
    with the same bounds held, and its multipliers make the KKT conditions hold; the interior
    point's solution, made exact by the active set it identifies, equals it too."""
    import scipy.sparse as sps
    from lagrgen.collocation import sqp
    res, tr, x, rng = swing_near_optimum(swing, 5)
    stages, rows = sqp.Stages.of(tr), sqp.Rows.of(tr)
    lam = res._lam * (1 + 0.1 * rng.standard_normal(res._lam.size))
    lin = sqp.linearize(tr, x, lam, stages, rows)
    row_z = res._lam[tr.defect_row + tr.n_defects + rows.index]
    active = sqp.ActiveSet.start(lin, res._z[:tr.layout.p_start], row_z)
    qp = sqp.solve_qp(tr, stages, rows, lin, active)
    assert rows.index.size            # the torque's envelope between its points
    L = tr.layout
    N = L.p_start
    on = np.flatnonzero(active.side != 0)
    row_on = np.flatnonzero(active.row_side != 0)
    H = sps.block_diag(list(lin.W)).tocsr()
    equalities = tr.defect_row + tr.n_defects       # the residuals and defects
    J = sps.coo_matrix((tr.jacobian(x), (tr.jac_rows, tr.jac_cols)),
                       shape=(tr.n_constraints, L.size)).tocsr()[:equalities, :N]
    B = sps.coo_matrix((np.ones(on.size), (np.arange(on.size), on)), shape=(on.size, N))
    E = sps.coo_matrix((tr.E.values, (tr.E.rows, tr.E.cols)),
                       shape=tr.E.shape).tocsr()[row_on][:, :N]
    A = sps.vstack([J, B, E]).tocsc()
    K = sps.bmat([[H, A.T], [A, None]]).tocsc()
    c = tr.constraints(x)[:equalities]
    rhs = np.concatenate([-lin.g.ravel(), -c, active.targets(lin)[on],
                          active.row_targets(lin)[row_on]])
    reference = np.linalg.lstsq(K.toarray(), rhs, rcond=None)[0][:N]   # rows may repeat bounds
    assert np.abs(qp.dz.ravel() - reference).max() < 1e-7 * (1 + np.abs(reference).max())
    inner, inertia = sqp.ActiveSet.start(lin), sqp.Inertia()     # by the interior point, cold
    structured = sqp.StructuredQP(tr, stages, rows, lin)
    found = sqp.solve_qp_interior(structured, lin, inner, inertia)
    exact = sqp._purified(structured, lin, inner, inertia, 1e-10, found)
    assert exact is not found and exact.interior
    assert np.abs(exact.dz.ravel() - reference).max() < 1e-7 * (1 + np.abs(reference).max())
    lam_qp = sqp.constraint_multipliers(tr, qp, rows)
    z = np.zeros(L.size)
    z[:N] = np.where(active.side != 0, active.z, 0.0)
    stationarity = (lin.g.ravel() + (lin.W @ qp.dz[:, :, None])[:, :, 0].ravel()
                    + np.bincount(tr.jac_cols, tr.jacobian(x) * lam_qp[tr.jac_rows],
                                  minlength=L.size)[:N] + z[:N])
    assert np.abs(stationarity).max() < 1e-6 * (1 + np.abs(lin.g).max())
    found_lam = sqp.constraint_multipliers(tr, found, rows)
    jt = np.bincount(tr.jac_cols, tr.jacobian(x) * found_lam[tr.jac_rows], minlength=L.size)[:N]
    residual = lin.g.ravel() + (lin.W @ found.dz[:, :, None])[:, :, 0].ravel() + jt
    kept = sqp.bound_multipliers(L, found.active, found.z_all)[:N]
    assert np.abs(residual + kept).max() < 1e-6 * (1 + np.abs(lin.g).max())
    assert np.abs(residual).max() > 1e3 * np.abs(residual + kept).max()     # bounds it rides


def test_the_point_hessians_are_the_nlps_hessian_point_by_point(swing):
    """The SQP's per-point Hessian blocks (`point_hessians`, written at both places of each
    entry) equal the blocks of IPOPT's sparse Lagrangian Hessian (objective factor 1) on the
    diagonal, made symmetric, at a point away from any optimum; add_symmetric accumulates
    repeated entries as np.add.at does."""
    from lagrgen.collocation.nlp import add_symmetric
    model, mod = swing
    T, = model.input_functions
    tr = swing_problem(mod, T, nodes=9).transcription("exact")
    L = tr.layout
    rng = np.random.default_rng(5)
    x = rng.uniform(-1.0, 1.0, L.size)
    lam = rng.normal(size=tr.n_constraints)
    W = tr.point_hessians(x, lam)
    rows, cols = tr.hessianstructure()
    H = np.zeros((L.size, L.size))
    np.add.at(H, (rows, cols), tr.hessian(x, lam, 1.0))
    H = H + np.tril(H, -1).T
    assert np.abs(W).max() > 0
    for j in range(L.points):
        block = slice(j * L.nz, (j + 1) * L.nz)
        assert np.allclose(W[j], H[block, block], rtol=1e-12, atol=1e-12)
    pairs = np.array([[2, 1], [0, 0], [2, 1], [1, 0]])
    values = rng.normal(size=(3, 4))
    out = np.zeros((3, 9))
    add_symmetric(out, 3, pairs, values)
    dense = np.zeros((3, 3, 3))
    for (r, c), v in zip(pairs, values.T):
        dense[:, r, c] += v
        if r != c:
            dense[:, c, r] += v
    assert np.allclose(out.reshape(3, 3, 3), dense)


def test_the_riccati_factor_skips_a_stages_input_rows_exactly():
    """_riccati.factor with `states` s (A's rows from s on 0, B's [0 1]: a collocation stage's
    end inputs are its own) equals the full products and the recursion written out in NumPy:
    H = Q + [A B]ᵀ·P·[A B], gain = −Hvv⁻¹·Hvx, P = Hxx + Hxv·gain; so do the vectors' pass
    and the forward pass (b's rows from s on 0)."""
    from lagrgen.collocation._riccati import factor, forward, vectors
    rng = np.random.default_rng(7)
    K, s, m, nv = 5, 6, 3, 6
    nx = s + m
    A, B = np.zeros((K, nx, nx)), np.zeros((K, nx, nv))
    A[:, :s], B[:, :s] = rng.normal(size=(K, s, nx)), rng.normal(size=(K, s, nv))
    B[:, s:, nv - m:] = np.eye(m)
    H = rng.normal(size=(K, nx + nv, nx + nv))
    H = H @ H.transpose(0, 2, 1) + 0.1 * np.eye(nx + nv)
    Qxx, Qxv, Qvv = (np.ascontiguousarray(H[:, a, b]) for a, b in (
        (slice(0, nx), slice(0, nx)), (slice(0, nx), slice(nx, None)),
        (slice(nx, None), slice(nx, None))))
    end = rng.normal(size=(nx, nx))
    end = end @ end.T

    def factored(states):
        out = (np.zeros((K + 1, nx, nx)), np.zeros((K, nx, nv)), np.zeros((K, nv, nv)),
               np.zeros((K, nv, nx)))
        assert factor(Qxx, Qxv, Qvv, A, B, end, 0.0, *out, states) == 0
        return out
    skipped, full = factored(s), factored(-1)
    P, Hk_vv = end, {}
    for k in range(K - 1, -1, -1):
        AB = np.concatenate([A[k], B[k]], axis=1)
        Hk = H[k] + AB.T @ P @ AB
        Hk_vv[k] = Hk[nx:, nx:]
        gain = -np.linalg.solve(Hk[nx:, nx:], Hk[nx:, :nx])
        assert np.allclose(full[3][k], gain, rtol=1e-10, atol=1e-12)
        P = Hk[:nx, :nx] + Hk[:nx, nx:] @ gain
        assert np.allclose(full[0][k], P, rtol=1e-10, atol=1e-10)
    for a, b in zip(skipped, full):
        assert np.allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(b).max())
    P, Hxv, chol, gain = full
    qx, qv, b = rng.normal(size=(K, nx)), rng.normal(size=(K, nv)), np.zeros((K, nx))
    b[:, :s] = rng.normal(size=(K, s))
    p_end, X0 = rng.normal(size=nx), rng.normal(size=nx)

    def passes(states):
        p, ff = np.zeros((K + 1, nx)), np.zeros((K, nv))
        vectors(qx, qv, A, B, b, p_end, P, Hxv, chol, p, ff, states)
        X, v = np.zeros((K + 1, nx)), np.zeros((K, nv))
        forward(X0, A, B, b, gain, ff, X, v, states)
        return p, ff, X, v
    (p, ff, X, v), again = passes(-1), passes(s)
    for a, b_ in zip(again, (p, ff, X, v)):
        assert np.allclose(a, b_, rtol=1e-12, atol=1e-12 * np.abs(b_).max())
    p_next = p_end                          # V_k's linear term: p = hx + Hxv·ff, hv = qv + Bᵀ·l
    for k in range(K - 1, -1, -1):
        lin = P[k + 1] @ b[k] + p_next
        hv = qv[k] + B[k].T @ lin
        assert np.allclose(ff[k], -np.linalg.solve(Hk_vv[k], hv), rtol=1e-10, atol=1e-12)
        p_next = qx[k] + A[k].T @ lin + Hxv[k] @ ff[k]
        assert np.allclose(p[k], p_next, rtol=1e-10, atol=1e-10)
    for k in range(K):
        assert np.allclose(v[k], gain[k] @ X[k] + ff[k], rtol=1e-12, atol=1e-12)
        assert np.allclose(X[k + 1], A[k] @ X[k] + B[k] @ v[k] + b[k], rtol=1e-12, atol=1e-12)


def test_the_stage_hessians_skip_the_inner_points_input_rows_exactly():
    """_riccati.stage_hessians with `states` s (C's rows from s on 0, E's the identity's rows
    of each inner point's block of v) equals the full products and Q = G_s + Σ [C E]ᵀ·G·[C E]
    written out in NumPy; so does stage_gradients (e's rows from s on 0)."""
    from lagrgen.collocation._riccati import stage_gradients, stage_hessians
    rng = np.random.default_rng(11)
    K, s, m, inner = 4, 5, 2, 2
    ny, nv = s + m, 3 * m
    points = np.arange(K * (inner + 1), dtype=np.int64).reshape(K, inner + 1)
    G = rng.normal(size=(points.size, ny, ny))
    G = G + G.transpose(0, 2, 1)
    C, E = np.zeros((inner, K, ny, ny)), np.zeros((inner, K, ny, nv))
    C[:, :, :s], E[:, :, :s] = rng.normal(size=(inner, K, s, ny)), rng.normal(size=(inner, K, s,
                                                                                    nv))
    for p in range(inner):
        E[p, :, s:, p * m:(p + 1) * m] = np.eye(m)

    def staged(states):
        out = np.zeros((K, ny, ny)), np.zeros((K, ny, nv)), np.zeros((K, nv, nv))
        stage_hessians(G, points, C, E, *out, states)
        return out
    skipped, full = staged(s), staged(-1)
    gamma, e = rng.normal(size=(points.size, ny)), np.zeros((inner, K, ny))
    e[:, :, :s] = rng.normal(size=(inner, K, s))

    def gradients(states):
        out = np.zeros((K, ny)), np.zeros((K, nv))
        stage_gradients(G, gamma, points, C, E, e, *out, states)
        return out
    for got, full_ in zip(gradients(s), gradients(-1)):
        assert np.allclose(got, full_, rtol=1e-12, atol=1e-12 * np.abs(full_).max())
    qx, qv = gradients(s)
    for k in range(K):
        lin = [G[points[k, p + 1]] @ e[p, k] + gamma[points[k, p + 1]] for p in range(inner)]
        assert np.allclose(qx[k], gamma[points[k, 0]] + sum(C[p, k].T @ lin[p]
                                                           for p in range(inner)))
        assert np.allclose(qv[k], sum(E[p, k].T @ lin[p] for p in range(inner)))
    for k in range(K):
        Q = np.zeros((ny + nv, ny + nv))
        Q[:ny, :ny] = G[points[k, 0]]
        for p in range(inner):
            CE = np.concatenate([C[p, k], E[p, k]], axis=1)
            Q += CE.T @ G[points[k, p + 1]] @ CE
        for got, want in zip((a[k] for a in full), (Q[:ny, :ny], Q[:ny, ny:], Q[ny:, ny:])):
            assert np.allclose(got, want, rtol=1e-12, atol=1e-12)
    for a, b in zip(skipped, full):
        assert np.allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(b).max())


def test_the_filter_takes_what_lowers_the_violation_or_the_objective_and_remembers_it():
    """IPOPT's filter: a trial lowering θ or φ by the margin is taken and its start (moved by
    the margins) enters the filter; a later trial the entry dominates is refused; near
    feasibility a step along a steep descent needs Armijo's decrease (and adds nothing); θ
    above θ_max, an objective risen by more than 1e5·max(1, |φ|) and NaN are refused."""
    from lagrgen.collocation.sqp import FILTER_GAMMA, _Filter
    f = _Filter.at(2.0)
    assert f.theta_max == pytest.approx(2e4) and f.theta_min == pytest.approx(2e-4)
    assert f.takes(10.0, 1.0, 0.0, 1.0, 11.0, 0.5)             # θ down, φ up: h-type
    assert f.pairs == [pytest.approx((1.0 - FILTER_GAMMA, 10.0 - FILTER_GAMMA))]
    assert not f.takes(9.0, 0.5, 0.0, 1.0, 10.5, 0.999)        # dominated by that entry
    assert f.takes(9.0, 0.5, 0.0, 1.0, 8.0, 0.6)               # φ down by the margin
    assert not f.takes(10.0, 1.0, 0.0, 1.0, 10.0, 1.0)         # neither falls
    near = _Filter.at(0.0)
    assert near.takes(5.0, 1e-8, -1.0, 1.0, 4.0, 2e-8)          # φ-type: Armijo holds
    assert not near.takes(5.0, 1e-8, -1.0, 1.0, 5.0 - 1e-6, 1e-9)   # Armijo fails
    assert near.pairs == []
    assert not near.takes(5.0, 1e-8, 0.0, 1.0, 4.0, 2e4)        # beyond θ_max
    assert not near.takes(5.0, 1.0, 0.0, 1.0, 5.0 + 1e6, 0.1)   # φ risen beyond any
    assert not near.takes(5.0, 1.0, 0.0, 1.0, np.nan, 0.1)
    assert not near.takes(5.0, 1.0, 0.0, 1.0, 4.0, np.nan)


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_a_cut_step_damps_the_bounds_multipliers_as_the_constraints(swing):
    """Where the line search cuts a step to α, the bounds' multipliers move by α of the QP's
    change as the constraints' do (undamped, a cut step close to tol lifted the stationarity
    to 1.2 on a 1016-node mesh of Talos): from zero multipliers, the step the line search
    refuses at full length (an objective risen beyond any) and takes at half gives half the full
    step's λ and z."""
    from lagrgen.collocation import sqp
    _, tr, x0, _ = swing_near_optimum(swing, 7)
    alphas = []

    def monitor(iteration, value, primal, dual, alpha):
        alphas.append(alpha)
    full = sqp.solve(tr, x0, max_iter=1, monitor=monitor)

    class Refusing:
        """tr, its objective at the full step's point made worse than any."""
        def __getattr__(self, name):
            return getattr(tr, name)

        def objective(self, x):
            return 1e30 if np.allclose(x, full.x, rtol=0, atol=1e-14) else tr.objective(x)
    cut = sqp.solve(Refusing(), x0, max_iter=1, monitor=monitor)
    assert alphas == [1.0, 0.5]
    assert np.abs(full.z).max() > 0 and np.abs(full.lam).max() > 0
    assert np.allclose(cut.z, 0.5 * full.z, rtol=1e-12, atol=1e-12 * np.abs(full.z).max())
    assert np.allclose(cut.lam, 0.5 * full.lam, rtol=1e-12,
                       atol=1e-12 * np.abs(full.lam).max())
    assert np.allclose(cut.x, np.clip(x0 + 0.5 * (full.x - x0), tr.lo, tr.hi))


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_a_qp_not_to_be_purified_is_taken_as_the_interior_point_leaves_it(swing, monkeypatch):
    """solve_qp(purify=False), the SQP's QPs after one whose active set did not make the
    interior point's solution exact: the interior point's solution as it stands (as_left, with
    its multipliers of every bound), no passes of the active set after it."""
    from lagrgen.collocation import sqp
    tr, lin, _ = swing_qp_at_optimum(swing)
    stages, rows = sqp.Stages.of(tr), sqp.Rows.of(tr)

    def unsettled(*args, **kwargs):
        raise sqp.Unsupported("the QP's active set did not settle")
    purified = []
    monkeypatch.setattr(sqp, "solve_qp_active", unsettled)
    monkeypatch.setattr(sqp, "_purified", lambda *args: purified.append(args) or args[-1])
    taken = sqp.solve_qp(tr, stages, rows, lin, sqp.ActiveSet.start(lin), purify=False)
    assert taken.interior and taken.as_left and taken.z_all.shape == (lin.W.shape[0]
                                                                       * lin.W.shape[1],)
    assert not purified
    again = sqp.solve_qp(tr, stages, rows, lin, sqp.ActiveSet.start(lin))
    assert len(purified) == 1 and again.interior
    assert np.allclose(again.dz, taken.dz, rtol=0, atol=1e-12)


def swing_qp_at_optimum(swing):
    """(transcription, linearization, StructuredQP) of the swing-up on 9 nodes at IPOPT's
    solution."""
    from lagrgen.collocation import sqp
    model, mod = swing
    prob = swing_problem(mod, model.input_functions[0], nodes=9)
    res = prob.solve(progress=False, mesh_tol=None, solver="ipopt")
    tr = prob.transcription("exact").bound(3.0)
    stages, rows = sqp.Stages.of(tr), sqp.Rows.of(tr)
    lin = sqp.linearize(tr, res.x, res._lam, stages, rows)
    return tr, lin, sqp.StructuredQP(tr, stages, rows, lin)


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_a_points_costs_with_a_diagonal_added_are_the_eliminated_blocks(swing):
    """diagonal_costs / diagonal_gradients (TᵀWT formed once, the diagonal's terms added) equal
    Tᵀ·(W + diag(add))·T and Tᵀ·((W + diag(add))·t + g) formed whole; the G of the last factor
    is never the buffer the next diagonal_costs writes."""
    _, lin, qp = swing_qp_at_optimum(swing)
    rng = np.random.default_rng(3)
    P, nz = lin.W.shape[:2]
    for _ in range(2):
        add = rng.uniform(0, 1e3, P * nz) * (rng.random(P * nz) < 0.5)
        W = lin.W + np.einsum("pi,ij->pij", add.reshape(P, nz), np.eye(nz))
        g = rng.standard_normal((P, nz))
        G, gamma = qp.point_costs(W, g)
        scale = np.abs(G).max()
        assert np.abs(qp.diagonal_costs(add) - G).max() < 1e-12 * scale
        assert np.allclose(qp.diagonal_gradients(add, g), gamma, rtol=1e-12, atol=1e-12 * scale)
    factored = qp.diagonal_costs(np.full(P * nz, 10.0))     # positive definite along the inputs
    kept = factored.copy()
    assert qp.factor(factored)
    for _ in range(3):                  # the next G is never written over the factored one
        assert qp.diagonal_costs(rng.uniform(0, 1e3, P * nz)) is not qp.G
        assert qp.G is factored and np.array_equal(qp.G, kept)


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_the_qps_regularization_is_the_least_that_serves_from_any_last_one(swing):
    """A QP that is not convex along its inputs is factored with the least regularization of
    the grid 1e-8·10ᵏ that makes it positive definite (what a search up from 1e-8 finds),
    whatever regularization the last factor needed; started at the last one, the search takes
    three factors (none, the last, a tenth of it) where the search up from 1e-8 takes more."""
    from lagrgen.collocation import sqp
    tr, lin, qp = swing_qp_at_optimum(swing)
    u = tr.layout.nz - 1                                  # the torque's place in a point
    W = lin.W.copy()
    W[:, u, u] -= 3e-3 * np.abs(W[:, u, u]).max() + 1e-4
    G = qp.point_costs(W, lin.g)[0]
    grid = [0.0] + [sqp.FIRST_REGULARIZATION * sqp.GROWTH ** k for k in range(13)]
    least = next(delta for delta in grid if qp.factor(G, delta))
    assert least > 1e-6, least                            # not convex: it needs one
    reference = [np.copy(a) for a in qp.factored()]
    qp.vectors(qp.point_costs(W, lin.g)[1])
    steps = qp.solve()

    calls = []
    factor = qp.factor
    qp.factor = lambda *args: calls.append(args[1]) or factor(*args)
    for last in (0.0, least, least * 1e3, least * 1e-4):
        calls.clear()
        inertia = sqp.Inertia(last)
        delta = sqp._factored(qp, G, inertia)
        gamma = qp.point_costs(W, lin.g)[1]
        assert delta == pytest.approx(least, rel=1e-12) and inertia.last == delta
        qp.vectors(gamma)
        assert np.allclose(qp.solve(), steps, rtol=1e-12, atol=1e-12)
        assert all(np.array_equal(a, b) for a, b in zip(qp.factored()[:4], reference[:4]))
        if last == least:
            assert calls == [0.0, least, least / sqp.GROWTH]
    assert grid.index(least) + 1 >= 5                     # the search up from 1e-8's factors


def test_refined_meshes_by_the_sqp_reach_ipopts_optimum(swing, monkeypatch):
    """solver="auto": the first mesh, started from a guess, is IPOPT's; the refinement's meshes
    after it, started from the last solution and its multipliers, are the structured SQP's (a
    torque that stays inside its bounds, the velocity riding its own); solver="sqp": the first
    mesh too, from the guess without multipliers; both at IPOPT's optimum on the same meshes
    (solver="ipopt")."""
    from lagrgen.collocation import solver as solver_module
    model, mod = swing
    T, = model.input_functions
    structured, starts = solver_module.solve_structured, []

    def recording(problem, tr, x0, lam0, z0, settings, **options):
        starts.append(lam0 is not None and z0 is not None)
        return structured(problem, tr, x0, lam0, z0, settings, **options)
    monkeypatch.setattr(solver_module, "solve_structured", recording)
    results = {solver: swing_problem(mod, T, limit=20.0).solve(progress=False, solver=solver)
               for solver in ("sqp", "auto", "ipopt")}
    ipopt = results["ipopt"]
    assert ipopt.success and ipopt.solver == "ipopt" and len(ipopt.meshes) > 1
    assert {m.solver for m in ipopt.meshes} == {"ipopt"}
    later = ["sqp"] * (len(ipopt.meshes) - 1)
    for name, first in (("sqp", "sqp"), ("auto", "ipopt")):
        by = results[name]
        assert by.success and by.solver == "sqp" and not by.sqp_failed
        assert [m.solver for m in by.meshes] == [first] + later
        assert [m.nodes for m in by.meshes] == [m.nodes for m in ipopt.meshes]
        assert abs(by.objective - ipopt.objective) < 1e-7 * ipopt.objective
        assert by.error <= 1e-6
    assert starts == [False] + [True] * (2 * len(ipopt.meshes) - 2)


def test_where_the_sqps_stationarity_stalls_auto_hands_the_refinement_to_ipopt(swing,
                                                                              monkeypatch):
    """solver="auto": a refined mesh on which the SQP's stationarity residual stops falling
    (here held at 3e-5 once the constraints hold, over full steps that still move the
    objective) is solved by IPOPT from the same start, with a note, and so is every mesh after
    it, at IPOPT's optimum; solver="sqp" goes on to its flat stop instead."""
    from lagrgen.collocation import sqp
    model, mod = swing
    T, = model.input_functions
    kkt_error = sqp.kkt_error

    def stalling(*args):
        primal, dual = kkt_error(*args)
        return primal, dual if primal > sqp.STALLED_PRIMAL else max(dual, 3e-5)
    monkeypatch.setattr(sqp, "kkt_error", stalling)
    stall = sqp.STALL
    monkeypatch.setattr(sqp, "STALL", -1.0)                 # no flat stop before it stalls
    auto = swing_problem(mod, T, nodes=21, limit=20.0).solve(progress=False)
    ipopt = swing_problem(mod, T, nodes=21, limit=20.0).solve(progress=False, solver="ipopt")
    assert auto.success and auto.status == 0 and auto.solver == "ipopt" and auto.sqp_failed
    assert {m.solver for m in auto.meshes} == {"ipopt"} and len(auto.meshes) > 2
    said = [n for n in auto.notes if "structured SQP failed" in n]
    assert len(said) == 1 and "stationarity residual stalled at 3.0e-05" in said[0]
    assert "on mesh 2" in said[0] and "the meshes after it" in said[0]
    assert "stalled at 3.0e-05" in auto.sqp_failed
    assert auto.objective == pytest.approx(ipopt.objective, rel=1e-10)
    monkeypatch.setattr(sqp, "STALL", stall)
    by_sqp = swing_problem(mod, T, nodes=21, limit=20.0).solve(progress=False, solver="sqp")
    assert by_sqp.solver == "sqp" and by_sqp.status == 1 and by_sqp.sqp_failed == ""
    assert any("3.0e-05 above tol" in n for n in by_sqp.notes)


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_where_the_sqp_stalls_near_tol_ipopt_finishes_from_its_answer(swing, monkeypatch):
    """solver="auto": a stall within STALLED_NEAR·tol (the interior point's rounding of its
    multipliers on Talos's meshes) ends the SQP as a flat optimum does, and IPOPT finishes each
    refined mesh from the SQP's motion and multipliers (a few iterations), at IPOPT's optimum;
    nothing is handed over from a mesh's start."""
    from lagrgen.collocation import sqp
    model, mod = swing
    T, = model.input_functions
    kkt_error, near = sqp.kkt_error, 0.5 * sqp.STALLED_NEAR * 1e-8

    def stalling(*args):
        primal, dual = kkt_error(*args)
        return primal, dual if primal > sqp.STALLED_PRIMAL else max(dual, near)
    monkeypatch.setattr(sqp, "kkt_error", stalling)
    monkeypatch.setattr(sqp, "STALL", -1.0)
    auto = swing_problem(mod, T, nodes=21, limit=20.0).solve(progress=False)
    ipopt = swing_problem(mod, T, nodes=21, limit=20.0).solve(progress=False, solver="ipopt")
    assert auto.success and auto.status == 0 and not auto.sqp_failed and len(auto.meshes) > 2
    finished = [n for n in auto.notes if "IPOPT finished this mesh from its motion" in n]
    assert finished and not [n for n in auto.notes if "structured SQP failed" in n]
    assert all(m.iterations <= 10 for m in auto.meshes[1:])
    assert auto.objective == pytest.approx(ipopt.objective, rel=1e-10)


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_the_sqp_stops_where_its_constraints_hold_to_tol(swing, monkeypatch):
    """The SQP's constraints are met to tol, as IPOPT's (not to 1e-3·tol): a violation held at
    half tol (the remainder that QPs taken as the interior point leaves them carry on Talos's
    meshes) ends each refined mesh's solve once it is stationary to tol; held at twice tol it
    does not, and IPOPT solves the mesh with a note."""
    from lagrgen.collocation import sqp
    model, mod = swing
    T, = model.input_functions
    kkt_error, held = sqp.kkt_error, [0.5e-8]

    def violated(*args):
        primal, dual = kkt_error(*args)
        return max(primal, held[0]), dual
    monkeypatch.setattr(sqp, "kkt_error", violated)
    met = swing_problem(mod, T, nodes=21, limit=20.0).solve(progress=False, solver="sqp")
    assert met.status == 0 and len(met.meshes) > 1
    assert [m.solver for m in met.meshes[1:]] == ["sqp"] * (len(met.meshes) - 1)
    assert not [note for note in met.notes if "SQP" in note]
    held[0] = 2e-8
    off = swing_problem(mod, T, nodes=21, limit=20.0).solve(progress=False, solver="sqp")
    assert off.meshes[1].solver == "ipopt" and off.sqp_failed
    assert any("structured SQP failed" in note for note in off.notes)


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_a_replan_equals_a_cold_solve_from_the_new_state(swing):
    """resolve(warm, initial, shift): the plan from the state 0.3 s into the first one, warm-
    started from its shifted motion (by the structured SQP, solver "auto"'s choice for a
    re-plan, and by IPOPT), equals a cold solve of the same problem from that state;
    the state read off the solution on its velocity bound (beyond it by the solver's tolerance)
    is clipped with a note; a state clearly outside is refused."""
    model, mod = swing
    T, = model.input_functions
    prob = swing_problem(mod, T)
    first = prob.solve(progress=False, mesh_tol=None)
    state = first.state_at(0.3)
    again = prob.resolve(first, initial={"q": state[:1], "qd": state[1:]}, shift=0.3)
    assert again.success and again.solver == "sqp" and again.solve_seconds > 0
    assert 0 < again.callback_seconds < again.seconds       # the SQP's own work besides
    by_ipopt = prob.resolve(first, initial={"q": state[:1], "qd": state[1:]}, shift=0.3,
                            solver="ipopt")
    assert by_ipopt.success and by_ipopt.solver == "ipopt"
    assert abs(by_ipopt.objective - again.objective) < 1e-6 * again.objective
    cold = swing_problem(mod, T)
    cold._fixed.clear()
    cold.initial(q=state[:1], qd=np.clip(state[1:], -4.0, 4.0)).final(q=[np.pi], qd=[0.0])
    reference = cold.solve(progress=False, mesh_tol=None, solver="ipopt")
    assert abs(again.objective - reference.objective) < 1e-6 * reference.objective
    assert np.abs(again.y - reference.y).max() < 1e-4
    over = prob.resolve(again, initial={"qd": [4.0 + 1e-8]})
    said = [note for note in over.notes if "outside its bounds" in note]
    assert over.success and len(said) == 1 and "np.float64" not in said[0]
    with pytest.raises(lagrgen.errors.LagrgenError, match="outside its bounds"):
        prob.resolve(again, initial={"qd": [4.1]})
    with pytest.raises(lagrgen.errors.LagrgenError, match="shift"):
        prob.resolve(again, shift=5.0)


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_a_replan_whose_sqp_crawls_near_the_solution_is_finished_from_its_last_iterate(
        swing, monkeypatch):
    """solver="auto": a re-plan whose SQP creeps near the solution (here its constraints'
    violation held at 2e-7, above tol, while the rest converges) is handed over after
    CRAWL_ITERATIONS iterations that each lower the KKT error less than STALLED_DROP times, and
    IPOPT finishes it from the SQP's last iterate and multipliers in a few iterations (not from
    the re-plan's start), at the IPOPT re-plan's optimum, as is one whose line search then
    finds no step; a re-plan whose SQP ends far from a solution (that line search failing
    with NEAR_SOLUTION made tiny) is still IPOPT's from the re-plan's start."""
    from lagrgen.collocation import solver as solver_module, sqp
    model, mod = swing
    T, = model.input_functions
    prob = swing_problem(mod, T)
    first = prob.solve(progress=False, mesh_tol=None)
    state = first.state_at(0.3)
    initial = {"q": state[:1] + 0.05, "qd": np.clip(state[1:], -4.0, 4.0)}
    reference = prob.resolve(first, initial=initial, shift=0.3, solver="ipopt")
    kkt_error, starts = sqp.kkt_error, []

    def creeping(*args):
        primal, dual = kkt_error(*args)
        return max(primal, 2e-7), dual
    monkeypatch.setattr(sqp, "kkt_error", creeping)
    monkeypatch.setattr(sqp, "CRAWL_ITERATIONS", 2)     # before its line search finds no step
    solve_nlp = solver_module.solve_nlp

    def recording(problem, tr, x0, settings, start=None, multipliers=None):
        starts.append((start, multipliers is not None))
        return solve_nlp(problem, tr, x0, settings, start, multipliers)
    monkeypatch.setattr(solver_module, "solve_nlp", recording)
    again = prob.resolve(first, initial=initial, shift=0.3)
    assert again.success and again.status == 0 and again.solver == "ipopt"
    assert starts == [("near", True)] and again.iterations <= 10
    said = [n for n in again.notes if "KKT error fell less than 10 times" in n]
    assert len(said) == 1 and "IPOPT finished this mesh from its motion and multipliers" in said[0]
    assert "KKT error" in again.sqp_failed
    assert abs(again.objective - reference.objective) < 1e-8 * reference.objective
    monkeypatch.setattr(sqp, "CRAWL_ITERATIONS", 10**6)
    starts.clear()
    stuck = prob.resolve(first, initial=initial, shift=0.3)
    assert stuck.solver == "ipopt" and starts == [("near", True)]
    assert any("line search failed): IPOPT finished this mesh from its motion" in n
               for n in stuck.notes)
    monkeypatch.setattr(sqp, "NEAR_SOLUTION", 1e-12)           # nowhere near: not handed on
    starts.clear()
    far = prob.resolve(first, initial=initial, shift=0.3)
    assert far.solver == "ipopt" and starts == [(None, False)]
    assert any("line search failed): IPOPT solved this mesh from the same start" in n
               for n in far.notes)
    assert abs(far.objective - reference.objective) < 1e-6 * reference.objective


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_a_replan_that_raises_leaves_the_problem_as_it_was(swing):
    """A resolve refused for its options or its new initial state changes nothing: the next
    solve starts from the declared initial state and equals the first one."""
    model, mod = swing
    prob = swing_problem(mod, model.input_functions[0], nodes=21)
    first = prob.solve(progress=False, mesh_tol=None)
    with pytest.raises(lagrgen.errors.LagrgenError, match="max_iter"):
        prob.resolve(first, initial={"q": [0.5]}, max_iter=-1)
    with pytest.raises(lagrgen.errors.LagrgenError, match="outside its bounds"):
        prob.resolve(first, initial={"qd": [9.0]})
    again = prob.solve(progress=False, mesh_tol=None)
    assert again.success and np.allclose(again.y[:, 0], [0.0, 0.0], atol=1e-12)
    assert abs(again.objective - first.objective) < 1e-9 * first.objective
    moved = prob.resolve(first, initial={"q": [0.1]})          # one that succeeds keeps it
    assert moved.success and abs(moved.y[0, 0] - 0.1) < 1e-12
    assert abs(prob.solve(progress=False, mesh_tol=None).y[0, 0] - 0.1) < 1e-12


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_a_refined_replans_solve_seconds_count_every_mesh(swing):
    """res.solve_seconds of a resolve is the wall time of the whole re-plan: with mesh_tol, every
    mesh of it (at least the sum of the meshes' seconds), within the call's own time."""
    model, mod = swing
    prob = swing_problem(mod, model.input_functions[0], nodes=21)
    first = prob.solve(progress=False, mesh_tol=None)
    state = first.state_at(0.3)
    began = time.perf_counter()
    refined = prob.resolve(first, initial={"q": state[:1], "qd": state[1:]}, shift=0.3,
                           mesh_tol=1e-6)
    wall = time.perf_counter() - began
    assert len(refined.meshes) >= 2
    assert sum(m.seconds for m in refined.meshes) <= refined.solve_seconds <= wall


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_a_replan_the_sqp_does_not_cover_says_ipopt_solved_it(swing):
    """Where the SQP does not apply (a terminal constraint), a re-plan is IPOPT's, with a note
    that says why; with solver="ipopt" asked for, no note."""
    model, mod = swing
    th, = model.q
    prob = swing_problem(mod, model.input_functions[0], nodes=21)
    prob.terminal(th, np.pi - 0.1, np.pi + 0.1)
    first = prob.solve(progress=False, mesh_tol=None)
    again = prob.resolve(first, shift=0.2)
    assert again.success and again.solver == "ipopt"
    said = [n for n in again.notes if "structured SQP does not handle" in n]
    assert len(said) == 1 and "terminal" in said[0]
    asked = prob.resolve(first, shift=0.2, solver="ipopt")
    assert not [n for n in asked.notes if "structured SQP" in n]


def swing_replan(swing):
    """(the swing-up's problem, its solution, resolve's arguments of the re-plan from its state
    at 0.3 s)."""
    model, mod = swing
    prob = swing_problem(mod, model.input_functions[0])
    first = prob.solve(progress=False, mesh_tol=None)
    state = first.state_at(0.3)
    return prob, first, dict(initial={"q": state[:1], "qd": state[1:]}, shift=0.3)


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_a_replan_bounded_by_max_iter_is_the_sqps_iterate_there(swing, monkeypatch):
    """resolve(..., max_iter=k) below the SQP's own limit bounds the work (real-time iterations):
    the SQP's iterate after k iterations is the result, status -1 and not a success, never
    handed to IPOPT; each iteration lowers the distance to the converged re-plan, and
    max_iter=0 is the shifted warm start itself."""
    from lagrgen.collocation import solver
    prob, first, replan = swing_replan(swing)
    converged = prob.resolve(first, **replan)
    assert converged.status == 0 and converged.iterations > 2
    monkeypatch.setattr(solver, "solve_nlp", None)          # IPOPT never called
    distances = []
    for k in range(3):
        bounded = prob.resolve(first, max_iter=k, **replan)
        assert (bounded.solver, bounded.status, bounded.success) == ("sqp", -1, False)
        assert bounded.iterations == k and f"max_iter={k}" in bounded.message
        distances.append(np.abs(bounded.y - converged.y).max())
    start = first.state_at(np.minimum(converged.t + 0.3, first.duration))
    assert np.abs(prob.resolve(first, max_iter=0, **replan).y - start).max() < 1e-6
    assert distances[0] > distances[1] > distances[2]


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_an_arms_replans_by_the_sqp_converge_where_its_joints_ride_their_limits(out_dir,
                                                                               monkeypatch):
    """The seven-joint arm's re-plans of a move on which every joint rides its velocity limit:
    the QPs whose active sets do not settle go to the interior point, whose solution is then
    made exact by the active set it identified (or, far from the solution, taken as the interior
    point leaves it at a loose tolerance, the active set not tried there nor in the step after);
    each re-plan by the SQP converges to tol (no flat stop, no failed step handed to IPOPT) at
    IPOPT's optimum from the same start; with solver="sqp" the first solve too, from the cold
    guess (its line search the filter: the ℓ1 merit function cut such steps to a crawl)."""
    from lagrgen.collocation import sqp
    tolerances, interior, qps, solve_qp = [], sqp.solve_qp_interior, [], sqp.solve_qp

    def spied(qp, lin, active, inertia, tol=1e-9, **kwargs):
        tolerances.append(tol)
        return interior(qp, lin, active, inertia, tol, **kwargs)

    def recorded(*args, passes=sqp.ACTIVE_PASSES, loose=False, **kwargs):
        qps.append((passes, loose))
        return solve_qp(*args, passes=passes, loose=loose, **kwargs)

    monkeypatch.setattr(sqp, "solve_qp_interior", spied)
    monkeypatch.setattr(sqp, "solve_qp", recorded)
    model = lagrgen.from_urdf(ARM, name="motions_arm", joint_dynamics=False)
    mod = lagrgen.build(model, out_dir=out_dir)
    n = mod.n_coordinates
    lower, upper, velocity = (np.array([mod.limits[c][i] for c in mod.coordinates])
                              for i in (0, 1, 2))
    middle, half = (lower + upper) / 2, (upper - lower) / 2
    prob = lagrgen.Collocation(mod, nodes=41, duration=1.2).bound_limits()
    prob.initial(q=middle - 0.35 * half * np.linspace(1, -1, n), qd=np.zeros(n))
    prob.final(q=middle + 0.35 * half * np.linspace(1, -1, n), qd=np.zeros(n))
    prob.minimize(integral=sum(u ** 2 for u in model.input_functions))
    last = prob.solve(progress=False, mesh_tol=None)
    assert last.success
    riding = np.abs(np.abs(last.y[n:]) - velocity[:, None]) < 1e-6
    assert riding.any(axis=1).all()
    cold = prob.solve(progress=False, mesh_tol=None, solver="sqp")   # its first mesh too
    assert cold.solver == "sqp" and cold.status == 0 and not cold.sqp_failed
    assert abs(cold.objective - last.objective) < 1e-7 * last.objective
    assert np.abs(cold.y - last.y).max() < 1e-5
    for _ in range(3):
        state = last.state_at(0.12)
        replan = dict(initial={"q": state[:n], "qd": state[n:]}, shift=0.12)
        by_sqp = prob.resolve(last, solver="sqp", **replan)
        by_ipopt = prob.resolve(last, solver="ipopt", **replan)
        assert by_sqp.solver == "sqp" and by_sqp.status == 0, by_sqp.notes
        assert not [note for note in by_sqp.notes if "SQP" in note]
        assert by_ipopt.status == 0
        assert abs(by_sqp.objective - by_ipopt.objective) < 1e-7 * by_ipopt.objective
        last = by_ipopt
    assert sqp.LOOSE_TOL in tolerances
    loose = [k for k, (_, far) in enumerate(qps) if far]      # a solve never ends on one
    assert loose and all(qps[k][0] == 0 for k in loose)
    assert all(qps[k + 1][0] == 0 for k in loose)
    assert any(passes > 0 for passes, _ in qps)


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_an_arms_refined_meshes_by_the_sqp_converge_on_the_interior_points_multipliers(
        out_dir, monkeypatch):
    """The seven-joint arm's move riding its velocity limits, refined with solver="auto", every
    QP of the SQP solved by the interior point and taken as it leaves it (the active set made
    to fail: what Talos's refined meshes do), with its multipliers of every bound (μ/s on the
    inactive ones): the SQP converges to tol on the refined meshes (before, its stationarity
    residual stalled at the size of the multipliers it dropped), at IPOPT's optimum. A mesh
    after one whose QPs were taken as they stood takes them so from its first (purify=False),
    and after a QP taken so the active set is not tried again."""
    from lagrgen.collocation import sqp
    interior, purifies, events = [], [], []
    sqp_solve = sqp.solve

    def recorded(*args, **kwargs):
        purifies.append(kwargs.get("purify", True))
        return sqp_solve(*args, **kwargs)

    def unsettled(*args, **kwargs):
        events.append("active")
        raise sqp.Unsupported("the QP's active set did not settle")

    def spied(*args, **kwargs):
        interior.append(sqp_interior(*args, **kwargs))
        events.append(interior[-1])
        return interior[-1]
    sqp_interior = sqp.solve_qp_interior
    model = lagrgen.from_urdf(ARM, name="motions_arm", joint_dynamics=False)
    mod = lagrgen.build(model, out_dir=out_dir)
    n = mod.n_coordinates
    lower, upper = (np.array([mod.limits[c][i] for c in mod.coordinates]) for i in (0, 1))
    middle, half = (lower + upper) / 2, (upper - lower) / 2
    prob = lagrgen.Collocation(mod, nodes=21, duration=1.2).bound_limits()
    prob.initial(q=middle - 0.35 * half * np.linspace(1, -1, n), qd=np.zeros(n))
    prob.final(q=middle + 0.35 * half * np.linspace(1, -1, n), qd=np.zeros(n))
    prob.minimize(integral=sum(u ** 2 for u in model.input_functions))
    ipopt = prob.solve(progress=False, mesh_tol=1e-5, solver="ipopt")
    monkeypatch.setattr(sqp, "solve_qp_active", unsettled)
    monkeypatch.setattr(sqp, "solve_qp_interior", spied)
    monkeypatch.setattr(sqp, "solve", recorded)
    auto = prob.solve(progress=False, mesh_tol=1e-5)
    assert auto.success and auto.status == 0 and not auto.sqp_failed
    assert [m.solver for m in auto.meshes[:3]] == ["ipopt", "sqp", "sqp"]
    assert all(m.status == 0 for m in auto.meshes)
    assert all(qp.z_all is not None for qp in interior)
    assert sum(qp.as_left for qp in interior) >= 4       # not far from the solution: to tol
    assert len(purifies) == len(auto.meshes) - 1 and purifies[0] and not any(purifies[1:])
    first = next(i for i, e in enumerate(events) if e != "active" and e.as_left)
    assert "active" not in events[first + 2:]     # after its purification failed: none tried
    assert abs(auto.objective - ipopt.objective) < 1e-7 * ipopt.objective
    assert auto.error <= 1e-5


def test_the_sqps_kkt_error_counts_the_multipliers_of_bounds_it_is_off():
    """kkt_error: the stationarity residual with every bound's multiplier, and complementarity,
    |z|·(the distance to its bound), where a multiplier sits on a bound the point is off."""
    from types import SimpleNamespace

    from lagrgen.collocation.sqp import kkt_error
    tr = SimpleNamespace(lo=np.array([0.0, -np.inf]), hi=np.array([1.0, np.inf]),
                         g_lo=np.zeros(0), g_hi=np.zeros(0), jac_rows=np.zeros(0, int),
                         jac_cols=np.zeros(0, int), constraints=lambda x: np.zeros(0),
                         jacobian=lambda x: np.zeros(0), gradient=lambda x: np.array([-2.0,
                                                                                        0.0]))
    lam = np.zeros(0)
    assert kkt_error(tr, np.array([1.0, 3.0]), lam, np.array([2.0, 0.0])) == (0.0, 0.0)
    assert kkt_error(tr, np.array([0.75, 3.0]), lam, np.array([2.0, 0.0])) == (0.0, 0.5)
    assert kkt_error(tr, np.array([1.0, 3.0]), lam, np.array([1.5, 0.0])) == (0.0, 0.5)


def test_an_active_set_is_abandoned_only_when_its_changes_do_not_shrink_fast_enough():
    """_hopeless: a set whose changes grow, or shrink too slowly to settle in the passes left,
    goes to the interior point; one shrinking fast enough, or changing a few constraints, goes
    on."""
    from lagrgen.collocation.sqp import HOPELESS_FEW, _hopeless
    assert _hopeless(3476, 1774, 18)                   # growing
    assert _hopeless(176, 205, 18)                     # ×0.86 a pass: ~34 more passes
    assert not _hopeless(61, 105, 17)                  # ×0.58 a pass: ~8 more
    assert not _hopeless(HOPELESS_FEW, 4 * HOPELESS_FEW, 1)
    assert not _hopeless(1774, np.inf, 19)             # the first pass


def test_an_interior_points_set_is_made_exact_while_its_changes_shrink_on_average():
    """_hopeless_on_average (the interior point's set made exact): Talos's 615-node mesh, whose
    set had not settled after 20 passes, is given up by its third; a set settling with one pass
    that changes more than the one before goes on."""
    from lagrgen.collocation.sqp import SETTLING_PASSES, _hopeless_on_average
    talos = [1485, 840, 792, 582, 460, 349, 353, 289, 289, 206]
    verdicts = [_hopeless_on_average(now, talos[0], k, SETTLING_PASSES - k)
                for k, now in enumerate(talos, 1)]
    assert verdicts.index(True) <= 2
    settling = [300, 120, 150, 45, 12, 3]
    assert not any(_hopeless_on_average(now, settling[0], k, SETTLING_PASSES - k)
                   for k, now in enumerate(settling, 1))


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_an_sqp_solve_that_ends_on_a_flat_optimum_says_so(swing, monkeypatch):
    """An SQP solve that converges to tol carries no note; one that ends because its steps no
    longer lower the objective, its stationarity residual above tol (a flat optimum), says so
    with the residual and how to solve to tol under solver="sqp", and is finished to tol by
    IPOPT from its motion and multipliers under solver="auto" (with a note)."""
    from lagrgen.collocation import sqp
    model, mod = swing
    T, = model.input_functions
    prob = swing_problem(mod, T)
    first = prob.solve(progress=False, mesh_tol=None)
    state = first.state_at(0.3)
    replan = dict(initial={"q": state[:1], "qd": state[1:]}, shift=0.3, solver="sqp")
    exact = prob.resolve(first, **replan)
    assert exact.success and exact.status == 0 and not [n for n in exact.notes if "SQP" in n]
    solve = sqp.solve

    def flat(*args, **kwargs):
        outcome = solve(*args, **kwargs)
        outcome.dual = 3.2e-4
        time.sleep(0.3)                   # an SQP that takes its time
        return outcome
    monkeypatch.setattr(sqp, "solve", flat)
    stalled = prob.resolve(first, **replan)
    said = [n for n in stalled.notes if "SQP" in n]
    assert len(said) == 1 and "3.2e-04 above tol 1e-08" in said[0] and "'ipopt'" in said[0]
    assert stalled.success and stalled.status == 1 and "flat optimum" in stalled.message
    assert not [n for n in stalled.notes if "IPOPT stopped at its acceptable level" in n]
    replan.pop("solver")                    # "auto": IPOPT finishes what the SQP left flat
    finished = prob.resolve(first, **replan)
    assert finished.solver == "ipopt" and finished.status == 0
    said = [n for n in finished.notes if "SQP" in n]
    assert len(said) == 1 and "stopped short of tol" in said[0] and "3.2e-04" in said[0]
    assert finished.solve_seconds >= finished.seconds >= 0.3       # the SQP's time and IPOPT's
    assert abs(finished.objective - exact.objective) < 1e-6 * exact.objective


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_where_a_step_of_the_sqp_fails_ipopt_solves_with_a_note(swing, monkeypatch):
    """solver="sqp": a step that fails (here every QP's), or iterations that end without
    converging, hand the mesh to IPOPT from the same start, which says so and reaches IPOPT's
    optimum; a problem the SQP does not cover is still an error saying why."""
    from lagrgen.collocation import sqp
    prob, first, replan = swing_replan(swing)

    def stalled(*args, **kwargs):
        raise sqp.Unsupported("the QP's interior point did not converge in 60 iterations")
    monkeypatch.setattr(sqp, "solve_qp", stalled)
    taken = prob.resolve(first, solver="sqp", **replan)
    by_ipopt = prob.resolve(first, solver="ipopt", **replan)
    assert taken.success and taken.solver == "ipopt"
    said = [n for n in taken.notes if "structured SQP failed" in n]
    assert len(said) == 1 and "interior point did not converge" in said[0]
    assert taken.objective == pytest.approx(by_ipopt.objective, rel=1e-12)
    monkeypatch.undo()
    monkeypatch.setattr(sqp, "SQP_ITERATIONS", 1)
    short = prob.resolve(first, solver="sqp", **replan)
    assert short.success and short.solver == "ipopt"
    said = [n for n in short.notes if "structured SQP failed" in n]
    assert len(said) == 1 and "not converged in 1 iterations" in said[0]
    assert short.objective == pytest.approx(by_ipopt.objective, rel=1e-12)
    free = lagrgen.Collocation(swing[1], nodes=11, duration=(1.0, 4.0))
    free.initial(q=[0.0], qd=[0.0]).final(q=[np.pi], qd=[0.0]).minimize(time=True)
    with pytest.raises(lagrgen.errors.LagrgenError, match="cannot solve this problem: .*free "
                       "duration"):
        free.solve(progress=False, mesh_tol=None, solver="sqp")


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_a_state_that_leaves_its_bound_between_the_points_is_said(swing):
    """Issue 45 item 4 (states): collocation bounds q̇ at its points; where the velocity rides its
    bound, the interpolant between points goes beyond it, and the result says by how much
    (bound_excursions, a note), as a dense sampling of state_at finds it."""
    model, mod = swing
    T, = model.input_functions
    res = swing_problem(mod, T, limit=20.0).solve(progress=False, mesh_tol=None)
    found = res.bound_excursions()
    assert set(found) == {"theta_dot"}
    excess, when = found["theta_dot"]
    dense = np.abs(res.state_at(np.linspace(0.0, res.duration, 20001))[1]) - 4.0
    assert 0.0 < excess and abs(excess - dense.max()) < 0.05 * dense.max()
    assert any("theta_dot leaves its bound" in note for note in res.notes)
    free = lagrgen.Collocation(mod, nodes=21, duration=3.0)
    free.initial(q=[0.0], qd=[0.0]).final(q=[np.pi], qd=[0.0]).minimize(integral=T ** 2)
    assert free.solve(progress=False, mesh_tol=None).bound_excursions() == {}


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_a_least_time_motion_keeps_its_states_within_their_bounds_between_the_points(swing):
    """With a free duration the states' cubics are held within their bounds by their Bernstein
    coefficients (two rows an interval for each bounded state): a least-time swing that rides
    its velocity limit stays within it everywhere (sampled densely), where on the same grid with
    a fixed duration the interpolant bulges beyond it; the duration is the least the hulls allow
    (a fixed duration a little shorter cannot be met within them)."""
    model, mod = swing
    T, = model.input_functions

    def problem(duration, nodes=21):
        prob = lagrgen.Collocation(mod, nodes=nodes, duration=duration)
        prob.bound("T", -6.0, 6.0).bound("theta_dot", -4.0, 4.0).bound("theta", -1.0, 4.0)
        return prob.initial(q=[0.0], qd=[0.0]).final(q=[np.pi], qd=[0.0])

    fastest = problem((1.0, 6.0)).minimize(time=True)
    tr = fastest.transcription()
    assert tr.n_hull == 2 * 2 * 20 and tr.n_constraints == tr.hull_row + tr.n_hull
    res = fastest.solve(progress=False, mesh_tol=None)
    assert res.success and res.bound_excursions() == {}
    dense = res.state_at(np.linspace(0.0, res.duration, 20001))
    assert 3.9 < np.abs(dense[1]).max() <= 4.0 + 1e-6
    used = res._transcription
    hulls = used.constraints(res.x)[used.hull_row:]
    assert np.abs(hulls).max() > 4.0 - 1e-6                   # a hull of theta_dot holds it
    assert dense[0].min() >= -1.0 - 1e-6
    fixed = problem(res.duration).minimize(integral=T ** 2).solve(progress=False, mesh_tol=None)
    assert fixed.success and "theta_dot" in fixed.bound_excursions()
    shorter = problem((1.0, 0.999 * res.duration)).minimize(time=True)
    assert not shorter.solve(progress=False, mesh_tol=None, max_iter=200).success


@pytest.mark.filterwarnings("ignore", category=DiscretizationWarning)
def test_terminal_constraints_and_costs(swing):
    """prob.terminal(expr, lo, hi) holds expr at the last node (the same optimum as the final
    value it states); minimize(terminal=cost) adds the cost of the last node: the motion it
    finds is the optimum of the fixed end it reaches, its objective that one's plus the cost.
    The SQP says it does not take them."""
    model, mod = swing
    T, = model.input_functions
    theta = model.q[0]

    def problem():
        prob = lagrgen.Collocation(mod, nodes=31, duration=3.0).bound("T", -20.0, 20.0)
        return prob.initial(q=[0.0], qd=[0.0])

    fixed = problem().final(q=[np.pi], qd=[0.0]).minimize(integral=T ** 2)
    reference = fixed.solve(progress=False, mesh_tol=None)
    stated = problem().final(qd=[0.0])
    stated.terminal(sp.cos(theta), -1.0, -1.0).terminal(theta, 0.0, 4.0)
    res = stated.minimize(integral=T ** 2).solve(progress=False, mesh_tol=None)
    assert res.success and abs(res.y[0, -1] - np.pi) < 1e-6
    assert abs(res.objective - reference.objective) < 1e-6 * reference.objective
    w = 20.0
    costed = problem().final(qd=[0.0]).minimize(integral=T ** 2,
                                                 terminal=w * (theta - np.pi) ** 2)
    soft = costed.solve(progress=False, mesh_tol=None)
    end = soft.y[0, -1]
    assert soft.success and 1.0 < end < np.pi - 1e-3
    same_end = problem().final(q=[end], qd=[0.0]).minimize(integral=T ** 2)
    hard = same_end.solve(progress=False, mesh_tol=None)
    assert abs(soft.objective - (hard.objective + w * (end - np.pi) ** 2)) \
        < 1e-6 * soft.objective
    with pytest.raises(lagrgen.errors.LagrgenError, match="terminal"):
        stated.solve(progress=False, mesh_tol=None, solver="sqp")
