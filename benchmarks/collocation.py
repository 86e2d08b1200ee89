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
one its gallery uses. Writes benchmarks/results/collocation.md and .json.
"""
import argparse
import json
import os
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
def worker_lagrgen(task, out_dir, hessian, nodes, links, restart, start):
    start = time.perf_counter()
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
    res = prob.solve(guess=guess, hessian=hessian, progress=False)
    done = time.perf_counter()
    objective = res.objective / (prob.nodes - 1) if task == "cart" else res.objective
    return {"tool": "lagrgen", "imports": imported - start, "build": built - imported,
            "setup": ready - built, "solve": done - ready, "in_process": done - imported,
            "iterations": res.iterations, "objective": objective, "status": res.status,
            "ipopt_seconds": res.seconds, "callback_seconds": res.callback_seconds,
            "violation": res.constraint_violation,
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


def worker_opty(task, save):
    start = time.perf_counter()
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
    ready = time.perf_counter()
    solution, info = prob.solve(guess)
    done = time.perf_counter()
    if save:
        np.save(save, solution)
    objective = solution[-1] if task == "cart" else info["obj_val"]
    return {"tool": "opty", "imports": imported - start, "build": 0.0,
            "setup": ready - imported, "solve": done - ready, "in_process": done - imported,
            "iterations": len(prob.obj_value), "objective": float(objective),
            "status": int(info["status"]), "variables": int(prob.num_free)}


# -- the runner ----------------------------------------------------------------------------------
def spawn(args, timeout=1800):
    """Run a worker in a fresh process; its JSON result with `process` (wall time) added."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", *args]
    start = time.perf_counter()
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    wall = time.perf_counter() - start
    lines = [line for line in proc.stdout.splitlines() if line.startswith("{")]
    if proc.returncode or not lines:
        return {"error": (proc.stderr or proc.stdout).strip().splitlines()[-1:] or ["failed"]}
    out = json.loads(lines[-1])
    out["process"] = wall
    return out


def opty_available():
    try:
        import opty  # noqa: F401
        return True
    except ImportError:
        return False


def rel(a, b):
    return abs(a - b) / abs(b)


def fmt(x, digits=3):
    return "—" if x is None else f"{x:.{digits}g}"


def head_to_head(quick, with_opty, tmp):
    rows, notes = [], []
    for task in ("swing-up", "cart"):
        out_dir = str(Path(tmp) / f"gen_{task}")
        opty = None
        save = str(Path(tmp) / f"opty_{task}.npy")
        if with_opty:
            opty = spawn(["opty", task, "--save", save])
            rows.append((task, "opty 1.5.0 (quasi-Newton)", opty))
        cold = spawn(["lagrgen", task, "--out", out_dir, "--hessian", "exact"])
        rows.append((task, "lagrgen exact Hessian, cold", cold))
        warm = spawn(["lagrgen", task, "--out", out_dir, "--hessian", "exact"])
        rows.append((task, "lagrgen exact Hessian, warm", warm))
        if not quick:
            qn = spawn(["lagrgen", task, "--out", out_dir, "--hessian", "quasi-newton"])
            rows.append((task, "lagrgen quasi-Newton, warm", qn))
        if task == "cart" and opty and "error" not in opty:
            again = spawn(["lagrgen", task, "--out", out_dir, "--hessian", "exact",
                           "--restart", save])
            rows.append((task, "lagrgen exact, started at opty's answer", again))
    return rows, notes


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
        cold = spawn(["lagrgen", "chain", "--out", out_dir, "--hessian", "exact", "--links",
                      str(n)])
        warm = spawn(["lagrgen", "chain", "--out", out_dir, "--hessian", "exact", "--links",
                      str(n)])
        qn = spawn(["lagrgen", "chain", "--out", out_dir, "--hessian", "quasi-newton",
                    "--links", str(n)])
        out.append((n, cold, warm, qn))
    return out


