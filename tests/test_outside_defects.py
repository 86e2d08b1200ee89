"""Defects of the core API found from outside (issue 42's wave), on a two-mass chain: fit_modes
refuses frequencies it would pair wrongly; fit takes the values of the parameters it does not fit
(p=) and Symbols for names; a smooth run has empty transitions and mode; modes(lin) refuses
arguments a linearization cannot take; frequency_response refuses frequencies that are not
finite and takes the input's function; the Python backend refuses unknown build options; the
eigenvalues are in ascending order exactly."""
import warnings

import numpy as np
import pytest
import sympy as sp

import lagrgen

TRUE = {"k1": 30.0, "k2": 20.0}


@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    model = lagrgen.Model("outside_chain2")
    x1, x2 = model.coordinates("x1 x2")
    m1, m2, k1, k2, c1, c2 = model.parameters(m1=1.0, m2=0.5, k1=40.0, k2=25.0, c1=0.4,
                                              c2=0.2)
    F, = model.inputs("F")
    model.particle(m1, [x1])
    model.particle(m2, [x2])
    model.spring(k1, x1)
    model.spring(k2, x2 - x1)
    model.damper(c1, x1)
    model.damper(c2, x2 - x1)
    model.generalized_force(x2, F)
    return model, lagrgen.build(model, out_dir=str(tmp_path_factory.mktemp("outside")),
                                quiet=True)


def test_fit_modes_refuses_frequencies_out_of_order(chain):
    """Paired with the modes in order, [f2, f1] fitted to wrong stiffnesses with success=True;
    ascending, the same fit recovers the truth."""
    model, mod = chain
    truth = lagrgen.modes(mod, [0.0, 0.0], p=TRUE).frequencies_hz
    with pytest.raises(ValueError, match="ascending"):
        lagrgen.fit_modes(mod, [0.0, 0.0], truth[::-1], ["k1", "k2"])
    upd = lagrgen.fit_modes(mod, [0.0, 0.0], truth, ["k1", "k2"])
    assert upd.success
    assert upd.params["k1"] == pytest.approx(30.0, rel=1e-6)
    assert upd.params["k2"] == pytest.approx(20.0, rel=1e-6)


def test_fit_takes_the_unfitted_parameters_values_and_symbols_for_names(chain):
    """Data made with k1 = 30, k2 = 20: fitting k1 alone recovers 30 only with k2 = 20 given
    (p=), not at its default 25; names, initial and bounds may be the model's Symbols; bounds in
    SciPy's form get an error that says a dict is wanted."""
    model, mod = chain
    m1, m2, k1, k2, c1, c2 = model.parameter_symbols
    t = np.linspace(0.0, 3.0, 61)
    y0 = [0.1, -0.05, 0.0, 0.0]
    data = lagrgen.simulate(mod, (0.0, 3.0), y0, params=TRUE, t_eval=t, rtol=1e-10,
                            atol=1e-12).y[:2]
    given = lagrgen.fit(mod, t, data, [k1], y0, initial={k1: 35.0}, bounds={k1: (1.0, 100.0)},
                        p={"k2": 20.0}, rtol=1e-10, atol=1e-12)
    assert given.success and list(given.params) == ["k1"]
    assert given.params["k1"] == pytest.approx(30.0, rel=1e-6)
    default = lagrgen.fit(mod, t, data, ["k1"], y0, rtol=1e-10, atol=1e-12)
    assert abs(default.params["k1"] - 30.0) > 1e-3
    with pytest.raises(TypeError, match="dict"):
        lagrgen.fit(mod, t, data, ["k1"], y0, bounds=([0.0], [100.0]))
    sol = lagrgen.simulate(mod, (0.0, 1.0), y0, sensitivities=[k2])
    named = lagrgen.simulate(mod, (0.0, 1.0), y0, sensitivities=["k2"])
    assert np.array_equal(sol.sensitivities, named.sensitivities)


def test_a_smooth_run_has_no_transitions_and_no_mode(chain):
    model, mod = chain
    for engine in ("native", "scipy"):
        sol = lagrgen.simulate(mod, (0.0, 0.5), [0.1, 0.0, 0.0, 0.0], engine=engine)
        assert sol.transitions == [] and sol.mode == {}


def test_modes_of_a_linearization_refuse_what_it_cannot_take(chain):
    """modes(lin, p=...) returned lin's modes unchanged (a wrong number for the new p)."""
    model, mod = chain
    lin = lagrgen.linearize(mod, [0.0, 0.0])
    for extra in ({"p": {"k1": 200.0}}, {"q0": [0.3, 0.0]}, {"u": [5.0]}, {"t": 1.0}):
        with pytest.raises(TypeError, match="Linearization"):
            lagrgen.modes(lin, **extra)
    stiff = lagrgen.modes(mod, [0.0, 0.0], p={"k1": 200.0}).omega
    assert not np.allclose(stiff, lagrgen.modes(lin).omega)


