"""Impacts and frictions run as given or refused with a clear error (issues 28 and 32): contacts
that start at their surface, coefficients given as parameter values, solves that make no
progress, duplicate contacts. Each on the native (C) and SciPy engines."""
import time

import numpy as np
import pytest
import sympy as sp

import lagrgen
from lagrgen import ContactError, Model, ModelError

G = 9.81
TOL = dict(rtol=1e-10, atol=1e-12)
ENGINES = ("native", "scipy")


def ball_model():
    model = Model("start_ball")
    y, = model.coordinates("y")
    e, = model.parameters(e=0.8)
    model.particle(1, sp.Matrix([0, y]))
    model.potential_energy(G * y)
    model.impact("floor", y, restitution=e)
    return model


def block_model():
    model = Model("rough_block")
    x, = model.coordinates("x")
    mu, mu_s = model.parameters(mu=0.2, mu_s=0.3)
    model.particle(1, sp.Matrix([x, 0]))
    model.potential_energy(10 * x ** 2 / 2)
    model.friction("floor", x.diff(model.t), G, mu, mu_static=mu_s)
    return model


def touching_floors():
    """Two floors that touch where x = 0 (gaps y and y + x²): a ball falling at x = 0 strikes
    both at once, and their gradients are parallel there (duplicate contacts)."""
    model = Model("touching_floors")
    x, y = model.coordinates("x y")
    model.particle(1, sp.Matrix([x, y]))
    model.potential_energy(G * y)
    model.impact("flat", y, restitution=0.5)
    model.impact("bowl", y + x ** 2, restitution=0.5)
    return model


def walls(name, width, restitution):
    """A particle between walls at x = 0 and x = w, struck with `restitution` at each."""
    model = Model(name)
    x, = model.coordinates("x")
    w, = model.parameters(w=width)
    model.particle(1, sp.Matrix([x, 0]))
    model.potential_energy(G * x)
    model.impact("left", x, restitution=restitution)
    model.impact("right", w - x, restitution=restitution)
    return model


def slot_model():
    """A particle in a slot of width w (walls at x = 0 and x = w)."""
    return walls("slot", 1e-3, 0.0)


def elastic_slot_model():
    """A particle bouncing elastically between walls 1 nm apart (wedged)."""
    return walls("elastic_slot", 1e-9, 1.0)


@pytest.fixture(scope="module")
def built(compile_factory):
    return compile_factory


# -- 28.2: a contact at its surface at the start ---------------------------------------------------
@pytest.mark.parametrize("engine", ENGINES)
def test_a_contact_closing_at_the_start_is_struck_first(built, engine):
    """A ball at the floor moving down at 1 m/s (a state saved at an impact) bounces at t = 0
    with 0.8 m/s instead of sinking through the floor."""
    mod = built(ball_model)
    sol = lagrgen.simulate(mod, (0, 1), [0.0, -1.0], engine=engine, **TOL)
    assert sol.success
    assert sol.transitions[0] == (0.0, "floor", "impact")
    assert sol.t[0] == sol.t[1] == 0.0                 # saved before and after the impact
    assert sol.y[1, 0] == -1.0 and sol.y[1, 1] == pytest.approx(0.8, rel=1e-12)
    assert np.all(sol.y[0] >= -1e-9)
    # it lands again after 2·0.8/g, as a ball thrown up at 0.8 m/s
    assert sol.transitions[1][0] == pytest.approx(2 * 0.8 / G, rel=1e-9)


