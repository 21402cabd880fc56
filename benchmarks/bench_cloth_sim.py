"""Cloth simulator benchmark (vidsim.cloth): speed per integrator, force cost, artificial
damping, MuJoCo flex comparison, and cost growth with resolution.

Usage::

    NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 python benchmarks/bench_cloth_sim.py \
        [speed force damping mujoco scaling resolution settle split]

(no argument: all but ``resolution``, which takes ~5 CPU-minutes, ``settle``, the gap
suite's swatch at rest with and without the settle bath, docs/gap.md, and ``split``, the
split damping against the explicit one at the damped corners the full fits visited).

Case (issue 4): a 20x20-vertex swatch, 0.3 m, 0.2 kg/m^2, its two top corners waved
(5 cm sideways at 1.5 Hz, 8 cm back and forth at 1 Hz, 3 cm up-down) from rest: the
waving is faded in over the first 0.3 s with a C2 smoothstep (an instantaneous start gives
the grips a 0.7 m/s velocity jump, a point impulse whose near-field response depends on
the mesh; ``resolution`` measures both starts), mid-range parameters
(:func:`vidsim.cloth.mid_range_params`), 50 frames at 30 Hz, the default bending model
(``bending="dihedral"``) unless a row says ``quadratic``.

Timing under shared load: every time is printed as the median wall time and the median
CPU time of the process (``time.process_time``, less disturbed by other jobs on the
cores) after a warm-up run (numba compilation excluded), with the 1-minute load average.
The per-triangle force cost is the *minimum* over 1000 windows of ~1 ms (the least
disturbed window; the median is printed beside it). The plot of the scaling section goes
to ``results/benchmarks/cloth_scaling.png``.
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from vidsim.cloth import ClothParams, DrivenVertices, energies, mid_range_params, simulate, swatch  # noqa: E402
from vidsim.cloth.integrate import _accel  # noqa: E402
from vidsim.cloth.simulate import _col, _drv, _model, _param_vector  # noqa: E402
from vidsim.cloth.collision import Colliders  # noqa: E402

SIZE = 0.3
TIMES = np.arange(50) / 30.0
RAMP = 0.3  # [s] fade-in of the waving (C2 smoothstep)


def ramp(t: float, t_ramp: float = RAMP) -> float:
    """0 -> 1 over [0, t_ramp] with zero first and second derivatives at both ends."""
    if t_ramp <= 0:
        return 1.0
    u = min(max(t / t_ramp, 0.0), 1.0)
    return u**3 * (10.0 - 15.0 * u + 6.0 * u * u)


def wave_offset(t: float, t_ramp: float = RAMP) -> np.ndarray:
    """Offset [m] of both gripped corners at time t [s] (t_ramp = 0: instantaneous start)."""
    return ramp(t, t_ramp) * np.array([0.05 * np.sin(2 * np.pi * 1.5 * t), 0.08 * np.sin(2 * np.pi * 1.0 * t),
                                       0.03 * (1 - np.cos(2 * np.pi * 1.5 * t))])


def wave(mesh, t_ramp: float = RAMP) -> DrivenVertices:
    idx = mesh.tags["top_corners"]
    p0 = mesh.rest_positions[idx]
    return DrivenVertices.from_function(idx, lambda t: p0 + wave_offset(t, t_ramp), 0.0, TIMES[-1], 1000.0)


def load() -> str:
    return f"load {os.getloadavg()[0]:.1f}"


def median_time(fn, runs: int = 5) -> tuple[float, object]:
    """Median wall time [s] after a warm-up; the median CPU time is kept in LAST_CPU[0]."""
    out = fn()  # warm-up
    ts, cs = [], []
    for _ in range(runs):
        t = time.perf_counter()
        c = time.process_time()
        out = fn()
        ts.append(time.perf_counter() - t)
        cs.append(time.process_time() - c)
    LAST_CPU[0] = float(np.median(cs))
    return float(np.median(ts)), out


LAST_CPU = [0.0]


def min_window(fn, reps: int, windows: int = 1000) -> tuple[float, float]:
    """(minimum, median) time per call [s] over ``windows`` windows of ``reps`` calls."""
    fn()
    w = []
    for _ in range(windows):
        t = time.perf_counter()
        fn()
        w.append(time.perf_counter() - t)
    return min(w) / reps, float(np.median(w)) / reps


def max_edge_strain(mesh, X: np.ndarray) -> float:
    e = mesh.unique_edges()
    L0 = np.linalg.norm(mesh.rest_positions[e[:, 0]] - mesh.rest_positions[e[:, 1]], axis=1)
    L = np.linalg.norm(X[:, e[:, 0]] - X[:, e[:, 1]], axis=-1)
    return float(np.max(L / L0 - 1.0))


def bench_speed() -> dict:
    mesh = swatch(20, 20, SIZE, SIZE)
    p = mid_range_params()
    drv = wave(mesh)
    print("\n## 50 frames at 30 Hz, 20x20 swatch (722 triangles), mid-range parameters")
    print("| integrator | bending | self collision | median wall [s] | median CPU [s] | steps | rejected | force evals "
          "| step [ms] | max edge strain | load |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    out = {}
    for bending in ("dihedral", "quadratic"):
        for integ in ("fast", "rk45"):
            for sc in (False, True):
                if bending == "quadratic" and sc:
                    continue
                runs = 3 if integ == "rk45" else 5
                t, r = median_time(lambda: simulate(mesh, p, drv, TIMES, integrator=integ, self_collision=sc,
                                                    bending=bending), runs)
                assert r.ok, r.failure
                out[(integ, sc, bending)] = (t, r)
                print(f"| {integ} | {bending} | {sc} | {t:.3f} | {LAST_CPU[0]:.3f} | {r.steps} | {r.rejected} | "
                      f"{r.evaluations} | {1e3 * r.dt:.3f} | {100 * max_edge_strain(mesh, r.positions):.1f} % | {load()} |")
    a = out[("fast", False, "dihedral")][1].positions
    b = out[("rk45", False, "dihedral")][1].positions
    c = out[("fast", False, "quadratic")][1].positions
    print(f"fast vs rk45: max vertex distance over 50 frames {1e3 * np.max(np.linalg.norm(a - b, axis=-1)):.2f} mm; "
          f"quadratic vs dihedral bending (fast): {1e3 * np.max(np.linalg.norm(a - c, axis=-1)):.2f} mm")
    return out


def bench_force() -> None:
    """Cost of one evaluation of all forces (``_accel``: gravity, stretch, shear, their
    damping, drag, bending, no self collision) per triangle, incl. its share of bend edges
    (1.45 per triangle on these meshes), and of each kernel."""
    from vidsim.cloth.forces import bend_forces_fused, bend_forces_quadratic, triangle_forces

    print(f"\n## force evaluation (all forces, no self collision), ns per triangle incl. its bend edges ({load()})")
    print("| mesh | triangles | bend edges | bending | min [ns / triangle] | median [ns / triangle] |")
    print("|---|---|---|---|---|---|")
    p = mid_range_params()
    rng = np.random.default_rng(0)
    breakdown = []
    for n in (20, 40, 60):
        mesh = swatch(n, n, SIZE, SIZE)
        x = mesh.rest_positions + 1e-3 * rng.standard_normal(mesh.rest_positions.shape)
        v = 0.1 * rng.standard_normal(x.shape)
        model = _model(mesh, p, np.zeros(3))
        drv = _drv(DrivenVertices.none())
        col = _col(Colliders.none())
        acc = np.zeros_like(x)
        f = np.zeros_like(x)
        pr = -np.ones((1, 2), dtype=np.int64)
        ep = np.zeros((0, 2), dtype=np.int64)
        dw = np.zeros((3, 1, 3))
        M, E = mesh.n_triangles, mesh.bend_edges.shape[0]
        reps = max(1, 20000 // M)
        for bending in ("dihedral", "quadratic"):
            P = _param_vector(mesh, p, False, bending)

            def loop():
                for _ in range(reps):
                    _accel(0.0, x, v, acc, f, model, P, drv, dw, col, pr, ep, x)

            tmin, tmed = min_window(loop, reps)
            print(f"| {n}x{n} | {M} | {E} | {bending} | {1e9 * tmin / M:.0f} | {1e9 * tmed / M:.0f} |")
        if n == 20:
            tn = np.zeros((M, 3))
            w = np.zeros(3)

            def tri():
                for _ in range(reps):
                    triangle_forces(x, v, mesh.triangles, mesh.tri_coef, mesh.tri_area, p.stretch, p.stretch, p.shear,
                                    p.stretch_damping, p.shear_damping, p.drag_linear, p.drag_quad,
                                    p.drag_degrade, w, tn, f)

            def tri_nodrag():
                for _ in range(reps):
                    triangle_forces(x, v, mesh.triangles, mesh.tri_coef, mesh.tri_area, p.stretch, p.stretch, p.shear,
                                    p.stretch_damping, p.shear_damping, 0.0, 0.0, 0.0, w, tn, f)

            def bend():
                for _ in range(reps):
                    bend_forces_fused(x, v, mesh.bend_edges, mesh.bend_tris, tn, mesh.bend_coef, mesh.bend_rest,
                                      p.bend, p.bend_damping, f)

            def bendq():
                for _ in range(reps):
                    bend_forces_quadratic(x, v, mesh.bend_edges, mesh.bend_quad, p.bend, p.bend_damping, f)

            tt = min_window(tri, reps)[0]
            tnd = min_window(tri_nodrag, reps)[0]
            tb = min_window(bend, reps)[0]
            tq = min_window(bendq, reps)[0]
            breakdown.append(
                f"breakdown at 20x20 (minimum over windows): triangle kernel (stretch+shear+damping+drag) "
                f"{1e9 * tt / M:.0f} ns/triangle (without drag {1e9 * tnd / M:.0f}); dihedral bend kernel "
                f"{1e9 * tb / E:.0f} ns/edge; quadratic bend kernel {1e9 * tq / E:.0f} ns/edge")
    for line in breakdown:
        print(line)


def bench_damping() -> None:
    """Artificial damping: a swatch pinned along its top row, released 30 degrees out of its
    hanging plane, swings (and rings in its stretch modes) with all physical damping and drag
    off. The energy above the static equilibrium, E_osc, must stay constant; its change per
    second is numerical."""
    print("\n## artificial damping (physical damping and drag off): 20x20 swatch pinned along its top row, "
          "released 30 deg from vertical")
    mesh = swatch(20, 20, SIZE, SIZE)
    top = mesh.tags["top_row"]
    drv = DrivenVertices.fixed(top, mesh.rest_positions[top])
    p0 = mid_range_params(bend_damping=0.0, stretch_damping=0.0, shear_damping=0.0, drag_linear=0.0,
                          drag_quad=0.0, drag_degrade=0.0)
    a = np.deg2rad(30.0)
    X = mesh.rest_positions.copy()
    y, z = X[:, 1].copy(), X[:, 2].copy()
    X[:, 1] = np.cos(a) * y - np.sin(a) * z
    X[:, 2] = np.sin(a) * y + np.cos(a) * z
    # static equilibrium energy: same system with heavy tangential and normal drag, settled
    settled = simulate(mesh, p0.replace(drag_linear=20.0, drag_quad=20.0), drv, np.array([0.0, 3.0]),
                       integrator="fast", x0=X)
    e_eq = energies(mesh, p0, settled.positions[-1], np.zeros((mesh.n_vertices, 3)))["total"]
    T = 2.0
    times = np.linspace(0.0, T, 201)
    print("| scheme | mean step [ms] | E_osc(0) [mJ] | change of E_osc per second |")
    print("|---|---|---|---|")
    for integ, kw in (("fast", {}), ("rk45", {}), ("rk45", {"rtol": 1e-3, "atol_x": 1e-4, "atol_v": 1e-3})):
        r = simulate(mesh, p0, drv, times, integrator=integ, x0=X, **kw)
        E = np.array([energies(mesh, p0, r.positions[k], r.velocities[k])["total"] for k in range(len(times))])
        osc = E - e_eq
        # linear fit of E_osc(t): slope relative to E_osc(0)
        slope = np.polyfit(times, osc, 1)[0]
        label = integ + (" (loose: rtol 1e-3, atol 1e-4 m, 1e-3 m/s)" if kw else " (default tolerances)")
        print(f"| {label} | {1e3 * r.dt:.3f} | {1e3 * osc[0]:.2f} | {100 * slope / osc[0]:+.3f} % /s |")
    # backward Euler for comparison (analytic): energy factor 1/(1 + (h w)^2) per step
    w_swing = np.sqrt(9.81 / (SIZE / 2))  # physical pendulum of the hanging swatch, order of magnitude
    w1 = np.pi / (2 * SIZE) * np.sqrt(p0.stretch / p0.density)
    for w, mode in ((w_swing, "swing"), (w1, "lowest stretch")):
        for h in (1 / 300, 1 / 1000):
            per_s = 1 - (1.0 / (1.0 + (h * w) ** 2)) ** (1 / h)
            print(f"| implicit Euler, analytic, {mode} mode w = {w:.1f} rad/s, h = {1e3 * h:.2f} ms | {1e3 * h:.2f} | - | "
                  f"{-100 * per_s:+.1f} % /s |")


def bench_mujoco(ours: dict | None) -> None:
    import mujoco

    n = 20
    mesh = swatch(n, n, SIZE, SIZE)
    p = mid_range_params()
    s = SIZE / (n - 1)
    print(f"\n## MuJoCo {mujoco.__version__} flex cloth, same mesh size, mass and motion (implicitfast, edge equality "
          f"constraints) ({load()})")
    print("| solref timeconst [s] | timestep [ms] | median wall [s] | median CPU [s] | max edge strain | ok |")
    print("|---|---|---|---|---|---|")
    best = None
    for tc in (0.004, 0.002):
        for dt in (2e-3, 1e-3, 5e-4):
            if tc < 2 * dt:  # MuJoCo requires timeconst >= 2 timestep (clamped otherwise)
                continue
            xml = f"""
