"""Optimal motions of robots (issue 42): lagrgen.Collocation on example-robot-data's Panda and
Talos, re-planned, in the least time and on a 20-link chain, against CasADi + IPOPT and Crocoddyl
on the same problem in the same run, every answer re-simulated with Pinocchio's `aba`.

    pip install ".[test]" casadi example-robot-data
    python benchmarks/robot_motions.py                  # the whole table (an hour or more)
    python benchmarks/robot_motions.py --repeat 1 --replans 5 --mintime-timeout 300 \
        --talos-timeout 480 --chain-timeout 480         # the committed table (~25 minutes)
    python benchmarks/robot_motions.py --quick          # a smoke run: one of each, no Talos
    python benchmarks/robot_motions.py --croc-python .venv-croc/bin/python

Problems (every robot from its URDF, `lagrgen.from_urdf(path, joint_dynamics=False)`, the
rigid-body dynamics Pinocchio's `aba` computes):

  panda      example-robot-data's panda.urdf with its finger joints made fixed (the URDF rewritten
             into a temporary file), rest to rest in 1 s from `PANDA_START` (its "ready" pose) to
             `PANDA_GOAL`, within every URDF limit (`bound_limits()`: positions, velocities,
             efforts), least ∫Σ τ² dt, Hermite–Simpson from 51 nodes refined to mesh_tol 1e-6.
  talos      talos_reduced.urdf with every joint but the torso's two and the arms' fourteen made
             fixed (16 joints, the base fixed), the same kind of move (`TALOS_START` to
             `TALOS_GOAL`).
  re-plan    the Panda's motion on 101 nodes (mesh_tol=None); then `REPLANS` re-plans in a loop,
             each `prob.resolve(warm=last, initial=last.state_at(0.1), shift=0.1)` (the same 1 s
             move to the goal from where the last plan is at 0.1 s), each against a cold
             `prob.solve` of the same re-plan problem, against IPOPT's re-plan from the same
             warm start (`solver="ipopt"`) and against one QP from it (`max_iter=1`, a
             real-time iteration: how far it is from the converged re-plan). Then re-plans
             from a disturbed state: the first plan's state at 0.1 s with `DISTURBANCES` rad
             times a standard normal draw (seeded) added to every joint angle, on the 101-node
             plan and on the Panda's refined first motion (mesh_tol 1e-6), each against a cold
             solve of the same problem (refined alike).
  min-time   the Panda from start to goal in the least time within its limits,
             `Collocation(mod, nodes=51, duration=(0.1, 5.0))`, `minimize(time=True)`: on the 51
             nodes alone (mesh_tol=None), then refined (the defaults), checked by 101 nodes and
             by a solve from another start (duration 4.5 s, straight lines); each figure printed
             when measured, so a process stopped at --mintime-timeout still reports those.
  chain      benchmarks/collocation.py's 20-link planar chain (a torque per joint, hanging to 30°
             in 2 s, least effort), refined to mesh_tol 1e-6.

Peers, each in its own process:

  CasADi     the same Hermite–Simpson NLP written by hand in CasADi SX (variables q, q̇, q̈, τ at
             nodes and midpoints; the residual RNEA(q, q̇, q̈) − τ = 0 at every point, with the
             recursive Newton–Euler algorithm written here over Pinocchio's model and checked
             against `pin.rnea` first; Simpson and Hermite defects divided by the interval; the
             inputs' envelope rows; Simpson's quadrature of the objective), 101 nodes, IPOPT
             (MUMPS) with the options lagrgen's exact-Hessian solve uses, started from the cubic
             between the end states with its inverse-dynamics torques (lagrgen's default start);
             re-plans from a primal warm start (the last plan shifted by 0.1 s).
  Crocoddyl  FDDP with the effort limits as box constraints (SolverBoxFDDP), 100 Euler nodes of
             10 ms, ∫Σ τ² dt (control residual) and the goal as a terminal cost of weight
             `CROC_GOAL_WEIGHT`: it cannot state the position and velocity limits (how far its
             answer leaves them is reported). Crocoddyl 3.2.1 from the package index computes
             wrong dynamics next to pin 4.1.0 (an ABI mismatch), so it runs in a separate
             environment with pin 4.0.0 (--croc-python; see benchmarks/README.md), its
             `calc` checked against `aba` of the main environment's pin before it is timed.

Accuracy: each answer's nodes re-simulated with `pin.aba` (SciPy's DOP853, rtol 1e-11,
atol 1e-12), each interval from the collocated state with the inputs the scheme implies
(lagrgen: `res.input_signals()`; CasADi: the same quadratic through node, midpoint and node;
Crocoddyl: the control held over its step), the largest error at the interval's end relative to
each state's size (1 + its largest magnitude), as lagrgen's `res.error` measures it; and the whole
motion re-simulated from the first node, its distance from the last node.

Cold figures come from fresh processes with empty build folders (`import lagrgen` included in
`process`); `--repeat` processes give the medians. Writes benchmarks/results/robot_motions.md and
.json (`--quick`: robot_motions_quick.*), with the load average before and after.
"""
import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
sys.path.insert(0, str(HERE))

PANDA_JOINTS = tuple(f"panda_joint{i}" for i in range(1, 8))
#: The Panda's "ready" pose, and a goal inside every limit that joint 1 cannot reach in 1 s at
#: rest to rest without riding its velocity limit (a cubic would need 2.4 rad/s, the limit 2.175).
PANDA_START = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)
PANDA_GOAL = (1.6, 0.3, 0.5, -1.2, 0.8, 2.6, 2.0)
TALOS_JOINTS = ("torso_1_joint", "torso_2_joint") + tuple(
    f"arm_{side}_{i}_joint" for side in ("left", "right") for i in range(1, 8))
#: Arms hanging with the elbows a little bent, to the torso turned and leaning, both arms raised
#: forward and bent (inside every limit; gravity needs less than 60 % of any joint's effort).
TALOS_START = (0.0, 0.0, 0.0, 0.3, 0.0, -0.5, 0.0, 0.0, 0.0,
               0.0, -0.3, 0.0, -0.5, 0.0, 0.0, 0.0)
TALOS_GOAL = (0.5, 0.2, -0.8, 0.6, 0.5, -1.5, 0.8, -0.4, 0.3,
              0.8, -0.6, -0.5, -1.5, -0.8, -0.4, 0.3)
ROBOTS = {
    "panda": ("panda_description/urdf/panda.urdf", PANDA_JOINTS, PANDA_START, PANDA_GOAL),
    "talos": ("talos_data/robots/talos_reduced.urdf", TALOS_JOINTS, TALOS_START, TALOS_GOAL),
}
DURATION, NODES, REPLAN_NODES, SHIFT = 1.0, 51, 101, 0.1
#: The disturbances of the disturbed re-plans (rad, the scale of a normal draw per joint angle).
DISTURBANCES = (0.01, 0.05)
CROC_NODES, CROC_GOAL_WEIGHT, CROC_MAX_ITER = 100, 1e5, 1000
#: Re-simulation with Pinocchio's aba.
RESIM = {"method": "DOP853", "rtol": 1e-11, "atol": 1e-12}


# -- the robots -----------------------------------------------------------------------------------
def fixed_urdf(source, moving, dest):
    """Write `source` to `dest` with every joint not in `moving` made fixed (its mimic, limit,
    axis and dynamics dropped)."""
    import xml.etree.ElementTree as ET
    tree = ET.parse(source)
    for joint in tree.getroot().iter("joint"):
        if joint.get("type") in (None, "fixed") or joint.get("name") in moving:
            continue
        joint.set("type", "fixed")
        for tag in ("mimic", "limit", "axis", "dynamics"):
            for element in joint.findall(tag):
                joint.remove(element)
    tree.write(dest)
    return str(dest)


def robot_urdf(robot, folder):
    """The robot's URDF with only its benchmark joints moving, written into `folder`."""
    from robots import robots_dir
    relative, moving, _, _ = ROBOTS[robot]
    Path(folder).mkdir(parents=True, exist_ok=True)
    return fixed_urdf(robots_dir() / relative, set(moving), Path(folder) / f"{robot}.urdf")


def pin_order(pm, names):
    """The index in Pinocchio's q of each coordinate of `names` (all revolute: nq = nv)."""
    joints = [pm.names[i] for i in range(1, pm.njoints)]
    return np.array([pm.joints[joints.index(name) + 1].idx_q for name in names])


