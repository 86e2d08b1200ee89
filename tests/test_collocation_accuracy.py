"""Optimal motions you can trust (issue 36): each solution's dynamics error measured per interval,
mesh refinement until it is within mesh_tol (the brachistochrone against the cycloid, a bang-bang
switch located, the stop at the tolerance), no false success on a coarse grid, a default start
that solves opty's swing-up; models of any formulation; limits as bounds; and the checks of
issue 37 (standard errors of undetermined parameters, check()'s time limit, bad arguments)."""
import warnings

import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose
from scipy.optimize import brentq

import lagrgen
from lagrgen.collocation.accuracy import interval_errors
from lagrgen.collocation.refine import DiscretizationWarning, inputs_switching
from lagrgen.errors import LagrgenError, ModelError, UnknownNameError
from conftest import damped_oscillator, double_integrator

pytest.importorskip("cyipopt", reason="IPOPT (pip install 'lagrgen[optimize]') is not installed")

G = 9.81
END = (2.0, -1.0)           # where the bead goes, from rest at the origin


@pytest.fixture(scope="module")
def out_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("collocation_accuracy")


@pytest.fixture(scope="module")
def bead(out_dir):
    """A bead at (x, y) under gravity, the wire's reaction N·(−ẏ, ẋ) an input normal to its
    velocity: it turns the bead and does no work."""
    model = lagrgen.Model("accuracy_bead")
    x, y = model.coordinates("x y")
    g, = model.parameters(g=G)
    N, = model.inputs("N")
    t = model.t
    model.particle(1, sp.Matrix([x, y]))
    model.potential_energy(g * y)
    model.force(sp.Matrix([-N * y.diff(t), N * x.diff(t)]), at=sp.Matrix([x, y]))
    return model, lagrgen.build(model, out_dir=out_dir)


@pytest.fixture(scope="module")
def integrator(out_dir):
    """ẍ = F."""
    model = double_integrator("accuracy_integrator")
    return model, lagrgen.build(model, out_dir=out_dir)


@pytest.fixture(scope="module")
def pendulum(out_dir):
    """opty's compound pendulum I·θ̈ + m·g·d·sin θ = T."""
    model = lagrgen.Model("accuracy_pendulum")
    th, = model.coordinates("theta")
    I, m, g, d = model.parameters(I=1.0, m=1.0, g=G, d=1.0)
    T, = model.inputs("T")
    model.kinetic_energy(I * th.diff(model.t) ** 2 / 2)
    model.potential_energy(-m * g * d * sp.cos(th))
    model.torque(T, th)
    return model, lagrgen.build(model, out_dir=out_dir)


def cycloid():
    """(a, φ_f, T) of the cycloid x = a(φ − sin φ), y = −a(1 − cos φ) through END: the
    brachistochrone, travelled with φ = √(g/a)·t."""
    ratio = END[0] / -END[1]
    phi = brentq(lambda f: (f - np.sin(f)) / (1 - np.cos(f)) - ratio, 1e-3, 2 * np.pi - 1e-3)
    a = -END[1] / (1 - np.cos(phi))
    return a, phi, phi * np.sqrt(a / G)


def brachistochrone(mod, nodes):
    prob = lagrgen.Collocation(mod, nodes=nodes, duration=(0.1, 3.0))
    prob.bound("N", -10.0, 10.0)
    prob.initial(q=[0.0, 0.0], qd=[0.0, 0.0]).final(q=list(END))
    return prob.minimize(time=True)


# -- the brachistochrone -------------------------------------------------------------------
def test_the_brachistochrone_by_minimum_time_is_the_cycloid(bead):
    """No effort term: on its own grid the input chatters between its bounds and the scheme
    gains energy (the time beats the cycloid's, the error says so); refined by default, the
    time is the cycloid's to 1e-5 and the bead is on the cycloid at every node."""
    _, mod = bead
    a, phi_end, T = cycloid()
    res = brachistochrone(mod, 21).solve(progress=False)
    assert res.success and res.error <= 1e-6
    assert len(res.meshes) >= 2 and res.meshes[0].error > 1e-3
    assert res.meshes[0].objective < T * (1 - 1e-3)           # the exploit, caught
    assert abs(res.duration / T - 1) < 1e-5
    phi = np.sqrt(G / a) * res.t
    assert_allclose(res.y[0], a * (phi - np.sin(phi)), atol=1e-4)
    assert_allclose(res.y[1], -a * (1 - np.cos(phi)), atol=1e-4)
    assert res.errors.shape == (res.t.size - 1,) and res.error == res.errors.max()
    assert res.iterations == sum(m.iterations for m in res.meshes)
    assert "dynamics error" in res.summary()


