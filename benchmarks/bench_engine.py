"""Accuracy and speed benchmark of the frogsim engine against an independent SciPy reference.

Run:  python benchmarks/bench_engine.py [--repeats N] [--ref-repeats N] [--no-reproduce]

Case
    One hip muscle through the paper's 2 s cycle (Sec. 4.1): charge command at 0 s, vent command
    at 1 s, paper supply mode with the per-branch limit set to 45 L/min (Sec. 4.3), every other
    value from the "fan2017" parameter set. Output on a 1 ms grid.

Reference
    The same equations written again here in plain Python/NumPy and integrated with
    ``scipy.integrate.solve_ivp``; only the parameter values (SI floats) are read from the loaded
    frogsim Scenario, none of frogsim's physics or circuit functions is used. State: mass and
    pressure of the source, the exhaust and the muscle. Each volume obeys the adiabatic open-volume
    energy balance  V dp/dt = k R (sum m_in T_in - m_out T) - k p dV/dt  with T = p V/(m R); valve
    flows follow ISO 6358 / paper Eq. (8) with a laminar region above the pressure ratio 0.999; the
    charge flow is clipped to the branch limit; the muscle volume is Eq. (5) plus the dead volume,
    with the length moving along a smoothstep (cubic Hermite, zero end slopes) from L0 to
    L0 (1 - eps) from command + delay over the rise time, and back after the vent command.
    Commands sit on the 1 kHz controller grid and act after the valve dead time (2 ms).
    solve_ivp is called once per interval between valve switchings and motion knots, so no step
    straddles a jump of the right-hand side or of its time derivative; the state-dependent kinks
    (branch-limit clip, laminar boundary) are left to step-size control, as in frogsim.

Checks and targets (acceptance criteria)
    * agreement: max |p_frogsim - p_reference| of the muscle and the source pressures on the 1 ms
      grid below 0.1 % of 6 bar (600 Pa); reference: DOP853, rtol 1e-9;
    * speed: frogsim.simulate on a prebuilt model at least 100 x faster than the reference, best
      of N calls each, after a warm-up call that absorbs Numba compilation (timed and shown on its
      own). The verdict uses the reference at frogsim's own method and tolerance (RK45, the
      scenario's rtol) so that the ratio compares implementations, not tolerances; the tight
      reference's time is shown too;
    * wall heat transfer: the same cycle with the parameter set "fan2017-heat" (heat through the
      walls of the muscle, the source and the exhaust) at most 15 % slower than with it off
      (fan2017), both timed in turns in this run, best of rounds (option --heat, on by default);
      the steps and right-hand-side evaluations of each are shown, since the heat changes the
      dynamics the integrator follows, not only the cost of one evaluation;
    * ``frogsim reproduce --out <tmpdir>`` wall time, with a fresh Numba cache so compilation is
      included, below 15 s, best of --reproduce-runs (2) cold runs (option --reproduce, on by
      default; skipped with a message when the command is missing or fails). Each run follows a
      cold run of the code before the one stepping driver (BASELINE, from the git history), and
      the ratio to its best is printed: this machine's speed drifts, so only a baseline timed in
      turns with the run says whether it got slower.

Exit status: 0 when every measured target is met, 1 otherwise.
"""
from __future__ import annotations

import argparse
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass

import numba
import numpy as np
import scipy
from scipy.integrate import solve_ivp

import frogsim
from frogsim.engine.integrator import run_schedule