def pin_robot(urdf, names):
    """(Pinocchio's model of `urdf`, pin_order of `names`, to_pin: the index in Pinocchio's state
    of each state of lagrgen's order, pinned: a state (2n,) in lagrgen's order to Pinocchio's)."""
    import pinocchio as pin
    pm = pin.buildModelFromUrdf(urdf)
    order = pin_order(pm, names)
    to_pin = np.concatenate([order, len(names) + order])

    def pinned(y):
        out = np.empty(to_pin.size)
        out[to_pin] = y
        return out
    return pm, order, to_pin, pinned


def pin_limits(pm, order):
    """(lower, upper, velocity, effort) of the coordinates in lagrgen's order."""
    return (pm.lowerPositionLimit[order], pm.upperPositionLimit[order],
            pm.velocityLimit[order], pm.effortLimit[order])


# -- accuracy against Pinocchio's aba -------------------------------------------------------------
def aba_accuracy(pm, order, t, Y, inputs):
    """The answer (node times t, node states Y (2n, N) in lagrgen's order, inputs(k, s) the
    inputs (n,) on interval k at time s) against Pinocchio's aba: `interval`, the largest
    relative error at an interval's end of the re-simulation from its start (relative to
    1 + each state's largest magnitude); `motion`, the largest distance of the whole motion
    re-simulated from the first node to the last node's state (rad, rad/s)."""
    import pinocchio as pin
    from scipy.integrate import solve_ivp
    data, n = pm.createData(), len(order)
    qp, vp, up = np.zeros(pm.nq), np.zeros(pm.nv), np.zeros(pm.nv)

    def rhs(k):
        def f(s, y):
            qp[order], vp[order], up[order] = y[:n], y[n:], inputs(k, s)
            return np.concatenate([y[n:], pin.aba(pm, data, qp, vp, up)[order]])
        return f

    scale = 1.0 + np.abs(Y).max(axis=1)
    worst = 0.0
    for k in range(t.size - 1):
        sol = solve_ivp(rhs(k), (t[k], t[k + 1]), Y[:, k], **RESIM)
        worst = max(worst, float((np.abs(sol.y[:, -1] - Y[:, k + 1]) / scale).max()))
    y = Y[:, 0]
    for k in range(t.size - 1):
        y = solve_ivp(rhs(k), (t[k], t[k + 1]), y, **RESIM).y[:, -1]
    return {"interval": worst, "motion": float(np.abs(y - Y[:, -1]).max())}


def simpson_inputs(t, U):
    """inputs(k, s) of the quadratic through each Hermite–Simpson interval's node, midpoint and
    node values (U: (n, 2N − 1) at the points)."""
    def inputs(k, s):
        a, m, b = U[:, 2 * k], U[:, 2 * k + 1], U[:, 2 * k + 2]
        x = (s - t[k]) / (t[k + 1] - t[k])
        return a * (1 - x) * (1 - 2 * x) + 4 * m * x * (1 - x) + b * x * (2 * x - 1)
    return inputs


def signal_inputs(signals, names):
    """inputs(k, s) of lagrgen's `res.input_signals()` in the inputs' order."""
    def inputs(k, s):
        return np.array([signals[name](s) for name in names])
    return inputs


def limit_excess(Y, U, limits):
    """How far states (2n, ·) and inputs (n, ·) leave the limits (0 when within)."""
    lower, upper, velocity, effort = (np.asarray(x)[:, None] for x in limits)
    n = lower.shape[0]
    q, v = Y[:n], Y[n:]
    return {"position": float(max(0.0, (lower - q).max(), (q - upper).max())),
            "velocity": float(max(0.0, (np.abs(v) - velocity).max())),
            "effort": float(max(0.0, (np.abs(U) - effort).max()))}


# -- lagrgen --------------------------------------------------------------------------------------
def cpu_time():
    """CPU seconds (user + system) of this process and of the compilers it waited for."""
    own, children = (resource.getrusage(who) for who in (resource.RUSAGE_SELF,
                                                          resource.RUSAGE_CHILDREN))
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def emit(out):
    """Print the figures so far (a worker stopped by its time limit still reports them)."""
    print(json.dumps(out), flush=True)


class MeshLog:
    """What each mesh of a lagrgen solve ran: nodes, solver ("ipopt" / "sqp"), wall time,
    iterations, and why the structured SQP did not apply when it was tried and IPOPT solved the
    mesh instead (Collocation.solve's solver="auto"). Wraps lagrgen.collocation.solver's
    solve_mesh and solve_structured while in use; it changes nothing they do."""

    def __init__(self):
        self.meshes, self._refused = [], None

    def __enter__(self):
        from lagrgen.collocation import solver
        self._solver, self._saved = solver, (solver.solve_mesh, solver.solve_structured)
        mesh, structured = self._saved

        def solve_structured(*args, **kwargs):
            try:
                return structured(*args, **kwargs)
            except Exception as exc:
                self._refused = str(exc)
                raise

        def solve_mesh(problem, layout, *args, **kwargs):
            self._refused = None
            began = time.perf_counter()
            result = mesh(problem, layout, *args, **kwargs)
            self.meshes.append({"nodes": int(layout.nodes), "solver": result.solver,
                                "seconds": time.perf_counter() - began,
                                "solver_seconds": float(result.seconds),
                                "iterations": int(result.iterations),
                                "sqp_refused": self._refused})
            return result

        solver.solve_mesh, solver.solve_structured = solve_mesh, solve_structured
        return self

    def __exit__(self, *exc):
        self._solver.solve_mesh, self._solver.solve_structured = self._saved
        return False

    def take(self):
        out, self.meshes = self.meshes, []
        return out


def least_effort(lagrgen, model, mod, robot, nodes, duration=DURATION):
    """The robot's rest-to-rest move within its limits, least ∫Σ τ² dt (Hermite–Simpson)."""
    _, names, start, goal = ROBOTS[robot]
    assert tuple(mod.coordinates) == names, mod.coordinates
    n = len(names)
    prob = lagrgen.Collocation(mod, nodes=nodes, duration=duration)
    prob.bound_limits()
    prob.initial(q=list(start), qd=[0.0] * n).final(q=list(goal), qd=[0.0] * n)
    if duration == DURATION:
        prob.minimize(integral=sum(u ** 2 for u in model.input_functions))
    else:
        prob.minimize(time=True)
    return prob


def load_robot(lagrgen, robot, folder):
    urdf = robot_urdf(robot, folder)
    model = lagrgen.from_urdf(urdf, joint_dynamics=False)
    mod = lagrgen.build(model, out_dir=str(Path(folder) / "gen"), quiet=True)
    return urdf, model, mod


def result_summary(res, wall):
    return {"wall": wall, "seconds": float(res.seconds), "iterations": int(res.iterations),
            "objective": float(res.objective), "success": bool(res.success),
            "status": int(res.status), "error": float(res.error), "solver": res.solver,
            "meshes": [[m.nodes, m.iterations, float(m.error)] for m in res.meshes],
            "callback_seconds": float(res.callback_seconds), "duration": float(res.duration)}


def timed_solve(solve, log):
    """(the result of `solve()`, its summary with wall and CPU time and the meshes' log)."""
    began, cpu = time.perf_counter(), cpu_time()
    res = solve()
    return res, dict(result_summary(res, time.perf_counter() - began),
                     cpu=cpu_time() - cpu, log=log.take())


def lagrgen_accuracy(res, urdf):
    pm, order, _, _ = pin_robot(urdf, res.coordinates)
    out = aba_accuracy(pm, order, res.t, res.y,
                       signal_inputs(res.input_signals(), res.inputs))
    out.update(limit_excess(res.y, res.u, pin_limits(pm, order)))
    return out


