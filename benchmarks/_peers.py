"""Competing tools for the n-link pendulum benchmark, each behind the same small interface.

`build_pydy(n, work, deadline)` and `build_casadi(n, work, deadline)` derive the planar n-link pendulum
(point masses at the link ends, absolute angles, parameters ordered m0..m{n-1}, l0..l{n-1}, g as in
lagrgen's model) with the peer's own tools, generate and compile its code, and return a `Built`.
Neither peer is a dependency of lagrgen: `versions()` reports what is installed.
"""
import ctypes
import os
import signal
import subprocess
import time
from importlib import metadata
from pathlib import Path

import numpy as np

from _built import Built  # noqa: F401  (the builders' result; nlink_tools reads it here)

PEER_PACKAGES = {"PyDy": ("pydy", "Cython"), "CasADi": ("casadi",), "Pinocchio": ("pin",)}


class BuildTimeout(Exception):
    """A peer's build went past its time cap."""


def versions():
    """Installed version of each peer's packages, None where a package is missing."""
    out = {}
    for tool, packages in PEER_PACKAGES.items():
        found = {}
        for package in packages:
            try:
                found[package] = metadata.version(package)
            except metadata.PackageNotFoundError:
                found[package] = None
        out[tool] = found
    return out


def missing(tool):
    """The packages of `tool` that are not installed (an empty list when it can run)."""
    return [name for name, version in versions()[tool].items() if version is None]


def default_parameters(n):
    """The benchmark's parameter vector: unit masses and lengths, g = 9.81."""
    return np.r_[np.ones(2 * n), 9.81]


def remaining(deadline):
    """Seconds left before `deadline` (a `time.perf_counter` value); raise BuildTimeout if none."""
    left = deadline - time.perf_counter()
    if left <= 0:
        raise BuildTimeout("build time cap reached")
    return left


def run_capped(cmd, deadline, cwd=None):
    """Run `cmd` in its own process group, killing the whole group if it outlives `deadline`."""
    proc = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            start_new_session=True)
    try:
        out, _ = proc.communicate(timeout=remaining(deadline))
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        raise BuildTimeout(f"{cmd[0]} still running at the time cap") from None
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, cmd))} failed:\n{out.decode(errors='replace')[-2000:]}")


# --------------------------------------------------------------------------------------------- PyDy

def pydy_equations(n):
    """KanesMethod for the n-link pendulum; returns (kane, q, u, constants in lagrgen's order)."""
    import sympy as sp
    from sympy.physics import mechanics as me

    q = me.dynamicsymbols(f"q0:{n}")
    u = me.dynamicsymbols(f"u0:{n}")
    m = sp.symbols(f"m0:{n}")
    l = sp.symbols(f"l0:{n}")
    g = sp.Symbol("g")
    frame = me.ReferenceFrame("N")
    point = me.Point("O")
    point.set_vel(frame, 0)
    particles, loads = [], []
    for i in range(n):
        nxt = point.locatenew(f"P{i}", l[i] * (sp.sin(q[i]) * frame.x - sp.cos(q[i]) * frame.y))
        nxt.set_vel(frame, point.vel(frame)
                    + l[i] * u[i] * (sp.cos(q[i]) * frame.x + sp.sin(q[i]) * frame.y))
        particles.append(me.Particle(f"pa{i}", nxt, m[i]))
        loads.append((nxt, -m[i] * g * frame.y))
        point = nxt
    kane = me.KanesMethod(frame, q_ind=q, u_ind=u, kd_eqs=[q[i].diff() - u[i] for i in range(n)])
    kane.kanes_equations(particles, loads)
    return kane, q, u, [*m, *l, g]


def build_pydy(n, work, deadline):
    """PyDy: KanesMethod, then generate_ode_function(generator="cython") on the minimal M, F form.

    PyDy's generated function returns the same output array on every call, so the `rhs` given to
    solve_ivp copies it (without the copy Radau takes far more steps); it needs C-contiguous input,
    which SciPy's stiff solvers do not always pass, so input is made contiguous. No Jacobian.
    """
    import sympy as sp
    from pydy.codegen.ode_function_generators import generate_ode_function

    start = time.perf_counter()
    kane, q, u, constants = pydy_equations(n)
    derived = time.perf_counter()
    remaining(deadline)
    f = generate_ode_function(kane.forcing, q, u, constants, mass_matrix=kane.mass_matrix,
                              coordinate_derivatives=sp.Matrix(u), generator="cython",
                              constants_arg_type="array", time_first=True,
                              tmp_dir=str(work), prefix=f"pydy_nlink{n}")
    done = time.perf_counter()
    remaining(deadline)
    p = default_parameters(n)
    contiguous = np.ascontiguousarray

    def rhs(t, y):
        return f(t, contiguous(y, dtype=float), p).copy()

    return Built("PyDy", rhs,
                 build={"derive": derived - start, "compile": done - derived, "cold": done - start},
                 notes=["PyDy: derive = KanesMethod; compile = generate_ode_function(cython) "
                        "(codegen + Cython + gcc together); no Jacobian, stiff solvers use "
                        "SciPy's finite differences; rhs output copied per call"])


