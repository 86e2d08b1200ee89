"""Names the command line offers as choices, importable without SciPy: the integration methods
(SciPy's `solve_ivp` methods) and the measures of a sweep."""
METHODS = ("RK23", "RK45", "DOP853", "Radau", "BDF", "LSODA")
#: The methods handed the analytic Jacobian.
STIFF_METHODS = ("Radau", "BDF", "LSODA")
#: What `lagrgen.sweep` measures of each coordinate over the steady window.
MEASURES = ("amplitude", "max", "final")