def worker_first_motion(robot, folder, warm, accuracy):
    """The first optimal motion in a fresh process with an empty cache: from_urdf + build, the
    units compiled on first use (the residual's Hessian; the objective and the NLP), the solve
    refined to mesh_tol 1e-6; then `warm` solves of the same problem in the same process."""
    marks = [(time.perf_counter(), cpu_time())]
    import lagrgen
    marks.append((time.perf_counter(), cpu_time()))
    urdf, model, mod = load_robot(lagrgen, robot, folder)
    marks.append((time.perf_counter(), cpu_time()))
    prob = least_effort(lagrgen, model, mod, robot, NODES)
    mod.function_address("residual_hessian")
    marks.append((time.perf_counter(), cpu_time()))
    prob.transcription("exact")
    marks.append((time.perf_counter(), cpu_time()))
    with MeshLog() as log:
        res = prob.solve(progress=False)
        marks.append((time.perf_counter(), cpu_time()))
        units, solved = marks[4][0], marks[5][0]
        emit({"partial": True, "first": dict(result_summary(res, solved - units),
                                             log=list(log.meshes))})
        first = dict(result_summary(res, solved - units), log=log.take())
        warms = []
        for _ in range(warm):
            warms.append(timed_solve(lambda: prob.solve(progress=False), log)[1])
        by_ipopt = timed_solve(lambda: prob.solve(progress=False, solver="ipopt"), log)[1] \
            if warm else None
    out = {"formulation": mod.formulation, "n": len(mod.coordinates), "first": first,
           "warm": warms, "ipopt_warm": by_ipopt, "variables": int(prob.layout.size)}
    for clock, suffix in ((0, ""), (1, "_cpu")):
        for key, (a, b) in (("imports", (0, 1)), ("build", (1, 2)), ("hessian_unit", (2, 3)),
                            ("problem_unit", (3, 4)), ("solve", (4, 5)),
                            ("first_motion", (0, 5))):
            out[key + suffix] = marks[b][clock] - marks[a][clock]
    if accuracy:
        out["accuracy"] = lagrgen_accuracy(res, urdf)
    return out


def worker_replan(folder, replans, accuracy):
    """The Panda on 101 nodes, then `replans` re-plans in a loop, each against a cold solve of the
    same re-plan problem."""
    import lagrgen
    urdf, model, mod = load_robot(lagrgen, "panda", folder)
    n = len(mod.coordinates)
    prob = least_effort(lagrgen, model, mod, "panda", REPLAN_NODES)
    began = time.perf_counter()
    res = prob.solve(progress=False, mesh_tol=None)
    out = {"plan": result_summary(res, time.perf_counter() - began), "replans": [],
           "states": []}
    if accuracy:
        out["plan"]["accuracy"] = lagrgen_accuracy(res, urdf)
    last = res
    for k in range(replans):
        state = last.state_at(SHIFT)
        out["states"].append(state.tolist())
        began, cpu = time.perf_counter(), cpu_time()
        res2 = prob.resolve(warm=last, initial={"q": state[:n], "qd": state[n:]}, shift=SHIFT)
        wall, cpu = time.perf_counter() - began, cpu_time() - cpu
        began = time.perf_counter()
        cold = prob.solve(progress=False, mesh_tol=None)
        cold_wall = time.perf_counter() - began
        step = {"wall": wall, "cpu": cpu, "solve_seconds": float(res2.solve_seconds),
                "solver": res2.solver, "iterations": int(res2.iterations),
                "objective": float(res2.objective), "success": bool(res2.success),
                "notes": len(res2.notes), "cold_wall": cold_wall,
                "cold_iterations": int(cold.iterations), "cold_objective": float(cold.objective),
                "cold_success": bool(cold.success), "error": float(res2.error)}
        step.update(replan_by_ipopt(lagrgen, prob, last, state, n))
        step.update(one_qp_replan(prob, last, state, n, res2))
        if accuracy and k == 0:
            step["accuracy"] = lagrgen_accuracy(res2, urdf)
        out["replans"].append(step)
        last = res2
    refined = least_effort(lagrgen, model, mod, "panda", NODES).solve(progress=False)
    out["disturbed"] = [disturbed_replan(plan, size, seed, mesh_tol)
                        for plan, mesh_tol in ((res, None), (refined, 1e-6))
                        for seed, size in enumerate(DISTURBANCES)]
    return out


def disturbed_replan(plan, size, seed, mesh_tol):
    """A re-plan of `plan`'s problem from its state at SHIFT with `size`·N(0, 1) rad added to each
    joint angle (drawn with `seed`), against a cold solve of the same problem (mesh_tol as the
    plan's: None keeps its grid, else refined)."""
    import numpy as np
    prob, n = plan._problem, plan._problem.layout.n
    state = plan.state_at(SHIFT).copy()
    state[:n] += size * np.random.default_rng(seed).standard_normal(n)
    began = time.perf_counter()
    res = prob.resolve(warm=plan, initial={"q": state[:n], "qd": state[n:]}, shift=SHIFT,
                       mesh_tol=mesh_tol)
    wall = time.perf_counter() - began
    began = time.perf_counter()
    cold = prob.solve(progress=False, mesh_tol=mesh_tol)
    return {"size": size, "nodes": int(plan.t.size), "refined": mesh_tol is not None,
            "wall": wall, "solver": res.solver, "iterations": int(res.iterations),
            "success": bool(res.success), "objective": float(res.objective),
            "handed_over": next((note.split(":")[0] for note in res.notes if "SQP" in note), ""),
            "cold_wall": time.perf_counter() - began, "cold_objective": float(cold.objective),
            "cold_success": bool(cold.success)}


def one_qp_replan(prob, last, state, n, converged):
    """The same re-plan bounded to one SQP iteration (`max_iter=1`, one QP: a real-time
    iteration): its time and its largest state difference from the converged re-plan."""
    import numpy as np
    began = time.perf_counter()
    res = prob.resolve(warm=last, initial={"q": state[:n], "qd": state[n:]}, shift=SHIFT,
                       max_iter=1)
    return {"one_qp_wall": time.perf_counter() - began,
            "one_qp_distance": float(np.abs(res.y - converged.y).max())}


def replan_by_ipopt(lagrgen, prob, last, state, n):
    """The same re-plan by IPOPT from the same warm start (`solver="ipopt"`): its figures, or
    why it did not solve."""
    began, cpu = time.perf_counter(), cpu_time()
    try:
        res = prob.resolve(warm=last, initial={"q": state[:n], "qd": state[n:]}, shift=SHIFT,
                           solver="ipopt")
    except lagrgen.LagrgenError as exc:
        return {"ipopt_failed": str(exc)[:300]}
    return {"ipopt_wall": time.perf_counter() - began, "ipopt_cpu": cpu_time() - cpu,
            "ipopt_iterations": int(res.iterations), "ipopt_objective": float(res.objective),
            "ipopt_success": bool(res.success)}


def worker_min_time(folder, warm):
    """The Panda from start to goal in the least time within its limits: on 51 nodes alone
    (mesh_tol=None; the units compiled here), then refined to 1e-6 (the defaults), warm;
    checked by 101 nodes and by another start. Each figure is printed when measured."""
    import lagrgen
    _, model, mod = load_robot(lagrgen, "panda", folder)

    def problem(nodes):
        return least_effort(lagrgen, model, mod, "panda", nodes, duration=(0.1, 5.0))

    prob, out = problem(NODES), {"warm": []}
    with MeshLog() as log:
        res, out["single"] = timed_solve(lambda: prob.solve(progress=False, mesh_tol=None), log)
        out["notes"] = list(res.notes)
        emit(out)
        res, out["cold"] = timed_solve(lambda: prob.solve(progress=False), log)
        out["notes"] = list(res.notes)
        emit(out)
        for _ in range(warm):
            out["warm"].append(timed_solve(lambda: prob.solve(progress=False), log)[1])
            emit(out)
        finer = problem(2 * NODES - 1)
        out["finer"] = timed_solve(lambda: finer.solve(progress=False), log)[1]
        emit(out)
        out["other"] = timed_solve(
            lambda: prob.solve(progress=False, guess={"duration": 4.5}), log)[1]
    return out


def worker_chain(folder, links, warm):
    """benchmarks/collocation.py's planar chain: build, units, a solve on its 51 nodes alone
    (mesh_tol=None), then refined to mesh_tol 1e-6 and `warm` solves (each figure printed when
    measured)."""
    import sympy as sp
    import lagrgen
    from collocation import chain_lagrgen
    began = time.perf_counter()
    prob, _, built = chain_lagrgen(lagrgen, sp, np, folder, links)
    prob.transcription("exact")
    units = time.perf_counter()
    out = {"build": built - began, "units": units - built}
    with MeshLog() as log:
        out["single"] = timed_solve(lambda: prob.solve(progress=False, mesh_tol=None), log)[1]
        emit(out)
        out["cold"] = timed_solve(lambda: prob.solve(progress=False, mesh_tol=1e-6), log)[1]
        out["first_motion"] = out["build"] + out["units"] + out["cold"]["wall"]
        emit(out)
        out["warm"] = [timed_solve(lambda: prob.solve(progress=False, mesh_tol=1e-6), log)[1]
                       for _ in range(warm)]
    return out


