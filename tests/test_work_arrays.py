"""Issue 37.1: the generated functions keep their work arrays off the stack when they are large.
Every registered function of a 1200-coordinate model (a chain of masses joined by springs: the
recursive formulation, chosen by itself) runs, and gives the chain's closed-form numbers, on the
main thread and on a thread with a 256 KiB stack, and so do the native engine's solves through
them; n×n arrays on the stack (M, the Jacobian's B, the recursion's per-node records) crashed the
process there. The calls run in a subprocess, so that a crash fails the test instead of killing
pytest. A dense model with constraints, whose workspaces hold the saddle-point solve's blocks, gives
the same numbers with every workspace on the stack and with every one on the heap."""
import json
import shutil
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import sympy as sp
from numpy.testing import assert_allclose

import lagrgen
from lagrgen.build import derived, model_info
from lagrgen.codegen.c_model import standalone_files
from lagrgen.functions import FUNCTIONS
from lagrgen.toolchain import compiler_command

from test_tree import random_tree

N_CHAIN = 1200
#: The stack of the threads the functions run on: less than any platform's default (macOS 512 KiB).
SMALL_STACK = 256 * 1024


def spring_chain(n, name):
    """n masses m on a line, x_i absolute, joined by springs k, the first to a wall: M = m·I and
    F = −K·x with K = k·tridiag(−1, 2, −1) but K[n−1, n−1] = k (the last mass is free)."""
    model = lagrgen.Model(name)
    xs = model.coordinates([f"x{i}" for i in range(n)])
    k, m = model.parameters(k=4.0, m=2.0)
    for x in xs:
        model.particle(m, sp.Matrix([x]))
    model.spring(k, xs[0])
    for a, b in zip(xs, xs[1:]):
        model.spring(k, b - a)
    return model


@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    """The chain built into a directory of its own, its units compiled on first use made here (at
    -O0: the frames are largest, and it compiles fastest)."""
    out = tmp_path_factory.mktemp("chain")
    mod = lagrgen.build(spring_chain(N_CHAIN, "big_chain"), out_dir=out, opt_level="-O0",
                        quiet=True)
    assert mod.formulation == "recursive"
    for function in LARGE:
        mod.compiled_model.address(function.name)
    return out


#: The functions called on the chain: all but the residual's Hessian, a dense (3n)² matrix for
#: collocation (13 million entries here) from a planar tree's symbolic second derivatives, and the
#: link functions (the chain has no links).
LARGE = [f for f in FUNCTIONS if f.name != "residual_hessian" and f.call != "link"]