@pytest.mark.parametrize("engine", ENGINES)
def test_a_contact_at_rest_at_the_start_is_held_and_one_opening_is_free(built, engine):
    mod = built(ball_model)
    rest = lagrgen.simulate(mod, (0, 1), [0.0, 0.0], engine=engine, **TOL)
    assert rest.success and rest.mode == {"floor": "contact"} and rest.transitions == []
    assert np.all(np.abs(rest.y) < 1e-12)
    up = lagrgen.simulate(mod, (0, 1), [0.0, 2.0], engine=engine, **TOL)
    assert up.success and up.transitions[0][2] == "impact"
    assert up.transitions[0][0] == pytest.approx(2 * 2.0 / G, rel=1e-9)
    apex = lagrgen.simulate(mod, (0, 1), [0.0, 2.0], engine=engine, t_eval=[2.0 / G], **TOL)
    assert apex.y[0, 0] == pytest.approx(2.0 ** 2 / (2 * G), rel=1e-9)


def test_a_start_inside_the_surface_is_an_error(built):
    mod = built(ball_model)
    for engine in ENGINES:
        with pytest.raises(ContactError, match="starts inside the surface of impact 'floor'"):
            lagrgen.simulate(mod, (0, 1), [-0.01, 0.0], engine=engine)
    with pytest.raises(ContactError, match="run 1: the run starts inside"):
        lagrgen.simulate_many(mod, (0, 1), [[1.0, 0.0], [-0.01, 0.0]], t_eval=[0, 1])


# -- 28.7: coefficients given as parameters ------------------------------------------------------------
@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("factory, params, message", [
    (ball_model, {"e": 1.5}, "restitution 1.5 .* between 0 and 1"),
    (ball_model, {"e": -0.5}, "restitution -0.5 .* between 0 and 1"),
    (block_model, {"mu": -0.3, "mu_s": 0.3}, "mu = -0.3 .* must be ≥ 0"),
    (block_model, {"mu": 0.2, "mu_s": 0.1}, "mu_static = 0.1 below mu = 0.2"),
])
def test_coefficients_out_of_range_in_the_values_of_a_run_are_errors(built, engine, factory,
                                                                     params, message):
    mod = built(factory)
    with pytest.raises(ContactError, match=message):
        lagrgen.simulate(mod, (0, 1), [1.0, 0.0], params=params, engine=engine)


def test_coefficients_are_checked_for_every_run_of_an_ensemble(built):
    mod = built(ball_model)
    with pytest.raises(ContactError, match="run 2: impact 'floor' has restitution 1.2"):
        lagrgen.simulate_many(mod, (0, 1), [1.0, 0.0], params=[{"e": 0.5}, {"e": 1.0},
                                                                  {"e": 1.2}], t_eval=[0, 1])
    ens = lagrgen.simulate_many(mod, (0, 1), [1.0, 0.0], params=[{"e": 0.0}, {"e": 1.0}],
                                t_eval=[0, 1])
    assert ens.success.all()


def test_declared_friction_coefficients_are_checked_when_declared():
    model = Model("declared")
    x, = model.coordinates("x")
    with pytest.raises(ModelError, match=r"mu_static \(0.1\) must be at least mu \(0.2\)"):
        model.friction("floor", x.diff(model.t), 1.0, 0.2, mu_static=0.1)


# -- 28.9: solves that would never end -----------------------------------------------------------------
@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("rest_velocity", [0.0, 1e-16])
def test_bounces_that_never_come_to_rest_stop_as_making_no_progress(built, engine,
                                                                    rest_velocity):
    """rest_velocity=0 (or below round-off): the bounces of a ball never rest and shrink to
    segments that end where they start; the solve says so instead of running for ever."""
    mod = built(ball_model)
    start = time.monotonic()
    sol = lagrgen.simulate(mod, (0, 6), [1.0, 0.0], engine=engine, rest_velocity=rest_velocity,
                           max_transitions=10 ** 9)
    assert time.monotonic() - start < 20
    assert not sol.success and "made no progress" in sol.message
    assert "rest_velocity" in sol.message and "impact 'floor'" in sol.message
    zeno = np.sqrt(2 / G) * (1 + 2 * 0.8 / (1 - 0.8))
    assert sol.t[-1] == pytest.approx(zeno, abs=1e-4)