# -- CasADi + IPOPT: the same Hermite–Simpson NLP ------------------------------------------------
def casadi_rnea(pm):
    """casadi.Function rnea(q, v, a) -> τ = M(q)·a + C(q, v)·v + g(q) of the Pinocchio model `pm`
    (the recursive Newton–Euler algorithm in each joint's frame, spatial vectors [ω; v], the
    joints' transforms, axes and inertias of benchmarks/c_loop.py's trace of `aba`)."""
    import casadi as ca
    from c_loop import gravity_acceleration, joint_link, motion_cross, spatial_inertia
    q, v, a = ca.SX.sym("q", pm.nq), ca.SX.sym("v", pm.nv), ca.SX.sym("a", pm.nv)
    nj = pm.njoints
    X, S, f = [None] * nj, [None] * nj, [None] * nj
    vel, acc = [ca.SX.zeros(6, 1)] * nj, [gravity_acceleration(ca, pm)] * nj
    for i in range(1, nj):
        jm, parent = pm.joints[i], pm.parents[i]
        X[i], S[i] = joint_link(ca, pm, i, q)
        vJ = ca.mtimes(S[i], v[jm.idx_v:jm.idx_v + jm.nv])
        vel[i] = ca.mtimes(X[i], vel[parent]) + vJ
        acc[i] = ca.mtimes(X[i], acc[parent]) + ca.mtimes(S[i], a[jm.idx_v:jm.idx_v + jm.nv]) \
            + ca.mtimes(motion_cross(ca, vel[i]), vJ)
        inertia = spatial_inertia(ca, pm.inertias[i])
        f[i] = ca.mtimes(inertia, acc[i]) - ca.mtimes(motion_cross(ca, vel[i]).T,
                                                      ca.mtimes(inertia, vel[i]))
    tau = [None] * pm.nv
    for i in range(nj - 1, 0, -1):
        jm, parent = pm.joints[i], pm.parents[i]
        t = ca.mtimes(S[i].T, f[i])
        for k in range(jm.nv):
            tau[jm.idx_v + k] = t[k]
        if parent > 0:
            f[parent] = f[parent] + ca.mtimes(X[i].T, f[i])
    return ca.Function("rnea", [q, v, a], [ca.vertcat(*tau)])


def check_rnea(f, pm, states=5):
    """The largest relative difference of `f` from pin.rnea at random states."""
    import pinocchio as pin
    from c_loop import check_against
    return check_against(f, pin.rnea, pm, spans=(2.0, 5.0), seed=2, states=states)


class HermiteSimpsonNLP:
    """lagrgen's Hermite–Simpson transcription of the least-effort move written in CasADi SX:
    per point z = [q, q̇, q̈, τ] (coordinates in Pinocchio's order); rows: RNEA(q, q̇, q̈) − τ = 0 at
    every point, per interval Simpson's (x_e − x_s)/h − (f_s + 4 f_m + f_e)/6 = 0 and Hermite's
    (x_m − (x_s + x_e)/2)/h − (f_s − f_e)/8 = 0 on x = (q, q̇), and each input's envelope
    lo ≤ 2 τ_m − (τ_s + τ_e)/2 ≤ hi; bounds from the limits at every point, the end states
    fixed; objective Σ_j w_j·Σ τ_j² with Simpson's weights."""

    def __init__(self, pm, nodes, duration, limits, options):
        import casadi as ca
        n, P = pm.nv, 2 * nodes - 1
        self.n, self.nodes, self.P, self.T = n, nodes, P, duration
        h = duration / (nodes - 1)
        Z = ca.SX.sym("z", 4 * n, P)
        q, v, a, u = Z[:n, :], Z[n:2 * n, :], Z[2 * n:3 * n, :], Z[3 * n:, :]
        rnea = casadi_rnea(pm)
        self.rnea_check = check_rnea(rnea, pm)
        residual = rnea.map(P)(q, v, a) - u
        x, dx = ca.vertcat(q, v), ca.vertcat(v, a)
        s, m, e = list(range(0, P - 1, 2)), list(range(1, P, 2)), list(range(2, P, 2))
        simpson = (x[:, e] - x[:, s]) / h - (dx[:, s] + 4 * dx[:, m] + dx[:, e]) / 6
        hermite = (x[:, m] - (x[:, s] + x[:, e]) / 2) / h - (dx[:, s] - dx[:, e]) / 8
        envelope = 2 * u[:, m] - (u[:, s] + u[:, e]) / 2
        weights = np.zeros(P)
        weights[0:-1:2] += h / 6
        weights[1::2] = 4 * h / 6
        weights[2::2] += h / 6
        objective = ca.sum2(ca.sum1(u * u) * ca.DM(weights).T)
        g = ca.vertcat(ca.vec(residual), ca.vec(simpson), ca.vec(hermite), ca.vec(envelope))
        lower, upper, velocity, effort = limits          # in Pinocchio's order
        equalities = np.zeros(n * P + 4 * n * (nodes - 1))
        self.g_lo = np.concatenate([equalities, np.tile(-effort, nodes - 1)])
        self.g_hi = np.concatenate([equalities, np.tile(effort, nodes - 1)])
        lo = np.tile(np.concatenate([lower, -velocity, np.full(n, -np.inf), -effort])[:, None],
                     (1, P))
        hi = np.tile(np.concatenate([upper, velocity, np.full(n, np.inf), effort])[:, None],
                     (1, P))
        self.x_lo, self.x_hi = lo, hi
        self.solver = ca.nlpsol("hs", "ipopt", {"x": ca.vec(Z), "f": objective, "g": g},
                                {"print_time": False, "ipopt": options})
        self.n_variables, self.n_constraints = Z.numel(), g.numel()

    def bounds(self, start, goal):
        """(lbx, ubx) with the first node at `start` and the last at `goal` ((2n,) each)."""
        lo, hi = self.x_lo.copy(), self.x_hi.copy()
        n = self.n
        lo[:2 * n, 0] = hi[:2 * n, 0] = start
        lo[:2 * n, -1] = hi[:2 * n, -1] = goal
        return lo.ravel(order="F"), hi.ravel(order="F")

    def solve(self, x0, start, goal):
        lbx, ubx = self.bounds(start, goal)
        began = time.perf_counter()
        sol = self.solver(x0=x0, lbx=lbx, ubx=ubx, lbg=self.g_lo, ubg=self.g_hi)
        wall = time.perf_counter() - began
        stats = self.solver.stats()
        Z = np.array(sol["x"]).reshape(4 * self.n, self.P, order="F")
        return Z, {"wall": wall, "iterations": int(stats["iter_count"]),
                   "objective": float(sol["f"]), "status": stats["return_status"],
                   "success": bool(stats["success"])}

    def times(self):
        return np.linspace(0.0, self.T, self.P)

    def cubic_start(self, pm, start, goal):
        """lagrgen's default start: each coordinate on the cubic between the end states (at rest),
        with the torques RNEA gives along it."""
        import pinocchio as pin
        n, T = self.n, self.T
        s = self.times() / T
        dq = (goal - start)[:n, None]
        q = start[:n, None] + dq * (3 * s ** 2 - 2 * s ** 3)
        v = dq * (6 * s - 6 * s ** 2) / T
        a = dq * (6 - 12 * s) / T ** 2
        data = pm.createData()
        u = np.array([pin.rnea(pm, data, q[:, j], v[:, j], a[:, j]) for j in range(self.P)]).T
        return np.vstack([q, v, a, u]).ravel(order="F")

    def shifted(self, Z, shift):
        """Z's motion with its first `shift` seconds dropped and its end held."""
        t = self.times()
        later = np.minimum(t + shift, self.T)
        return np.array([np.interp(later, t, row) for row in Z]).ravel(order="F")