def test_a_coarse_grid_no_longer_reports_a_false_success(bead):
    """The chattering optimum of 11 nodes: with no mesh left to refine, success is False with a
    message saying what to do; on the given grid alone (mesh_tol=None) IPOPT's success stands
    but the error is reported and warned about."""
    _, mod = bead
    _, _, T = cycloid()
    stuck = brachistochrone(mod, 11).solve(progress=False, max_meshes=1)
    assert not stuck.success and stuck.status == 0
    assert stuck.duration < T * (1 - 1e-3) and stuck.error > 1e-3
    assert "exceeds mesh_tol=1e-06" in stuck.message and "max_meshes" in stuck.message
    with pytest.warns(DiscretizationWarning, match="dynamics error of this solution is"):
        alone = brachistochrone(mod, 11).solve(progress=False, mesh_tol=None)
    assert alone.success and alone.error == pytest.approx(stuck.error)
    assert alone.mesh_tol is None and len(alone.meshes) == 1
    assert inputs_switching(alone, alone._problem, alone._layout.node_fractions) == {0}


@pytest.mark.parametrize("bounds, values, tied", [
    ((-1.0, 1.0), [1, 1, 0.5, 0, -0.5, -1, -1, -1, -1, -1, -1], True),      # a switch
    ((-1.0, 1.0), [1, 1, 0.5, 0, 0, 0, 0, 0, -0.5, -1, -1], False),         # far apart
    ((-1.0, 1.0), [1, 0.2, 1, 0.3, 0.1, 0, 0, 0, 0, 0, 0], True),           # back to a bound
    ((-1.0, 1.0), [0.2, 0.3, 1, 1, 1, 0.5, 0, 0, 0, 0, 0], False),          # one arc on it
    ((0.0, np.inf), [0, 0.5, 0, 0.6, 0, 0.4, 0.2, 0.1, 0.3, 0.2, 0.1], True),   # one-sided
    ((0.0, np.inf), [0, 0, 0, 0.2, 0.4, 0.6, 0.8, 0.9, 1, 1, 1], False),
    ((-np.inf, np.inf), [1, -1, 1, -1, 1, -1, 1, -1, 1, -1, 1], False),     # no bound
])
def test_which_inputs_chatter_or_switch(bounds, values, tied):
    """`inputs_switching` on point values over 10 control intervals of one point each: an input
    that comes back to a bound, or crosses from one to the other within SWITCH_SPAN + 1
    intervals, is tied; one arc on a bound, or bounds reached far apart, is not."""
    from types import SimpleNamespace
    fractions = np.linspace(0.0, 1.0, 11)
    result = SimpleNamespace(_layout=SimpleNamespace(fractions=fractions, nu=1),
                             _point_values=lambda kind, k: np.asarray(values, float))
    problem = SimpleNamespace(_bounds={("u", 0): bounds}, _given=set())
    assert inputs_switching(result, problem, tuple(fractions)) == (
        frozenset({0}) if tied else frozenset())


def test_only_an_input_that_switches_between_its_bounds_is_tied(integrator, pendulum):
    """The refinement ties an input to the problem's grid when it goes from one bound to the
    other within a few control intervals (a bang-bang switch; the chatter above), not when it
    rides one bound (a least-time robot's burst at its torque limit, tied, was held to a
    quadratic over an interval longer than the burst)."""
    model, mod = pendulum
    T, = model.input_functions
    rides = lagrgen.Collocation(mod, nodes=21, duration=3.0)
    rides.bound("T", -10.0, 5.0)
    rides.initial(q=[0.0], qd=[0.0]).final(q=[np.pi], qd=[0.0]).minimize(integral=T ** 2)
    res = rides.solve(progress=False)
    assert res.success and res.error <= 1e-6
    first = res.meshes[0]
    on_bound = res._point_values("u", 0) >= 5.0 - 1e-3 * 15.0
    assert on_bound.sum() >= 3 and res._point_values("u", 0).min() > -9.0
    assert inputs_switching(res, rides, res._layout.node_fractions) == frozenset()
    assert len(res.meshes) >= 2 and first.nodes == 21
    bang = lagrgen.Collocation(integrator[1], nodes=41, duration=(0.5, 5.0))
    bang.bound("F", -1.0, 1.0)
    bang.initial(q=[0.0], qd=[0.0]).final(q=[1.0], qd=[0.0]).minimize(time=True)
    with pytest.warns(DiscretizationWarning):
        coarse = bang.solve(progress=False, mesh_tol=None)
    assert inputs_switching(coarse, bang, bang.layout.node_fractions) == {0}