<mujoco>
  <option timestep="{dt}" integrator="implicitfast" gravity="0 0 -9.81"/>
  <worldbody>
    <body name="grip" mocap="true" pos="0 0 0">
      <flexcomp name="cloth" type="grid" count="{n} {n} 1" spacing="{s} {s} {s}" mass="{p.density * SIZE * SIZE}"
                radius="0.001" dim="2" euler="90 0 0" pos="{SIZE / 2} 0 {-SIZE / 2}">
        <edge equality="true" solref="{tc} 1"/>
        <contact selfcollide="none" conaffinity="0" contype="0"/>
        <pin id="{n - 1} {n * n - 1}"/>
      </flexcomp>
    </body>
  </worldbody>
</mujoco>"""
            model = mujoco.MjModel.from_xml_string(xml)
            data = mujoco.MjData(model)
            edges = model.flex_edge.reshape(-1, 2)

            def run():
                mujoco.mj_resetData(model, data)
                mujoco.mj_forward(model, data)
                x0 = data.flexvert_xpos.copy()
                L0 = np.linalg.norm(x0[edges[:, 0]] - x0[edges[:, 1]], axis=1)
                strain = 0.0
                nsteps = int(round(TIMES[-1] / dt))
                fi = 1
                for k in range(nsteps):
                    data.mocap_pos[0] = wave_offset((k + 1) * dt)
                    mujoco.mj_step(model, data)
                    if fi < len(TIMES) and (k + 1) * dt >= TIMES[fi] - 1e-9:
                        x = data.flexvert_xpos
                        L = np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1)
                        strain = max(strain, float(np.max(L / L0 - 1)))
                        fi += 1
                ok = bool(np.all(np.isfinite(data.qpos)))
                return strain, ok

            t, (strain, ok) = median_time(run, 3)
            cpu = LAST_CPU[0]
            print(f"| {tc} | {1e3 * dt:.2f} | {t:.3f} | {cpu:.3f} | {100 * strain:.1f} % | {ok} |")
            if ok and strain <= 0.10 and (best is None or cpu < best[4]):
                best = (t, tc, dt, strain, cpu)
    if best is None:
        print("no MuJoCo setting reached max edge strain <= 10 %")
        return
    t_mj, tc, dt, strain, cpu_mj = best
    print(f"fastest MuJoCo setting (by CPU time) with max edge strain <= 10 %: solref {tc} 1, timestep {1e3 * dt} ms: "
          f"wall {t_mj:.3f} s, CPU {cpu_mj:.3f} s (strain {100 * strain:.1f} %)")
    drv = wave(mesh)
    print("ours, same mesh and motion (ratios by CPU time, wall in brackets):")
    print("| stretch [N/m] | integrator | median wall [s] | median CPU [s] | max edge strain | ratio ours / MuJoCo | load |")
    print("|---|---|---|---|---|---|---|")
    for ks in (200.0, 400.0, 1000.0):
        pk = p.replace(stretch=ks)
        for integ in ("fast", "rk45"):
            t_o, r = median_time(lambda: simulate(mesh, pk, drv, TIMES, integrator=integ), 3 if integ == "fast" else 1)
            c_o = LAST_CPU[0]
            print(f"| {ks:.0f} | {integ} | {t_o:.3f} | {c_o:.3f} | {100 * max_edge_strain(mesh, r.positions):.1f} % | "
                  f"{c_o / cpu_mj:.2f} ({t_o / t_mj:.2f}) | {load()} |")


def bench_scaling() -> None:
    print(f"\n## cost growth with resolution (50 frames, waving, mid-range parameters), median CPU time ({load()})")
    print("| n x n | triangles | fast [s] | fast + self collision [s] | rk45 [s] | fast steps | fast step [ms] | load |")
    print("|---|---|---|---|---|---|---|---|")
    p = mid_range_params()
    rows = []
    for n in (10, 20, 30, 40, 60):
        mesh = swatch(n, n, SIZE, SIZE)
        drv = wave(mesh)
        runs = 3 if n <= 30 else 1
        median_time(lambda: simulate(mesh, p, drv, TIMES, integrator="fast"), runs)
        tf, rf = LAST_CPU[0], None
        rf = simulate(mesh, p, drv, TIMES, integrator="fast")
        try:
            median_time(lambda: simulate(mesh, p, drv, TIMES, integrator="fast", self_collision=True), runs)
            ts = LAST_CPU[0]
        except ValueError:  # thickness too large for the finest mesh
            ts = float("nan")
        if n <= 40:
            median_time(lambda: simulate(mesh, p, drv, TIMES, integrator="rk45"), 1 if n >= 30 else 3)
            tr = LAST_CPU[0]
        else:
            tr = float("nan")
        rows.append((n, mesh.n_triangles, tf, ts, tr))
        print(f"| {n} | {mesh.n_triangles} | {tf:.3f} | {ts:.3f} | {tr:.3f} | {rf.steps} | {1e3 * rf.dt:.3f} | {load()} |")
    arr = np.array(rows, dtype=float)
    names = {2: "fast", 3: "fast + self collision", 4: "rk45"}
    for c, name in names.items():
        ok = np.isfinite(arr[:, c])
        k = np.polyfit(np.log(arr[ok, 0]), np.log(arr[ok, c]), 1)[0]
        print(f"growth exponent ({name}): time ~ n^{k:.2f} (n vertices per side)")
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from vidsim.io.atomic import atomic_path
        from vidsim.io.paths import results_dir

        fig, ax = plt.subplots(figsize=(5, 4))
        for c, name in names.items():
            ok = np.isfinite(arr[:, c])
            ax.loglog(arr[ok, 0], arr[ok, c], "o-", label=name)
        ax.loglog(arr[:, 0], arr[1, 2] * (arr[:, 0] / 20) ** 3, "k--", lw=0.8, label="n^3")
        ax.set_xlabel("vertices per side n")
        ax.set_ylabel("CPU time for 50 frames [s]")
        ax.legend()
        fig.tight_layout()
        out = results_dir() / "benchmarks" / "cloth_scaling.png"
        with atomic_path(out) as tmp:
            fig.savefig(tmp, dpi=100)
        print(f"plot: {out}")
    except Exception as exc:  # plotting is optional
        print(f"plot skipped: {exc}")


def bench_resolution() -> None:
    """Resolution independence: bottom-corner trajectories of 10x10, 20x20, 40x40 (and
    60x60 where affordable) swatches with the same parameters, max over 50 frames of the
    distance to the finest mesh, in % of the swatch size (target <= 5 %), per bending
    rigidity and start of the waving."""
    print(f"\n## resolution independence: max over 50 frames of the bottom-corner distance to the finest mesh, "
          f"% of the swatch size ({load()})")
    print("| bend D [N m] | bending length (D/(rho g))^(1/3) [cm] | bending | start | 10x10 | 20x20 | 40x40 | reference |")
    print("|---|---|---|---|---|---|---|---|")
    cases = [(1e-4, 1e-6, (10, 20, 40)), (1e-4, None, (10, 20, 40)), (1e-5, None, (10, 20, 40)),
             (3.16e-6, None, (10, 20, 40, 60)), (1e-6, None, (10, 20, 40, 60))]
    for D, kd, ns in cases:
        p = mid_range_params(bend=D) if kd is None else mid_range_params(bend=D, bend_damping=kd)
        lb = (D / (p.density * 9.81)) ** (1 / 3)
        variants = [("dihedral", RAMP), ("dihedral", 0.0)]
        if kd is None and D in (1e-5, 3.16e-6):
            variants.append(("quadratic", RAMP))
        for bending, t_ramp in variants:
            label = f"smooth ({RAMP} s)" if t_ramp > 0 else "instantaneous"
            ns_run = ns[:-1] if (t_ramp == 0.0 or bending == "quadratic") and 60 in ns else ns
            traj = {}
            for n in ns_run:
                mesh = swatch(n, n, SIZE, SIZE)
                r = simulate(mesh, p, wave(mesh, t_ramp), TIMES, integrator="fast", bending=bending)
                assert r.ok, r.failure
                traj[n] = r.positions[:, mesh.tags["corners"][2:]]
            ref = max(traj)
            cells = []
            for n in (10, 20, 40):
                if n in traj and n != ref:
                    cells.append(f"{100 * np.max(np.linalg.norm(traj[n] - traj[ref], axis=-1)) / SIZE:.1f}")
                else:
                    cells.append("-")
            dlabel = f"{D:g}" + ("" if kd is None else f" (bend damping {kd:g})")
            print(f"| {dlabel} | {100 * lb:.1f} | {bending} | {label} | {' | '.join(cells)} | {ref}x{ref} |",
                  flush=True)
    # the perturbation floor: the same 40x40 run with half the time step
    p = mid_range_params()
    mesh = swatch(40, 40, SIZE, SIZE)
    a = simulate(mesh, p, wave(mesh), TIMES, integrator="fast").positions[:, mesh.tags["corners"][2:]]
    b = simulate(mesh, p, wave(mesh), TIMES, integrator="fast", safety=0.45).positions[:, mesh.tags["corners"][2:]]
    print(f"floor: 40x40 at mid-range D with the time step halved moves the corners by "
          f"{100 * np.max(np.linalg.norm(a - b, axis=-1)) / SIZE:.2f} % of the swatch size")


def bench_settle() -> None:
    """The gap suite's swatch (12x12, twin truth, motion exp1): frame-0 speed with and without the
    settle bath, and how far runs that differ only in their settle drift apart afterwards."""
    from vidsim.clothfit.film import swatch_driver, swatch_model_mesh
    from vidsim.gap.cloth_suite import ClothSceneConfig, twin_truth_params
    from vidsim.reality.cloth import corner_paths, swatch_motion

    p = twin_truth_params(ClothSceneConfig(), {})
    g = np.arange(0, 19) / 30
    cp = corner_paths(swatch_motion("exp1"), g)
    runs = {}
    for c in (0.0, 10.0, 20.0, 40.0):
        for settle in (0.5, 1.0, 4.0):
            mesh = swatch_model_mesh(cp[0], 12, 0.3)
            drv, t0 = swatch_driver(mesh, g, cp, settle)
            r = simulate(mesh, p, drv, g, integrator="fast", t0=t0, settle_bath=c)
            runs[(c, settle)] = r.positions
            v = np.linalg.norm(r.velocities[0], axis=1)
            print(f"settle {settle:3.1f} s, bath {c:4.1f} 1/s: frame-0 speed mean {1e3 * v.mean():6.2f} mm/s "
                  f"max {1e3 * v.max():6.2f} mm/s", flush=True)
    ref = runs[(40.0, 4.0)]
    for k, P in runs.items():
        d = 1e3 * np.linalg.norm(P - ref, axis=2).mean(axis=1)
        print(f"settle {k[1]:3.1f} s, bath {k[0]:4.1f}: mean distance to (4 s, bath 40) at frames 0/9/18: "
              f"{d[0]:.3f} / {d[9]:.2f} / {d[18]:.2f} mm")


#: two corners of the parameter space where the full study's slowest fits spent their time (the
#: optima of satin exp1 and linen exp1 in the 4 Dec 2026 full run; densities 0.1 and 0.2 kg/m^2)
DAMPED_CORNERS = {
    "satin corner": dict(bend=6.57e-5, stretch=1632.0, shear=490.0, bend_damping=1e-6, stretch_damping=0.1,
                         shear_damping=0.084, drag_linear=0.0023, drag_quad=1.45, drag_degrade=0.74, density=0.1),
    "linen corner": dict(bend=1e-4, stretch=1362.0, shear=376.0, bend_damping=1e-6, stretch_damping=0.05,
                         shear_damping=0.0046, drag_linear=0.0085, drag_quad=1.48, drag_degrade=0.52, density=0.2),
}


def bench_split() -> None:
    """``damping="split"`` (the condition dampings as per-condition decays after each step) against
    ``"explicit"``: the cost of the decay passes per element, and 50 frames of the waved 20x20 swatch
    at mid-range parameters and at the two damped corners (multirate "auto" as in the fits): steps,
    multirate factor, CPU time, and the distance to an explicit reference at an eighth of the step
    over the first 10 frames (after that the swing is chaotic, docs/gap.md)."""
    from vidsim.cloth.forces import bend_damping, color_order, membrane_damping, triangle_forces
    from vidsim.cloth.simulate import _model

    mesh = swatch(20, 20, SIZE, SIZE)
    p = mid_range_params()
    rng = np.random.default_rng(0)
    x = mesh.rest_positions + 1e-3 * rng.standard_normal(mesh.rest_positions.shape)
    v = 0.1 * rng.standard_normal(x.shape)
    m = _model(mesh, p, np.zeros(3))
    tris, coef, area, edges, bcoef, etris, tn, bquad, im = m[0], m[1], m[2], m[3], m[4], m[13], m[14], m[15], m[16]
    f = np.zeros_like(x)
    to, eo = color_order(tris, mesh.n_vertices), color_order(edges, mesh.n_vertices)
    M, E = len(tris), len(edges)
    reps = max(1, 20000 // M)

    def tri():
        for _ in range(reps):
            triangle_forces(x, v, tris, coef, area, p.stretch, p.stretch, p.shear, p.stretch_damping, p.shear_damping,
                            p.drag_linear, p.drag_quad, p.drag_degrade, np.zeros(3), tn, f)

    def mem():
        for _ in range(reps):
            membrane_damping(x, v, tris, coef, area, 0.01, 0.01, im, 1e-4, False, to)

    def bnd():
        for _ in range(reps):
            bend_damping(x, v, edges, etris, tn, bcoef, bquad, False, 1e-7, im, 1e-4, False, eo)

    print(f"\n## split damping ({load()})")
    print(f"decay passes at 20x20 (minimum over windows): membrane {1e9 * min_window(mem, reps)[0] / M:.0f} ns/triangle, "
          f"bending {1e9 * min_window(bnd, reps)[0] / E:.0f} ns/edge; the triangle force kernel "
          f"{1e9 * min_window(tri, reps)[0] / M:.0f} ns/triangle")
    drv = wave(mesh)
    print("| parameters | damping | mode used | step [ms] | multirate | steps | median CPU [s] | max distance to reference, frames 0-9 [mm] |")
    print("|---|---|---|---|---|---|---|---|")
    sets = {"mid-range": p, **{k: ClothParams(**kw) for k, kw in DAMPED_CORNERS.items()}}
    for name, q in sets.items():
        h = simulate(mesh, q, drv, TIMES[:10], integrator="fast").dt
        ref = simulate(mesh, q, drv, TIMES[:10], integrator="fast", dt=h / 8)
        for mode in ("explicit", "split", "auto"):
            t, r = median_time(lambda: simulate(mesh, q, drv, TIMES, integrator="fast", multirate="auto", damping=mode), 3)
            assert r.ok, r.failure
            d = 1e3 * np.max(np.linalg.norm(r.positions[:10] - ref.positions, axis=-1))
            print(f"| {name} | {mode} | {r.stats['damping']} | {1e3 * r.dt:.3f} | {r.stats['multirate']} | {r.steps} | "
                  f"{LAST_CPU[0]:.3f} | {d:.3f} |")


def main(argv: list[str]) -> None:
    which = set(argv) or {"speed", "force", "damping", "mujoco", "scaling"}
    print(f"cloth simulator benchmark; numba threads = {os.environ.get('NUMBA_NUM_THREADS')}")
    ours = bench_speed() if ("speed" in which or "mujoco" in which) else None
    if "force" in which:
        bench_force()
    if "damping" in which:
        bench_damping()
    if "mujoco" in which:
        bench_mujoco(ours)
    if "scaling" in which:
        bench_scaling()
    if "resolution" in which:
        bench_resolution()
    if "settle" in which:
        bench_settle()
    if "split" in which:
        bench_split()


if __name__ == "__main__":
    main(sys.argv[1:])