@pytest.mark.parametrize("engine", ENGINES)
def test_a_body_wedged_between_two_impacts_stops_on_every_guard(built, engine):
    """Each wall is struck 10⁹ times a second: the guards count over the whole hybrid solve
    (its segments take a few steps each), not per segment."""
    mod = built(elastic_slot_model)
    y0 = [0.5e-9, 1.0]
    sol = lagrgen.simulate(mod, (0, 1), y0, engine=engine, max_transitions=300)
    assert not sol.success and "more than 300 mode switches" in sol.message
    assert len(sol.transitions) == 301
    sol = lagrgen.simulate(mod, (0, 1), y0, engine=engine, max_transitions=10 ** 9, max_steps=400)
    assert not sol.success and "max_steps=400" in sol.message
    assert len(sol.transitions) <= 401 and sol.t[-1] < 1e-6      # one impact at the start
    start = time.monotonic()
    sol = lagrgen.simulate(mod, (0, 1), y0, engine=engine, max_transitions=10 ** 9,
                           max_wall_time=0.3)
    assert time.monotonic() - start < 10
    assert not sol.success and "max_wall_time" in sol.message
    assert np.all(sol.y[0] >= -1e-12) and np.all(sol.y[0] <= 1e-9 + 1e-12)


def test_an_ensemble_run_closing_at_the_start_is_struck_first(built):
    mod = built(ball_model)
    ens = lagrgen.simulate_many(mod, (0, 1), [[0.0, -1.0], [0.0, 0.0], [0.0, 1.0]], workers=1,
                                t_eval=[0.0, 0.05], **TOL)
    assert ens.success.all()
    alone = [lagrgen.simulate(mod, (0, 1), y0, t_eval=[0.0, 0.05], **TOL)
             for y0 in ([0.0, -1.0], [0.0, 0.0], [0.0, 1.0])]
    for run, sol in enumerate(alone):
        np.testing.assert_allclose(ens.y[run], sol.y, rtol=1e-12, atol=1e-15)
    assert alone[0].transitions[0] == (0.0, "floor", "impact")
    assert ens.y[0][1, 1] == pytest.approx(0.8 - G * 0.05, rel=1e-9)     # bounced, not sunk
    assert ens.y[0][0, 1] > 0


# -- 37.3: a closed contact's speed at the start ---------------------------------------------
def rest_speed(gap_tol):
    """The speed of a fall through gap_tol under g: below it a closed gap is at rest."""
    return np.sqrt(2 * gap_tol * G)


def rod_model():
    """A rod (centre x, y, angle th) whose left end touches the floor: gap y − (L/2)·sin th."""
    model = Model("leaning_rod")
    x, y, th = model.coordinates("x y th")
    m, inertia, L = 2.0, 0.5, 1.0
    model.rigid_body(m, inertia, sp.Matrix([x, y]), th)
    model.potential_energy(m * G * y)
    model.impact("end", y - L / 2 * sp.sin(th), restitution=0.5)
    return model


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("gap_tol, speed", [(1e-9, -9e-7), (1e-9, -0.5 * rest_speed(1e-9)),
                                            (1e-6, -0.5 * rest_speed(1e-6)),
                                            (1e-3, -0.5 * rest_speed(1e-3))])
def test_a_contact_closing_slower_than_a_fall_through_gap_tol_is_held_at_rest(built, engine,
                                                                             gap_tol, speed):
    """A ball at the floor closing at less than √(2·gap_tol·g) is at rest: an inelastic impulse
    stops it at t = 0 (a "contact" transition, the states before and after saved) and it stays
    at y = 0 for 1000 s instead of sinking at that speed."""
    mod = built(ball_model)
    sol = lagrgen.simulate(mod, (0, 1000), [0.0, speed], engine=engine, gap_tol=gap_tol,
                           params={"e": 0.5}, **TOL)
    assert sol.success and sol.transitions == [(0.0, "floor", "contact")]
    assert sol.mode == {"floor": "contact"}
    assert sol.t[0] == sol.t[1] == 0.0
    assert sol.y[:, 0].tolist() == [0.0, speed] and sol.y[:, 1].tolist() == [0.0, 0.0]
    assert sol.t[-1] == 1000.0 and np.all(sol.y[:, 1:] == 0.0)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("gap_tol", [1e-9, 1e-6, 1e-3])
