"""Issues 28.4 and 32.4: `fit` and `fit_modes` claim only what the data can see — duplicated
names refused, unidentifiable directions reported with infinite standard errors and a warning
naming them, all-zero weights refused, estimates on their bounds flagged — and their edges (NaN
times, a negative mass at a trial point, infinite frequencies, complex coefficients, huge step
counts) give clear errors."""
import warnings

import numpy as np
import pytest
import sympy as sp

import lagrgen
from lagrgen import FitWarning, MassMatrixError, Model, ModelError


def oscillator():
    """m·ẍ + c·ẋ + k·x = 0, and a parameter z that appears in no equation."""
    model = Model("fit_edges_osc")
    x, = model.coordinates("x")
    m, c, k, z = model.parameters(m=1.0, c=0.4, k=4.0, z=3.0)
    model.particle(m, sp.Matrix([x]))
    model.spring(k, x)
    model.damper(c, x)
    return model


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    mod = lagrgen.build(oscillator(), out_dir=tmp_path_factory.mktemp("fit_edges"))
    t = np.linspace(0, 5, 51)
    truth = lagrgen.simulate(mod, (0, 5), [1.0, 0.0], t_eval=t, rtol=1e-10, atol=1e-12)
    data = truth.y[:1] + 1e-3 * np.random.default_rng(0).standard_normal((1, t.size))
    return mod, t, data


def test_a_parameter_in_no_equation_has_an_infinite_standard_error(record):
    mod, t, data = record
    with pytest.warns(FitWarning, match=r"do not determine z .*rank 1 of 2.*z alone"):
        fit = lagrgen.fit(mod, t, data, ["k", "z"], [1.0, 0.0])
    assert fit.stderr["z"] == np.inf and fit.unidentified == ("z",)
    assert 0 < fit.stderr["k"] < 0.01 and abs(fit.params["k"] - 4.0) < 4 * fit.stderr["k"]
    assert np.isnan(fit.cov[0, 1]) and np.isfinite(fit.cov[0, 0])


def test_an_unseen_combination_is_named_and_gets_no_zero_variance(record):
    """A free response fixes k/m and c/m only: m, k, c scaled together change nothing."""
    mod, t, data = record
    with pytest.warns(FitWarning, match=r"do not determine m, k, c .*rank 2 of 3.*"
                                        r"δm : δk : δc = "):
        fit = lagrgen.fit(mod, t, data, ["m", "k", "c"], [1.0, 0.0],
                          initial={"m": 1.1, "k": 4.1, "c": 0.5},
                          bounds={"m": (0.1, 10), "k": (0.1, 40), "c": (0.01, 4)})
    assert all(fit.stderr[n] == np.inf for n in "mkc")
    direction, = fit.unseen
    ratio = [direction[n] / fit.params[n] for n in "mkc"]      # the direction is ∝ (m, k, c)
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-3)
    assert fit.params["k"] / fit.params["m"] == pytest.approx(4.0, rel=1e-3)


def test_identifiable_fits_raise_no_warning(record):
    mod, t, data = record
    with warnings.catch_warnings():
        warnings.simplefilter("error", FitWarning)
        fit = lagrgen.fit(mod, t, data, ["k", "c", "y0:x"], [1.0, 0.0])
    assert fit.unidentified == () and fit.at_bounds == ()
    assert all(0 < fit.stderr[n] < 0.01 for n in fit.names)


def test_duplicated_names_and_zero_weights_are_refused(record):
    mod, t, data = record
    with pytest.raises(ValueError, match="params names 'k' twice"):
        lagrgen.fit(mod, t, data, ["k", "k"], [1.0, 0.0])
    with pytest.raises(ValueError, match="every weight is zero"):
        lagrgen.fit(mod, t, data, ["k"], [1.0, 0.0], weights=0)
    with pytest.raises(ValueError, match="weights must be finite and non-negative"):
        lagrgen.fit(mod, t, data, ["k"], [1.0, 0.0], weights=np.nan)
    with pytest.raises(ValueError, match="params names 'k' twice"):
        lagrgen.fit_modes(mod, [0.0], [0.3], ["k", "k"])


def test_an_estimate_on_its_bound_is_flagged(record):
    mod, t, data = record
    with pytest.warns(FitWarning, match=r"on their bounds: k = 4\.1 \(lower bound\)"):
        fit = lagrgen.fit(mod, t, data, ["k"], [1.0, 0.0], bounds={"k": (4.1, 5.0)},
                          initial={"k": 4.5})
    assert fit.at_bounds == ("k",) and fit.params["k"] == pytest.approx(4.1)
    with pytest.warns(FitWarning, match=r"on their bounds: k = 5 \(upper bound\)"):
        update = lagrgen.fit_modes(mod, [0.0], [0.5], ["k"], bounds={"k": (1.0, 5.0)})
    assert update.at_bounds == ("k",)