#: Run in a fresh process: every function of the chain at one state, on the main thread and on a
#: thread with a small stack, compared with the closed forms; one JSON line per call.
CALLS = textwrap.dedent("""
    import json, sys, threading
    import numpy as np
    import lagrgen
    mod = lagrgen.load("big_chain", sys.argv[1])
    n, k, m = mod.n_coordinates, 4.0, 2.0
    rng = np.random.default_rng(37)
    x, v, a = rng.normal(size=n), rng.normal(size=n), rng.normal(size=n)
    y, p = np.concatenate([x, v]), np.array([k, m])
    K = k * (2 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1))
    K[-1, -1] = k
    F = -K @ x
    J = np.block([[np.zeros((n, n)), np.eye(n)], [-K / m, np.zeros((n, n))]])
    P = np.vstack([np.zeros((n, 2)), np.column_stack([F / (m * k), -F / m ** 2])])
    dy, dp = rng.normal(size=(3, 2 * n)), rng.normal(size=(3, 2))
    none = np.zeros(0)
    EXPECTED = {
        "mass_matrix": (lambda: mod.mass_matrix(x, 0.0, p), [m * np.eye(n)]),
        "forcing": (lambda: mod.forcing(x, v, 0.0, p), [F]),
        "rhs": (lambda: mod.rhs(0.0, y, p), [np.concatenate([v, F / m])]),
        "jacobian": (lambda: mod.jacobian(0.0, y, p), [J]),
        "parameter_jacobian": (lambda: mod.parameter_jacobian(0.0, y, p), [P]),
        "directional_derivatives": (lambda: mod.directional_derivatives(0.0, y, dy, dp, p),
                                    [np.concatenate([v, F / m]), dy @ J.T + dp @ P.T]),
        "linear_terms": (lambda: mod.linear_terms(x, v, 0.0, p),
                         [m * np.eye(n), -K, np.zeros((n, n)), np.zeros((n, 0))]),
        "power_terms": (lambda: mod.power_terms(0.0, y, p), [np.zeros(2)]),
        "outputs": (lambda: mod.outputs(0.0, y, p)[:3],
                    [np.array([m * v @ v / 2, x @ K @ x / 2, m * v @ v / 2 + x @ K @ x / 2])]),
        "constraint_forces": (lambda: mod.constraint_forces(0.0, y, p), [none]),
        "constraint_residuals": (lambda: mod.constraint_residuals(0.0, y, p), [none]),
        "constraint_residual_jacobian": (lambda: mod.constraint_residual_jacobian(0.0, y, p),
                                         [np.zeros((0, 2 * n))]),
        "constraint_terms": (lambda: mod.constraint_terms(x, v, 0.0, p),
                             [np.zeros((0, n)), none, np.zeros((n, n))]),
        "events": (lambda: mod.events(0.0, y, p), [none]),
        "hybrid_terms": (lambda: mod.hybrid_terms(0.0, y, p),
                         [m * np.eye(n), F, np.zeros((0, n)), none, none]),
        "residual_terms": (lambda: mod.residual_terms(x, v, a, 0.0, p),
                           [m * a - F, np.hstack([K, np.zeros((n, n))]), m * np.eye(n),
                            np.zeros((n, 0))]),
        "residual_parameter_jacobian": (lambda: mod.residual_parameter_jacobian(x, v, a, 0.0, p),
                                        [np.column_stack([K @ x / k, a])]),
        "regressor": (lambda: mod.regressor(x, v, a, 0.0, p), [np.zeros((n, 0))]),
    }

    def relative_error(name):
        call, expected = EXPECTED[name]
        got = call()
        got = list(got) if isinstance(got, tuple) else [got]
        assert [g.shape for g in got] == [e.shape for e in expected], name
        return max((float(np.abs(g - e).max()) / max(1.0, float(np.abs(e).max()))
                    for g, e in zip(got, expected) if e.size), default=0.0)

    def native_solves():
        sol = lagrgen.simulate(mod, (0.0, 0.01), y, params={"k": k, "m": m}, method="RK45",
                               engine="native", sensitivities=["k"], rtol=1e-8, atol=1e-10)
        assert sol.success and sol.engine == "native", sol.message
        return float(np.abs(sol.y[:, -1] - y).max())

    def run(name, call):
        print(json.dumps({"name": name, "where": where, "started": True}), flush=True)
        print(json.dumps({"name": name, "where": where, "value": call()}), flush=True)

    names = sys.argv[2:]
    where = "main thread"
    for name in names:
        run(name, lambda: relative_error(name))
    run("native solves", native_solves)
    where = "thread with a 256 KiB stack"
    threading.stack_size(SMALL_STACK)
    def on_small_stack():
        for name in names:
            run(name, lambda: relative_error(name))
        run("native solves", native_solves)
    thread = threading.Thread(target=on_small_stack)
    thread.start()
    thread.join()
""").replace("SMALL_STACK", str(SMALL_STACK))