def test_a_contact_closing_faster_at_the_start_bounces_and_one_opening_flies(built, engine,
                                                                            gap_tol):
    """At 0.9 m/s (above √(2·gap_tol·g) for every gap_tol here, 0.14 m/s at 1e-3) the ball is
    struck at t = 0 and bounces at e·0.9; moving up at 0.9 m/s it flies and lands 2·0.9/g later
    — not held at the floor, where it sank (or rose) at 0.9 m/s with gap_tol = 1e-3."""
    mod = built(ball_model)
    down = lagrgen.simulate(mod, (0, 2), [0.0, -0.9], engine=engine, gap_tol=gap_tol,
                            params={"e": 0.5}, **TOL)
    assert down.success and down.transitions[0] == (0.0, "floor", "impact")
    assert down.y[1, 1] == pytest.approx(0.45, rel=1e-12)
    assert down.transitions[1][0] == pytest.approx(2 * 0.45 / G, rel=1e-9)
    assert down.y[0].min() >= -gap_tol and down.mode == {"floor": "contact"}
    up = lagrgen.simulate(mod, (0, 2), [0.0, 0.9], engine=engine, gap_tol=gap_tol,
                          params={"e": 0.5}, t_eval=[0.9 / G], **TOL)
    assert up.transitions[0][2] == "impact"
    assert up.transitions[0][0] == pytest.approx(2 * 0.9 / G, rel=1e-9)
    assert up.y[0, 0] == pytest.approx(0.9 ** 2 / (2 * G), rel=1e-9)     # the apex


def test_ensemble_runs_closing_at_the_start_are_held_or_struck_as_alone(built):
    mod = built(ball_model)
    y0 = [[0.0, -0.9], [0.0, -0.1], [0.0, 0.9]]
    t = np.array([0.0, 0.05, 0.5, 1.0, 2.0])
    options = dict(gap_tol=1e-3, params={"e": 0.5}, t_eval=t, **TOL)
    ens = lagrgen.simulate_many(mod, (0, 2), y0, workers=1, **options)
    assert ens.success.all()
    for run, start in enumerate(y0):
        alone = lagrgen.simulate(mod, (0, 2), start, **options)
        np.testing.assert_allclose(ens.y[run], alone.y, rtol=1e-12, atol=1e-15)
        assert ens.transitions[run] == alone.transitions
    assert ens.transitions[1] == [(0.0, "floor", "contact")] and np.all(ens.y[1] == 0.0)
    assert ens.transitions[0][0] == (0.0, "floor", "impact")
    assert ens.y[0][1, 1] == pytest.approx(0.45 - G * t[1], rel=1e-9)      # bounced, not sunk
    assert np.all(ens.y[:, 0] >= -1e-3)


def test_the_impulse_that_holds_a_contact_at_the_start_is_along_the_inverse_mass(built):
    """A rod leaning on one end, closing slowly there: the impulse Λ along the gap's gradient W
    sets ġ = 0 and changes q̇ by M⁻¹·Wᵀ·Λ (x untouched, y and th in the ratio of 1/m to
    −(L/2)·cos th/I), the same on both engines."""
    mod = built(rod_model)
    th, yd, thd = 0.3, 0.1, 0.3
    gap_rate = yd - 0.5 * np.cos(th) * thd                  # −0.043: below √(2·1e-3·g)
    y0 = [0.1, 0.5 * np.sin(th), th, 0.7, yd, thd]
    after = {}
    for engine in ENGINES:
        sol = lagrgen.simulate(mod, (0, 0.01), y0, engine=engine, gap_tol=1e-3, **TOL)
        assert sol.transitions[0] == (0.0, "end", "contact")
        after[engine] = sol.y[:, 1]
    np.testing.assert_allclose(after["native"], after["scipy"], rtol=1e-13, atol=1e-15)
    change = after["native"][3:] - np.array(y0[3:])
    W = np.array([0.0, 1.0, -0.5 * np.cos(th)])
    assert change[0] == 0.0
    assert W @ after["native"][3:] == pytest.approx(0.0, abs=1e-15)
    impulse = change[1] * 2.0
    np.testing.assert_allclose(change, impulse * W / [2.0, 2.0, 0.5], rtol=1e-12)
    assert gap_rate < 0 and impulse > 0