SCENARIO = {
    "name": "bench-hip",
    "parameters": "fan2017",
    "duration": "2 s",
    "output_interval": "1 ms",
    "programs": {"stroke": {"pressurise": "1 s", "release": "1 s"}},
    "muscles": {"hip": {"type": "hip", "program": "stroke",
                        "motion": {"kind": "stroke", "delay": "0.1 s", "rise": "0.3 s",
                                   "fall": "0.3 s"}}},
    "supply": {"branch_limit": "45 L/min"},
}
MUSCLE = "hip"
BAR = 1e5
PRESSURE_SCALE = 6 * BAR            # the paper's 6 bar source pressure
AGREEMENT_TOL = 1e-3                # 0.1 % of PRESSURE_SCALE
SPEEDUP_TARGET = 100.0
REPRODUCE_TARGET = 15.0             # [s]
CHECK_METHOD, CHECK_RTOL = "DOP853", 1e-9
HEAT_PARAMETERS = "fan2017-heat"
HEAT_SLOWDOWN_TARGET = 1.15         # heat on / heat off, wall time
BASELINE = "e625af2"                # the last commit before the one stepping driver

# reference state vector
MS, PS, ME, PE, MM, PM = range(6)


@dataclass(frozen=True)
class Valve:
    """ISO 6358 characteristics of one valve (SI)."""
    C: float          # sonic conductance [m^3/(s Pa)]
    b: float          # critical pressure ratio [-]
    m: float          # subsonic index [-]
    r_lam: float      # laminar pressure ratio [-]
    dead_time: float  # [s]


@dataclass(frozen=True)
class Stroke:
    """One smoothstep move of the muscle length from L_from to L_to over [t0, t0 + duration]."""
    t0: float
    duration: float
    L_from: float
    L_to: float


@dataclass(frozen=True)
class Params:
    """Every number the reference needs, read from the loaded Scenario (SI floats)."""
    R: float
    k: float
    rho_ref: float
    T_ref: float
    T_amb: float
    p_atm: float
    V_s: float
    V_e: float
    p_s0: float
    p_e0: float
    p_m0: float
    b0: float
    n_turns: float
    V_dead: float
    L0: float
    charge: Valve
    discharge: Valve
    m_limit: float          # branch limit as a mass flow [kg/s]
    strokes: tuple          # Stroke, in time order
    switches: tuple         # (time [s], charge open, discharge open), in time order
    duration: float


def command_time(t: float, rate: float) -> float:
    """First controller sample at or after t [s]."""
    return math.ceil(t * rate - 1e-9) / rate


def params_from_scenario(sc) -> Params:
    """Collect the reference's parameters from a single-muscle frogsim Scenario."""
    (muscle,) = sc.muscles.values()
    mt = sc.muscle_types[muscle.type]
    air = sc.air
    rho_ref = air.reference_pressure_abs / (air.gas_constant * air.reference_temperature)
    b0 = mt.nominal_length / math.cos(mt.braid_angle)
    n_turns = b0 * math.sin(mt.braid_angle) / (math.pi * mt.inner_diameter)
    valves = [Valve(v.sonic_conductance, v.critical_ratio, v.subsonic_index, v.laminar_ratio,
                    v.dead_time) for v in (sc.valves.charge, sc.valves.discharge)]
    eps = mt.stroke_contraction if muscle.motion.contraction is None else muscle.motion.contraction
    rate = sc.controller.rate
    strokes, switches = [], []
    L_now = mt.nominal_length
    for t_cmd, state in muscle.program.steps:
        tq = command_time(t_cmd, rate)
        # valve states (charge, discharge) after this command, each valve after its own dead time
        want = {"charge": (True, False), "vent": (False, True), "hold": (False, False)}[state]
        switches.append((tq + valves[0].dead_time, 0, want[0]))
        switches.append((tq + valves[1].dead_time, 1, want[1]))
        if state == "hold":
            continue
        L_target = mt.nominal_length * (1.0 - eps) if state == "charge" else mt.nominal_length
        if L_target != L_now:
            dur = muscle.motion.rise if state == "charge" else muscle.motion.fall
            strokes.append(Stroke(tq + muscle.motion.delay, dur, L_now, L_target))
            L_now = L_target
    # merge per-valve events into a list of (time, charge open, discharge open)
    u = [False, False]
    merged = []
    for t, j, val in sorted(switches):
        u[j] = val
        if merged and abs(merged[-1][0] - t) < 1e-12:
            merged[-1] = (merged[-1][0], u[0], u[1])
        else:
            merged.append((t, u[0], u[1]))
    p_atm = air.atmospheric_pressure_abs
    p_m0 = p_atm + (muscle.initial_pressure_gauge if muscle.initial_pressure_gauge is not None
                    else sc.exhaust.initial_pressure_gauge)
    return Params(
        R=air.gas_constant, k=air.heat_capacity_ratio, rho_ref=rho_ref,
        T_ref=air.reference_temperature, T_amb=air.ambient_temperature, p_atm=p_atm,
        V_s=sc.source.volume, V_e=sc.exhaust.volume,
        p_s0=p_atm + sc.source.initial_pressure_gauge,
        p_e0=p_atm + sc.exhaust.initial_pressure_gauge,
        p_m0=p_m0, b0=b0, n_turns=n_turns, V_dead=mt.dead_volume, L0=mt.nominal_length,
        charge=valves[0], discharge=valves[1], m_limit=rho_ref * sc.supply.branch_limit,
        strokes=tuple(strokes), switches=tuple(merged), duration=sc.duration)


