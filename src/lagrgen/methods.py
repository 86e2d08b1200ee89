"""The names of the integration methods (SciPy's `solve_ivp` methods), importable without SciPy."""
METHODS = ("RK23", "RK45", "DOP853", "Radau", "BDF", "LSODA")
#: The methods handed the analytic Jacobian.
STIFF_METHODS = ("Radau", "BDF", "LSODA")
