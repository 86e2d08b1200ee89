"""Direct collocation (issue 29): lagrgen.Collocation against opty 1.5.0 on opty's own gallery
problems, side by side in the same run, each in a fresh process; iterations with the exact Hessian
against IPOPT's quasi-Newton update; growth with the number of nodes and with the model's size.

    python benchmarks/collocation.py [--quick] [--no-opty]

Problems (as in opty's examples-gallery, read from its sources):
  swing-up   compound pendulum I·θ̈ + m·g·d·sin θ = T, |T| ≤ 2, θ: 0 → π at rest in 10 s,
             min ∫T² dt; 501 nodes, backward Euler; opty's start: standard-normal random values
             (here with a fixed seed, the same numbers for both tools)
  cart       two-link pendulum on a cart (beginner/intermediate `plot_two_link_pendulum_on_a_cart`):
             from hanging to upright at rest (final accelerations 0 as well) in the least time,
             |F| ≤ 50, |q1| ≤ 5; 300 nodes, backward Euler, free duration (opty: the node
             interval h is the objective; lagrgen: T = 299·h); opty's start (linear angles,
             F = 50, h = 0.01)

Timings: `process` is the wall time of the whole fresh process (interpreter, imports, build,
solve); `in-process` starts after the imports of numpy and SymPy that both tools make (so it holds
each tool's own imports, the model's build or opty's set-up, and the solve). lagrgen runs twice:
`cold` into an empty build directory (model compiled, collocation units generated and compiled),
then `warm` (both cached, as a second run of a script finds them). opty's `numpy` backend is the
one its gallery uses. lagrgen solves on the given grid alone (mesh_tol=None, as opty does; the
worker's --mesh-tol refines) and reports each solution's dynamics error. Writes
benchmarks/results/collocation.md and .json.
"""
import argparse
import compileall
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "collocation"
OPTY_OBJECTIVES = {"swing-up": 15.641553623563, "cart": 9.7801161e-03}   # issue 29, opty 1.5.0


# -- the problems, as lagrgen code -------------------------------------------------------------
def swing_up_lagrgen(lagrgen, sp, np, out_dir, nodes=501, start="random"):
    model = lagrgen.Model("bench_swing_up")
    th, = model.coordinates("theta")
    I, m, g, d = model.parameters(I=1.0, m=1.0, g=9.81, d=1.0)
    T, = model.inputs("T")
    model.kinetic_energy(I * th.diff(model.t) ** 2 / 2)
    model.potential_energy(-m * g * d * sp.cos(th))
    model.torque(T, th)
    mod = lagrgen.build(model, out_dir=out_dir, quiet=True)
    built = time.perf_counter()
    prob = lagrgen.Collocation(mod, nodes=nodes, duration=10.0, scheme="backward-euler")
    prob.bound("T", -2, 2)
    prob.initial(q=[0.0], qd=[0.0]).final(q=[np.pi], qd=[0.0])
    prob.minimize(integral=T ** 2)
    if start == "rest":
        return prob, {"theta": 0.0, "theta_dot": 0.0}, built
    theta, omega, torque = swing_up_start(np, nodes)
    return prob, {"theta": theta, "theta_dot": omega, "T": torque}, built


def swing_up_start(np, nodes, seed=0):
    rng = np.random.default_rng(seed)
    return rng.standard_normal(nodes), rng.standard_normal(nodes), rng.standard_normal(nodes)