def test_every_function_of_a_large_model_runs_on_a_small_stack(chain):
    names = [f.name for f in LARGE]
    run = subprocess.run([sys.executable, "-c", CALLS, str(chain), *names], capture_output=True,
                         text=True, timeout=600)
    lines = [json.loads(line) for line in run.stdout.splitlines()]
    started = [line for line in lines if line.get("started")]
    assert run.returncode == 0, (
        f"the process died ({run.returncode}) in {started[-1]['name'] if started else 'loading'} "
        f"on the {started[-1]['where'] if started else 'main thread'}: {run.stderr[-1500:]}")
    values = {(line["name"], line["where"]): line["value"] for line in lines if "value" in line}
    assert len(values) == 2 * (len(names) + 1)
    for (name, where), value in values.items():
        if name == "native solves":
            assert 0.0 < value < 1.0, (where, value)      # it moved, by a little
        else:
            assert value < 1e-12, (name, where, value)


#: Run in a fresh process: forcing of the chain (an N×N workspace, an output of N) with the address
#: space capped just above what the process uses, then without the cap.
NO_ROOM = textwrap.dedent("""
    import resource, sys
    import numpy as np
    import lagrgen
    mod = lagrgen.load("big_chain", sys.argv[1])
    x, v = np.linspace(0.0, 1.0, mod.n_coordinates), np.zeros(mod.n_coordinates)
    expected = mod.forcing(x, v)
    used = int(open("/proc/self/statm").read().split()[0]) * resource.getpagesize()
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    resource.setrlimit(resource.RLIMIT_AS, (used + 4 * 2 ** 20, hard))
    try:
        mod.forcing(x, v)
        print("computed")
    except MemoryError as error:
        print("MemoryError:", error)
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
    print(np.array_equal(mod.forcing(x, v), expected))
""")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/statm")
def test_a_workspace_the_heap_has_no_room_for_is_a_memory_error(chain):
    """A function whose workspace cannot be allocated returns LG_NO_MEMORY (2), which the runtime
    raises as MemoryError saying so, and the model works again once there is room."""
    run = subprocess.run([sys.executable, "-c", NO_ROOM, str(chain)], capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-1500:]
    refused, again = run.stdout.splitlines()
    assert refused.startswith("MemoryError: compiled model 'big_chain' could not allocate the "
                              "work arrays"), refused
    assert again == "True"


# -- every workspace on the stack, every one on the heap ---------------------------------------
def cart_pendulum(name):
    """A cart x driven by an input force, with a pendulum bob (px, py) held on a rod of length L
    (a holonomic constraint) and a damper: the saddle-point solves' blocks in the workspaces."""
    model = lagrgen.Model(name)
    x, px, py = model.coordinates("x px py")
    m, M, L, g, c = model.parameters(m=0.5, M=2.0, L=0.8, g=9.81, c=0.3)
    force, = model.inputs("F")
    model.particle(M, sp.Matrix([x]))
    model.particle(m, sp.Matrix([px, py]))
    model.potential_energy(m * g * py)
    model.damper(c, x)
    model.force(sp.Matrix([force]), at=sp.Matrix([x]))
    model.constraint((px - x) ** 2 + py ** 2 - L ** 2, name="rod")
    model.event("swing", px - x)
    return model


