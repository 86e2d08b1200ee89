"""lagrgen's generated C against a trace and against Pinocchio, in plain C loops (no Python):
ns per call of the rhs, the mass matrix and the Jacobian, and flops per joint of the rhs.

Three sides, compiled by the same compiler with the same flags (`FLAGS`), each timed in a loop
of its own process:

* lagrgen: `export_c` of the robot (`from_urdf` as benchmarks/robots.py reads it), its
  `<name>_rhs`, `<name>_mass_matrix` and `<name>_jacobian` called in a C loop;
* the trace: the articulated-body algorithm written here in CasADi SX over Pinocchio's parsed
  model (its joint placements, joint types and inertias, in each joint's frame as Pinocchio's
  `aba` runs it; CasADi folds the numbers and drops products with 0 and 1), checked equal to
  `pin.aba` at random states first, then emitted by CasADi's `CodeGenerator` and called in a C
  loop;
* Pinocchio's own `aba`, `crba` and `computeABADerivatives` (the `pin` wheel's library and
  headers, Eigen from the CasADi wheel) in a C++ loop.

Every figure is the best of `--repeats` runs (ns per call of the process's CPU time) and, with valgrind
installed, the instructions per call (callgrind: the loop run twice as long, the difference per
call), which a loaded machine does not change. Flops per joint: `+ − * /` counted in the rhs's
straight-line C (lagrgen's traced q̈, lg_lean_qdd; the trace's generated function).

    python benchmarks/c_loop.py                        # UR5, Panda, Talos reduced, tiago, Solo12
    python benchmarks/c_loop.py --robots ur5_robot panda --repeats 3

Writes benchmarks/results/c_loop.md and c_loop.json with the load average before and after.
"""
import argparse
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from robots import RESULTS, robots_dir  # noqa: E402

FLAGS = ["-O2", "-fno-math-errno", "-DNDEBUG"]
#: (file stem, folder under robots/, floating base)
ROBOTS = {"ur5_robot": ("ur_description/urdf", False), "panda": ("panda_description/urdf", False),
          "talos_reduced": ("talos_data/robots", False), "tiago": ("tiago_description/robots", False),
          "solo12": ("solo_description/robots", True)}


# -- the trace: the articulated-body algorithm in CasADi SX -------------------------------------
def _skew(ca, r):
    return ca.vertcat(ca.horzcat(0, -r[2], r[1]), ca.horzcat(r[2], 0, -r[0]),
                      ca.horzcat(-r[1], r[0], 0))


def _quaternion_matrix(ca, x, y, z, w):
    return ca.vertcat(
        ca.horzcat(1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)),
        ca.horzcat(2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)),
        ca.horzcat(2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)))


def _axis_rotation(ca, axis, c, s):
    """The rotation by the angle (cos c, sin s) about the unit axis (numbers)."""
    K = _skew(ca, ca.DM(axis))
    return ca.DM.eye(3) + s * K + (1 - c) * ca.mtimes(K, K)