def cart_lagrgen(lagrgen, sp, np, out_dir, nodes=300):
    model = lagrgen.Model("bench_cart_two_link")
    q1, q2, q3 = model.coordinates("q1 q2 q3")
    lx, m1, m2, m3, g, i1, i2 = model.parameters(lx=2.0, m1=1.0, m2=1.0, m3=1.0, g=9.81,
                                                 iZZ1=2.0, iZZ2=2.0)
    F, = model.inputs("F")
    P1 = sp.Matrix([q1, 0])
    P2 = P1 + lx * sp.Matrix([sp.cos(q2), sp.sin(q2)])
    P3 = P2 + lx * sp.Matrix([sp.cos(q3), sp.sin(q3)])
    model.particle(m1, P1)
    model.rigid_body(m2, i1, P2, q2)          # mass at the rod's end, inertia iZZ1 about it
    model.rigid_body(m3, i2, P3, q3)
    model.potential_energy(m2 * g * P2[1] + m3 * g * P3[1])
    model.force(sp.Matrix([F, 0]), at=P1)
    mod = lagrgen.build(model, out_dir=out_dir, quiet=True)
    built = time.perf_counter()
    prob = lagrgen.Collocation(mod, nodes=nodes, duration=(0.0, nodes - 1.0),
                               scheme="backward-euler")
    prob.bound("F", -50, 50)
    prob.bound("q1", -5, 5)
    prob.initial(q=[0, -np.pi / 2, -np.pi / 2], qd=[0, 0, 0])
    prob.final(q={"q2": np.pi / 2, "q3": np.pi / 2}, qd=[0, 0, 0], qdd=[0, 0, 0])
    prob.minimize(time=True)
    line = np.linspace(-np.pi / 2, np.pi / 2, nodes)
    guess = {"q2": line, "q3": line, "F": 50.0, "duration": 0.01 * (nodes - 1),
             "q1_dot": 0.0, "q2_dot": 0.0, "q3_dot": 0.0}       # opty's start: speeds 0
    return prob, guess, built


def chain_lagrgen(lagrgen, sp, np, out_dir, links, nodes=51):
    """An n-link pendulum with a torque at every joint, swung from hanging at rest to every link
    at 30° at rest in 2 s with the least ∫Σ τ² dt (Hermite–Simpson)."""
    model = lagrgen.Model(f"bench_chain{links}")
    q = model.coordinates([f"q{i}" for i in range(links)])
    g, = model.parameters(g=9.81)
    tau = model.inputs([f"tau{i}" for i in range(links)])
    point = sp.Matrix([0, 0])
    for i in range(links):
        point = point + sp.Matrix([sp.sin(q[i]), -sp.cos(q[i])])
        model.particle(1, point)
        model.potential_energy(g * point[1])
        model.torque(tau[i], q[i] - (q[i - 1] if i else 0))
    mod = lagrgen.build(model, out_dir=out_dir, quiet=True)
    built = time.perf_counter()
    prob = lagrgen.Collocation(mod, nodes=nodes, duration=2.0, scheme="hermite-simpson")
    prob.initial(q=[0.0] * links, qd=[0.0] * links)
    prob.final(q=[np.pi / 6] * links, qd=[0.0] * links)
    prob.minimize(integral=sum(t ** 2 for t in tau))
    return prob, None, built


# -- workers (each in a fresh process) -----------------------------------------------------------
#: IPOPT's own defaults for the options lagrgen sets with the exact Hessian.
IPOPT_DEFAULTS = {"mu_strategy": "monotone", "min_refinement_steps": 1}


def worker_floor():
    """The imports both tools' scripts make."""
    began = time.perf_counter()
    import numpy  # noqa: F401
    import sympy  # noqa: F401
    return {"tool": "floor", "imports": time.perf_counter() - began}


def worker_lagrgen(task, out_dir, hessian, nodes, links, restart, start, options, mesh_tol=None):
    began = time.perf_counter()
    import numpy as np
    import sympy as sp
    imported = time.perf_counter()
    import lagrgen
    if task == "swing-up":
        prob, guess, built = swing_up_lagrgen(lagrgen, sp, np, out_dir, nodes or 501, start)
    elif task == "cart":
        prob, guess, built = cart_lagrgen(lagrgen, sp, np, out_dir, nodes or 300)
    else:
        prob, guess, built = chain_lagrgen(lagrgen, sp, np, out_dir, links, nodes or 51)
    if restart:
        guess = opty_cart_guess(np, np.load(restart), prob.nodes)
    prob.transcription(hessian)
    ready = time.perf_counter()
    res = prob.solve(guess=guess, hessian=hessian, progress=False, options=options,
                     mesh_tol=mesh_tol)
    done = time.perf_counter()
    objective = res.objective / (prob.nodes - 1) if task == "cart" else res.objective
    return {"tool": "lagrgen", "imports": imported - began, "build": built - imported,
            "setup": ready - built, "solve": done - ready, "in_process": done - imported,
            "iterations": res.iterations, "objective": objective, "status": res.status,
            "ipopt_seconds": res.seconds, "callback_seconds": res.callback_seconds,
            "violation": res.constraint_violation, "dynamics_error": res.error,
            "meshes": [m.nodes for m in res.meshes],
            "variables": int(prob.layout.size),
            "constraints": int(prob.transcription(hessian).n_constraints)}