def driver_source(info, point, k=2):
    """A C program calling every function of the standalone model `info.name` at `point` (t, y of
    4n + 2·n_constraints values [q, q̇, a, mu], p, u, dy, dp), each into an output of exactly its size on the
    heap, printing the status and the outputs; then every function once more at a state of NaN
    (the early returns of a failed factorization)."""
    name, dims = info.name, {**info.dimensions, "k": k}
    t, y, p, u, dy, dp = point

    def array(values):
        return "{" + ", ".join(repr(float(v)) for v in values) + ", 0.0}"

    n = len(info.coordinates)
    link_state = list(y[:n + 3]) + [len(info.link_names) - 1]   # [q, point, the last link]
    lines = ["#include <math.h>", "#include <stdio.h>", "#include <stdlib.h>",
             f'#include "{name}_model.h"',
             "static void show(const char *fn, int status, const double *out, int size)",
             "{", '    printf("%s %d", fn, status);', "    for (int i = 0; i < size; ++i)",
             '        printf(" %.17g", out[i]);', '    printf("\\n");', "}",
             "int main(void)", "{",
             f"    const double y[] = {array(y)}, p[] = {array(p)}, u[] = {array(u)};",
             f"    const double dy[] = {array(np.ravel(dy))}, dp[] = {array(np.ravel(dp))};",
             f"    const double link_state[] = {array(link_state)};",
             f"    double nan_state[{len(y)}];",
             f"    for (int i = 0; i < {len(y)}; ++i)", "        nan_state[i] = NAN;"]
    for state in ("y", "nan_state"):
        for f in FUNCTIONS:
            size = f.size(dims)
            at = "link_state" if f.call == "link" and state == "y" else state
            call = (f"{name}_{f.name}({t!r}, {state}, p, u, {k}, dy, dp, out)"
                    if f.call == "directions" else f"{name}_{f.name}({t!r}, {at}, p, u, out)")
            lines += ["    {", f"        double *out = malloc({max(size, 1)} * sizeof(double));",
                      f"        int status = {call};",
                      f'        show("{f.name}", status, out, status || {state} != y ? 0 : {size});',
                      "        free(out);", "    }"]
    return "\n".join(lines + ["    return 0;", "}"]) + "\n"


def module_outputs(mod, point, k=2):
    """{function: its outputs concatenated} of the built model `mod` at `point`."""
    t, y, p, u, dy, dp = point
    n, m = mod.n_coordinates, mod.n_constraints
    q, qd, a, mu = y[:n], y[n:2 * n], y[2 * n:3 * n + m], y[3 * n + m:4 * n + 2 * m]
    calls = {"q": lambda f: f(q, t, p, u), "q_qd": lambda f: f(q, qd, t, p, u),
             "state": lambda f: f(t, y[:2 * n], p, u),
             "implicit": lambda f: f(q, qd, a, t, p, u),
             "weighted": lambda f: f(q, qd, a, mu, t, p, u),
             "directions": lambda f: f(t, y[:2 * n], dy, dp, p, u),
             "link": lambda f: f(mod.link_names[-1], q, y[n:n + 3], p)}
    out = {}
    for function in FUNCTIONS:
        if function.call == "link" and not mod.link_names:
            continue
        got = calls[function.call](getattr(mod, function.name))
        got = got if isinstance(got, tuple) else (got,)
        out[function.name] = np.concatenate([np.ravel(g) for g in got])
    return out


#: A spatial tree (lagrgen.tree3d): a revolute joint about a skew axis, a prismatic one below it
#: and a third branch, with off-diagonal inertias.
ROBOT = """<?xml version="1.0"?><robot name="r">
<link name="base"/>
<link name="a"><inertial><origin xyz="0.05 0.02 -0.1" rpy="0.1 0.2 0.3"/><mass value="1.3"/>
<inertia ixx="0.02" ixy="0.001" ixz="-0.002" iyy="0.025" iyz="0.003" izz="0.01"/></inertial></link>
<link name="b"><inertial><origin xyz="0 0.03 0.01"/><mass value="0.7"/>
<inertia ixx="0.004" ixy="0" ixz="0.0005" iyy="0.006" iyz="0" izz="0.005"/></inertial></link>
<link name="c"><inertial><origin xyz="0 0 -0.05"/><mass value="0.5"/>
<inertia ixx="0.003" ixy="0.0002" ixz="0" iyy="0.003" iyz="0.0001" izz="0.001"/></inertial></link>
<joint name="j1" type="revolute"><parent link="base"/><child link="a"/>
<origin xyz="0 0 0.3" rpy="0.3 -0.2 0.1"/><axis xyz="0 0.6 0.8"/>
<dynamics damping="0.2"/></joint>
<joint name="j2" type="prismatic"><parent link="a"/><child link="b"/>
<origin xyz="0.1 0 -0.25" rpy="0 1.5707963267948966 0"/><axis xyz="1 0 0"/></joint>
<joint name="j3" type="continuous"><parent link="a"/><child link="c"/>
<origin xyz="0.02 0 -0.1"/><axis xyz="1 0 0"/></joint>
</robot>"""