def worker_casadi(urdf, names, start, goal, states, accuracy):
    """CasADi + IPOPT on the Panda's move at 101 nodes: build, solve, the re-plans from `states`
    (lagrgen's order) warm-started from the last plan shifted, each answer against aba."""
    began = time.perf_counter()
    import casadi as ca
    import pinocchio  # noqa: F401  (its import counted in `imports`)
    from lagrgen.collocation.solver import EXACT_OPTIONS
    imported = time.perf_counter()
    pm, order, to_pin, pinned = pin_robot(urdf, names)
    n = len(names)
    options = {"print_level": 0, "sb": "yes", "tol": 1e-8, **EXACT_OPTIONS}
    limits = [np.empty(n) for _ in range(4)]
    for k, x in enumerate(pin_limits(pm, order)):
        limits[k][order] = x
    nlp = HermiteSimpsonNLP(pm, REPLAN_NODES, DURATION, limits, options)
    built = time.perf_counter()
    rest = np.zeros(n)
    start, goal = pinned(np.concatenate([start, rest])), pinned(np.concatenate([goal, rest]))
    Z, first = nlp.solve(nlp.cubic_start(pm, start, goal), start, goal)
    out = {"imports": imported - began, "build": built - imported, "solve": first,
           "cpu": cpu_time(),
           "rnea_check": nlp.rnea_check, "version": ca.__version__,
           "variables": int(nlp.n_variables), "constraints": int(nlp.n_constraints)}

    def check(Z):
        t = nlp.times()[::2]
        Y = Z[:2 * n, ::2][to_pin]
        U = Z[3 * n:][order]
        acc = aba_accuracy(pm, order, t, Y, simpson_inputs(t, U))
        acc.update(limit_excess(Y, U, pin_limits(pm, order)))
        return acc

    if accuracy:
        out["solve"]["accuracy"] = check(Z)
    out["replans"] = []
    for k, state in enumerate(states):
        Z, step = nlp.solve(nlp.shifted(Z, SHIFT), pinned(np.asarray(state)), goal)
        if accuracy and k == 0:
            step["accuracy"] = check(Z)
        out["replans"].append(step)
    return out


# -- Crocoddyl (its own environment: pin 4.0.0) ---------------------------------------------------
def worker_crocoddyl(urdf, names, start, goal, states, reference):
    """Crocoddyl's BoxFDDP on the Panda's move (100 Euler steps, the goal a terminal cost, the
    effort limits as the controls' box) and the re-plans from `states`, warm-started from the
    last plan shifted; first its `calc` against `reference` (aba of the main environment's
    Pinocchio at random states). States and controls go back in lagrgen's order."""
    began = time.perf_counter()
    import crocoddyl
    import pinocchio as pin
    imported = time.perf_counter()
    pm, order, to_pin, pinned = pin_robot(urdf, names)
    n = len(names)

    rest = np.zeros(n)
    x0, goal = pinned(np.concatenate([start, rest])), pinned(np.concatenate([goal, rest]))
    effort = np.empty(n)
    effort[order] = pm.effortLimit[order]
    state = crocoddyl.StateMultibody(pm)
    actuation = crocoddyl.ActuationModelFull(state)
    running = crocoddyl.CostModelSum(state, n)
    running.addCost("effort", crocoddyl.CostModelResidual(
        state, crocoddyl.ResidualModelControl(state, n)), 2.0)          # Σ τ² per second
    terminal = crocoddyl.CostModelSum(state, n)
    terminal.addCost("goal", crocoddyl.CostModelResidual(
        state, crocoddyl.ResidualModelState(state, goal, n)), 2.0 * CROC_GOAL_WEIGHT)
    dynamics = crocoddyl.DifferentialActionModelFreeFwdDynamics(state, actuation, running)
    data, worst = dynamics.createData(), 0.0
    for x, u, qdd in reference:
        dynamics.calc(data, np.asarray(x), np.asarray(u))
        worst = max(worst, float(np.abs(data.xout - qdd).max() / max(np.abs(qdd).max(), 1.0)))
    out = {"imports": imported - began, "calc_check": worst,
           "version": f"crocoddyl {crocoddyl.__version__}, pin {pin.__version__}"}
    if worst > 1e-9:
        out["error"] = [f"Crocoddyl's calc differs from aba by {worst:.2g} (relative): not timed"]
        return out
    dt = DURATION / CROC_NODES
    step = crocoddyl.IntegratedActionModelEuler(dynamics, dt)
    step.u_lb, step.u_ub = -effort, effort
    end = crocoddyl.IntegratedActionModelEuler(
        crocoddyl.DifferentialActionModelFreeFwdDynamics(state, actuation, terminal), 0.0)
    problem = crocoddyl.ShootingProblem(x0, [step] * CROC_NODES, end)
    solver = crocoddyl.SolverBoxFDDP(problem)
    built = time.perf_counter()
    out["build"] = built - imported

    def solve(xs, us):
        began = time.perf_counter()
        converged = solver.solve(xs, us, CROC_MAX_ITER, False)
        wall = time.perf_counter() - began
        xs, us = np.array(solver.xs), np.array(solver.us)
        figures = {"wall": wall, "iterations": int(solver.iter), "success": bool(converged),
                   "objective": float((us ** 2).sum() * dt),
                   "goal_miss": float(np.abs(xs[-1] - goal).max()),
                   "t": (np.arange(CROC_NODES + 1) * dt).tolist(),
                   "y": xs[:, to_pin].T.tolist(), "u": us[:, order].T.tolist()}
        return xs, us, figures

    xs = [x0] * (CROC_NODES + 1)
    xs, us, out["solve"] = solve(xs, problem.quasiStatic(xs[:-1]))
    out["cpu"] = cpu_time()
    out["replans"] = []
    drop = int(round(SHIFT / dt))
    for k, y in enumerate(states):
        problem.x0 = pinned(np.asarray(y))
        xs_warm = np.vstack([problem.x0, xs[drop + 1:], np.repeat(xs[-1:], drop, axis=0)])
        us_warm = np.vstack([us[drop:], np.repeat(us[-1:], drop, axis=0)])
        xs, us, figures = solve(list(xs_warm), list(us_warm))
        if k:
            del figures["t"], figures["y"], figures["u"]
        out["replans"].append(figures)
    return out


def crocoddyl_reference(urdf, states=5):
    """[(x, u, q̈)] at random states in Pinocchio's order, q̈ from this environment's aba."""
    import pinocchio as pin
    pm = pin.buildModelFromUrdf(urdf)
    data, rng, out = pm.createData(), np.random.default_rng(3), []
    for _ in range(states):
        q = pin.randomConfiguration(pm, -np.ones(pm.nq), np.ones(pm.nq))
        v, u = rng.uniform(-2, 2, pm.nv), rng.uniform(-20, 20, pm.nv)
        out.append((np.concatenate([q, v]).tolist(), u.tolist(),
                    pin.aba(pm, data, q, v, u).tolist()))
    return out


def crocoddyl_accuracy(figures, urdf, names):
    """aba re-simulation of Crocoddyl's answer (each control held over its step) and how far it
    leaves the limits it cannot state."""
    pm, order, _, _ = pin_robot(urdf, names)
    t, Y, U = (np.array(figures.pop(key)) for key in ("t", "y", "u"))
    out = aba_accuracy(pm, order, t, Y, lambda k, s: U[:, k])
    out.update(limit_excess(Y, U, pin_limits(pm, order)))
    return out


# -- the runner -----------------------------------------------------------------------------------
WORKERS = {"first": worker_first_motion, "replan": worker_replan, "mintime": worker_min_time,
           "chain": worker_chain, "casadi": worker_casadi, "crocoddyl": worker_crocoddyl}


def spawn(kind, kwargs, python=None, timeout=1800):
    """Run the worker `kind` with `kwargs` in a fresh process (`python`: another environment's
    interpreter); its JSON result with `process` (wall time) added, or {"error": [...]}."""
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(kwargs, f)
    cmd = [python or sys.executable, str(Path(__file__).resolve()), "--worker", kind, f.name]
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    began, children = time.perf_counter(), resource.getrusage(resource.RUSAGE_CHILDREN)
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired as exc:
        stopped = f"stopped at its time limit of {timeout / 60:.0f} minutes"
        partial = exc.stdout.decode() if isinstance(exc.stdout, bytes) else exc.stdout or ""
        lines = [line for line in partial.splitlines() if line.startswith("{")]
        return dict(json.loads(lines[-1]), stopped=stopped) if lines else {"error": [stopped]}
    finally:
        os.unlink(f.name)
    wall = time.perf_counter() - began
    lines = [line for line in proc.stdout.splitlines() if line.startswith("{")]
    if proc.returncode or not lines:
        return {"error": (proc.stderr or proc.stdout).strip().splitlines()[-3:] or ["failed"]}
    out = json.loads(lines[-1])
    done = resource.getrusage(resource.RUSAGE_CHILDREN)
    out["process"] = wall
    out["process_cpu"] = (done.ru_utime + done.ru_stime) - (children.ru_utime + children.ru_stime)
    return out