def report(rows, nodes, sizes, load):
    lines = ["# Direct collocation: lagrgen against opty 1.5.0", "",
             f"Same machine, same run, each figure a fresh process; load average {load}. "
             "Objective of the cart problem: the node interval h (lagrgen: T/299).", "",
             "| problem | tool | objective | rel. to opty | iterations | imports s "
             "| build / set-up s | solve s | in-process s | process s | status |",
             "| --- | --- | --: | --: | --: | --: | --: | --: | --: | --: | --: |"]
    opty = {task: r for task, tool, r in rows if tool.startswith("opty") and "error" not in r}
    for task, tool, r in rows:
        if "error" in r:
            lines.append(f"| {task} | {tool} | error: {r['error'][0][:60]} | | | | | | | | |")
            continue
        ref = opty.get(task)
        ratio = f"{rel(r['objective'], ref['objective']):.1e}" if ref and tool != \
            "opty 1.5.0 (quasi-Newton)" else ""
        lines.append(f"| {task} | {tool} | {r['objective']:.12g} | {ratio} | {r['iterations']} "
                     f"| {r['imports']:.2f} | {r['build'] + r['setup']:.2f} | {r['solve']:.2f} "
                     f"| {r['in_process']:.2f} | {r['process']:.2f} | {r['status']} |")
    lines += ["", "Wall-time ratios lagrgen / opty (target ≤ 0.2):", ""]
    for task, ref in opty.items():
        for tool_name in ("lagrgen exact Hessian, cold", "lagrgen exact Hessian, warm"):
            r = next((r for t, tool, r in rows if t == task and tool == tool_name
                      and "error" not in r), None)
            if r:
                lines.append(f"- {task}, {tool_name.split(', ')[1]}: process "
                             f"{r['process'] / ref['process']:.2f}, in-process "
                             f"{r['in_process'] / ref['in_process']:.2f}, solve "
                             f"{r['solve'] / ref['solve']:.2f} (iterations {r['iterations']} vs "
                             f"{ref['iterations']})")
    lines += ["", "Where lagrgen's solve time goes (IPOPT's own work — factorizing and solving the "
              "KKT systems — against the evaluation of the NLP in lagrgen's callbacks):", ""]
    for task, tool, r in rows:
        if tool.startswith("lagrgen") and "error" not in r:
            lines.append(f"- {task}, {tool}: {r['ipopt_seconds']:.2f} s in IPOPT's solve, of "
                         f"which {r['callback_seconds']:.2f} s in the callbacks "
                         f"({1e3 * r['ipopt_seconds'] / max(r['iterations'], 1):.1f} ms per "
                         "iteration)")
    lines += ["", "## Growth with the number of nodes (swing-up started at rest, exact Hessian, "
              "warm cache)", "",
              "| nodes | variables | iterations | solve s | ms per iteration | of which callbacks "
              "| objective |",
              "| --: | --: | --: | --: | --: | --: | --: |"]
    for n, r in nodes:
        if "error" in r:
            lines.append(f"| {n} | error: {r['error'][0][:60]} | | | | | |")
            continue
        per = 1e3 / max(r["iterations"], 1)
        lines.append(f"| {n} | {r['variables']} | {r['iterations']} | {r['solve']:.2f} | "
                     f"{per * r['ipopt_seconds']:.1f} | {per * r['callback_seconds']:.1f} | "
                     f"{r['objective']:.10g} |")
    lines += ["", "## Growth with the model (n-link chain, a torque per joint, 51 nodes, "
              "Hermite–Simpson)", "",
              "| links | variables | cold: build + units s | cold total s | warm total s | "
              "iterations exact | iterations quasi-Newton | solve exact s | solve quasi-Newton s |",
              "| --: | --: | --: | --: | --: | --: | --: | --: | --: |"]
    for n, cold, warm, qn in sizes:
        if any("error" in r for r in (cold, warm, qn)):
            bad = next(r for r in (cold, warm, qn) if "error" in r)
            lines.append(f"| {n} | error: {bad['error'][0][:60]} | | | | | | | |")
            continue
        lines.append(f"| {n} | {cold['variables']} | {cold['build'] + cold['setup']:.2f} | "
                     f"{cold['in_process']:.2f} | {warm['in_process']:.2f} | "
                     f"{warm['iterations']} | {qn['iterations']} | {warm['solve']:.2f} | "
                     f"{qn['solve']:.2f} |")
    return "\n".join(lines) + "\n"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer sizes and runs")
    parser.add_argument("--no-opty", action="store_true", help="leave the peer out")
    parser.add_argument("--worker", nargs="+", help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    parser.add_argument("--hessian", default="exact", help=argparse.SUPPRESS)
    parser.add_argument("--nodes", type=int, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--links", type=int, default=5, help=argparse.SUPPRESS)
    parser.add_argument("--restart", help=argparse.SUPPRESS)
    parser.add_argument("--save", help=argparse.SUPPRESS)
    parser.add_argument("--start", default="random", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        tool, task = args.worker
        if tool == "opty":
            result = worker_opty(task, args.save)
        else:
            result = worker_lagrgen(task, args.out, args.hessian, args.nodes, args.links,
                                    args.restart, args.start)
        print(json.dumps(result))
        return 0
    with_opty = not args.no_opty and opty_available()
    if not with_opty:
        print("opty is not installed (pip install --no-deps opty==1.5.0): lagrgen alone")
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    with tempfile.TemporaryDirectory(prefix="lagrgen_collocation_") as tmp:
        rows, _ = head_to_head(args.quick, with_opty, tmp)
        nodes = nodes_growth(args.quick, tmp)
        sizes = size_growth(args.quick, tmp)
    load = f"{load} at the start, {', '.join(f'{x:.2f}' for x in os.getloadavg())} at the end"
    text = report(rows, nodes, sizes, load)
    print(text)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    suffix = "_quick" if args.quick else ""
    (RESULTS.parent / f"collocation{suffix}.md").write_text(text)
    (RESULTS.parent / f"collocation{suffix}.json").write_text(json.dumps(
        {"head_to_head": [[t, tool, r] for t, tool, r in rows],
         "nodes": nodes, "sizes": sizes, "load": load}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