# -- the error estimate -------------------------------------------------------------------------
def test_the_error_estimate_is_each_interval_s_local_error(integrator, pendulum):
    """Hermite–Simpson is exact on the cubic of the minimum-effort double integrator (error at
    round-off); the trapezoidal rule's local error falls as h³ (halving h divides it by 8); and
    the estimate agrees with the local error measured by a re-simulation of one interval."""
    model, mod = integrator
    F, = model.input_functions
    exact = lagrgen.Collocation(mod, nodes=11, duration=1.0)
    exact.initial(q=[0.0], qd=[0.0]).final(q=[1.0], qd=[0.0]).minimize(integral=F ** 2)
    assert exact.solve(progress=False).error < 1e-12
    pmodel, pmod = pendulum
    T, = pmodel.input_functions
    largest = []
    for nodes in (21, 41):
        prob = lagrgen.Collocation(pmod, nodes=nodes, duration=2.0, scheme="trapezoidal")
        prob.initial(q=[0.0], qd=[0.0]).final(q=[1.0], qd=[0.0]).minimize(integral=T ** 2)
        with pytest.warns(DiscretizationWarning):
            res = prob.solve(progress=False, mesh_tol=None)
        largest.append(res.error)
    assert 6 < largest[0] / largest[1] < 10
    k = int(np.argmax(res.errors))
    piece = lagrgen.simulate(pmod, (res.t[k], res.t[k + 1]), res.y[:, k],
                             inputs=res.input_signals(), rtol=1e-12, atol=1e-12,
                             t_eval=[res.t[k + 1]])
    scale = 1 + np.abs(res._layout.point_block(res.x)[:, :2]).max(axis=0)
    end = np.abs(piece.y[:, -1] - res.y[:, k + 1]) / scale
    assert end.max() == pytest.approx(res.errors[k], rel=0.3)
    assert_allclose(interval_errors(res), res.errors, rtol=1e-6)


def test_refinement_stops_at_the_tolerance(pendulum):
    """For each tolerance the refinement stops at the first mesh within it: every mesh before
    the last is above it, the last below, and a tighter tolerance takes more nodes."""
    model, mod = pendulum
    T, = model.input_functions
    nodes = {}
    for tol in (1e-4, 1e-8):
        prob = lagrgen.Collocation(mod, nodes=11, duration=3.0)
        prob.bound("T", -6.0, 6.0)
        prob.initial(q=[0.0], qd=[0.0]).final(q=[np.pi], qd=[0.0]).minimize(integral=T ** 2)
        res = prob.solve(progress=False, mesh_tol=tol)
        assert res.success and res.error <= tol
        assert all(m.error > tol for m in res.meshes[:-1]) and len(res.meshes) >= 2
        assert [m.nodes for m in res.meshes] == sorted(m.nodes for m in res.meshes)
        nodes[tol] = res.t.size
        assert res.check() < 1e3 * tol               # the motion the inputs produce
    assert nodes[1e-8] > nodes[1e-4]
    _check_error_plot(res)


def _check_error_plot(res):
    """plot_errors draws one step curve per mesh, each the mesh's errors, and the tolerance,
    with the legend outside the axes (no curve hidden behind it)."""
    fig = res.plot_errors()
    ax = fig.axes[0]
    labels = ax.get_legend_handles_labels()[1]
    assert labels[:len(res.meshes)] == [
        f"mesh {k}: {m.nodes} nodes, largest {m.error:.1e}" for k, m in enumerate(res.meshes, 1)]
    assert labels[-1] == f"mesh_tol {res.mesh_tol:g}"
    steps = [p for p in ax.patches if hasattr(p, "get_data")]
    assert len(steps) == len(res.meshes)
    for patch, mesh in zip(steps, res.meshes):
        values, edges = patch.get_data()[:2]
        np.testing.assert_allclose(edges, mesh.times)
        np.testing.assert_allclose(values, np.maximum(mesh.errors, 1e-16))
    fig.canvas.draw()
    legend = ax.get_legend().get_window_extent()
    assert legend.x0 >= ax.get_window_extent().x1


def _mesh(times, errors):
    from lagrgen.collocation.result import MeshRecord
    return MeshRecord(len(times), 0, float(max(errors)), 0.0, 0, 0.0, np.asarray(times, float),
                      np.asarray(errors, float))


@pytest.mark.parametrize("order", [4.0, 2.5, 1.5])
def test_the_order_a_refinement_showed_is_measured_per_interval(order):
    """Intervals of errors e = C·h^(p+1), split into 2 to 4 pieces whose errors follow the same
    law: `observed_orders` gives each piece p back (the duration scaled, as a free one is); an
    interval not split, one within mesh_tol and pieces of error 0 say nothing (ORDER); a piece
    that gained less than order 1 gets LEAST_ORDER."""
    from lagrgen.collocation.refine import LEAST_ORDER, ORDER, observed_orders
    coarse = np.linspace(0.0, 1.0, 11)
    h = np.diff(coarse)
    C = np.linspace(1.0, 30.0, 10) / h[0] ** (order + 1) * 1e-4
    pieces = np.array([2, 3, 4, 2, 3, 4, 2, 3, 4, 1])
    fine, errors = [0.0], []
    for k, c in enumerate(pieces):
        fine += list(coarse[k] + h[k] * np.arange(1, c + 1) / c)
        errors += [C[k] * (h[k] / c) ** (order + 1)] * c
    before, after = _mesh(2.5 * coarse, C * h ** (order + 1)), _mesh(2.5 * np.asarray(fine), errors)
    orders = observed_orders([before, after], 1e-6)
    assert orders.shape == (len(fine) - 1,)
    assert_allclose(orders[:-1], order, rtol=1e-9)
    assert orders[-1] == ORDER
    tiny = _mesh(2.5 * coarse, np.full(10, 1e-7))
    assert np.all(observed_orders([tiny, after], 1e-6) == ORDER)
    assert np.all(observed_orders([before, _mesh(after.times, np.zeros(len(errors)))], 1e-6)
                  == ORDER)
    stuck = _mesh(after.times, np.repeat(before.errors, pieces))
    assert np.all(observed_orders([before, stuck], 1e-6)[:-1] == LEAST_ORDER)