# -- 32.6: duplicate contacts ----------------------------------------------------------------------
def test_duplicate_contacts_are_refused_when_declared():
    model = Model("duplicates")
    y, = model.coordinates("y")
    L, = model.parameters(L=2.0)
    model.impact("floor", y)
    for gap, where in ((y, "the same surface"), (2 * y, "the same surface"),
                       (-y, "the two sides of one surface"), (L * y, "one surface")):
        with pytest.raises(ModelError, match=f"{where} \\(duplicate contacts"):
            model.impact("again", gap)


@pytest.mark.parametrize("engine", ENGINES)
def test_redundant_contacts_found_while_running_are_held(built, engine):
    """Two contacts along one gradient (issue 44: redundant contacts are held, never refused):
    a ball landing where two floors touch rests on both, each carrying half its weight (the
    least-norm forces); a particle wedged in a slot of width 0 rests against the wall gravity
    pushes it on, the other touching it without force."""
    mod = built(touching_floors)
    sol = lagrgen.simulate(mod, (0, 3), [0.0, 1.0, 0.0, 0.0], engine=engine, **TOL)
    assert sol.success and sol.mode == {"flat": "contact", "bowl": "contact"}
    np.testing.assert_allclose([sol.multipliers["flat"][-1], sol.multipliers["bowl"][-1]],
                               [G / 2, G / 2], rtol=1e-6)
    assert abs(sol.y[1, -1]) <= 1.5e-9                      # on the floor, within gap_tol
    slot = built(slot_model)
    sol = lagrgen.simulate(slot, (0, 1), [0.0, 0.0], params={"w": 0.0}, engine=engine, **TOL)
    assert sol.success and sol.mode == {"left": "contact", "right": "open"}
    assert sol.multipliers["left"][-1] == pytest.approx(G) and sol.y[0, -1] == 0.0


# -- 28.13: what a run with impacts or frictions gives back -----------------------------------------
@pytest.mark.parametrize("engine", ENGINES)
def test_contact_and_friction_forces_are_readable(built, engine):
    ball = built(ball_model)
    sol = lagrgen.simulate(ball, (0, 6), [1.0, 0.0], engine=engine, t_eval=[0.1, 5.0, 6.0],
                           **TOL)
    assert sol.contact_names == ("floor",)
    np.testing.assert_allclose(sol.multipliers["floor"], [0.0, G, G], rtol=1e-9)   # m·g at rest
    block = built(block_model)
    held = lagrgen.simulate(block, (0, 1), [0.1, 0.0], engine=engine, **TOL)
    assert held.mode == {"floor": "stick"}
    np.testing.assert_allclose(held.multipliers["floor"], 10 * 0.1, rtol=1e-9)     # = k·x
    sliding = lagrgen.simulate(block, (0, 0.1), [0.0, 1.0], engine=engine, **TOL)
    np.testing.assert_allclose(sliding.multipliers["floor"], -0.2 * G, rtol=1e-12)  # −μ·N