def _joint(ca, jm, q, v):
    """(R, p, S) of a Pinocchio joint model at q: its motion M_J = (R, p) and its motion subspace
    S (6×nv, [ω; v] order), for the joint types of example-robot-data's robots."""
    kind = jm.shortname()
    iq, nq, iv, nv = jm.idx_q, jm.nq, jm.idx_v, jm.nv
    unit = {"X": [1.0, 0.0, 0.0], "Y": [0.0, 1.0, 0.0], "Z": [0.0, 0.0, 1.0]}
    zero = ca.SX.zeros(3, 1)
    if kind in ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned",
                "JointModelRUBX", "JointModelRUBY", "JointModelRUBZ"):
        axis = unit[kind[-1]] if not kind.endswith("Unaligned") else list(jm.extract().axis)
        if kind.startswith("JointModelRUB"):
            c, s = q[iq], q[iq + 1]
        else:
            c, s = ca.cos(q[iq]), ca.sin(q[iq])
        if kind[-1] in "XYZ" and not kind.endswith("Unaligned"):
            i = "XYZ".index(kind[-1])
            j, k = (i + 1) % 3, (i + 2) % 3
            R = ca.SX.zeros(3, 3)
            R[i, i] = 1
            R[j, j], R[k, k], R[k, j], R[j, k] = c, c, s, -s
        else:
            R = _axis_rotation(ca, axis, c, s)
        return R, zero, ca.DM(axis + [0.0, 0.0, 0.0])
    if kind in ("JointModelPX", "JointModelPY", "JointModelPZ", "JointModelPrismaticUnaligned"):
        axis = unit[kind[-1]] if not kind.endswith("Unaligned") else list(jm.extract().axis)
        return ca.SX.eye(3), ca.DM(axis) * q[iq], ca.DM([0.0, 0.0, 0.0] + axis)
    if kind == "JointModelFreeFlyer":
        R = _quaternion_matrix(ca, q[iq + 3], q[iq + 4], q[iq + 5], q[iq + 6])
        S = ca.DM.zeros(6, 6)
        S[0:3, 3:6] = ca.DM.eye(3)      # Pinocchio's v = [linear; angular]
        S[3:6, 0:3] = ca.DM.eye(3)
        return R, q[iq:iq + 3], S
    raise NotImplementedError(kind)


def _spd_inverse(ca, D):
    """D⁻¹ of a symmetric positive definite SX matrix by its Cholesky factor (scalar: 1/D)."""
    n = D.shape[0]
    if n == 1:
        return 1 / D
    L = ca.SX.zeros(n, n)
    for j in range(n):
        L[j, j] = ca.sqrt(D[j, j] - ca.sumsqr(L[j, :j]))
        for i in range(j + 1, n):
            L[i, j] = (D[i, j] - ca.dot(L[i, :j], L[j, :j])) / L[j, j]
    Linv = ca.solve(L, ca.SX.eye(n))
    return ca.mtimes(Linv.T, Linv)