def median(values):
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def ok(runs):
    """The runs with every figure (not failed, not stopped at the time limit)."""
    return [r for r in runs if "error" not in r and "partial" not in r]


def versions(croc):
    from importlib.metadata import PackageNotFoundError, version
    out = {"python": platform.python_version(), "cores": os.cpu_count()}
    for name in ("lagrgen", "pin", "casadi", "cyipopt-wheels", "example-robot-data", "numpy",
                 "scipy"):
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = "not installed"
    out["crocoddyl"] = croc
    return out


def croc_python(given):
    """The interpreter of Crocoddyl's environment, or None."""
    candidates = [given] if given else [os.environ.get("LAGRGEN_CROC_PYTHON"),
                                        str(HERE.parent / ".venv-croc" / "bin" / "python")]
    for path in candidates:
        if path and Path(path).exists():
            probe = subprocess.run([path, "-c", "import crocoddyl, pinocchio; print("
                                    "crocoddyl.__version__, pinocchio.__version__)"],
                                   capture_output=True, text=True)
            if probe.returncode == 0:
                return path
    return None


def casadi_available():
    try:
        import casadi  # noqa: F401
        return True
    except ImportError:
        return False


def measure(args, tmp, say):
    """Every figure of the report (a dict)."""
    repeat = 1 if args.quick else max(args.repeat, 1)
    replans = args.replans if args.replans is not None else 2 if args.quick else 10
    tmp = Path(tmp)
    urdf = robot_urdf("panda", tmp / "urdf")
    names, start, goal = PANDA_JOINTS, list(PANDA_START), list(PANDA_GOAL)
    out = {"repeat": repeat}
    say("Panda: first motion from a cold cache ...")
    out["panda"] = [spawn("first", {"robot": "panda", "folder": str(tmp / f"panda{r}"),
                                    "warm": 1, "accuracy": r == 0}) for r in range(repeat)]
    cache = str(tmp / "panda0")
    say("Panda: re-plans ...")
    out["replan"] = spawn("replan", {"folder": cache, "replans": replans, "accuracy": True})
    states = out["replan"].get("states", [])
    say("Panda: minimum time ...")
    out["mintime"] = spawn("mintime", {"folder": cache, "warm": repeat},
                           timeout=args.mintime_timeout)
    out["talos"] = out["chain"] = None
    if not args.quick and not args.no_talos:
        say("Talos: first motion from a cold cache ...")
        out["talos"] = [spawn("first", {"robot": "talos", "folder": str(tmp / f"talos{r}"),
                                        "warm": 0, "accuracy": r == 0},
                              timeout=args.talos_timeout) for r in range(repeat)]
    if not args.quick:
        say("20-link chain refined ...")
        out["chain"] = spawn("chain", {"folder": str(tmp / "chain"), "links": 20,
                                       "warm": repeat}, timeout=args.chain_timeout)
    out["casadi"] = None
    if casadi_available():
        say("CasADi + IPOPT ...")
        out["casadi"] = [spawn("casadi", {"urdf": urdf, "names": names, "start": start,
                                          "goal": goal, "states": states,
                                          "accuracy": r == 0}) for r in range(repeat)]
    croc = croc_python(args.croc_python)
    out["crocoddyl"] = None
    if croc:
        say("Crocoddyl ...")
        reference = crocoddyl_reference(urdf)
        runs = [spawn("crocoddyl", {"urdf": urdf, "names": names, "start": start, "goal": goal,
                                    "states": states, "reference": reference}, python=croc)
                for _ in range(repeat)]
        for r in ok(runs)[:1]:
            r["solve"]["accuracy"] = crocoddyl_accuracy(r["solve"], urdf, names)
            if r["replans"]:
                r["replans"][0]["accuracy"] = crocoddyl_accuracy(r["replans"][0], urdf, names)
        for r in ok(runs)[1:]:
            for figures in [r["solve"]] + r["replans"][:1]:
                for key in ("t", "y", "u"):
                    figures.pop(key, None)
        out["crocoddyl"] = runs
    return out


# -- the report -----------------------------------------------------------------------------------
def fmt(x, spec=".2f", none="—"):
    return none if x is None else format(x, spec)


def ms(seconds):
    return fmt(None if seconds is None else 1e3 * seconds, ".1f")


def failed(run):
    """The reason a worker gave no figures ("" when it did)."""
    if run is None:
        return "not run"
    if "error" in run:
        return "failed: " + " / ".join(str(line)[:200] for line in run["error"])
    if run.get("partial"):
        first = run["first"]
        return (f"{run['stopped']}, after its first solve ({first['wall']:.1f} s, meshes "
                f"{meshes_text(first['meshes'])}, error {first['error']:.2g})")
    return ""


def accuracy_cells(acc):
    """Per-interval error, whole-motion distance and the largest limit excess against aba."""
    if not acc:
        return "—", "—", "—"
    excess = max(acc["position"], acc["velocity"], acc["effort"])
    worst = max(("position", "velocity", "effort"), key=acc.get)
    return (f"{acc['interval']:.2g}", f"{acc['motion']:.2g}",
            "0" if excess == 0 else f"{excess:.2g} ({worst})")


def meshes_text(meshes):
    return " → ".join(str(m[0]) for m in meshes) if meshes else "—"


def solvers_text(log):
    return " / ".join(f"{m['solver']} {m['iterations']}" for m in log) if log else "—"


def panda_rows(out):
    """The head-to-head rows of the Panda's move."""
    rows, first, replan = [], ok(out["panda"] or []), out["replan"]
    header = ("| tool | first answer s (CPU s) | warm solve s | re-plan median ms | iterations | "
              "objective | error per interval vs aba | whole motion vs aba | limits exceeded |\n"
              "| --- | --: | --: | --: | --: | --: | --: | --: | --: |")
    if first:
        acc = first[0].get("accuracy")
        warm = median([w["wall"] for r in first for w in r["warm"]])
        f = first[0]["first"]
        rows.append(f"| lagrgen, refined to 1e-6 ({meshes_text(f['meshes'])} nodes) | "
                    f"{fmt(median([r['first_motion'] for r in first]))} "
                    f"({fmt(median([r.get('first_motion_cpu') for r in first]))}) | "
                    f"{fmt(warm)} | — | {f['iterations']} | {f['objective']:.10g} | "
                    + " | ".join(accuracy_cells(acc)) + " |")
    else:
        rows.append(f"| lagrgen, refined to 1e-6 | {failed((out['panda'] or [None])[0])} |"
                    " | | | | | | |")
    if not failed(replan):
        plan = replan["plan"]
        steps = replan["replans"]
        acc = steps[0].get("accuracy") if steps else None
        rows.append(f"| lagrgen, {REPLAN_NODES} nodes, mesh_tol=None (re-plans: `resolve`) | "
                    f"(the same units) | {fmt(plan['wall'])} | "
                    f"{ms(median([s['wall'] for s in steps]))} | {plan['iterations']} | "
                    f"{plan['objective']:.10g} | "
                    + " | ".join(accuracy_cells(plan.get("accuracy"))) + " |")
        if acc:
            rows.append(f"| ↳ its first re-plan | | | {ms(steps[0]['wall'])} | "
                        f"{steps[0]['iterations']} ({steps[0]['solver']}) | "
                        f"{steps[0]['objective']:.10g} | "
                        + " | ".join(accuracy_cells(acc)) + " |")
    else:
        rows.append(f"| lagrgen, {REPLAN_NODES} nodes, re-plans | {failed(replan)} | | | | | | |"
                    " |")
    runs = ok(out["casadi"] or [])
    if runs:
        c = runs[0]
        acc = c["solve"].get("accuracy")
        first_answer = median([r["imports"] + r["build"] + r["solve"]["wall"] for r in runs])
        rows.append(f"| CasADi {c['version']} + IPOPT, {REPLAN_NODES} nodes (build "
                    f"{fmt(median([r['build'] for r in runs]))} s) | {fmt(first_answer)} "
                    f"({fmt(median([r.get('cpu') for r in runs]))}) | "
                    f"{fmt(median([r['solve']['wall'] for r in runs]))} | "
                    f"{ms(median([s['wall'] for r in runs for s in r['replans']]))} | "
                    f"{c['solve']['iterations']} | {c['solve']['objective']:.10g} | "
                    + " | ".join(accuracy_cells(acc)) + " |")
        if c["replans"] and c["replans"][0].get("accuracy"):
            s = c["replans"][0]
            rows.append(f"| ↳ its first re-plan | | | {ms(s['wall'])} | {s['iterations']} | "
                        f"{s['objective']:.10g} | "
                        + " | ".join(accuracy_cells(s["accuracy"])) + " |")
    else:
        rows.append(f"| CasADi + IPOPT | {failed((out['casadi'] or [None])[0])} | | | | | | | |")
    runs = ok(out["crocoddyl"] or [])
    if runs:
        c = runs[0]
        acc = c["solve"].get("accuracy")
        converged = "" if c["solve"]["success"] else " (not converged)"
        rows.append(f"| {c['version']}, BoxFDDP, {CROC_NODES} Euler steps (goal missed by "
                    f"{c['solve']['goal_miss']:.2g}) | "
                    f"{fmt(median([r['imports'] + r['build'] + r['solve']['wall'] for r in runs]))}"
                    f" ({fmt(median([r.get('cpu') for r in runs]))}) | "
                    f"{fmt(median([r['solve']['wall'] for r in runs]))} | "
                    f"{ms(median([s['wall'] for r in runs for s in r['replans']]))} | "
                    f"{c['solve']['iterations']}{converged} | {c['solve']['objective']:.10g} | "
                    + " | ".join(accuracy_cells(acc)) + " |")
    else:
        reason = failed((out["crocoddyl"] or [None])[0]) if out["crocoddyl"] else \
            "not run (no Crocoddyl environment: --croc-python)"
        rows.append(f"| Crocoddyl | {reason} | | | | | | | |")
    return header + "\n" + "\n".join(rows)