# -- reference equations --------------------------------------------------------------------------

def muscle_length(t: float, par: Params) -> tuple[float, float]:
    """Muscle length L [m] and dL/dt [m/s]: smoothstep moves, constant in between."""
    L = par.L0
    for s in par.strokes:
        if t <= s.t0:
            break
        x = min((t - s.t0) / s.duration, 1.0)
        L = s.L_from + (s.L_to - s.L_from) * x * x * (3.0 - 2.0 * x)
        if x < 1.0:
            return L, (s.L_to - s.L_from) * 6.0 * x * (1.0 - x) / s.duration
    return L, 0.0


def muscle_volume(t: float, par: Params) -> tuple[float, float]:
    """Volume V = (b0^2 - L^2) L / (4 pi n^2) + V_dead [m^3] (Eq. (5)) and dV/dt [m^3/s]."""
    L, dL = muscle_length(t, par)
    c = 4.0 * math.pi * par.n_turns ** 2
    return (par.b0 ** 2 - L * L) * L / c + par.V_dead, (par.b0 ** 2 - 3.0 * L * L) / c * dL


def omega(sigma: float, v: Valve) -> float:
    """ISO 6358 flow function: choked, subsonic, and linear (laminar) above r_lam  [-]."""
    if sigma <= v.b:
        return 1.0
    if sigma >= 1.0:
        return 0.0
    if sigma > v.r_lam:
        w_lam = (1.0 - ((v.r_lam - v.b) / (1.0 - v.b)) ** 2) ** v.m
        return (1.0 - sigma) / (1.0 - v.r_lam) * w_lam
    return (1.0 - ((sigma - v.b) / (1.0 - v.b)) ** 2) ** v.m


def valve_flow(p1: float, T1: float, p2: float, T2: float, v: Valve, par: Params) -> float:
    """Eq. (8) mass flow from side 1 to side 2 [kg/s] (negative when it runs from 2 to 1)."""
    if p1 >= p2:
        return v.C * par.rho_ref * p1 * math.sqrt(par.T_ref / T1) * omega(p2 / p1, v)
    return -v.C * par.rho_ref * p2 * math.sqrt(par.T_ref / T2) * omega(p1 / p2, v)


