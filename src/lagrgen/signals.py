"""Tabulated inputs: `lagrgen.Signal`, interpolated in C by the native engine and callable of t."""
import numpy as np

KINDS = ("linear", "cubic", "previous")


class Signal:
    """A time-varying input given by samples, e.g. a measured base acceleration.

    Parameters
    ----------
    t_samples : array_like, shape (m,)
        Strictly increasing, finite sample times (m >= 2).
    values : array_like, shape (m,)
        Finite sample values.
    kind : {"linear", "cubic", "previous"}
        "linear": `numpy.interp` (the end values are held outside the samples).
        "cubic": SciPy's `CubicSpline(t, values)` with its default not-a-knot end conditions,
        extrapolated with its end pieces as CubicSpline does.
        "previous": the last sample at or before t (the first sample before it).

    A Signal is callable, ``sig(t)``, so it works on the SciPy engine too; the native engine
    evaluates the same interpolant in C.
    """

    def __init__(self, t_samples, values, kind="linear"):
        if kind not in KINDS:
            raise ValueError(f"unknown Signal kind {kind!r}: use one of {', '.join(KINDS)}")
        try:
            t = np.array(t_samples, dtype=float)
            v = np.array(values, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"Signal samples must be numbers ({exc})") from None
        if t.ndim != 1 or v.ndim != 1:
            raise ValueError("Signal t_samples and values must be 1-D arrays")
        if t.size != v.size:
            raise ValueError(f"Signal t_samples has {t.size} values but values has {v.size}")
        if t.size < 2:
            raise ValueError("a Signal needs at least 2 samples")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
            raise ValueError("Signal t_samples and values must be finite")
        if np.any(np.diff(t) <= 0):
            raise ValueError("Signal t_samples must be strictly increasing")
        t.flags.writeable = False
        v.flags.writeable = False
        self.t, self.values, self.kind = t, v, kind
        self._spline = None
        coef = np.zeros(0)
        if kind == "cubic":
            from scipy.interpolate import CubicSpline
            self._spline = CubicSpline(t, v, bc_type="not-a-knot")
            coef = np.ascontiguousarray(self._spline.c.T)   # (m - 1, 4): piece k, powers 3..0
        self._coef = coef.ravel()

    @classmethod
    def piecewise(cls, t_breaks, coefficients):
        """A "cubic" Signal given by its pieces: on [t_k, t_k+1] the polynomial
        c_k0·x³ + c_k1·x² + c_k2·x + c_k3 of x = t − t_k (SciPy's PPoly; the end pieces
        extrapolate), `coefficients` of shape (len(t_breaks) − 1, 4)."""
        from scipy.interpolate import PPoly
        t = np.asarray(t_breaks, dtype=float)
        c = np.asarray(coefficients, dtype=float)
        if t.ndim != 1 or c.shape != (t.size - 1, 4) or not np.all(np.isfinite(c)):
            raise ValueError(f"Signal.piecewise needs finite coefficients of shape "
                             f"({t.size - 1}, 4) for {t.size} breakpoints, got {c.shape}")
        ends = np.append(c[:, 3], np.polyval(c[-1], t[-1] - t[-2]))
        signal = cls(t, ends, kind="cubic")
        signal._spline = PPoly(np.ascontiguousarray(c.T), signal.t)
        signal._coef = np.ascontiguousarray(c).ravel()
        return signal

    def __call__(self, t):
        """The interpolated value(s) at t (a float for a scalar t)."""
        tt = np.asarray(t, dtype=float)
        if self.kind == "linear":
            out = np.interp(tt, self.t, self.values)
        elif self.kind == "cubic":
            out = self._spline(tt)
        else:
            k = np.clip(np.searchsorted(self.t, tt, side="right") - 1, 0, self.t.size - 1)
            out = self.values[k]
        return float(out) if np.ndim(out) == 0 else out

    def native_spec(self):
        """(kind, value, t, values, coef): the description the C core evaluates."""
        return (self.kind, 0.0, self.t, self.values, self._coef)

    def __repr__(self):
        return (f"Signal({self.t.size} samples on [{self.t[0]:g}, {self.t[-1]:g}], "
                f"kind={self.kind!r})")


def constant_spec(value):
    """The C core's description of a constant input."""
    return ("constant", float(value), np.zeros(1), np.zeros(1), np.zeros(0))