def casadi_aba(pm):
    """casadi.Function aba(q, v, tau) -> q̈ of the Pinocchio model `pm` (LOCAL convention: each
    joint's frame; spatial vectors [ω; v] at its origin; liMi = placement·M_J(q))."""
    import casadi as ca
    q, v, tau = ca.SX.sym("q", pm.nq), ca.SX.sym("v", pm.nv), ca.SX.sym("tau", pm.nv)
    nj = pm.njoints
    X, S, vel, c, IA, pA = [None] * nj, [None] * nj, [None] * nj, [None] * nj, [None] * nj, \
        [None] * nj

    def action(R, p):       # the motion transform parent -> child of liMi = (R, p)
        Rt = R.T
        return ca.vertcat(ca.horzcat(Rt, ca.SX.zeros(3, 3)),
                          ca.horzcat(-ca.mtimes(Rt, _skew(ca, p)), Rt))

    def crm(x):
        w, u = x[0:3], x[3:6]
        return ca.vertcat(ca.horzcat(_skew(ca, w), ca.SX.zeros(3, 3)),
                          ca.horzcat(_skew(ca, u), _skew(ca, w)))

    for i in range(1, nj):
        jm, parent = pm.joints[i], pm.parents[i]
        RJ, pJ, S[i] = _joint(ca, jm, q, v)
        M = pm.jointPlacements[i]
        R = ca.mtimes(ca.DM(M.rotation), RJ)
        p = ca.DM(M.translation) + ca.mtimes(ca.DM(M.rotation), pJ)
        X[i] = action(R, p)
        vJ = ca.mtimes(S[i], v[jm.idx_v:jm.idx_v + jm.nv])
        vp = ca.mtimes(X[i], vel[parent]) if parent > 0 else ca.SX.zeros(6, 1)
        vel[i] = vp + vJ
        c[i] = ca.mtimes(crm(vel[i]), vJ)
        Y = pm.inertias[i]
        m, lever = Y.mass, ca.DM(Y.lever)
        Cx = _skew(ca, lever)
        IO = ca.DM(Y.inertia) - m * ca.mtimes(Cx, Cx)
        IA[i] = ca.vertcat(ca.horzcat(IO, m * Cx), ca.horzcat(m * Cx.T, m * ca.DM.eye(3)))
        h = ca.mtimes(IA[i], vel[i])
        pA[i] = -ca.mtimes(crm(vel[i]).T, h)       # v ×* (I·v)
    U, Dinv, u = [None] * nj, [None] * nj, [None] * nj
    for i in range(nj - 1, 0, -1):
        jm, parent = pm.joints[i], pm.parents[i]
        U[i] = ca.mtimes(IA[i], S[i])
        Dinv[i] = _spd_inverse(ca, ca.mtimes(S[i].T, U[i]))
        u[i] = tau[jm.idx_v:jm.idx_v + jm.nv] - ca.mtimes(S[i].T, pA[i])
        if parent > 0:
            UD = ca.mtimes(U[i], Dinv[i])
            Ia = IA[i] - ca.mtimes(UD, U[i].T)
            pa = pA[i] + ca.mtimes(Ia, c[i]) + ca.mtimes(UD, u[i])
            IA[parent] = IA[parent] + ca.mtimes(ca.mtimes(X[i].T, Ia), X[i])
            pA[parent] = pA[parent] + ca.mtimes(X[i].T, pa)
    acc, qdd = [None] * nj, [None] * (pm.nv)
    g = ca.DM(list(np.zeros(3)) + list(-pm.gravity.linear))
    for i in range(1, nj):
        jm, parent = pm.joints[i], pm.parents[i]
        ap = ca.mtimes(X[i], acc[parent] if parent > 0 else g) + c[i]
        x = ca.mtimes(Dinv[i], u[i] - ca.mtimes(U[i].T, ap))
        for k in range(jm.nv):
            qdd[jm.idx_v + k] = x[k]
        acc[i] = ap + ca.mtimes(S[i], x)
    return ca.Function("aba", [q, v, tau], [ca.vertcat(*qdd)])


def check_trace(f, pm, states=3):
    """The largest relative difference of the trace from pin.aba at random states."""
    import pinocchio as pin
    data, rng, worst = pm.createData(), np.random.default_rng(1), 0.0
    for _ in range(states):
        q = pin.randomConfiguration(pm, -np.ones(pm.nq), np.ones(pm.nq))
        v, tau = rng.uniform(-1, 1, pm.nv), rng.uniform(-1, 1, pm.nv)
        a = pin.aba(pm, data, q, v, tau)
        b = np.array(f(q, v, tau)).ravel()
        worst = max(worst, float(np.abs(a - b).max() / max(np.abs(a).max(), 1.0)))
    return worst


# -- C loops ---------------------------------------------------------------------------------------
TIMER = r"""
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
static double lg_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}
static volatile double lg_sink;
"""

LAGRGEN_LOOP = TIMER.replace("{", "{{").replace("}", "}}") + r"""
#include "{name}_model.h"
int main(int argc, char **argv)
{{
    const long iterations = atol(argv[2]);
    double y[2 * {n}], p[{n_params}], u[{n_inputs}], *out = malloc(sizeof(double) * 4 * {n} * {n});
    for (int i = 0; i < 2 * {n}; ++i)
        y[i] = 0.3 * ((i * 7919) % 13) / 13.0 - 0.15 + 0.01 * i;
    for (int i = 0; i < {n_params}; ++i)
        p[i] = {name}_defaults[i];
    for (int i = 0; i < {n_inputs}; ++i)
        u[i] = 0.1;
    int (*f)(double, const double *, const double *, const double *, double *) =
        argv[1][0] == 'r' ? {name}_rhs : argv[1][0] == 'm' ? {name}_mass_matrix : {name}_jacobian;
    const double start = lg_now();
    for (long k = 0; k < iterations; ++k) {{
        y[0] += 1e-12;
        if (f(0.0, y, p, u, out))
            return 1;
        lg_sink += out[2 * {n} - 1];
    }}
    printf("%.6g\n", (lg_now() - start) / iterations * 1e9);
    return 0;
}}
"""