def rhs(t, y, par: Params, charge_open: bool, discharge_open: bool) -> list:
    """d/dt of [m_s, p_s, m_e, p_e, m_m, p_m]; valve states constant over the call's segment."""
    m_s, p_s, m_e, p_e, m_m, p_m = y
    R, k = par.R, par.k
    V_m, dV_m = muscle_volume(t, par)
    T_s = p_s * par.V_s / (m_s * R)
    T_e = p_e * par.V_e / (m_e * R)
    T_m = p_m * V_m / (m_m * R)
    # (mass in, enthalpy in = sum m_in T_in, mass out) of source, exhaust, muscle
    in_s = h_s = out_s = in_e = h_e = out_e = in_m = h_m = out_m = 0.0
    if charge_open:
        mc = valve_flow(p_s, T_s, p_m, T_m, par.charge, par)
        mc = min(max(mc, -par.m_limit), par.m_limit)
        if mc >= 0.0:
            out_s += mc
            in_m += mc
            h_m += mc * T_s
        else:
            out_m -= mc
            in_s -= mc
            h_s -= mc * T_m
    if discharge_open:
        md = valve_flow(p_m, T_m, p_e, T_e, par.discharge, par)
        if md >= 0.0:
            out_m += md
            in_e += md
            h_e += md * T_m
        else:
            out_e -= md
            in_m -= md
            h_m -= md * T_e
    return [in_s - out_s, k * R * (h_s - out_s * T_s) / par.V_s,
            in_e - out_e, k * R * (h_e - out_e * T_e) / par.V_e,
            in_m - out_m, (k * R * (h_m - out_m * T_m) - k * p_m * dV_m) / V_m]


def segments(par: Params) -> list:
    """(t_start, t_end, charge open, discharge open) between valve switchings and motion knots."""
    cuts = {0.0, par.duration}
    cuts |= {t for t, _, _ in par.switches}
    for s in par.strokes:
        cuts |= {s.t0, s.t0 + s.duration}
    cuts = sorted(t for t in cuts if 0.0 <= t <= par.duration)
    out = []
    for a, b in zip(cuts, cuts[1:]):
        state = (False, False)
        for t_sw, ch, dis in par.switches:
            if t_sw <= a:
                state = (ch, dis)
        out.append((a, b, *state))
    return out


def simulate_reference(par: Params, t_out: np.ndarray, method: str, rtol: float) -> np.ndarray:
    """Integrate the reference, one solve_ivp call per segment; state at t_out, shape (n, 6)."""
    V0, _ = muscle_volume(0.0, par)
    y = np.array([par.p_s0 * par.V_s / (par.R * par.T_amb), par.p_s0,
                  par.p_e0 * par.V_e / (par.R * par.T_amb), par.p_e0,
                  par.p_m0 * V0 / (par.R * par.T_amb), par.p_m0])
    # absolute tolerances: rtol times each state's size at atmospheric pressure
    scale = np.array([par.V_s, 1.0, par.V_e, 1.0, V0, 1.0]) * par.p_atm
    scale[[MS, ME, MM]] /= par.R * par.T_amb
    atol = rtol * scale
    out = np.full((t_out.size, 6), np.nan)
    out[t_out <= 0.0] = y
    for a, b, ch, dis in segments(par):
        sel = (t_out > a) & (t_out <= b)
        t_eval = t_out[sel]
        if not t_eval.size or t_eval[-1] != b:
            t_eval = np.append(t_eval, b)          # the segment's end state seeds the next one
        sol = solve_ivp(rhs, (a, b), y, method=method, rtol=rtol, atol=atol, t_eval=t_eval,
                        args=(par, ch, dis))
        if not sol.success:
            raise RuntimeError(f"reference integration failed on [{a:g}, {b:g}] s: {sol.message}")
        out[sel] = sol.y[:, :np.count_nonzero(sel)].T
        y = sol.y[:, -1]
    return out


# -- measurements ---------------------------------------------------------------------------------

def time_calls(fn, repeats: int) -> tuple[float, float, object]:
    """Best and median wall time [s] of `repeats` calls of fn, and the last call's return value."""
    times = []
    value = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        value = fn()
        times.append(time.perf_counter() - t0)
    return min(times), statistics.median(times), value