# ------------------------------------------------------------------------------------------- CasADi

def casadi_equations(n):
    """The n-link pendulum in CasADi SX by AD of the Lagrangian: returns (t, y, p, ẏ, dense ∂ẏ/∂y).

    M = ∂²L/∂q̇², F = ∂L/∂q − (∂²L/∂q̇∂q)·q̇, q̈ = casadi.solve(M, F) (symbolic, in SX).
    """
    import casadi as ca

    q, qd = ca.SX.sym("q", n), ca.SX.sym("qd", n)
    p, t = ca.SX.sym("p", 2 * n + 1), ca.SX.sym("t")
    m, l, g = p[0:n], p[n:2 * n], p[2 * n]
    height = vx = vy = kinetic = potential = 0
    for i in range(n):
        height = height - l[i] * ca.cos(q[i])
        vx = vx + l[i] * ca.cos(q[i]) * qd[i]
        vy = vy + l[i] * ca.sin(q[i]) * qd[i]
        kinetic = kinetic + 0.5 * m[i] * (vx ** 2 + vy ** 2)
        potential = potential + m[i] * g * height
    lagrangian = kinetic - potential
    dl_dqd = ca.gradient(lagrangian, qd)
    mass = ca.jacobian(dl_dqd, qd)
    forcing = ca.gradient(lagrangian, q) - ca.mtimes(ca.jacobian(dl_dqd, q), qd)
    y = ca.vertcat(q, qd)
    ydot = ca.densify(ca.vertcat(qd, ca.solve(mass, forcing)))
    return t, y, p, ydot, ca.densify(ca.jacobian(ydot, y))


TIMING_DRIVER = r"""
#include <stdlib.h>
#include <time.h>
typedef long long int casadi_int;
int NAME(const double** arg, double** res, casadi_int* iw, double* w, int mem);
int NAME_work(casadi_int* sz_arg, casadi_int* sz_res, casadi_int* sz_iw, casadi_int* sz_w);

double NAME_time(long repeat, const double* t, const double* y, const double* p, double* out) {
    casadi_int sz_arg, sz_res, sz_iw, sz_w;
    NAME_work(&sz_arg, &sz_res, &sz_iw, &sz_w);
    const double** arg = calloc(sz_arg > 3 ? sz_arg : 3, sizeof(double*));
    double** res = calloc(sz_res > 1 ? sz_res : 1, sizeof(double*));
    casadi_int* iw = calloc(sz_iw + 1, sizeof(casadi_int));
    double* w = calloc(sz_w + 1, sizeof(double));
    struct timespec a, b;
    arg[0] = t; arg[1] = y; arg[2] = p; res[0] = out;
    clock_gettime(CLOCK_MONOTONIC, &a);
    for (long k = 0; k < repeat; ++k) NAME(arg, res, iw, w, 0);
    clock_gettime(CLOCK_MONOTONIC, &b);
    free(arg); free(res); free(iw); free(w);
    return ((b.tv_sec - a.tv_sec) + 1e-9 * (b.tv_nsec - a.tv_nsec)) / repeat;
}
"""


def casadi_compile(function, work, deadline, opt_level="-O2"):
    """Generate C for a CasADi Function plus a timing loop, compile it with gcc into a shared library.

    Returns (seconds of codegen, seconds of compile, path of the library).
    """
    import casadi as ca

    name = function.name()
    start = time.perf_counter()
    generator = ca.CodeGenerator(f"{name}.c")
    generator.add(function)
    generator.generate(f"{work}/")
    (Path(work) / f"{name}_time.c").write_text(TIMING_DRIVER.replace("NAME", name))
    generated = time.perf_counter()
    library = Path(work) / f"lib{name}.so"
    run_capped(["gcc", opt_level, "-fPIC", "-shared", "-o", str(library), f"{name}.c",
                f"{name}_time.c", "-lm"], deadline, cwd=work)
    return generated - start, time.perf_counter() - generated, library