def test_each_refined_mesh_starts_ipopt_by_how_far_off_its_start_is(pendulum, monkeypatch):
    """The problem's grid starts cold; a refined mesh whose last mesh's error was above
    NEAR·mesh_tol with the "far" options of WARM_STARTS (mu_init 1e-4), one within it with the
    "near" ones (1e-6); each start keeps the last solution on its bounds (bound_push 1e-8). A
    re-plan starts cold. Only the "near" starts take the last mesh's multipliers (solver="ipopt";
    "auto" solves the refined meshes by the SQP)."""
    from lagrgen.collocation import solver
    from lagrgen.collocation.refine import NEAR
    model, mod = pendulum
    T, = model.input_functions
    prob = lagrgen.Collocation(mod, nodes=11, duration=3.0)
    prob.bound("T", -6.0, 6.0)
    prob.initial(q=[0.0], qd=[0.0]).final(q=[np.pi], qd=[0.0]).minimize(integral=T ** 2)
    seen, options = [], solver.solver_options

    def recording(hessian, tol, max_iter, given, start=None, duals=False):
        chosen = options(hessian, tol, max_iter, given, start, duals)
        seen.append((start, chosen.get("mu_init"), chosen.get("bound_push"),
                     chosen.get("warm_start_init_point")))
        return chosen

    monkeypatch.setattr(solver, "solver_options", recording)
    res = prob.solve(progress=False, mesh_tol=1e-8, solver="ipopt")
    assert res.success and len(res.meshes) >= 3
    kinds = ["near" if m.error <= NEAR * 1e-8 else "far" for m in res.meshes[:-1]]
    assert {"near", "far"} <= set(kinds)
    barrier, duals = {"far": 1e-4, "near": 1e-6}, {"far": None, "near": "yes"}
    assert seen == [(None, None, None, None)] + [(k, barrier[k], 1e-8, duals[k]) for k in kinds]
    seen.clear()
    prob.resolve(warm=res, initial={"q": [0.05], "qd": [0.0]}, mesh_tol=None, solver="ipopt")
    assert seen == [(None, None, None, None)]


def _swing_up_on_its_grid(model, mod, nodes):
    """(problem, result): the pendulum swung up in 3 s with |T| ≤ 6, least ∫T² dt, solved on
    its grid of `nodes` alone."""
    T, = model.input_functions
    prob = lagrgen.Collocation(mod, nodes=nodes, duration=3.0)
    prob.bound("T", -6.0, 6.0)
    prob.initial(q=[0.0], qd=[0.0]).final(q=[np.pi], qd=[0.0]).minimize(integral=T ** 2)
    with pytest.warns(DiscretizationWarning):
        res = prob.solve(progress=False, mesh_tol=None)
    assert res.success
    return prob, res


