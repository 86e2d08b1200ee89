"""Parameter sweeps for vibration engineers: a steady-state measure (amplitude, peak, final value) of
each coordinate against one swept value, run as an ensemble (`simulate_many`).

The swept name is a parameter of the model, or any name the `inputs` depend on (e.g. the angular
frequency w of a forcing F = A·sin(w·t)): then `inputs` is a function of the swept value.
"""
from dataclasses import dataclass

import numpy as np

from .ensemble import simulate_many
from .methods import MEASURES
from .runtime.arguments import parameters_from


@dataclass
class SweepResult:
    """`measure` of each coordinate for each swept value.

    Attributes
    ----------
    name : str
        The swept name.
    values : ndarray, shape (k,)
        Its values.
    measure : str
        "amplitude" (half the peak-to-peak over the steady window), "max" (the largest abs(q)
        there) or "final" (q at the end).
    table : ndarray, shape (k, n)
        The measure, one column per coordinate.
    coordinates : tuple of str
        The coordinates' names.
    success : ndarray of bool, shape (k,)
        Whether each run finished.
    """

    name: str
    values: np.ndarray
    measure: str
    table: np.ndarray
    coordinates: tuple
    success: np.ndarray

    def column(self, coordinate):
        """The measure of one coordinate (its name or index) against the swept values."""
        if isinstance(coordinate, str):
            coordinate = self.coordinates.index(coordinate)
        return self.table[:, coordinate]


def steady_measure(q, measure):
    """The measure of each row of q (n, samples) over the samples."""
    if measure == "amplitude":
        return (q.max(axis=1) - q.min(axis=1)) / 2
    if measure == "max":
        return np.abs(q).max(axis=1)
    return q[:, -1]


def sweep(mod, name, values, t_span, y0=None, inputs=None, params=None, measure="amplitude",
          settle=0.5, samples=400, method="RK45", rtol=1e-6, atol=1e-9, workers=None, client=None,
          progress=None):
    """Run `mod` once per value of `name` and measure each coordinate's steady response.

    Parameters
    ----------
    mod : a built model;  name : a parameter name or a name the inputs depend on
    values : the swept values;  t_span : (t0, t1) of every run;  y0 : initial state (default 0)
    inputs : None, one inputs dict, or a function value -> inputs dict
    params : other parameter values (dict or array), shared by all runs
    measure : one of MEASURES, over the window after the fraction `settle` of t_span
    samples : output times in that window;  method, rtol, atol, workers, client : as for
        `simulate_many`

    Returns
    -------
    SweepResult
    """
    if measure not in MEASURES:
        raise ValueError(f"unknown measure {measure!r}: use one of {', '.join(MEASURES)}")
    if not 0 <= settle < 1:
        raise ValueError(f"settle must lie in [0, 1), got {settle}")
    values = np.asarray(values, dtype=float).ravel()
    base = parameters_from(mod, params)
    P = np.tile(base, (len(values), 1))
    if name in mod.parameters:
        P[:, list(mod.parameters).index(name)] = values
    elif not callable(inputs):
        raise ValueError(f"{name!r} is not a parameter of model {mod.name!r} (its parameters are "
                         f"{', '.join(mod.parameters)}): to sweep a value the inputs depend on, "
                         "give inputs as a function of that value")
    run_inputs = [inputs(v) for v in values] if callable(inputs) else inputs
    t0, t1 = t_span
    t_eval = np.linspace(t0 + settle * (t1 - t0), t1, samples)
    y0 = np.zeros(2 * mod.n_coordinates) if y0 is None else y0
    ens = simulate_many(mod, t_span, y0, params=P, inputs=run_inputs, t_eval=t_eval,
                        method=method, rtol=rtol, atol=atol, workers=workers, client=client,
                        progress=progress)
    table = np.array([steady_measure(q, measure) for q in ens.q])
    return SweepResult(name, values, measure, table, tuple(mod.coordinates), ens.success)