def opty_cart_guess(np, solution, nodes):
    """opty's free vector [q1..3, u1..3 (nodes each), F, h1..3 (nodes each), h] as a lagrgen
    guess."""
    S = solution[:6 * nodes].reshape(6, nodes)
    U = solution[6 * nodes:10 * nodes].reshape(4, nodes)
    names = ["q1", "q2", "q3", "q1_dot", "q2_dot", "q3_dot"]
    guess = dict(zip(names, S))
    guess.update({"F": U[0], "q1_ddot": U[1], "q2_ddot": U[2], "q3_ddot": U[3],
                  "duration": (nodes - 1) * solution[-1]})
    return guess


def worker_opty(task, save, tol=None):
    began = time.perf_counter()
    import numpy as np
    import sympy as sm
    imported = time.perf_counter()
    from opty import Problem
    if task == "swing-up":
        from opty import create_objective_function
        duration, nodes = 10.0, 501
        interval = duration / (nodes - 1)
        I, m, g, d, t = sm.symbols('I, m, g, d, t')
        theta, omega, T = sm.symbols('theta, omega, T', cls=sm.Function)
        states = (theta(t), omega(t))
        eom = sm.Matrix([theta(t).diff() - omega(t),
                         I * omega(t).diff() + m * g * d * sm.sin(theta(t)) - T(t)])
        obj, obj_grad = create_objective_function(sm.Integral(T(t) ** 2, t), states, (T(t),),
                                                  tuple(), nodes, interval, time_symbol=t)
        prob = Problem(obj, obj_grad, eom, states, nodes, interval,
                       known_parameter_map={I: 1.0, m: 1.0, g: 9.81, d: 1.0},
                       instance_constraints=(theta(0.0), theta(duration) - np.pi, omega(0.0),
                                             omega(duration)),
                       bounds={T(t): (-2.0, 2.0)}, time_symbol=t, backend='numpy')
        guess = np.concatenate(swing_up_start(np, nodes))
    else:
        import sympy.physics.mechanics as me
        N, A1, A2 = sm.symbols('N A1, A2', cls=me.ReferenceFrame)
        t = me.dynamicsymbols._t
        O, P1, P2, P3 = sm.symbols('O P1 P2 P3', cls=me.Point)
        O.set_vel(N, 0)
        q1, q2, q3, u1, u2, u3, F = me.dynamicsymbols('q1 q2 q3 u1 u2 u3 F')
        h1, h2, h3 = me.dynamicsymbols('h1 h2 h3')
        lx, m1, m2, m3, g, iZZ1, iZZ2 = sm.symbols('lx, m1, m2, m3 g, iZZ1, iZZ2')
        A1.orient_axis(N, q2, N.z)
        A1.set_ang_vel(N, u2 * N.z)
        A2.orient_axis(N, q3, N.z)
        A2.set_ang_vel(N, u3 * N.z)
        P1.set_pos(O, q1 * N.x)
        P2.set_pos(P1, lx * A1.x)
        P2.v2pt_theory(P1, N, A1)
        P3.set_pos(P2, lx * A2.x)
        P3.v2pt_theory(P2, N, A2)
        bodies = [me.Particle('P1a', P1, m1),
                  me.RigidBody('P2a', P2, A1, m2, (me.inertia(A1, 0, 0, iZZ1), P2)),
                  me.RigidBody('P3a', P3, A2, m3, (me.inertia(A2, 0, 0, iZZ2), P3))]
        loads = [(P1, F * N.x - m1 * g * N.y), (P2, -m2 * g * N.y), (P3, -m3 * g * N.y)]
        kd = sm.Matrix([q1.diff(t) - u1, q2.diff(t) - u2, q3.diff(t) - u3])
        KM = me.KanesMethod(N, q_ind=[q1, q2, q3], u_ind=[u1, u2, u3], kd_eqs=kd)
        fr, frstar = KM.kanes_equations(bodies, loads=loads)
        eom = kd.col_join(fr + frstar)
        eom = eom.col_join(sm.Matrix([h1 - u1.diff(t), h2 - u2.diff(t), h3 - u3.diff(t)]))
        eom = sm.simplify(eom)
        h = sm.symbols('h')
        nodes = 300
        duration = (nodes - 1) * h
        target = np.pi / 2

        def obj(free):
            return free[-1]

        def obj_grad(free):
            grad = np.zeros_like(free)
            grad[-1] = 1.0
            return grad
        prob = Problem(obj, obj_grad, eom, (q1, q2, q3, u1, u2, u3), nodes, h,
                       known_parameter_map={lx: 2.0, m1: 1.0, m2: 1.0, m3: 1.0, g: 9.81,
                                            iZZ1: 2.0, iZZ2: 2.0},
                       instance_constraints=(
                           q1.func(0.0), q2.func(0.0) + target, q3.func(0.0) + target,
                           u1.func(0.0), u2.func(0.0), u3.func(0.0),
                           q2.func(duration) - target, q3.func(duration) - target,
                           u1.func(duration), u2.func(duration), u3.func(duration),
                           h1.func(duration), h2.func(duration), h3.func(duration)),
                       time_symbol=t,
                       bounds={F: (-50.0, 50.0), q1: (-5.0, 5.0), h: (0.0, 1.0)},
                       backend='numpy')
        guess = np.zeros(prob.num_free)
        guess[1 * nodes:2 * nodes] = np.linspace(-target, target, num=nodes)
        guess[2 * nodes:3 * nodes] = np.linspace(-target, target, num=nodes)
        guess[6 * nodes:7 * nodes] = 50.0
        guess[-1] = 0.01
    prob.add_option("print_level", 0)
    if tol is not None:
        prob.add_option("tol", tol)
        prob.add_option("max_iter", 5000)
    ready = time.perf_counter()
    solution, info = prob.solve(guess)
    done = time.perf_counter()
    if save:
        np.save(save, solution)
    objective = solution[-1] if task == "cart" else info["obj_val"]
    return {"tool": "opty", "imports": imported - began, "build": 0.0,
            "setup": ready - imported, "solve": done - ready, "in_process": done - imported,
            "iterations": len(prob.obj_value), "objective": float(objective),
            "status": int(info["status"]), "variables": int(prob.num_free)}