CASADI_LOOP = TIMER.replace("{", "{{").replace("}", "}}") + r"""
#include "{name}_trace.h"
int main(int argc, char **argv)
{{
    const long iterations = atol(argv[2]);
    (void)argc;
    double q[{nq}], v[{nv}], tau[{nv}], ddq[{nv}], w[aba_SZ_W > 0 ? aba_SZ_W : 1];
    casadi_int iw[aba_SZ_IW > 0 ? aba_SZ_IW : 1];
    const double *arg[3] = {{q, v, tau}};
    double *res[1] = {{ddq}};
    const double q0[{nq}] = {{{q0}}};
    for (int i = 0; i < {nq}; ++i)
        q[i] = q0[i];
    for (int i = 0; i < {nv}; ++i)
        v[i] = 0.3 * ((i * 7919) % 13) / 13.0 - 0.15, tau[i] = 0.1;
    const double start = lg_now();
    for (long k = 0; k < iterations; ++k) {{
        q[0] += 1e-12;
        aba(arg, res, iw, w, 0);
        lg_sink += ddq[{nv} - 1];
    }}
    printf("%.6g\n", (lg_now() - start) / iterations * 1e9);
    return 0;
}}
"""

PINOCCHIO_LOOP = r"""
#include <pinocchio/multibody.hpp>
#include <pinocchio/serialization.hpp>
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/aba-derivatives.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <ctime>
#include <cstdio>
#include <cstdlib>
#include <string>
int main(int argc, char **argv)
{
    pinocchio::Model model;
    model.loadFromBinary(argv[1]);     /* the model pinocchio.buildModelFromUrdf made */
    (void)argc;
    pinocchio::Data data(model);
    const long iterations = std::atol(argv[4]);
    Eigen::VectorXd q = pinocchio::neutral(model), v(model.nv), tau(model.nv);
    for (int i = 0; i < model.nv; ++i)
        v[i] = 0.3 * ((i * 7919) % 13) / 13.0 - 0.15, tau[i] = 0.1;
    const char f = argv[3][0];
    volatile double sink = 0.0;
    struct timespec t0, t1;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t0);
    for (long k = 0; k < iterations; ++k) {
        v[0] += 1e-12;
        if (f == 'r')
            sink += pinocchio::aba(model, data, q, v, tau)[model.nv - 1];
        else if (f == 'm')
            sink += pinocchio::crba(model, data, q)(0, model.nv - 1);
        else {
            pinocchio::computeABADerivatives(model, data, q, v, tau);
            sink += data.ddq_dq(model.nv - 1, 0);
        }
    }
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t1);
    const double seconds = (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec);
    std::printf("%.6g\n", seconds / iterations * 1e9);
    return 0;
}
"""


def compile_c(sources, exe, cxx=False, extra=()):
    cmd = ["g++" if cxx else "gcc", *FLAGS, *map(str, sources), "-o", str(exe), *extra, "-lm"]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode:
        raise RuntimeError(f"{' '.join(cmd)}\n{done.stderr[-3000:]}")
    return exe