def test_a_refined_mesh_starts_from_the_last_meshs_multipliers(pendulum):
    """`refined_multipliers` gives back a result's own multipliers on its own mesh, and on a
    mesh of every interval halved the Lagrangian's gradient ∇f + Jᵀλ + z (z: upper minus lower)
    at the interpolated start is a few percent of its terms Jᵀλ: the multipliers are densities
    of time scaled to the finer rows (h for Simpson's defects and the points, h² for
    Hermite's), the end values' multipliers kept as they are; with Hermite's rows scaled by h
    the residual is several times larger."""
    from lagrgen.collocation.guess import initial_guess, refined_multipliers
    from lagrgen.collocation.refine import refined_layout
    model, mod = pendulum
    prob, res = _swing_up_on_its_grid(model, mod, 21)
    same = prob.transcription("exact", res._layout).bound(3.0)
    lam, z = refined_multipliers(same, res)
    assert_allclose(lam, res._lam, rtol=1e-12, atol=1e-14)
    assert_allclose(z, res._z, rtol=1e-12, atol=1e-14)
    halved = refined_layout(res._layout, np.full(20, 1.0), 1e-6, (0.0, 1.0), order=1e3)
    assert halved.nodes == 41
    tr = prob.transcription("exact", halved).bound(3.0)
    x0 = initial_guess(prob, tr, res)
    lam, z = refined_multipliers(tr, res)
    J = np.zeros((tr.n_constraints, tr.layout.size))
    rows, cols = tr.jacobianstructure()
    np.add.at(J, (rows, cols), tr.jacobian(x0))
    grad = tr.gradient(x0)
    terms = np.abs(J.T @ lam).max()
    assert np.abs(grad + J.T @ lam + z).max() < 0.06 * terms
    per = tr.n_defects // 40
    hermite = tr.defect_row + (np.arange(40)[:, None] * per + np.arange(per // 2, per)).ravel()
    scaled_by_h = lam.copy()
    scaled_by_h[hermite] *= 2.0
    assert np.abs(grad + J.T @ scaled_by_h + z).max() > 0.12 * terms
    assert refined_multipliers(tr, {"q": 0.0}) is None


def test_a_refined_mesh_that_ties_an_input_starts_on_its_ties(pendulum):
    """An input the last mesh left free and the next ties to a coarser control mesh (it reached
    a bound) starts on its control polynomials: every tie row holds at the start, the carriers
    keep the last solution's values, and the interpolated start alone leaves the ties."""
    from lagrgen.collocation.grid import ControlMesh
    from lagrgen.collocation.guess import from_result, initial_guess
    from lagrgen.collocation.refine import refined_layout
    model, mod = pendulum
    prob, res = _swing_up_on_its_grid(model, mod, 21)
    knots = tuple(np.linspace(0.0, 1.0, 6))
    layout = refined_layout(prob.layout, np.full(20, 1e-3), 1e-6, knots)
    tr = prob.transcription("exact", layout, ControlMesh(knots, 2, frozenset({0})))
    ties = len(tr.ties)
    assert ties > 0 and tr.E.shape[0] >= ties
    interpolated, x0 = from_result(prob, tr, res), initial_guess(prob, tr, res)
    off = lambda x: np.abs(tr.E.dot(x)[:ties]).max()           # noqa: E731
    assert off(interpolated) > 0.05 and off(x0) < 1e-12
    carriers = sorted({c for cols, _ in tr.ties for c in cols[1:]})
    assert_allclose(x0[carriers], interpolated[carriers])
    moved = np.flatnonzero(x0 != interpolated)
    u_cols = {tr.layout.index(j, "u", 0) for j in range(tr.layout.points)}
    assert moved.size and set(moved) <= u_cols


def test_a_lower_order_splits_into_more_pieces(pendulum):
    """The next mesh splits an interval for the order given, one for all or one per interval:
    e = 1e-4 at mesh_tol 1e-6 takes ⌈(4·100)^(1/5)⌉ = 4 pieces for Hermite–Simpson's order 4,
    ⌈400^(1/3)⌉ = 8 for order 2."""
    from lagrgen.collocation.refine import refined_layout
    _, mod = pendulum
    layout = lagrgen.Collocation(mod, nodes=3, duration=1.0).layout
    errors = np.array([1e-4, 1e-8])
    assert refined_layout(layout, errors, 1e-6, (0.0, 1.0)).nodes == 3 + 3
    assert refined_layout(layout, errors, 1e-6, (0.0, 1.0), order=2.0).nodes == 3 + 7
    layout = lagrgen.Collocation(mod, nodes=5, duration=1.0).layout
    errors, orders = np.array([1e-4, 1e-4, 1e-8, 1e-8]), np.array([2.0, 4.0, 4.0, 4.0])
    assert refined_layout(layout, errors, 1e-6, (0.0, 1.0), orders).nodes == 5 + 7 + 3


# -- bang-bang ------------------------------------------------------------------------------------
@pytest.mark.parametrize("scheme", ["hermite-simpson", "trapezoidal", "backward-euler"])
def test_a_bang_bang_switch_is_located(integrator, scheme):
    """From rest at 0 to rest at 1 in the least time with |F| ≤ 1: full push, then full brake,
    switching at t = 1 of T = 2. The switch lies inside one control interval of the grid (41
    nodes: 0.05 s); the refinement narrows it to under √mesh_tol of the duration."""
    _, mod = integrator
    prob = lagrgen.Collocation(mod, nodes=41, duration=(0.5, 5.0), scheme=scheme)
    prob.bound("F", -1.0, 1.0)
    prob.initial(q=[0.0], qd=[0.0]).final(q=[1.0], qd=[0.0]).minimize(time=True)
    res = prob.solve(progress=False)
    assert res.success and res.error <= 1e-6
    assert res.duration == pytest.approx(2.0, rel=1e-6)
    u, t = res._point_values("u", 0), res.t_points
    j = np.flatnonzero((u[:-1] > 0) & (u[1:] <= 0))
    assert j.size == 1
    assert t[j[0]] >= 1.0 - 2e-3 and t[j[0] + 1] <= 1.0 + 2e-3
    assert_allclose(u[t < 0.99], 1.0, atol=1e-4)
    assert_allclose(u[t > 1.01], -1.0, atol=1e-4)


# -- the default start --------------------------------------------------------------------------
def test_the_default_start_solves_opty_s_swing_up(pendulum):
    """opty's fixed-duration swing-up (backward Euler, 501 nodes, |T| ≤ 2, 10 s) from no guess:
    on its own grid opty's optimum 15.641554 (straight lines between the end states stopped at a
    local infeasibility, 39.9); refined, the continuous optimum 9.313947 (Hermite–Simpson on
    1001 nodes gives 9.3139466)."""
    model, mod = pendulum
    T, = model.input_functions
    prob = lagrgen.Collocation(mod, nodes=501, duration=10.0, scheme="backward-euler")
    prob.bound("T", -2.0, 2.0)
    prob.initial(q=[0.0], qd=[0.0]).final(q=[np.pi], qd=[0.0]).minimize(integral=T ** 2)
    with pytest.warns(DiscretizationWarning):
        grid = prob.solve(progress=False, mesh_tol=None)
    assert grid.success and grid.objective == pytest.approx(15.641554, rel=1e-6)
    refined = prob.solve(progress=False)
    assert refined.success and refined.error <= 1e-6
    assert refined.objective == pytest.approx(9.313947, rel=1e-6)


def test_the_default_start_is_a_motion_of_the_model(integrator):
    """Between given end states: the cubic through them, its accelerations, and the inputs that
    make it a motion (here F = ẍ), so every residual and defect holds before the first step."""
    model, mod = integrator
    F, = model.input_functions
    prob = lagrgen.Collocation(mod, nodes=11, duration=2.0)
    prob.initial(q=[0.0], qd=[0.0]).final(q=[1.0], qd=[0.0]).minimize(integral=F ** 2)
    from lagrgen.collocation.guess import default_guess
    tr = prob.transcription()
    x = default_guess(prob, tr)
    assert np.abs(tr.constraints(x)).max() < 1e-12
    s = tr.layout.fractions
    assert_allclose(tr.layout.point_block(x)[:, 0], 3 * s ** 2 - 2 * s ** 3, atol=1e-12)


# -- formulations, limits -------------------------------------------------------------------------
def test_models_of_every_formulation_are_accepted(out_dir):
    """A three-link chain built with formulation "dense", "recursive" and None: the same optimum
    (a build with a formulation asked for was refused as 'changed after it was built')."""
    model = lagrgen.Model("accuracy_chain")
    q = model.coordinates("q0 q1 q2")
    tau = model.inputs("tau0 tau1 tau2")
    point = sp.Matrix([0, 0])
    for i in range(3):
        point = point + sp.Matrix([sp.sin(q[i]), -sp.cos(q[i])])
        model.particle(1, point)
        model.potential_energy(G * point[1])
        model.torque(tau[i], q[i] - (q[i - 1] if i else 0))
    objectives = {}
    for formulation in ("dense", "recursive", None):
        mod = lagrgen.build(model, out_dir=out_dir, formulation=formulation)
        prob = lagrgen.Collocation(mod, nodes=21, duration=1.0)
        prob.initial(q=[0, 0, 0], qd=[0, 0, 0]).final(q=[0.3, 0.3, 0.3], qd=[0, 0, 0])
        res = prob.minimize(integral=sum(t ** 2 for t in tau)).solve(progress=False)
        assert res.success
        objectives[formulation or "auto"] = res.objective
        assert mod.formulation == (formulation or "dense")
    assert objectives["recursive"] == pytest.approx(objectives["dense"], rel=1e-9)
    assert objectives["auto"] == pytest.approx(objectives["dense"], rel=1e-9)


def test_limits_are_declared_kept_and_made_bounds(out_dir):
    model = lagrgen.Model("accuracy_limits")
    a, b = model.coordinates("a b")
    model.inputs("tau_a")
    model.particle(1, sp.Matrix([a, b]))
    model.generalized_force(a, model.input_functions[0])
    model.limit("a", -1.0, 2.0, velocity=3.0, effort=0.5)
    model.limit(b, upper=1.5)
    expected = {"a": (-1.0, 2.0, 3.0, 0.5), "b": (None, 1.5, None, None)}
    assert model.limits == expected
    for bad, error in ((("z",), UnknownNameError), (("a", 2.0, 1.0), ModelError),
                       (("a", None, None, -1.0), ModelError),
                       (("a", None, None, None, float("nan")), ModelError),
                       (("a", float("inf")), ModelError), (("a", "x"), ModelError)):
        with pytest.raises(error):
            model.limit(*bad)
    assert model.limits == expected
    cmod = lagrgen.build(model, out_dir=out_dir)
    pmod = lagrgen.build(model, backend="python")
    assert cmod.limits == pmod.limits == expected
    prob = lagrgen.Collocation(cmod, nodes=11, duration=1.0).bound_limits()
    tr = prob.transcription()
    L = tr.layout
    for kind, i, lo, hi in (("q", 0, -1, 2), ("qd", 0, -3, 3), ("u", 0, -0.5, 0.5),
                            ("q", 1, -np.inf, 1.5), ("qd", 1, -np.inf, np.inf)):
        j = L.index(2, kind, i)
        assert (tr.lo[j], tr.hi[j]) == (lo, hi)
    prob.initial(q=[0.0, 0.0], qd=[0.0, 0.0]).final(q={"a": 0.1}, qd={"a": 0.0})
    res = prob.minimize(time=False, integral=model.input_functions[0] ** 2).solve(progress=False)
    assert res.success and np.abs(res.u).max() == pytest.approx(0.5, abs=1e-6)   # it binds
    bare = lagrgen.Model("accuracy_unlimited")
    c, = bare.coordinates("c")
    bare.particle(1, sp.Matrix([c]))
    with pytest.raises(LagrgenError, match="declares no limits"):
        lagrgen.Collocation(lagrgen.build(bare, out_dir=out_dir), 5, 1.0).bound_limits()


# -- issue 37: standard errors, check(), arguments -------------------------------------------------
@pytest.fixture(scope="module")
def oscillator(out_dir):
    """m·ẍ + c·ẋ + k·x = F, with a parameter `ghost` in no equation."""
    model = damped_oscillator("accuracy_oscillator", ghost=1.0)
    return model, lagrgen.build(model, out_dir=out_dir)


def record(mod, forced, noise, seed=1):
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0.0, 6.0, 120))
    shaker = lagrgen.Signal(np.linspace(0, 6, 61), np.sin(1.7 * np.linspace(0, 6, 61)))
    inputs = {"F": shaker if forced else 0.0}
    motion = lagrgen.simulate(mod, (0, 6), [0.5, 0.0], inputs=inputs, t_eval=t, rtol=1e-10,
                              atol=1e-12)
    return t, motion.y[0] + noise * rng.standard_normal(t.size), inputs["F"]