def test_fit_modes_names_what_the_frequencies_do_not_fix(record):
    mod = record[0]
    with pytest.warns(FitWarning, match=r"do not determine m, k .*δm : δk = "):
        update = lagrgen.fit_modes(mod, [0.0], [0.4], ["m", "k"],
                                   bounds={"m": (0.1, 10), "k": (0.1, 40)})
    assert update.unidentified == ("m", "k")
    omega = 2 * np.pi * 0.4
    assert update.params["k"] / update.params["m"] == pytest.approx(omega ** 2, rel=1e-6)


# -- 32.4: the edges --------------------------------------------------------------------------
def test_nan_in_the_sample_times_is_refused(record):
    mod, t, data = record
    t = t.copy()
    t[3] = np.nan
    with pytest.raises(ValueError, match="finite, increasing sample times"):
        lagrgen.fit(mod, t, data, ["k"], [1.0, 0.0])


def test_a_negative_mass_with_sensitivities_is_a_mass_matrix_error(record):
    mod, t, data = record
    for method in ("RK45", "Radau"):
        for engine in ("native", "scipy"):
            with pytest.raises(MassMatrixError, match="not positive definite"):
                lagrgen.simulate(mod, (0, 5), [1.0, 0.0], params={"m": -1.0}, method=method,
                                 sensitivities=["k"], engine=engine)
    with pytest.raises(MassMatrixError, match=r"failed at the trial point m = -1 .*bounds="):
        lagrgen.fit(mod, t, data, ["m"], [1.0, 0.0], initial={"m": -1.0})


def test_fit_modes_refuses_frequencies_that_are_not_finite(record):
    mod = record[0]
    for bad in (np.inf, np.nan, -1.0):
        with pytest.raises(ValueError, match="finite positive frequencies"):
            lagrgen.fit_modes(mod, [0.0], [bad], ["k"])


def test_complex_coefficients_are_model_errors():
    model = Model("complex_coefficients")
    x, = model.coordinates("x")
    m, = model.parameters(m=1.0)
    model.particle(m, sp.Matrix([x]))
    with pytest.raises(ModelError, match=r"restitution: expression I is complex"):
        model.impact("floor", x, restitution=sp.I)
    with pytest.raises(ModelError, match=r"mu: expression .*I.* is complex"):
        model.friction("belt", sp.diff(x, model.t), 1.0, mu=0.3 * sp.I)
    with pytest.raises(ModelError, match="mu_static: expression .* is complex"):
        model.friction("belt", sp.diff(x, model.t), 1.0, mu=0.3, mu_static=1 + sp.I)


def test_a_step_count_beyond_a_c_long_is_a_value_error(record):
    mod = record[0]
    with pytest.raises(ValueError, match="max_steps must be a positive integer"):
        lagrgen.simulate(mod, (0, 1), [1.0, 0.0], max_steps=2**70)


def stiff_oscillator():
    """m·ẍ + c·ẋ + k·x = 0 with k of 5.5e7 N/m (1.2 kHz), and an encoder that counts x/s, s a
    scale of 2.5e-8 m per count."""
    model = Model("fit_stiff")
    x, = model.coordinates("x")
    m, c, k, s = model.parameters(m=1.0, c=300.0, k=5.5e7, s=2.5e-8)
    model.particle(m, sp.Matrix([x]))
    model.spring(k, x)
    model.damper(c, x)
    model.output("counts", x / s)
    return model


@pytest.fixture(scope="module")
def stiff(tmp_path_factory):
    return lagrgen.build(stiff_oscillator(), out_dir=tmp_path_factory.mktemp("fit_stiff"))


def test_fits_do_not_depend_on_the_units_of_the_data(stiff):
    """A stiffness of 6e7 N/m from a 1 µm response in metres: the gradient Jᵀr was below
    least_squares' absolute gtol at the start, and the fit returned its start (5.5e7, 17 of its
    own standard errors off) with success; in micrometres it fitted. Now both find 6e7."""
    t = np.linspace(0, 0.01, 201)
    opts = dict(method="DOP853", rtol=1e-10)
    data = lagrgen.simulate(stiff, (0, 0.01), [1e-6, 0], params={"k": 6e7}, t_eval=t,
                            atol=1e-18, **opts).y[:1]
    for scale in (1.0, 1e6):
        fit = lagrgen.fit(stiff, t, data * scale, ["k"], [1e-6 * scale, 0], atol=1e-18 * scale,
                          **opts)
        assert fit.success and fit.params["k"] == pytest.approx(6e7, rel=1e-7)