def robot(name):
    """The ROBOT with inertial parameters, from a file of its own."""
    import tempfile
    from pathlib import Path
    path = Path(tempfile.mkdtemp()) / "robot.urdf"
    path.write_text(ROBOT)
    return lagrgen.from_urdf(path, name=name, parameters="inertial")


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc with AddressSanitizer")
@pytest.mark.parametrize("make, formulation", [(cart_pendulum, "dense"),
                                               (lambda name: random_tree(2, name=name),
                                                "recursive"),
                                               (robot, "recursive")],
                         ids=["dense", "planar tree", "spatial tree"])
def test_workspaces_on_the_stack_and_on_the_heap_give_the_same_numbers(tmp_path, make,
                                                                       formulation):
    """The standalone C of a dense model with a constraint, an input and an event, and of a
    recursive one, compiled with AddressSanitizer (out-of-bounds reads and writes, and leaks,
    end the program with an error) with its workspaces where they fall (the stack) and with
    every one on the heap (-DLG_STACK_DOUBLES=0): every function gives the compiled module's
    numbers, and a failed factorization returns without leaking."""
    model = make(f"work_{formulation}")
    mod = lagrgen.build(model, out_dir=tmp_path / "module", formulation=formulation, quiet=True)
    equations = derived(model.spec())
    info = model_info(model.spec(), equations, formulation)
    assert info.formulation == formulation
    for file_name, text in standalone_files(info, equations, FUNCTIONS).items():
        (tmp_path / file_name).write_text(text)
    rng = np.random.default_rng(3)
    n, m = mod.n_coordinates, mod.n_constraints
    point = (0.3, rng.uniform(-0.8, 0.8, 4 * n + 2 * m), np.asarray(mod.defaults),
             rng.uniform(-1, 1, len(mod.inputs)), rng.normal(size=(2, 2 * n)),
             rng.normal(size=(2, len(mod.parameters))))
    (tmp_path / "driver.c").write_text(driver_source(info, point))
    expected = module_outputs(mod, point)
    for flags in ([], ["-DLG_STACK_DOUBLES=0"]):
        exe = tmp_path / f"driver{len(flags)}"
        build = subprocess.run([*compiler_command(), "-std=c99", "-g", "-O1",
                                "-fsanitize=address", "-fno-omit-frame-pointer", *flags,
                                "-I", str(tmp_path), str(tmp_path / "driver.c"),
                                str(tmp_path / f"{info.name}_model.c"), "-lm", "-o", str(exe)],
                               capture_output=True, text=True)
        assert build.returncode == 0, build.stderr[-2000:]
        run = subprocess.run([str(exe)], capture_output=True, text=True, timeout=120)
        assert run.returncode == 0, f"{flags}: {run.stderr[-3000:]}"
        lines = [line.split() for line in run.stdout.splitlines()]
        assert len(lines) == 2 * len(FUNCTIONS)
        for (name, status, *values), function in zip(lines, FUNCTIONS):
            if function.call == "link" and not info.link_names:     # none to ask for
                assert name == function.name and status == "1", (flags, name, status)
                continue
            assert name == function.name and status == "0", (flags, name, status)
            assert_allclose(np.array(values, float), expected[name], rtol=1e-13,
                            atol=1e-13 * max(1.0, np.abs(expected[name]).max(initial=0.0)),
                            err_msg=f"{name} {flags}")
        failed = {name for name, status, *_ in lines[len(FUNCTIONS):] if status != "0"}
        assert {"rhs", "jacobian", "parameter_jacobian", "directional_derivatives"} <= failed