# -- the runner ----------------------------------------------------------------------------------
OPTY = "opty 1.5.0 (quasi-Newton)"
TIMES = ("imports", "build", "setup", "solve", "in_process", "process", "ipopt_seconds",
         "callback_seconds")


def spawn(args, timeout=1800):
    """Run a worker in a fresh process; its JSON result with `process` (wall time) added."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", *args]
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    start = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    wall = time.perf_counter() - start
    lines = [line for line in proc.stdout.splitlines() if line.startswith("{")]
    if proc.returncode or not lines:
        return {"error": (proc.stderr or proc.stdout).strip().splitlines()[-1:] or ["failed"]}
    out = json.loads(lines[-1])
    out["process"] = wall
    return out


def median_run(runs):
    """One run's figures with each time replaced by its median over `runs` (the rest is the same
    in every run); the first error if any run failed."""
    bad = [r for r in runs if "error" in r]
    if bad:
        return bad[0]
    out = dict(runs[0], runs=len(runs))
    for key in TIMES:
        if key in out:
            out[key] = statistics.median(r[key] for r in runs)
    return out


def compile_bytecode(with_opty):
    """lagrgen's and opty's sources compiled to bytecode, as an installed package has them."""
    import importlib.util
    names = ["lagrgen"] + (["opty"] if with_opty else [])
    for name in names:
        for folder in importlib.util.find_spec(name).submodule_search_locations:
            compileall.compile_dir(folder, quiet=1)


def opty_available():
    try:
        import opty  # noqa: F401
        return True
    except ImportError:
        return False


def rel(a, b):
    return abs(a - b) / abs(b)


def head_to_head(quick, with_opty, repeat, tmp):
    """The rows (task, tool, figures) and the floor's figures."""
    rows, floors = [], []
    for task in ("swing-up", "cart"):
        out_dir = str(Path(tmp) / f"gen_{task}")
        save = str(Path(tmp) / f"opty_{task}.npy")
        exact = ["lagrgen", task, "--out", out_dir, "--hessian", "exact"]
        cold = spawn(exact)
        times = repeat if task == "swing-up" else 1
        opty, warm = [], []
        for _ in range(times):
            if with_opty:
                opty.append(spawn(["opty", task, "--save", save]))
            warm.append(spawn(exact))
            floors.append(spawn(["floor", "-"]))
        if with_opty:
            rows.append((task, OPTY, median_run(opty)))
        rows.append((task, "lagrgen exact Hessian, cold", cold))
        rows.append((task, "lagrgen exact Hessian, warm", median_run(warm)))
        if not quick:
            qn = spawn(["lagrgen", task, "--out", out_dir, "--hessian", "quasi-newton"])
            rows.append((task, "lagrgen quasi-Newton, warm", qn))
        if task == "cart" and opty and "error" not in opty[0]:
            again = spawn([*exact, "--restart", save])
            rows.append((task, "lagrgen exact, started at opty's answer", again))
            if not quick:
                tight = spawn(["opty", task, "--tol", "1e-12"])
                rows.append((task, "opty 1.5.0, tol 1e-12", tight))
    return rows, median_run(floors)