def casadi_caller(function, shape, order="C"):
    """A Python callable (t, y) -> new array through CasADi's buffer API (the fastest call path)."""
    n_out = int(np.prod(shape))
    t_in, y_in, p_in = np.zeros(1), np.zeros(function.size1_in(1)), np.zeros(function.size1_in(2))
    out = np.zeros(n_out)
    buffer, evaluate = function.buffer()
    for i, array in enumerate((t_in, y_in, p_in)):
        buffer.set_arg(i, memoryview(array))
    buffer.set_res(0, memoryview(out))

    def call(t, y, p=None):
        t_in[0] = t
        y_in[:] = y
        if p is not None:
            p_in[:] = p
        evaluate()
        return out.reshape(shape, order=order).copy()

    call.keep = (function, buffer, t_in, y_in, p_in, out)
    return call, p_in


def casadi_timer(library, name, n):
    """seconds-per-call(t, y, repeat) of the compiled CasADi function `name`, looped inside C."""
    lib = ctypes.CDLL(str(library))
    fn = getattr(lib, f"{name}_time")
    fn.restype = ctypes.c_double
    pointer = ctypes.POINTER(ctypes.c_double)
    fn.argtypes = [ctypes.c_long, pointer, pointer, pointer, pointer]
    p = default_parameters(n)
    out = np.zeros(4 * n * n)

    def timer(t, y, repeat):
        t_arr = np.array([t], dtype=float)
        y_arr = np.ascontiguousarray(y, dtype=float)
        return fn(repeat, *(a.ctypes.data_as(pointer) for a in (t_arr, y_arr, p, out)))

    timer.keep = (lib, out)
    return timer


def build_casadi(n, work, deadline, opt_level="-O2"):
    """CasADi: SX equations, C code generated with CodeGenerator for ẏ and ∂ẏ/∂y, compiled with gcc.

    The two functions are compiled separately so that when the Jacobian's C does not compile within
    the cap the rhs is still the compiled one; the Jacobian then runs in CasADi's SX virtual machine
    and the build is reported as a timeout.
    """
    import casadi as ca

    start = time.perf_counter()
    t, y, p, ydot, jac = casadi_equations(n)
    f_rhs = ca.Function(f"casadi_nlink{n}_rhs", [t, y, p], [ydot])
    f_jac = ca.Function(f"casadi_nlink{n}_jac", [t, y, p], [jac])
    derive = time.perf_counter() - start
    built = Built("CasADi", None, build={"derive": derive, "cse+emit": 0.0, "compile": 0.0},
                  notes=["CasADi: SX symbolic M\\F (casadi.solve) and its SX Jacobian; "
                         f"cse+emit = CodeGenerator, compile = gcc {opt_level} of the generated C; "
                         "called through Function.buffer()"])
    timed_out = []
    for function, slot, shape, order in ((f_rhs, "rhs", (2 * n,), "C"),
                                         (f_jac, "jac", (2 * n, 2 * n), "F")):
        try:
            remaining(deadline)
            emit, compile_s, library = casadi_compile(function, work, deadline, opt_level)
            built.build["cse+emit"] += emit
            built.build["compile"] += compile_s
            external = ca.external(function.name(), str(library))
            caller, p_in = casadi_caller(external, shape, order)
            setattr(built, f"{slot}_in_c", casadi_timer(library, function.name(), n))
        except BuildTimeout:
            timed_out.append(slot)
            caller, p_in = casadi_caller(function, shape, order)
            built.notes.append(f"CasADi n={n}: {slot} C did not compile within the cap; "
                               f"its timings are CasADi's SX virtual machine (no C)")
        p_in[:] = default_parameters(n)
        setattr(built, slot, caller)
    built.build["cold"] = time.perf_counter() - start
    if timed_out:
        built.build["timeout"] = timed_out
    return built


def build_pinocchio(n, work, deadline):
    """Pinocchio (pip `pin`): see _pinocchio.py."""
    import _pinocchio
    return _pinocchio.build(n, work, deadline)


BUILDERS = {"PyDy": build_pydy, "CasADi": build_casadi, "Pinocchio": build_pinocchio}
