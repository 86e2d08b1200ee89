"""The native integration engine: a whole solve in C without the GIL.

`lg_ode.c`/`lg_ode.h` are the C core (a port of SciPy's _ivp, see README.md), `_ode` its Cython
wrapper (plain arrays in and out, no SciPy) and `engine` the Python face that builds SciPy's
OdeResult. Methods and their codes come from `lagrgen.methods`.
"""