def nodes_growth(quick, tmp):
    counts = (201, 501, 1001) if quick else (201, 501, 1001, 2001, 5001)
    out_dir = str(Path(tmp) / "gen_nodes")
    return [(n, spawn(["lagrgen", "swing-up", "--out", out_dir, "--hessian", "exact",
                       "--nodes", str(n), "--start", "rest"])) for n in counts]


def size_growth(quick, tmp):
    links = (5, 10) if quick else (5, 10, 20)
    out = []
    for n in links:
        out_dir = str(Path(tmp) / f"gen_chain{n}")
        chain = ["lagrgen", "chain", "--out", out_dir, "--links", str(n)]
        cold = spawn([*chain, "--hessian", "exact"])
        warm = spawn([*chain, "--hessian", "exact"])
        qn = spawn([*chain, "--hessian", "quasi-newton"])
        out.append((n, cold, warm, qn))
    return out


def option_comparison(quick, tmp, rows, nodes, sizes):
    """(problem, lagrgen's options' figures, IPOPT's defaults' figures) with the exact Hessian,
    warm caches (the directories of the runs before)."""
    ipopt = ["--hessian", "exact", "--options", json.dumps(IPOPT_DEFAULTS)]
    found = {f"{task}": r for task, tool, r in rows if tool == "lagrgen exact Hessian, warm"}
    cases = [("swing-up (random start)", found.get("swing-up"),
              ["lagrgen", "swing-up", "--out", str(Path(tmp) / "gen_swing-up")]),
             ("cart", found.get("cart"), ["lagrgen", "cart", "--out", str(Path(tmp) / "gen_cart")])]
    for n, r in nodes:
        if n in (501, 2001):
            cases.append((f"swing-up from rest, {n} nodes", r,
                          ["lagrgen", "swing-up", "--out", str(Path(tmp) / "gen_nodes"),
                           "--nodes", str(n), "--start", "rest"]))
    for n, _, warm, _ in sizes:
        if n <= (5 if quick else 10):
            cases.append((f"chain of {n} links", warm,
                          ["lagrgen", "chain", "--out", str(Path(tmp) / f"gen_chain{n}"),
                           "--links", str(n)]))
    return [(name, ours, spawn([*args, *ipopt])) for name, ours, args in cases if ours]