def test_ensembles_carry_contact_forces_and_transitions(built, tmp_path):
    pytest.importorskip("zarr")
    mod = built(ball_model)
    y0 = [[1.0, 0.0], [0.5, 0.0], [0.0, 0.0]]
    t = np.linspace(0, 2, 9)
    ens = lagrgen.simulate_many(mod, (0, 2), y0, t_eval=t, workers=1)
    assert ens.constraint_names == ("floor",) and ens.multipliers.shape == (3, 1, 9)
    for run in range(3):
        one = lagrgen.simulate(mod, (0, 2), y0[run], t_eval=t)
        np.testing.assert_array_equal(ens.multipliers[run, 0], one.multipliers["floor"])
        assert ens.transitions[run] == one.transitions
    ds = ens.to_xarray()
    table = list(zip(ds.transition_run.values.tolist(), ds.transition_time.values.tolist(),
                     ds.transition_element.values.tolist(), ds.transition_kind.values.tolist()))
    assert table == [(run, *tr) for run in range(3) for tr in ens.transitions[run]]
    stored = lagrgen.simulate_many(mod, (0, 2), y0, t_eval=t, workers=1,
                                   store=tmp_path / "ball.zarr")
    for name in ("multipliers", "transition_run", "transition_time", "transition_element",
                 "transition_kind"):
        np.testing.assert_array_equal(stored[name].values, ds[name].values)
    assert all(ens.success) and stored.attrs["messages"] == {}   # normal ends are not listed


def test_bench_times_a_model_with_impacts_with_its_hybrid_methods(built):
    from lagrgen.bench import markdown, runnable_methods, solve_seconds
    mod = built(ball_model)
    runnable, skipped = runnable_methods(mod, ("RK45", "Radau", "LSODA"))
    assert runnable == ["RK45", "Radau"] and list(skipped) == ["LSODA"]
    solves = {m: solve_seconds(mod, [1.0, 0.0], m, (0.0, 1.0), repeats=1) for m in runnable}
    assert all(s["success"] for s in solves.values())
    table = markdown({"name": "ball", "n": 1, "t_span": [0, 1], "rtol": 1e-8, "atol": 1e-8,
                      "build": dict.fromkeys(("cold", "derive", "cse+emit", "compile",
                                              "cached"), 1.0),
                      "calls": {p: dict.fromkeys(("rhs", "jacobian", "rhs_in_c",
                                                  "jacobian_in_c"), 1e-6)
                                for p in ("c", "python")},
                      "solves": {"c": solves, "python": solves}, "skipped": skipped})
    assert "| LSODA | skipped (a model with impacts or frictions runs with" in table


def test_show_lists_impacts_and_frictions():
    from lagrgen.outputs.display import render
    text = render(block_model())
    assert "# friction floor: slip velocity x', normal force 9.81, mu = mu, mu_static = mu_s" \
        in text
    assert "# impact floor: y >= 0, restitution e" in render(ball_model())
    assert "impact floor: $y$ >= 0" in render(ball_model(), latex=True)


def labelled(masses, lengths, g_unit):
    model = Model("labelled")
    y, = model.coordinates("y", units=lengths)
    m, g = model.parameters(m=(1.0, masses) if masses else 1.0, g=(G, g_unit))
    model.particle(m, sp.Matrix([0, y]))
    model.potential_energy(m * g * y)
    return model


@pytest.mark.parametrize("masses, lengths, g_unit, energy", [
    ("kg", "m", "m/s^2", "J"),
    ("g", "mm", "mm/s^2", "1e-09 J"),
    ("kg", "m", "m/s", None),                 # labels that give no energy: no label
    (None, "m", "m/s^2", None),               # a factor without a label: no label
])
def test_energies_carry_the_unit_the_labels_give(masses, lengths, g_unit, energy):
    model = labelled(masses, lengths, g_unit)
    mod = lagrgen.build(model, backend="python")
    for name in ("kinetic_energy", "potential_energy", "total_energy"):
        assert mod.units.get(name) == energy
    sol = lagrgen.simulate(mod, (0, 0.1), [1.0, 0.0])
    table = lagrgen.evaluate_outputs(mod, sol)
    assert table.units.get("total_energy") == energy