def test_frequency_response_refuses_frequencies_not_finite_and_takes_the_input_function(chain):
    model, mod = chain
    F, = model.input_functions
    with pytest.raises(ValueError, match="finite"):
        lagrgen.frequency_response(mod, [0.0, 0.0], [np.nan, 1.0], input="F")
    with pytest.raises(ValueError, match="finite"):
        lagrgen.frequency_response(mod, [0.0, 0.0], [np.inf], input="F")
    by_name = lagrgen.frequency_response(mod, [0.0, 0.0], [0.5, 1.0], input="F")
    by_function = lagrgen.frequency_response(mod, [0.0, 0.0], [0.5, 1.0], input=F)
    assert np.array_equal(by_name, by_function)


def test_the_python_backend_refuses_unknown_build_options(chain):
    model, _ = chain
    with pytest.raises(TypeError, match="quite"):
        lagrgen.build(model, backend="python", quite=True)
    assert lagrgen.build(model, backend="python", quiet=True).n_coordinates == 2


def test_eigenvalues_are_in_ascending_order_exactly(chain):
    """An undamped chain's eigenvalues lie on the imaginary axis: their real parts were LAPACK's
    round-off (9e-17, −4e-16, ...), which broke `np.diff(real) >= 0`; they are 0, the order holds
    exactly, and a damped system's conjugate pairs share one real part."""
    model, mod = chain
    undamped = lagrgen.linearize(mod, [0.0, 0.0], p={"c1": 0.0, "c2": 0.0}).eigenvalues
    assert np.all(undamped.real == 0.0) and np.all(np.diff(undamped.imag) > 0)
    damped = lagrgen.linearize(mod, [0.0, 0.0]).eigenvalues
    assert np.all(np.diff(damped.real) >= 0) and np.all(damped.real < 0)
    assert damped[0] == np.conj(damped[1]) and damped[2] == np.conj(damped[3])


def test_a_top_in_steady_precession_is_neutrally_stable_at_every_speed(tmp_path_factory):
    """A heavy symmetric top (Euler angles z-x-z) precessing steadily: its zero roots form a
    Jordan block that round-off splits into ±1e-7 real parts; modes(...).stable was False at
    some speeds and a sweep found four crossings that do not exist. Now stable everywhere, no
    crossings, the nutation frequency as the gyroscopic closed form gives it."""
    from lagrgen import rotation
    model = lagrgen.Model("precessing_top")
    psi, th, phi = model.coordinates("psi th phi")
    m, l, g, I1, I3 = model.parameters(m=1.0, l=0.1, g=9.81, I1=0.01, I3=0.004)
    R = rotation.z(psi) * rotation.x(th) * rotation.z(phi)
    centre = R * sp.Matrix([0, 0, l])
    model.rigid_body_3d(m, [I1, I1, I3], centre, orientation=R)
    model.potential_energy(m * g * centre[2])
    mod = lagrgen.build(model, out_dir=str(tmp_path_factory.mktemp("top")), quiet=True)
    I1p, th0 = 0.01 + 1.0 * 0.1 ** 2, 0.5

    def precession(rate):
        spin = (0.981 / rate + I1p * rate * np.cos(th0)) / 0.004    # m g l = Ω(I3 ω3 − I1' Ω cos θ)
        return [0.0, th0, 0.0], [rate, 0.0, spin - rate * np.cos(th0)], None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")                   # steady motion, not an equilibrium
        for rate in (1.6, 2.0, 3.6):
            assert lagrgen.modes(mod, *precession(rate)[:2]).stable
        sweep = lagrgen.eigenvalue_sweep(mod, np.linspace(1.0, 6.0, 26), precession)
    assert sweep.crossings() == [] and sweep.stable.all()
    rate = sweep.values[3]
    a = 0.004 * (precession(rate)[1][2] + rate * np.cos(th0))           # p_φ = I3·ω3
    b = I1p * rate * np.sin(th0) ** 2 + a * np.cos(th0)                  # p_ψ

    def routh(theta):          # the effective potential of θ with p_ψ and p_φ held
        return (b - a * np.cos(theta)) ** 2 / (2 * I1p * np.sin(theta) ** 2) + 0.981 * np.cos(theta)
    h = 1e-4
    nutation = np.sqrt((routh(th0 + h) - 2 * routh(th0) + routh(th0 - h)) / h ** 2 / I1p)
    assert abs(np.abs(sweep.eigenvalues[3].imag).max() - nutation) < 1e-6 * nutation
