"""What a run returns: `SimulationResult` (SciPy's OdeResult with names and a plot) and `Outputs`
(output histories addressable by name)."""
import numpy as np
from scipy.integrate._ivp.ivp import OdeResult


class SimulationResult(OdeResult):
    """SciPy's OdeResult (the same fields: t, y, nfev, ..., coordinates, q, qd) that can also plot
    itself."""

    @property
    def transitions(self):
        """[(t, name, kind)] of a hybrid solve's switches; [] for a smooth model's run."""
        return self.get("transitions", [])

    @property
    def mode(self):
        """{name: "open" | "contact" | "stick" | "slip"} at a hybrid solve's end; {} for a smooth
        model's run."""
        return self.get("mode", {})

    def plot(self, velocities=True, title=None):
        """q_i(t) (and q̇_i(t) in a second panel), labelled with the model's coordinate names.

        Parameters
        ----------
        velocities : bool
            Also plot the rates q̇_i(t).
        title : str, optional
            The figure's title (default: the model's name).

        Returns
        -------
        matplotlib.figure.Figure
        """
        from .outputs.plotting import plot_time_history
        if title is None:
            title = self.__dict__.get("_model_name")
        return plot_time_history(self, self.coordinates, velocities=velocities, title=title,
                                 units=self.__dict__.get("_units"))

    def animate(self, model=None, params=None, fps=20, max_frames=120, dpi=72, title=None):
        """The mechanism moving along this solution, as an object that shows itself in a notebook
        (HTML/JavaScript frames) and has `.save(path)` (GIF or MP4); see
        `lagrgen.outputs.notebook.animation` (`model`: the drawing, default the simulated one)."""
        from .outputs.notebook import animation
        return animation(self, model, params, fps, max_frames, dpi, title)

    def _repr_html_(self):
        from .outputs.notebook import summary_html
        return summary_html(self)


def with_coordinates(sol, coordinates, n, model_name=None):
    """`sol` as a SimulationResult with also `coordinates`, `q` (n × len(t)) and `qd`
    (n × len(t)), views of the rows of `y`."""
    result = sol if isinstance(sol, SimulationResult) else SimulationResult(sol)
    result.coordinates = tuple(coordinates)
    result.q = result.y[:n]
    result.qd = result.y[n:]
    if model_name is not None:
        result.__dict__["_model_name"] = model_name   # not a field: only the plot's title
    return result


def stopped_by_guard(sol, reason, t_stop, t_end, steps):
    """Mark `sol` as ended by a guard (max_steps, max_wall_time) at t_stop: status −1, `guard`
    the reason, and a message saying where, after how many steps, and what to try."""
    sol.guard = reason
    sol.success, sol.status = False, -1
    sol.message = (f"the integration was stopped at t = {t_stop:.6g} (of {t_end:g}) after {steps} "
                   f"steps: {reason}; the result holds the solution up to there. A discontinuous "
                   "force (sign, Heaviside, a stop) can make an explicit solver crawl: try "
                   "method='Radau', events on the switching surfaces, model.friction / "
                   "model.impact, or a smooth approximation such as tanh(v/eps)")


class Outputs(np.ndarray):
    """A (n_outputs, n_times) array of output histories that also answers `table[name]`."""

    def __new__(cls, values, names, units):
        obj = np.asarray(values, dtype=float).view(cls)
        obj.names, obj.units = tuple(names), dict(units)
        return obj

    def __array_finalize__(self, obj):
        self.names = getattr(obj, "names", ())
        self.units = getattr(obj, "units", {})

    def __getitem__(self, key):
        if isinstance(key, str):
            if key not in self.names:
                raise KeyError(f"no output {key!r}: the outputs are {', '.join(self.names)}")
            return np.asarray(self)[self.names.index(key)]
        return np.asarray(self)[key]