def heat_on_off(calls: int, rounds: int) -> dict:
    """Best wall time per call [s] of frogsim.simulate on the benchmark cycle with wall heat transfer
    off (fan2017) and on (fan2017-heat), timed in turns (``rounds`` rounds of ``calls`` calls each),
    and each run's stats."""
    models = {"off": frogsim.build_model(frogsim.load_scenario(SCENARIO)),
              "on": frogsim.build_model(frogsim.load_scenario({**SCENARIO, "parameters": HEAT_PARAMETERS}))}
    stats = {k: frogsim.simulate(m).stats for k, m in models.items()}      # (compiles, if needed)
    best = {k: float("inf") for k in models}
    for _ in range(rounds):
        for k, m in models.items():
            t0 = time.perf_counter()
            for _ in range(calls):
                frogsim.simulate(m)
            best[k] = min(best[k], (time.perf_counter() - t0) / calls)
    return {"best": best, "stats": stats}


def fmt_time(seconds: float) -> str:
    """A wall time with a readable unit."""
    if seconds >= 1.0:
        return f"{seconds:.2f} s"
    if seconds >= 1e-3:
        return f"{seconds * 1e3:.2f} ms"
    return f"{seconds * 1e6:.1f} us"


def numba_origin() -> str:
    """Whether the engine's first call compiled or loaded from Numba's on-disk cache."""
    stats = run_schedule.stats
    if sum(stats.cache_misses.values()):
        return "Numba compilation"
    if sum(stats.cache_hits.values()):
        return "machine code loaded from the Numba cache, not compiled"
    return "Numba compilation, caching off"


def time_reproduce(timeout: float, src: str | None = None) -> float | None:
    """Wall time [s] of `frogsim reproduce --out <tmpdir>` with a fresh Numba cache.

    ``src``: run the package found there (a ``src`` folder, e.g. an older commit's) instead of the
    installed ``frogsim`` command. Returns None (with a message) when the command is missing or
    fails, inf on timeout; on success prints the command's own last progress line.
    """
    env = dict(os.environ)
    if src is None:
        exe = shutil.which("frogsim")
        if exe is None:
            print("  skipped: no `frogsim` command on PATH")
            return None
        prefix = [exe]
    else:
        prefix = [sys.executable, "-m", "frogsim"]
        env["PYTHONPATH"] = src
    with tempfile.TemporaryDirectory(prefix="frogsim-out-") as out, \
            tempfile.TemporaryDirectory(prefix="frogsim-numba-") as cache:
        env["NUMBA_CACHE_DIR"] = cache
        cmd = prefix + ["reproduce", "--out", out]
        t0 = time.perf_counter()
        try:
            proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            print(f"  `frogsim reproduce` did not finish within {timeout:g} s")
            return math.inf
        wall = time.perf_counter() - t0
    lines = (proc.stderr or proc.stdout).strip().splitlines()
    last = lines[-1] if lines else "no output"
    if proc.returncode != 0:
        print(f"  skipped: `frogsim reproduce` failed (exit {proc.returncode}): {last}")
        return None
    print(f"  its last line: {last}")
    return wall