def pinocchio_loop(work):
    """The C++ loop over Pinocchio's calls, compiled once."""
    import casadi
    import pinocchio
    prefix = Path(pinocchio.__file__).resolve().parents[3] / "cmeel.prefix"
    if not (prefix / "include" / "pinocchio").is_dir():
        prefix = next(Path(p) for p in sys.path if (Path(p) / "cmeel.prefix").is_dir()) \
            / "cmeel.prefix"
    eigen = Path(casadi.__file__).parent / "include" / "eigen3"
    source, exe = work / "pinocchio_loop.cpp", work / "pinocchio_loop"
    if exe.exists() and source.exists() and source.read_text() == PINOCCHIO_LOOP:
        return exe                 # compiled by an earlier run into the same --work folder
    source.write_text(PINOCCHIO_LOOP)
    lib = prefix / "lib"
    return compile_c([source], work / "pinocchio_loop", cxx=True, extra=[
        "-I", str(prefix / "include"), "-I", str(eigen), "-DBOOST_MPL_LIMIT_LIST_SIZE=30", "-DBOOST_MPL_LIMIT_VECTOR_SIZE=30",
        "-DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS", "-DBOOST_FUSION_INVOKE_MAX_ARITY=12",
        "-L", str(lib), f"-Wl,-rpath,{lib}",
        "-lpinocchio_default", "-lboost_serialization", "-lboost_filesystem"])


def timed(cmd, iterations, repeats):
    """Best ns per call of the loop `cmd + [iterations]` over `repeats` runs."""
    best = float("inf")
    for _ in range(repeats):
        out = subprocess.run([*map(str, cmd), str(iterations)], capture_output=True, text=True,
                             check=True)
        best = min(best, float(out.stdout.split()[-1]))
    return best


def instructions(cmd, iterations):
    """Instructions per call: callgrind's totals of the loop at 2k and k iterations, apart."""
    if shutil.which("valgrind") is None:
        return None
    totals = []
    for k in (iterations, 2 * iterations):
        with tempfile.NamedTemporaryFile(suffix=".cg") as out:
            subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out.name}",
                            *map(str, cmd), str(k)], capture_output=True, check=True)
            text = Path(out.name).read_text()
        totals.append(int(re.search(r"^(?:summary|totals):\s+(\d+)", text, re.M).group(1)))
    return (totals[1] - totals[0]) / iterations


def flops_of(text, function):
    """`+ − * /` of the body of the C function `function` in `text` (binary operators: a minus
    after an operand; literals' exponents are not operators)."""
    start = text.index(f" {function}(")
    body = text[text.index("{", start):]
    depth, end = 0, 0
    for i, ch in enumerate(body):
        depth += ch == "{"
        depth -= ch == "}"
        if depth == 0:
            end = i
            break
    code = re.sub(r"/\*.*?\*/", "", body[:end], flags=re.S)
    code = re.sub(r"\d\.?\d*e[-+]\d+", "1", code)
    count = 0
    for line in code.splitlines():
        if "=" not in line or line.strip().startswith(("if", "return", "for")):
            continue
        rhs = line.split("=", 1)[1]
        count += len(re.findall(r"[*/+]", rhs))
        count += len(re.findall(r"(?<=[\w\])])\s*-", rhs))
    return count