def test_a_small_parameter_seen_only_through_an_output_is_fitted(stiff):
    """The encoder's scale s = 2e-8 m per count: the output's derivative stepped s by 1e-7
    (∂counts/∂s came out +3e7 for −7.3e8) and the fit stayed at its start, 2.5e-8."""
    t = np.linspace(0, 0.005, 101)
    opts = dict(method="DOP853", rtol=1e-10, atol=1e-18)
    sol = lagrgen.simulate(stiff, (0, 0.005), [1e-6, 0], t_eval=t, **opts)
    counts = sol.y[0] / 2e-8
    fit = lagrgen.fit(stiff, t, counts, ["s"], [1e-6, 0], measured=["counts"], **opts)
    assert fit.success and fit.params["s"] == pytest.approx(2e-8, rel=1e-7)


def test_fit_modes_updates_a_stiffness_of_any_size(stiff):
    """From 4e8 N/m to a measured 4010.7 Hz (6.35e8 N/m): the fit stopped at its start with
    success; 1.26 times the model's frequency at every size of k now lands on k = m·(2πf)²."""
    for k0 in (4.0, 4e4, 4e8):
        f = 1.26 * np.sqrt(k0) / (2 * np.pi)
        upd = lagrgen.fit_modes(stiff, [0.0], [f], ["k"], initial={"k": k0})
        assert upd.success and upd.params["k"] == pytest.approx((2 * np.pi * f) ** 2, rel=1e-7)


def test_one_sided_bounds_are_open_on_their_none_side(record):
    """bounds={"k": (0, None)} said the start was outside its bounds (None became NaN), and
    (0,) raised an IndexError."""
    mod, t, data = record
    fit = lagrgen.fit(mod, t, data, ["k"], [1.0, 0.0], bounds={"k": (0, None)})
    assert fit.params["k"] == pytest.approx(4.0, rel=1e-3)
    fit = lagrgen.fit(mod, t, data, ["k"], [1.0, 0.0], bounds={"k": (None, 10.0)})
    assert fit.params["k"] == pytest.approx(4.0, rel=1e-3)
    with pytest.raises(ValueError, match=r"bounds\['k'\] must be a pair \(low, high\)"):
        lagrgen.fit(mod, t, data, ["k"], [1.0, 0.0], bounds={"k": (0,)})
    upd = lagrgen.fit_modes(mod, [0.0], [0.4], ["k"], bounds={"k": (0, None)})
    assert upd.params["k"] == pytest.approx((2 * np.pi * 0.4) ** 2, rel=1e-6)


def test_fit_modes_pairs_measured_frequencies_with_elastic_modes(tmp_path):
    """A free-free pair of masses has a rigid-body mode at 0 Hz: its measured elastic frequency
    was paired with it and the fit died in an SVD of NaNs; now k = m/2·(2πf)² exactly. Two
    measured modes whose shapes pair with the same model mode are flagged, not matched."""
    model = Model("fit_free_free")
    x1, x2 = model.coordinates("x1 x2")
    m1, m2, k = model.parameters(m1=1.0, m2=1.0, k=100.0)
    model.particle(m1, sp.Matrix([x1]))
    model.particle(m2, sp.Matrix([x2]))
    model.spring(k, x2 - x1)
    mod = lagrgen.build(model, out_dir=tmp_path)
    upd = lagrgen.fit_modes(mod, [0.0, 0.0], [2.5], ["k"])
    assert upd.success and upd.pairing == (1,)
    assert upd.params["k"] == pytest.approx(0.5 * (2 * np.pi * 2.5) ** 2, rel=1e-8)
    shapes = lagrgen.modes(mod, [0.0, 0.0]).shapes
    alike = np.column_stack([shapes[:, 1], shapes[:, 1] + 0.05])
    with pytest.warns(FitWarning, match="measured modes 0 and 1 are paired with the same"):
        upd = lagrgen.fit_modes(mod, [0.0, 0.0], [2.5, 2.6], ["k"], shapes=alike)
    assert not upd.success and upd.pairing == (1, 1)


def test_a_linearization_refuses_point_arguments_in_frequency_response(record):
    """frequency_response(lin, ..., p=...) returned the response at lin's own parameters."""
    mod = record[0]
    lin = lagrgen.linearize(mod, [0.0])
    with pytest.raises(TypeError, match=r"frequency_response\(lin, p=\.\.\.\): a Linearization"):
        lagrgen.frequency_response(lin, None, [1.0], input="F", p={"k": 8.0})


def test_measured_coordinates_may_be_the_model_s_own_symbols(record):
    """measured=[x] with the x(t) that model.coordinates returned was an UnknownNameError."""
    mod, t, data = record
    x, = oscillator().q
    fit = lagrgen.fit(mod, t, data, ["k"], [1.0, 0.0], measured=[x])
    assert fit.params["k"] == pytest.approx(4.0, rel=1e-3)
    assert lagrgen.fit(mod, t, data, ["k"], [1.0, 0.0], measured=x).params == fit.params