def report(rows, floor, nodes, sizes, options, load, repeat):
    opty = {task: r for task, tool, r in rows if tool == OPTY and "error" not in r}
    lines = ["# Direct collocation: lagrgen against opty 1.5.0", "",
             f"Same machine, same run, each figure a fresh process; load average {load}. "
             f"The swing-up's opty and warm lagrgen figures are medians of {repeat} interleaved "
             "runs. Objective of the cart problem: the node interval h (lagrgen: T/299). "
             "`floor`: a process that imports numpy and SymPy and exits (both tools' scripts do): "
             + (f"{floor['process']:.2f} s, of which {floor['imports']:.2f} s imports "
                f"(median of {floor.get('runs', 1)})." if "error" not in floor else "failed."),
             "",
             "| problem | tool | objective | rel. to opty | iterations | imports s "
             "| build / set-up s | solve s | in-process s | process s | status |",
             "| --- | --- | --: | --: | --: | --: | --: | --: | --: | --: | --: |"]
    for task, tool, r in rows:
        if "error" in r:
            lines.append(f"| {task} | {tool} | error: {r['error'][0][:60]} | | | | | | | | |")
            continue
        ref = opty.get(task)
        ratio = f"{rel(r['objective'], ref['objective']):.1e}" if ref and tool != OPTY else ""
        lines.append(f"| {task} | {tool} | {r['objective']:.12g} | {ratio} | {r['iterations']} "
                     f"| {r['imports']:.2f} | {r['build'] + r['setup']:.2f} | {r['solve']:.2f} "
                     f"| {r['in_process']:.2f} | {r['process']:.2f} | {r['status']} |")
    tight = next((r for _, tool, r in rows if tool.endswith("tol 1e-12") and "error" not in r),
                 None)
    warm_cart = next((r for task, tool, r in rows if task == "cart" and
                      tool == "lagrgen exact Hessian, warm" and "error" not in r), None)
    if tight and warm_cart:
        lines += ["", f"opty's cart run stops above its local minimum: with tol 1e-12 it reaches "
                  f"{tight['objective']:.12g} (status {tight['status']}, {tight['iterations']} "
                  f"iterations), {rel(warm_cart['objective'], tight['objective']):.1e} from "
                  "lagrgen's."]
    lines += ["", "Wall-time ratios lagrgen / opty (target ≤ 0.2); `above the floor` compares "
              "what each process spends beyond the floor:", ""]
    base = floor.get("process", 0.0) if "error" not in floor else 0.0
    for task, ref in opty.items():
        for tool_name in ("lagrgen exact Hessian, cold", "lagrgen exact Hessian, warm"):
            r = next((r for t, tool, r in rows if t == task and tool == tool_name
                      and "error" not in r), None)
            if r:
                lines.append(f"- {task}, {tool_name.split(', ')[1]}: process "
                             f"{r['process'] / ref['process']:.2f}, in-process "
                             f"{r['in_process'] / ref['in_process']:.2f}, solve "
                             f"{r['solve'] / ref['solve']:.2f}, above the floor "
                             f"{(r['process'] - base) / (ref['process'] - base):.2f} "
                             f"(iterations {r['iterations']} vs {ref['iterations']})")
    lines += ["", "Where each warm process's time goes (s): the floor, the tool's own imports and "
              "the model's build (lagrgen: a cache hit) or set-up (opty: code generation), the "
              "solve (lagrgen: IPOPT's own work — factorizing and solving its KKT systems — the "
              "NLP callbacks, and the rest: the starting point and the result), and what is "
              "left (interpreter start and exit beyond the floor's):", "",
              "| problem | tool | floor | own imports, build / set-up | solve: IPOPT | "
              "solve: callbacks | solve: rest | left | process |",
              "| --- | --- | --: | --: | --: | --: | --: | --: | --: |"]
    for task, tool, r in rows:
        if "error" in r or tool not in (OPTY, "lagrgen exact Hessian, warm"):
            continue
        own = r["imports"] + r["build"] + r["setup"] - floor.get("imports", 0.0)
        if tool == OPTY:
            parts = [r["solve"], None, None]
        else:
            ipopt = r["ipopt_seconds"] - r["callback_seconds"]
            parts = [ipopt, r["callback_seconds"], r["solve"] - r["ipopt_seconds"]]
        left = r["process"] - base - own - r["solve"]
        cells = " | ".join("" if v is None else f"{v:.3f}" for v in parts)
        lines.append(f"| {task} | {tool} | {base:.3f} | {own:.3f} | {cells} | {left:.3f} | "
                     f"{r['process']:.3f} |")
    lines += ["", "## Growth with the number of nodes (swing-up started at rest, exact Hessian, "
              "warm cache)", "",
              "| nodes | variables | iterations | status | solve s | ms per iteration "
              "| of which callbacks | objective |",
              "| --: | --: | --: | --: | --: | --: | --: | --: |"]
    for n, r in nodes:
        if "error" in r:
            lines.append(f"| {n} | error: {r['error'][0][:60]} | | | | | | |")
            continue
        per = 1e3 / max(r["iterations"], 1)
        lines.append(f"| {n} | {r['variables']} | {r['iterations']} | {r['status']} | "
                     f"{r['solve']:.2f} | {per * r['ipopt_seconds']:.1f} | "
                     f"{per * r['callback_seconds']:.1f} | {r['objective']:.10g} |")
    lines += ["", "Status 2 is IPOPT's Infeasible_Problem_Detected: at 201 nodes backward "
              "Euler's numerical damping leaves |T| ≤ 2 too weak to bring the pendulum up.",
              "The dynamics error is each solution's on its grid (`res.error`): the chains' 51 "
              "nodes do not resolve their fast modes.",
              "", "## Growth with the model (n-link chain, a torque per joint, 51 nodes, "
              "Hermite–Simpson)", "",
              "| links | variables | cold: build + units s | cold total s | warm total s | "
              "iterations exact | iterations quasi-Newton | solve exact s | solve quasi-Newton s "
              "| dynamics error |",
              "| --: | --: | --: | --: | --: | --: | --: | --: | --: | --: |"]
    for n, cold, warm, qn in sizes:
        if any("error" in r for r in (cold, warm, qn)):
            bad = next(r for r in (cold, warm, qn) if "error" in r)
            lines.append(f"| {n} | error: {bad['error'][0][:60]} | | | | | | | | |")
            continue
        lines.append(f"| {n} | {cold['variables']} | {cold['build'] + cold['setup']:.2f} | "
                     f"{cold['in_process']:.2f} | {warm['in_process']:.2f} | "
                     f"{warm['iterations']} | {qn['iterations']} | {warm['solve']:.2f} | "
                     f"{qn['solve']:.2f} | {warm['dynamics_error']:.1e} |")
    lines += ["", "## lagrgen's IPOPT options against IPOPT's defaults (exact Hessian, warm)", "",
              "lagrgen: `mu_strategy=adaptive`, `mu_oracle=loqo`, `min_refinement_steps=0`; "
              f"IPOPT's defaults: {', '.join(f'`{k}={v}`' for k, v in IPOPT_DEFAULTS.items())}.",
              "", "| problem | iterations lagrgen / IPOPT | solve s lagrgen / IPOPT | "
              "objective lagrgen | objective IPOPT's defaults |",
              "| --- | --: | --: | --: | --: |"]
    for name, ours, theirs in options:
        if "error" in theirs:
            lines.append(f"| {name} | error: {theirs['error'][0][:60]} | | | |")
            continue
        lines.append(f"| {name} | {ours['iterations']} / {theirs['iterations']} | "
                     f"{ours['solve']:.2f} / {theirs['solve']:.2f} | {ours['objective']:.12g} | "
                     f"{theirs['objective']:.12g} |")
    return "\n".join(lines) + "\n"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer sizes and runs")
    parser.add_argument("--no-opty", action="store_true", help="leave the peer out")
    parser.add_argument("--repeat", type=int, default=3,
                        help="runs of the swing-up's opty and warm lagrgen figures (medians)")
    parser.add_argument("--worker", nargs="+", help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    parser.add_argument("--hessian", default="exact", help=argparse.SUPPRESS)
    parser.add_argument("--nodes", type=int, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--links", type=int, default=5, help=argparse.SUPPRESS)
    parser.add_argument("--restart", help=argparse.SUPPRESS)
    parser.add_argument("--save", help=argparse.SUPPRESS)
    parser.add_argument("--start", default="random", help=argparse.SUPPRESS)
    parser.add_argument("--options", default="{}", help=argparse.SUPPRESS)
    parser.add_argument("--tol", type=float, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--mesh-tol", type=float, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        tool, task = args.worker
        if tool == "floor":
            result = worker_floor()
        elif tool == "opty":
            result = worker_opty(task, args.save, args.tol)
        else:
            result = worker_lagrgen(task, args.out, args.hessian, args.nodes, args.links,
                                    args.restart, args.start, json.loads(args.options),
                                    args.mesh_tol)
        print(json.dumps(result))
        return 0
    with_opty = not args.no_opty and opty_available()
    if not args.no_opty and not with_opty:
        print("opty is not installed (pip install --no-deps opty==1.5.0): lagrgen alone")
    compile_bytecode(with_opty)
    repeat = 1 if args.quick else max(args.repeat, 1)
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    with tempfile.TemporaryDirectory(prefix="lagrgen_collocation_") as tmp:
        rows, floor = head_to_head(args.quick, with_opty, repeat, tmp)
        nodes = nodes_growth(args.quick, tmp)
        sizes = size_growth(args.quick, tmp)
        options = option_comparison(args.quick, tmp, rows, nodes, sizes)
    load = f"{load} at the start, {', '.join(f'{x:.2f}' for x in os.getloadavg())} at the end"
    text = report(rows, floor, nodes, sizes, options, load, repeat)
    print(text)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    suffix = "_quick" if args.quick else ""
    (RESULTS.parent / f"collocation{suffix}.md").write_text(text)
    (RESULTS.parent / f"collocation{suffix}.json").write_text(json.dumps(
        {"head_to_head": [[t, tool, r] for t, tool, r in rows], "floor": floor,
         "nodes": nodes, "sizes": sizes, "options": options, "load": load}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