def phases_table(runs, title):
    """The phases of a cold first motion (medians over the runs)."""
    good = ok(runs or [])
    if not good:
        return f"{title}: {failed((runs or [None])[0])}\n"
    r = good[0]
    lines = [f"{title} ({r['n']} joints, formulation {r['formulation']!r}, "
             f"{r['variables']} variables on the first mesh; {len(good)} cold "
             f"process{'es: medians' if len(good) > 1 else ''}):\n",
             "| phase | wall s | CPU s |", "| --- | --: | --: |"]
    for key, name in (("imports", "`import lagrgen` (lazy: its modules load in the next phase)"),
                      ("build", "`from_urdf` + `build`"),
                      ("hessian_unit", "the residual's Hessian unit"),
                      ("problem_unit", "the objective and NLP units (`transcription`)"),
                      ("solve", "`solve` (refined to 1e-6)"),
                      ("first_motion", "**first optimal motion** (`import lagrgen` on)")):
        lines.append(f"| {name} | {fmt(median([g[key] for g in good]))} | "
                     f"{fmt(median([g.get(key + '_cpu') for g in good]))} |")
    lines.append(f"| (the whole process: interpreter start, warm solves, accuracy) | "
                 f"{fmt(median([g['process'] for g in good]))} | "
                 f"{fmt(median([g.get('process_cpu') for g in good]))} |")
    f = r["first"]
    lines.append("")
    lines.append(f"Meshes {meshes_text(f['meshes'])} nodes (solver and iterations per mesh: "
                 f"{solvers_text(f['log'])}); {f['callback_seconds']:.2f} s of the solve's "
                 f"{f['seconds']:.2f} s in lagrgen's callbacks; error {f['error']:.2g}, "
                 f"objective {f['objective']:.10g}, success {f['success']}.")
    for w in r["warm"]:
        lines.append(f"Warm solve in the same process: {w['wall']:.2f} s "
                     f"({solvers_text(w['log'])}), objective {w['objective']:.10g}.")
    w = r.get("ipopt_warm")
    if w:
        lines.append(f"Warm solve with `solver=\"ipopt\"` (IPOPT on every mesh; by default the "
                     f"SQP solves the refined ones): {w['wall']:.2f} s "
                     f"({solvers_text(w['log'])}), objective {w['objective']:.10g}, error "
                     f"{w['error']:.2g}, success {w['success']}.")
    refused = {m["sqp_refused"] for g in good for m in g["first"]["log"] if m["sqp_refused"]}
    for reason in sorted(refused):
        lines.append(f"The SQP did not apply on a mesh: {reason}")
    if r.get("accuracy"):
        i, m, e = accuracy_cells(r["accuracy"])
        lines.append(f"Against aba: {i} per interval, {m} over the whole motion; limits "
                     f"exceeded: {e}.")
    return "\n".join(lines) + "\n"


def replan_table(replan):
    if failed(replan):
        return f"Re-plans: {failed(replan)}\n"
    lines = [f"Re-plans of the Panda's move on {REPLAN_NODES} nodes, each from the last plan's "
             f"state at {SHIFT} s (`resolve(warm=last, initial=..., shift={SHIFT})`), against a "
             "cold `solve` of the same problem:\n",
             "| re-plan | `resolve` ms | CPU ms | solver, iterations | objective | cold solve ms "
             "| cold iterations | cold objective | relative difference | notes | "
             "`solver=\"ipopt\"` ms | CPU ms | IPOPT iterations | IPOPT objective, relative "
             "difference | one QP (`max_iter=1`) ms | its largest state difference |",
             "| --: | --: | --: | --- | --: | --: | --: | --: | --: | --: | --: | --: | --: | --: "
             "| --: | --: |"]
    for k, s in enumerate(replan["replans"], 1):
        diff = abs(s["objective"] - s["cold_objective"]) / max(abs(s["cold_objective"]), 1e-300)
        lines.append(f"| {k} | {ms(s['wall'])} | {ms(s.get('cpu'))} | {s['solver']} "
                     f"{s['iterations']}{'' if s['success'] else ' (failed)'} | "
                     f"{s['objective']:.10g} | {ms(s['cold_wall'])} | {s['cold_iterations']}"
                     f"{'' if s['cold_success'] else ' (failed)'} | {s['cold_objective']:.10g} |"
                     f" {diff:.1e} | {s['notes']} | {ipopt_cells(s)} | "
                     f"{ms(s.get('one_qp_wall'))} | {s.get('one_qp_distance', float('nan')):.2g} |")
    return "\n".join(lines) + "\n" + disturbed_table(replan.get("disturbed", []))


def disturbed_table(runs):
    """The disturbed re-plans' table (`disturbed_replan`), or nothing where none ran."""
    if not runs:
        return ""
    lines = [f"\nRe-plans from a disturbed state (the plan's state at {SHIFT} s, each joint angle "
             "moved by the disturbance times a normal draw), against a cold `solve` of the same "
             "problem:\n",
             "| plan | disturbance rad | `resolve` ms | solver, iterations | objective | cold solve "
             "ms | cold objective | relative difference | the SQP's note |",
             "| --- | --: | --: | --- | --: | --: | --: | --: | --- |"]
    for s in runs:
        diff = abs(s["objective"] - s["cold_objective"]) / max(abs(s["cold_objective"]), 1e-300)
        plan = f"{s['nodes']} nodes" + (", refined to 1e-6" if s["refined"] else "")
        lines.append(f"| {plan} | {s['size']:g} | {ms(s['wall'])} | {s['solver']} "
                     f"{s['iterations']}{'' if s['success'] else ' (failed)'} | "
                     f"{s['objective']:.10g} | {ms(s['cold_wall'])}"
                     f"{'' if s['cold_success'] else ' (failed)'} | {s['cold_objective']:.10g} | "
                     f"{diff:.1e} | {s['handed_over'].replace('|', '/') or '—'} |")
    return "\n".join(lines) + "\n"


def ipopt_cells(s):
    """A re-plan's cells of IPOPT's figures from the same warm start."""
    if "ipopt_wall" not in s:
        reason = s.get("ipopt_failed", "not measured").replace("|", "/")
        return f"— | — | — | {reason}"
    diff = (abs(s["ipopt_objective"] - s["cold_objective"])
            / max(abs(s["cold_objective"]), 1e-300))
    return (f"{ms(s['ipopt_wall'])} | {ms(s['ipopt_cpu'])} | {s['ipopt_iterations']}"
            f"{'' if s['ipopt_success'] else ' (not converged)'} | "
            f"{s['ipopt_objective']:.10g}, {diff:.1e}")