def identification(mod, unknown, t, data, push, **params):
    prob = lagrgen.Collocation(mod, nodes=81, duration=6.0, unknown_params=unknown,
                               params=params)
    prob.input("F", push)
    return prob.track(t, data, "x", weights=1 / 0.01 ** 2)


def test_parameters_the_data_cannot_determine_get_infinite_standard_errors(oscillator):
    """`ghost` in no equation, from noise-free data: inf and named alone (it was 1 ± 0.0232);
    a free vibration determines only k/m and c/m: m, k and c scaled together is named, all
    three inf (a mass of 0.0055 ± 0.00086 came back); k alone keeps its finite error; an
    estimate on its bound is flagged."""
    _, mod = oscillator
    t, data, push = record(mod, forced=True, noise=0.0)
    with pytest.warns(lagrgen.IdentifiabilityWarning, match=r"do not determine ghost .*ghost "
                                                            r"alone"):
        res = identification(mod, ["k", "ghost"], t, data, push, k=3.0).solve(progress=False)
    assert res.success and res.unidentified == ("ghost",)
    assert "ghost = 1 (the data do not determine it)" in res.summary()
    assert res.stderr["ghost"] == np.inf and 0 < res.stderr["k"] < 1e-4
    assert res.params["k"] == pytest.approx(4.0, rel=1e-5)
    t, data, push = record(mod, forced=False, noise=0.0)
    free = identification(mod, ["m", "k", "c"], t, data, push, k=3.0)
    truth = {"params": {"m": 1.0, "k": 4.0, "c": 0.3}}
    with pytest.warns(lagrgen.IdentifiabilityWarning, match=r"δm : δk : δc = 0\.25 : 1 : "
                                                            r"0\.075"):
        res = free.solve(progress=False, guess=truth)
    assert res.success and set(res.unidentified) == {"m", "k", "c"}
    assert all(res.stderr[n] == np.inf for n in ("m", "k", "c"))
    res = free.solve(progress=False)      # from the data alone: the scale collapses (θ → 0)
    assert not res.success or all(res.stderr[n] == np.inf for n in ("m", "k", "c"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", lagrgen.IdentifiabilityWarning)
        alone = identification(mod, ["k", "c"], t, data, push, k=3.0).solve(progress=False)
    assert alone.params["k"] == pytest.approx(4.0, rel=1e-5)
    assert 0 < alone.stderr["k"] < 1e-6 and 0 < alone.stderr["c"] < 1e-6
    t, data, push = record(mod, forced=True, noise=0.01)
    bounded = identification(mod, ["k"], t, data, push, k=3.0).bound("k", 3.0, 3.5)
    with pytest.warns(lagrgen.FitWarning, match=r"on their bounds: k = 3\.5 \(upper bound\)"):
        res = bounded.solve(progress=False)
    assert res.at_bounds == ("k",) and "(on a bound)" in res.summary()


def test_a_re_plan_keeps_its_standard_errors_and_warns_of_a_coarse_grid(oscillator):
    """`resolve` on its grid (mesh_tol None, its default) returned stderr NaN and cov None for
    the unknown parameters, and never warned of a large dynamics error; now it gives the
    estimates' errors as `solve` does, and reading the error of a coarse re-plan warns."""
    _, mod = oscillator
    t, data, push = record(mod, forced=True, noise=0.01)
    prob = identification(mod, ["k"], t, data, push, k=3.0)
    res = prob.solve(progress=False)
    again = prob.resolve(res)
    assert again.success and np.isfinite(again.stderr["k"]) and again.cov is not None
    assert again.stderr["k"] == pytest.approx(res.stderr["k"], rel=1e-6)
    coarse = lagrgen.Collocation(mod, nodes=11, duration=6.0, unknown_params=["k"],
                                 params={"k": 3.0})
    coarse.input("F", push).track(t, data, "x", weights=1 / 0.01 ** 2)
    with pytest.warns(DiscretizationWarning):
        first = coarse.solve(progress=False, mesh_tol=None)
    replan = coarse.resolve(first)
    with pytest.warns(DiscretizationWarning, match="dynamics error of this solution"):
        assert replan.error > 1e-6


def test_tying_an_input_late_in_the_refinement_does_not_cost_the_optimum(pendulum):
    """A least-time swing-up with torque and speed limits, trapezoidal on 21 nodes refined to
    1e-9: its fourth mesh (296 nodes) reached 1.004836 s; the fifth tied the torque (found to
    switch) to one polynomial per interval of the user's 21 knots and returned 1.006341 s as a
    success. A mesh whose new ties cost more than the error allows is solved again untied."""
    _, mod = pendulum
    prob = lagrgen.Collocation(mod, nodes=21, duration=(0.3, 5.0), scheme="trapezoidal")
    prob.bound("T", -15, 15).bound("theta_dot", -4.5, 4.5)
    prob.initial(q=[0.0], qd=[0.0]).final(q=[np.pi], qd=[0.0]).minimize(time=True)
    res = prob.solve(progress=False, mesh_tol=1e-9)
    assert res.success and res.duration == pytest.approx(1.004835, abs=2e-6)
    assert min(m.objective for m in res.meshes) >= res.meshes[-1].objective - 1e-6


def test_check_stops_after_its_time_limit(pendulum):
    """A re-simulation that cannot finish in time (a step limit here) gives an infinite
    deviation with the simulation's message, not hours of stepping."""
    model, mod = pendulum
    T, = model.input_functions
    prob = lagrgen.Collocation(mod, nodes=11, duration=2.0)
    prob.initial(q=[0.0], qd=[0.0]).final(q=[1.0], qd=[0.0]).minimize(integral=T ** 2)
    res = prob.solve(progress=False)
    assert res.check() < 1e-4
    stopped = res.check(max_steps=5)
    assert float(stopped) == np.inf and "step limit max_steps=5" in stopped.message
    assert "stopped early" in stopped.message
    assert res.check(max_wall_time=1e-9).message.count("wall-time limit") == 1


def test_bad_arguments_get_clear_errors(integrator):
    model, mod = integrator
    F, = model.input_functions
    prob = lagrgen.Collocation(mod, 11, 1.0)
    for lo, hi in ((np.inf, np.inf), (-np.inf, -np.inf), (np.inf, 1.0)):
        with pytest.raises(LagrgenError, match="leaves no value"):
            prob.bound("F", lo, hi)
    with pytest.raises(LagrgenError, match="leaves no value"):
        prob.path(F, np.inf, np.inf)
    prob.initial(q=[0.0], qd=[0.0])
    with pytest.raises(LagrgenError, match="value of x at t = t0 is already given"):
        prob.initial(q=[1.0])
    prob.initial(u=[0.0])                      # another variable: fine
    prob.final(q={"x": 1.0})
    with pytest.raises(LagrgenError, match=r"value of x at t = t0 \+ T is already given"):
        prob.final(q=[1.0])
    prob.at(0.5, "x", 0.4)
    with pytest.raises(LagrgenError, match="already given"):
        prob.at(0.5, "x", 0.6)
    prob.at(0.0, "x_dot", 1.0)                 # contradicts initial(qd=0): found at the solve
    prob.minimize(integral=F ** 2)
    with pytest.raises(LagrgenError, match="x_dot at t = 0 contradict"):
        prob.solve(progress=False)
    ok = lagrgen.Collocation(mod, 11, 1.0)
    ok.initial(q=[0.0], qd=[0.0]).final(q=[1.0], qd=[0.0]).minimize(integral=F ** 2)
    for kwargs, match in (
            (dict(tol=-1), "tol must be a positive"), (dict(tol=np.nan), "tol must be"),
            (dict(tol="1e-8"), "tol must be"), (dict(max_iter=2 ** 40), "max_iter must be"),
            (dict(max_iter=1.5), "max_iter must be"), (dict(max_iter=-1), "max_iter must be"),
            (dict(options=[("tol", 1)]), "options must be a dict"),
            (dict(options={1: 2}), "option names are strings"),
            (dict(options={"tol": [1e-3]}), "must be a string or a finite number"),
            (dict(options={"tol": np.inf}), "finite number"),
            (dict(options={"no_such_option": 1}), "no_such_option=1: Tried to set Option: "
                                                  "no_such_option. It is not a valid option"),
            (dict(options={"mu_strategy": "bogus"}), "mu_strategy='bogus': Setting: \"bogus\" "
                                                     "is not a valid setting"),
            (dict(mesh_tol=0.0), "mesh_tol must be"), (dict(mesh_tol="x"), "mesh_tol must be"),
            (dict(max_meshes=0), "max_meshes must be"), (dict(hessian="bfgs"), "hessian")):
        with pytest.raises(LagrgenError, match=match):
            ok.solve(progress=False, **kwargs)
    assert ok.solve(progress=False, mesh_tol=None, options={"constr_mult_init_max": 0}).success
    t = np.linspace(0.0, 1.0, 5)
    with pytest.raises(LagrgenError, match=r"t must be a 1-D array of sample times, got shape "
                                           r"\(1, 5\)"):
        ok.track(t[None, :], t[None, :], "x")