# -- one robot -------------------------------------------------------------------------------------
def robot_rows(stem, folder, floating, work, pin_loop, repeats, say):
    import casadi as ca
    import pinocchio as pin
    from robots import _identifier, pinocchio_models

    import lagrgen
    from lagrgen.build import export_c
    path = robots_dir() / folder / f"{stem}.urdf"
    name = _identifier(stem) + ("_floating" if floating else "")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lagrgen.URDFWarning)
        model = lagrgen.from_urdf(path, joint_dynamics=False, mimic=False, check_inertias=False,
                                  massless="fixed", base="floating" if floating else "fixed",
                                  name=name)
    here = work / name
    here.mkdir(exist_ok=True)
    export_c(model, here)
    text = (here / f"{name}_model.c").read_text()
    n = len(model.q)
    spec = model.spec()
    loop = here / f"{name}_loop.c"
    loop.write_text(LAGRGEN_LOOP.format(name=name, n=n, n_params=max(len(spec.parameters), 1),
                                        n_inputs=max(len(spec.inputs), 1)))
    say(f"  {name}: compiling lagrgen's C ({n} joints) ...")
    lagrgen_exe = compile_c([loop, here / f"{name}_model.c"], here / f"{name}_loop",
                            extra=["-I", str(here)])
    _, pm = pinocchio_models(path, floating, model.coordinate_names)
    say(f"  {name}: tracing Pinocchio's model in CasADi ...")
    f = casadi_aba(pm)
    agreement = check_trace(f, pm)
    gen = ca.CodeGenerator(f"{name}_trace.c", {"with_header": True})
    gen.add(f)
    gen.generate(str(here) + "/")
    q0 = pin.neutral(pm)
    trace_loop = here / f"{name}_trace_loop.c"
    trace_loop.write_text(CASADI_LOOP.format(name=name, nq=pm.nq, nv=pm.nv,
                                             q0=", ".join(repr(float(x)) for x in q0)))
    trace_exe = compile_c([trace_loop, here / f"{name}_trace.c"], here / f"{name}_trace_loop",
                          extra=["-I", str(here)])
    trace_text = (here / f"{name}_trace.c").read_text()
    lean = "#define LG_LEAN_QDD 1" in text
    say(f"  {name}: timing ...")
    iterations = max(200, int(2e6 / max(n, 1) ** 1.5))
    pm.saveToBinary(str(here / f"{name}.pinocchio"))
    pin_cmd = [pin_loop, here / f"{name}.pinocchio", "-"]
    row = {"robot": stem + (" (floating base)" if floating else ""), "n": n,
           "trace_agreement": agreement,
           "flops_per_joint": {
               "lagrgen": flops_of(text, "lg_lean_qdd") / n if lean else None,
               "trace": flops_of(trace_text, "casadi_f0") / pm.nv},
           "ns": {}, "instructions": {}}
    cases = {("lagrgen", "rhs"): [lagrgen_exe, "rhs"], ("trace", "rhs"): [trace_exe, "rhs"],
             ("pinocchio", "rhs"): pin_cmd + ["r"],
             ("lagrgen", "M"): [lagrgen_exe, "mass"], ("pinocchio", "M"): pin_cmd + ["m"],
             ("lagrgen", "jacobian"): [lagrgen_exe, "jac"],
             ("pinocchio", "jacobian"): pin_cmd + ["d"]}
    for (side, what), cmd in cases.items():
        k = iterations if what != "jacobian" else max(50, iterations // 10)
        row["ns"][f"{side} {what}"] = timed(cmd, k, repeats)
    for (side, what), cmd in cases.items():
        k = max(20, iterations // 50) if what != "jacobian" else max(5, iterations // 500)
        row["instructions"][f"{side} {what}"] = instructions(cmd, k)
    return row


def table(rows):
    def cell(r, key, kind="ns"):
        x = r[kind].get(key)
        return "—" if x is None else f"{x:,.0f}"
    lines = ["| robot | n | rhs ns: lagrgen / trace / Pinocchio | lagrgen ÷ trace | M ns: lagrgen"
             " / `crba` | ratio | Jacobian ns: lagrgen / `computeABADerivatives` | ratio | "
             "flops per joint (rhs): lagrgen / trace | trace vs `pin.aba` |",
             "| :-- | --: | --: | --: | --: | --: | --: | --: | --: | --: |"]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['robot']} | | {r['error']} | | | | | | | |")
            continue
        t, fl = r["ns"], r["flops_per_joint"]
        ours = "—" if fl["lagrgen"] is None else f"{fl['lagrgen']:.0f}"
        lines.append(
            f"| {r['robot']} | {r['n']} | {cell(r, 'lagrgen rhs')} / {cell(r, 'trace rhs')} / "
            f"{cell(r, 'pinocchio rhs')} | {t['lagrgen rhs'] / t['trace rhs']:.2f}× | "
            f"{cell(r, 'lagrgen M')} / {cell(r, 'pinocchio M')} | "
            f"{t['lagrgen M'] / t['pinocchio M']:.2f}× | {cell(r, 'lagrgen jacobian')} / "
            f"{cell(r, 'pinocchio jacobian')} | "
            f"{t['lagrgen jacobian'] / t['pinocchio jacobian']:.2f}× | "
            f"{ours} / {fl['trace']:.0f} | {r['trace_agreement']:.0e} |")
    lines += ["", "Instructions per call (callgrind; a loaded machine does not change them):", "",
              "| robot | rhs: lagrgen / trace / Pinocchio | lagrgen ÷ trace | M: lagrgen / "
              "`crba` | ratio | Jacobian: lagrgen / `computeABADerivatives` | ratio |",
              "| :-- | --: | --: | --: | --: | --: | --: |"]
    for r in rows:
        if "error" in r or r["instructions"].get("lagrgen rhs") is None:
            continue
        i = r["instructions"]
        lines.append(
            f"| {r['robot']} | {cell(r, 'lagrgen rhs', 'instructions')} / "
            f"{cell(r, 'trace rhs', 'instructions')} / "
            f"{cell(r, 'pinocchio rhs', 'instructions')} | "
            f"{i['lagrgen rhs'] / i['trace rhs']:.2f}× | {cell(r, 'lagrgen M', 'instructions')}"
            f" / {cell(r, 'pinocchio M', 'instructions')} | "
            f"{i['lagrgen M'] / i['pinocchio M']:.2f}× | "
            f"{cell(r, 'lagrgen jacobian', 'instructions')} / "
            f"{cell(r, 'pinocchio jacobian', 'instructions')} | "
            f"{i['lagrgen jacobian'] / i['pinocchio jacobian']:.2f}× |")
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", nargs="*", default=list(ROBOTS), choices=list(ROBOTS))
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--no-write", action="store_true")
    parser.add_argument("--work", default=None, help="build folder (default: a temporary one)")
    args = parser.parse_args(argv)
    import pinocchio

    import lagrgen
    work = Path(args.work or tempfile.mkdtemp(prefix="lagrgen_c_loop_"))
    work.mkdir(parents=True, exist_ok=True)
    say = lambda s: print(s, file=sys.stderr, flush=True)      # noqa: E731
    say("compiling Pinocchio's loop ...")
    pin_loop = pinocchio_loop(work)
    load = os.getloadavg()
    rows = []
    for stem in args.robots:
        folder, floating = ROBOTS[stem]
        try:
            rows.append(robot_rows(stem, folder, floating, work, pin_loop, args.repeats, say))
        except Exception as exc:        # a robot a side cannot take: said in its row
            rows.append({"robot": stem, "error": f"{type(exc).__name__}: "
                         f"{str(exc).splitlines()[0][:160]}"})
    after = os.getloadavg()
    text = (f"# Generated C in plain C loops: lagrgen, a CasADi trace, Pinocchio\n\n"
            f"{time.strftime('%Y-%m-%d %H:%M')}, {platform.machine()}, gcc "
            f"{' '.join(FLAGS)} on every side, pin {pinocchio.__version__}, lagrgen "
            f"{lagrgen.__version__}; load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} "
            f"before, {after[0]:.2f} {after[1]:.2f} {after[2]:.2f} after (a shared 2-core "
            "machine: the instruction counts are the figures a load does not change).\n\n"
            "ns per call, best of the runs; the trace is the articulated-body algorithm in "
            "CasADi SX over Pinocchio's parsed model (checked against `pin.aba`: the last "
            "column), emitted by CasADi's CodeGenerator. Solo12's floating base: lagrgen's six "
            "coordinates (x, y, z, yaw, pitch, roll), the trace's and Pinocchio's free-flyer "
            "(a quaternion).\n\n" + table(rows) + "\n")
    print(text)
    if not args.no_write:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / "c_loop.md").write_text(text)
        (RESULTS / "c_loop.json").write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