def baseline_src(folder: str) -> str | None:
    """The ``src`` folder of BASELINE (from the repository's history, by ``git archive``) unpacked
    into folder, or None (with a message) when the history is not at hand."""
    import io
    import tarfile
    repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    try:
        blob = subprocess.run(["git", "-C", repo, "archive", BASELINE, "src"], capture_output=True,
                              check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        print(f"  baseline {BASELINE} skipped: no git history here")
        return None
    with tarfile.open(fileobj=io.BytesIO(blob)) as tar:
        tar.extractall(folder)
    return os.path.join(folder, "src")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=500,
                    help="timed frogsim.simulate calls, best taken (default 500)")
    ap.add_argument("--ref-repeats", type=int, default=7,
                    help="timed runs of each reference, best taken (default 7)")
    ap.add_argument("--ref-method", default="RK45", choices=("RK45", "DOP853"),
                    help="solve_ivp method of the reference timed for the verdict (default RK45)")
    ap.add_argument("--ref-rtol", type=float, default=None,
                    help="rtol of the reference timed for the verdict (default: frogsim's own)")
    ap.add_argument("--heat", action=argparse.BooleanOptionalAction, default=True,
                    help="also time the cycle with wall heat transfer on against off (default on)")
    ap.add_argument("--reproduce", action=argparse.BooleanOptionalAction, default=True,
                    help="also time `frogsim reproduce` with a fresh Numba cache (default on)")
    ap.add_argument("--reproduce-runs", type=int, default=2,
                    help="cold runs of `frogsim reproduce`, best taken, each after one of the baseline "
                         f"({BASELINE}; 0: no baseline, one run) (default 2)")
    ap.add_argument("--reproduce-timeout", type=float, default=300.0,
                    help="give up on `frogsim reproduce` after this many seconds (default 300)")
    args = ap.parse_args(argv)

    sc = frogsim.load_scenario(SCENARIO)
    par = params_from_scenario(sc)
    model = frogsim.build_model(sc)
    print(f"frogsim {frogsim.__version__} engine benchmark: one hip muscle, "
          f"{sc.duration:g} s cycle "
          f"(charge at 0 s, vent at 1 s), branch limit {sc.supply.branch_limit * 6e4:g} L/min "
          f"(standard), output every {sc.output_interval * 1e3:g} ms")
    print(f"Python {sys.version.split()[0]}, NumPy {np.__version__}, SciPy {scipy.__version__}, "
          f"Numba {numba.__version__}, {os.cpu_count()} CPUs")
    failures = []

    # frogsim: first call (compilation), then best of N
    t0 = time.perf_counter()
    frogsim.simulate(model)
    first_call = time.perf_counter() - t0
    origin = numba_origin()
    fs_best, fs_median, result = time_calls(lambda: frogsim.simulate(model), args.repeats)

    # references: the tight one for the check, the verdict's one for the timing
    check_cfg = (CHECK_METHOD, CHECK_RTOL)
    timed_cfg = (args.ref_method, sc.solver.rtol if args.ref_rtol is None else args.ref_rtol)
    refs = {}
    for cfg in dict.fromkeys((check_cfg, timed_cfg)):
        refs[cfg] = time_calls(lambda: simulate_reference(par, result.t, *cfg), args.ref_repeats)

    # 1. agreement
    y_ref = refs[check_cfg][2]
    limit = AGREEMENT_TOL * PRESSURE_SCALE
    print(f"\nAgreement with the reference ({CHECK_METHOD}, rtol {CHECK_RTOL:g}) at "
          f"{result.t.size} points of the {sc.output_interval * 1e3:g} ms grid")
    print(f"  {'quantity':<18}{'max |difference|':>18}{'% of 6 bar':>14}{'at t':>10}")
    worst = 0.0
    for label, ours, theirs in (("muscle pressure", result.muscle_pressure(MUSCLE), y_ref[:, PM]),
                                ("source pressure", result.source_pressure, y_ref[:, PS])):
        diff = np.abs(ours - theirs)
        j = int(np.argmax(diff))
        worst = max(worst, diff[j])
        print(f"  {label:<18}{diff[j]:>15.3f} Pa{100 * diff[j] / PRESSURE_SCALE:>12.5f} %"
              f"{result.t[j]:>8.3f} s")
    print(f"  {'limit':<18}{limit:>15.3f} Pa{100 * AGREEMENT_TOL:>12.5f} %")
    ok = worst < limit
    print(f"  agreement: {'PASS' if ok else 'FAIL'}")
    if not ok:
        failures.append("agreement")

    # 2. speed
    print(f"\nWall time of one {sc.duration:g} s simulation")
    print(f"  {'run':<44}{'best':>11}{'median':>11}")
    print(f"  {'frogsim simulate(model), first call':<44}{fmt_time(first_call):>11}{'-':>11}"
          f"   ({origin})")
    print(f"  {f'frogsim simulate(model), {args.repeats} calls':<44}{fmt_time(fs_best):>11}"
          f"{fmt_time(fs_median):>11}   ({result.stats['steps']} steps, "
          f"{result.stats['rejected']} rejected, rtol {sc.solver.rtol:g})")
    for (method, rtol), (best, median, y) in refs.items():
        name = f"reference {method}, rtol {rtol:g}, {args.ref_repeats} runs"
        note = ("the agreement reference" if (method, rtol) == check_cfg else
                f"max |muscle pressure - agreement reference| "
                f"{np.abs(y[:, PM] - y_ref[:, PM]).max():.3f} Pa")
        print(f"  {name:<44}{fmt_time(best):>11}{fmt_time(median):>11}   ({note})")
    print("  speed-up of frogsim, best / best:")
    for cfg, (best, _, _) in refs.items():
        role = "the verdict's" if cfg == timed_cfg else "information only"
        name = f"vs reference {cfg[0]}, rtol {cfg[1]:g}"
        print(f"    {name:<40}{best / fs_best:>9.1f} x   ({role})")
    speedup = refs[timed_cfg][0] / fs_best
    ok = speedup >= SPEEDUP_TARGET
    print(f"  speed-up: {'PASS' if ok else 'FAIL'} "
          f"({speedup:.1f} x, target >= {SPEEDUP_TARGET:g} x)")
    if not ok:
        failures.append("speed-up")

    # 3. wall heat transfer on against off, in turns
    if args.heat:
        h = heat_on_off(calls=50, rounds=max(3, args.repeats // 50))
        ratio = h["best"]["on"] / h["best"]["off"]
        print(f"\nWall heat transfer ({HEAT_PARAMETERS} against fan2017, the same cycle, timed in turns)")
        for k in ("off", "on"):
            st = h["stats"][k]
            print(f"  heat {k:<4}{fmt_time(h['best'][k]):>11}   ({st['steps']} steps, {st['rejected']} rejected, "
                  f"{st['rhs_evaluations']} rhs evaluations)")
        evals = h["stats"]["on"]["rhs_evaluations"] / h["stats"]["off"]["rhs_evaluations"]
        ok = ratio <= HEAT_SLOWDOWN_TARGET
        print(f"  on / off: {ratio:.3f} in wall time, {evals:.3f} in rhs evaluations: "
              f"{'PASS' if ok else 'FAIL'} (target <= {HEAT_SLOWDOWN_TARGET:g})")
        if not ok:
            failures.append("heat transfer slowdown")

    # 4. frogsim reproduce, cold; the code before the one-core change as the baseline, in turns
    print(f"\n`frogsim reproduce` with a fresh Numba cache (target < {REPRODUCE_TARGET:g} s; baseline: the "
          f"code of {BASELINE}, before the one stepping driver, in turns with it)")
    if args.reproduce:
        walls, base = [], []
        with tempfile.TemporaryDirectory(prefix="frogsim-baseline-") as folder:
            old = baseline_src(folder) if args.reproduce_runs > 0 else None
            for _ in range(max(1, args.reproduce_runs)):
                if old is not None:
                    print(f"  baseline {BASELINE}:")
                    w = time_reproduce(args.reproduce_timeout, old)
                    if w is not None:
                        base.append(w)
                print("  now:")
                w = time_reproduce(args.reproduce_timeout)
                if w is not None:
                    walls.append(w)
        if walls:
            wall = min(walls)
            ok = wall < REPRODUCE_TARGET
            print(f"  wall time {wall:.2f} s (best of {', '.join(f'{x:.2f}' for x in walls)} s)")
            if base:
                b = min(base)
                print(f"  baseline {BASELINE}: {b:.2f} s (best of {', '.join(f'{x:.2f}' for x in base)} s); "
                      f"now / baseline {wall / b:.2f}: {'no slower' if wall <= b else 'SLOWER'} than before")
                if wall > b:
                    failures.append(f"reproduce slower than {BASELINE}")
            print(f"  reproduce: {'PASS' if ok else 'FAIL'}")
            if not ok:
                failures.append("reproduce time")
    else:
        print("  skipped (--no-reproduce)")

    print(f"\n{'FAIL: ' + ', '.join(failures) if failures else 'PASS: all measured targets met'}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