def mintime_table(mt):
    if failed(mt):
        return f"Minimum time: {failed(mt)}\n"
    lines = [f"The Panda from start to goal in the least time within its limits "
             f"(`duration=(0.1, 5.0)`, `minimize(time=True)`, {NODES} nodes refined to 1e-6):\n",
             "| solve | wall s | CPU s | duration s | meshes | solvers, iterations | error | "
             "success |", "| --- | --: | --: | --: | --- | --- | --: | --- |"]
    runs = [(f"{NODES} nodes alone, mesh_tol=None (units compiled here)", mt.get("single")),
            ("refined (the defaults)", mt.get("cold"))] + \
        [(f"refined, warm {k}", w) for k, w in enumerate(mt.get("warm", []), 1)] + \
        [(f"{2 * NODES - 1} nodes, refined", mt.get("finer")),
         ("refined, from duration 4.5 s", mt.get("other"))]
    missing = [name for name, r in runs if r is None]
    runs = [(name, r) for name, r in runs if r is not None]
    for name, r in runs:
        lines.append(f"| {name} | {fmt(r['wall'])} | {fmt(r.get('cpu'))} | "
                     f"{r['duration']:.6f} | {meshes_text(r['meshes'])} | "
                     f"{solvers_text(r['log'])} | {r['error']:.2g} | {r['success']} |")
    if missing:
        lines.append(f"\n{mt.get('stopped', 'stopped')}: no figures for {', '.join(missing)}.")
    refined = [r["duration"] for name, r in runs if "refined" in name and r["success"]]
    if len(refined) > 1:
        lines.append(f"\nThe refined least times agree to {max(refined) - min(refined):.1e} s.")
    for note in mt.get("notes", []):
        lines.append(f"Note: {note}")
    return "\n".join(lines) + "\n"


def chain_table(chain):
    if failed(chain):
        return f"20-link chain: {failed(chain)}\n"
    single = chain.get("single")
    head = "" if single is None else (
        f"On its 51 nodes alone (mesh_tol=None): {single['wall']:.2f} s ({single['cpu']:.2f} s "
        f"CPU), {single['iterations']} iterations, error {single['error']:.2g}, objective "
        f"{single['objective']:.10g}.\n\n")
    if "cold" not in chain:
        return (f"20-link chain: build {chain['build']:.2f} s, units {chain['units']:.2f} s.\n"
                f"{head}Refined to mesh_tol 1e-6: {chain.get('stopped', 'no answer')}.\n")
    c = chain["cold"]
    lines = ["benchmarks/collocation.py's 20-link planar chain (hanging to 30° in 2 s, least "
             "effort), refined to mesh_tol 1e-6:\n",
             "| phase | wall s | CPU s |", "| --- | --: | --: |",
             f"| build | {fmt(chain['build'])} | — |", f"| units | {fmt(chain['units'])} | — |",
             f"| solve ({meshes_text(c['meshes'])} nodes, {solvers_text(c['log'])}) | "
             f"{fmt(c['wall'])} | {fmt(c.get('cpu'))} |",
             f"| **first motion** | {fmt(chain['first_motion'])} | — |"]
    for k, w in enumerate(chain.get("warm", []), 1):
        lines.append(f"| warm solve {k} ({solvers_text(w['log'])}) | {fmt(w['wall'])} | "
                     f"{fmt(w.get('cpu'))} |")
    lines.append(f"\nError {c['error']:.2g}, objective {c['objective']:.10g}, success "
                 f"{c['success']}.")
    if chain.get("stopped"):
        lines.append(f"The warm solves: {chain['stopped']}.")
    return head + "\n".join(lines) + "\n"


def peers_notes(out):
    lines = []
    for r in ok(out["casadi"] or [])[:1]:
        lines.append(f"CasADi's RNEA against `pin.rnea`: {r['rnea_check']:.1e} (relative); its NLP "
                     f"{r['variables']} variables, {r['constraints']} constraints; imports "
                     f"{r['imports']:.2f} s, building the NLP {r['build']:.2f} s.")
    for r in ok(out["crocoddyl"] or [])[:1]:
        lines.append(f"Crocoddyl's `calc` against this environment's `aba`: {r['calc_check']:.1e} "
                     f"(relative); converged: solve {r['solve']['success']}, re-plans "
                     f"{[s['success'] for s in r['replans']]}.")
    return "\n".join(lines)


def report(out, load, quick):
    info = out["versions"]
    kept = ", ".join(f"{k} {v}" for k, v in info.items())
    head = (f"# Optimal motions of robots (issue 42){' — quick run' if quick else ''}\n\n"
            f"{time.strftime('%Y-%m-%d %H:%M')}, {platform.machine()}, {kept}; load average "
            f"{load}; medians of {out['repeat']} cold process(es) where several ran. A shared "
            "2-core machine: where the load distorts wall times, the CPU times (user + system "
            "of the process, threads included) are the figures to compare.\n")
    if out.get("header_note"):
        head += f"\n{out['header_note']}\n"
    parts = [head,
             "## The Panda, rest to rest in 1 s within every URDF limit, least ∫Στ² dt\n",
             f"From `PANDA_START` to `PANDA_GOAL`; every answer's nodes re-simulated with "
             f"Pinocchio's `aba` (DOP853, rtol 1e-11): the largest error at an interval's end "
             f"relative to 1 + each state's size, and the whole motion re-simulated from the "
             f"first node, its distance from the last (rad, rad/s). First answer: from a fresh "
             f"process with an empty cache, `import` included (lagrgen: from_urdf, build, the "
             f"units compiled on first use, the solve); warm: the same problem again in the same "
             f"process; re-plan: from the state at {SHIFT} s, warm-started.\n",
             panda_rows(out), "", peers_notes(out), "",
             phases_table(out["panda"], "lagrgen's first motion of the Panda"),
             replan_table(out["replan"]), mintime_table(out["mintime"])]
    if not quick:
        parts += ["## Talos, torso and both arms (16 joints)\n",
                  phases_table(out["talos"], "lagrgen's first motion of Talos"),
                  "## A 20-link planar chain\n", chain_table(out["chain"])]
    return "\n".join(parts)


def strip_arrays(out):
    """`out` without the answers' arrays (the JSON keeps the figures)."""
    if isinstance(out, dict):
        return {k: strip_arrays(v) for k, v in out.items() if k not in ("t", "y", "u")}
    if isinstance(out, list):
        return [strip_arrays(v) for v in out]
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="one of each, no Talos, no chain")
    parser.add_argument("--repeat", type=int, default=3, help="cold processes per figure")
    parser.add_argument("--replans", type=int,
                        help="re-plans in the loop (default 10, 2 with --quick)")
    parser.add_argument("--no-talos", action="store_true", help="leave Talos out")
    parser.add_argument("--talos-timeout", type=float, default=1200,
                        help="seconds a Talos process may take")
    parser.add_argument("--mintime-timeout", type=float, default=600,
                        help="seconds the minimum-time process may take")
    parser.add_argument("--chain-timeout", type=float, default=1200,
                        help="seconds the 20-link chain's process may take")
    parser.add_argument("--croc-python", help="the interpreter of Crocoddyl's environment")
    parser.add_argument("--worker", nargs=2, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        kind, path = args.worker
        kwargs = json.loads(Path(path).read_text())
        print(json.dumps(WORKERS[kind](**kwargs)))
        return 0
    say = lambda s: print(s, file=sys.stderr, flush=True)      # noqa: E731
    before = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="lagrgen_robot_motions_") as tmp:
        out = measure(args, tmp, say)
    after = os.getloadavg()
    load = (f"{' '.join(f'{x:.2f}' for x in before)} before, "
            f"{' '.join(f'{x:.2f}' for x in after)} after")
    out["versions"] = versions(next((r["version"] for r in ok(out["crocoddyl"] or [])),
                                    "not run"))
    out["load"] = load
    given = [os.path.basename(a) if os.path.isabs(a) else a
             for a in (sys.argv[1:] if argv is None else argv)]
    if given:
        out["header_note"] = f"Run as `python benchmarks/robot_motions.py {' '.join(given)}`."
    text = report(out, load, args.quick)
    print(text)
    RESULTS.mkdir(exist_ok=True)
    stem = "robot_motions_quick" if args.quick else "robot_motions"
    (RESULTS / f"{stem}.md").write_text(text)
    (RESULTS / f"{stem}.json").write_text(json.dumps(strip_arrays(out), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
