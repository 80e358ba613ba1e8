"""The ``frogsim`` command: a thin layer over the registries and the engine (no physics here).

    frogsim studies                         list the registered studies
    frogsim scenarios                       list the shipped scenarios
    frogsim reproduce [STUDY ...] --out DIR reproduce the paper's studies (the pneumatic ones by
                                            default; name leg-in-air for the robot's in-air study)
    frogsim design [STUDY ...] --out DIR    the design studies (main tubes, endurance, valves)
    frogsim control [STUDY ...] --out DIR   the closed-loop control studies (control-pressure, control-joint,
                                            hysteresis, heat, control-tune)
    frogsim simulate SCENARIO [--patch PATCH.toml] --out DIR
                                            run one scenario (TOML path or shipped name)
    frogsim swim SCENARIO [--cycles N] [--output-interval T] --out DIR
                                            run the robot in MuJoCo (swim, leg-in-air): CSV,
                                            figure, summary.json, MJCF, animation
    frogsim params [NAME]                   show a parameter set with the source of every value
    frogsim sweep SPEC.toml --out RESULTS.nc run a parameter sweep (resumable; see docs/sweeps.md)
    frogsim plot RESULTS.nc --x P --metric M --out FIG.png
                                            a sweep's metric against one or two swept parameters
    frogsim fit FIT.toml --out DIR          calibrate parameters to measured traces (docs/fitting.md)
    frogsim optimize-gait SCENARIO --trials N --objective speed|distance-per-litre --out DIR
                                            search the gait's phase timing (resumable; docs/control.md)
    frogsim tune SCENARIO --trials N [--pareto] [--storage URL] --out DIR
                                            search the controllers' gains (resumable; docs/control.md)
    frogsim compare RUN[:SIGNAL] ... [--signal NAME] --out DIR
                                            overlay one signal of several runs or scenarios
    frogsim firmware SCENARIO [--patch PATCH.toml] --out DIR [--build]
                                            the valve controllers as an Arduino Mega 2560 sketch
                                            (docs/firmware.md); --build compiles it
    frogsim sil SCENARIO [--patch PATCH.toml] --firmware DIR --out DIR
                                            the built firmware on an emulated ATmega2560 in
                                            lockstep with the plant (software in the loop)
    frogsim log --port PORT [--firmware DIR] --out DIR
                                            record a board's serial log as a CSV trace

Output folders: a folder belongs to the command that first wrote it (its manifest.json says which:
command line, frogsim version, time, SHA-256 of the scenario's files, the files written). Another
command, or the same single-run command (simulate, swim, compare) again, refuses to write there
unless --overwrite, which first deletes the files of the run it replaces. reproduce and design may
add studies to their own folder; a study already there is replaced only with --overwrite. Files
are created with the user's umask.

Every option means the same in every command that has it (README, "Flags"); --out is required
wherever a command writes, and a bad --out (empty, the root, a file, a place that cannot be
written) is refused before anything runs.

Exit codes: 0 success, 1 simulation failure, 2 bad input (one-line message, nothing written).
"""
from __future__ import annotations

import argparse
import sys
import textwrap
import time
from pathlib import Path

from frogsim._files import out_folder
from frogsim._words import count as _count


def _err(msg: str, code: int) -> int:
    print(f"frogsim: error: {msg}", file=sys.stderr)
    return code


def _progress(msg: str) -> None:
    """A progress message on stderr (none with --quiet; warnings use _warn)."""
    if not _QUIET:
        print(msg, file=sys.stderr, flush=True)


#: [s] the longest a command stays silent on stderr while it works (unless --quiet)
PROGRESS_EVERY_S = 2.0


def _every(describe):
    """A progress callback for a long loop: ``tick(fraction)`` says ``describe(fraction)`` (a line)
    at most once per PROGRESS_EVERY_S, the first time that long after the callback was made."""
    last = [time.perf_counter()]

    def tick(fraction):
        now = time.perf_counter()
        if now - last[0] >= PROGRESS_EVERY_S:
            last[0] = now
            _progress(describe(fraction))
    return tick


def _compiling(dispatcher, engine: str) -> None:
    """Before a run whose compiled code is not cached yet (a first run on this machine, or after
    an update of frogsim or Numba): say so, since Numba then compiles for 10-60 s without a word."""
    from frogsim._jit import cache_is_warm
    if not cache_is_warm(dispatcher):
        _progress(f"compiling the {engine} engine, once per machine (cached afterwards) ...")


def _warn(msg: str) -> None:
    print(f"warning: {msg}", file=sys.stderr, flush=True)


def _folder(args, command: str, **kw):
    """The run's claim on its output folder, checked (ScenarioError: exit 2, nothing written)."""
    from frogsim.io.outputs import OutputFolder
    folder = OutputFolder(args.out, command, getattr(args, "argv", []), overwrite=args.overwrite, **kw)
    folder.check()
    return folder


def _finishing(folder, work):
    """Run work() in a claimed folder: manifest "running" first, then "complete", "interrupted"
    or "failed"."""
    from frogsim.io.outputs import ended_status
    folder.begin()
    if folder.left:
        _warn(f"--overwrite left {_count(len(folder.left), 'file')} in {folder.out} that the replaced run's manifest "
              "does not list (frogsim did not write them): " + ", ".join(folder.left[:4])
              + (", ..." if len(folder.left) > 4 else ""))
    try:
        result = work()
    except BaseException as exc:
        folder.finish(ended_status(exc))
        raise
    return result


def cmd_studies(args) -> int:
    from frogsim.studies import STUDIES, studies_in
    width = max(len(n) for n in STUDIES)
    for group, command in (("paper", "frogsim reproduce"),
                           ("robot", "frogsim reproduce NAME (named: compiles the MuJoCo engine on first use)"),
                           ("design", "frogsim design"), ("control", "frogsim control")):
        print(f"# {command}")
        for name in studies_in(group):
            print(f"{name:<{width}}  {STUDIES[name].title}")
    return 0


def cmd_scenarios(args) -> int:
    from frogsim.scenario.load import shipped_scenarios
    rows = shipped_scenarios()
    width = max(len(n) for n, _, _ in rows)
    for name, command, about in rows:
        print(f"{name:<{width}}  frogsim {command:<8}  {about}")
    return 0


def cmd_reproduce(args) -> int:
    return _run_studies(args, "paper")


def cmd_design(args) -> int:
    return _run_studies(args, "design")


def cmd_control(args) -> int:
    return _run_studies(args, "control")


def _study_task(name: str, out: str) -> tuple:
    """Compute one study and write its CSV and PNG; returns (name, summary, seconds).

    Runs in a worker process, so the costly first-run compilations of different engines (the
    pneumatic one, the coupled MuJoCo one) proceed side by side on the machine's cores.
    """
    from frogsim._files import write_figure
    from frogsim.studies import STUDIES
    from frogsim.studies.registry import write_table
    t0 = time.perf_counter()
    study = STUDIES[name]
    data = study.compute()
    write_table(name, data, out)
    write_figure(Path(out) / f"{name}.png", lambda p: study.draw(data, p))
    return name, data.summary, time.perf_counter() - t0


#: [s] while studies run on the pool, a line naming those still running at least this often
STUDY_HEARTBEAT_S = 5.0


def _run_studies(args, group: str) -> int:
    from frogsim._files import write_json
    from frogsim.io.outputs import scenario_record, shipped_inputs
    from frogsim.studies import STUDIES, studies_in
    names = list(dict.fromkeys(args.studies or studies_in(group)))
    own = studies_in(group) + (studies_in("robot") if group == "paper" else [])
    unknown = [n for n in names if n not in own]
    if unknown:
        other = STUDIES[unknown[0]].group if unknown[0] in STUDIES else None
        where = {"paper": "reproduce", "robot": "reproduce", "design": "design", "control": "control"}.get(other)
        return _err(f"study = {unknown[0]!r}: must be one of {', '.join(own)}"
                    + (f" (it is a study of `frogsim {where}`)" if where else ""), 2)
    out = out_folder(args.out)
    if args.workers is not None and args.workers < 1:
        return _err(f"--workers = {args.workers}: must be a whole number >= 1", 2)
    folder = _folder(args, args.command, studies={n: [f"{n}.csv", f"{n}.png"] for n in names},
                     scenario=scenario_record("shipped scenarios and parameter sets", shipped_inputs()))
    summaries = {}
    folder.begin()
    try:
        return _studies_into(args, folder, out, names, summaries)
    except BaseException as exc:
        from frogsim.io.outputs import ended_status
        done = [n for n in names if n in summaries]     # the studies that did finish stay recorded
        if done:
            summary = folder.previous_summary()
            for name in done:
                summary.update(summaries[name])
            write_json(out / "summary.json", summary)
        folder.finish(ended_status(exc), {n: list(summaries[n]) for n in done})
        raise


def _studies_into(args, folder, out: Path, names: list[str], summaries: dict) -> int:
    import multiprocessing
    import os
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    from frogsim._jit import cache_is_warm
    from frogsim.engine.integrator import advance
    from frogsim.engine.warmup import warm_up_parts
    from frogsim._files import write_json
    from frogsim.studies import STUDIES
    procs = args.workers or os.cpu_count() or 1
    workers = min(procs, len(names))
    # the engine is compiled (or loaded) on two processes or more even for a single study
    pool_size = min(procs, max(len(names), 2))
    if not cache_is_warm(advance):
        _progress(f"compiling the engines, once per machine, on {pool_size} process{'es' if pool_size > 1 else ''} "
                  "(cached afterwards) ...")
    studies = f"{len(names)} stud{'ies' if len(names) != 1 else 'y'}"
    _progress(f"{studies} on {workers} process{'es' if workers > 1 else ''} -> {out}/")
    order = sorted(names, key=lambda n: -STUDIES[n].cost)     # costly first, so they overlap the rest
    t_all = time.perf_counter()

    def report(k, name, summary, seconds):
        summaries[name] = summary
        _progress(f"[{k}/{len(names)}] {name} done in {seconds:.2f} s -> {out / name}.png, .csv: "
                  f"{STUDIES[name].title}")
        for entry in summary.values():
            if isinstance(entry, dict) and "conclusion" in entry:
                _progress(textwrap.fill(entry["conclusion"], 100, initial_indent="      ",
                                        subsequent_indent="      "))
    if pool_size == 1:
        for k, name in enumerate(order, 1):
            report(k, *_study_task(name, str(out)))
    else:
        # fork where the platform has it: the workers inherit the loaded libraries (about 2 s of
        # imports each with spawn); no threads are running yet, so forking is safe here
        methods = multiprocessing.get_all_start_methods()
        ctx = multiprocessing.get_context("fork" if "fork" in methods else "spawn")
        with ProcessPoolExecutor(pool_size, mp_context=ctx) as pool:
            # the engine's parts compiled (or loaded from the cache) side by side, first: on a
            # warm cache this loads the engine in parallel, in about the time the studies would
            warm_up_parts(pool, pool_size)
            futures = {pool.submit(_study_task, name, str(out)): name for name in order}
            pending, k, shown = set(futures), 0, time.perf_counter()
            while pending:
                # a line every few seconds while studies run, naming them: a long study is not silence
                done, pending = wait(pending, timeout=STUDY_HEARTBEAT_S, return_when=FIRST_COMPLETED)
                for fut in done:
                    k += 1
                    report(k, *fut.result())
                    shown = time.perf_counter()
                if pending and time.perf_counter() - shown >= STUDY_HEARTBEAT_S:
                    shown = time.perf_counter()
                    running = sorted(futures[f] for f in pending)
                    _progress(f"      {len(names) - len(pending)} of {len(names)} done; still running: "
                              f"{', '.join(running)} ({shown - t_all:.0f} s so far)")
    summary = folder.previous_summary()     # studies an earlier run of this command put here
    for name in names:                      # in registration order, whatever finished first
        summary.update(summaries[name])
    write_json(out / "summary.json", summary)
    folder.finish("complete", {n: list(summaries[n]) for n in names})
    _progress(f"{studies} in {time.perf_counter() - t_all:.1f} s; summary: {out / 'summary.json'}, "
              f"manifest: {out / 'manifest.json'}")
    return 0

def cmd_simulate(args) -> int:
    from frogsim.engine.pneumatic import simulate
    from frogsim.io.outputs import scenario_record
    from frogsim.scenario.load import load_scenario
    out = out_folder(args.out)
    scenario = load_scenario(_patched(args))          # all validation happens here, before any write
    folder = _folder(args, "simulate", files=["timeseries.csv", "pressures.png", "summary.json"],
                     scenario=scenario_record(scenario.name, _inputs(scenario, args)))

    def work():
        from frogsim.engine.integrator import advance
        _compiling(advance, "pneumatic")
        _progress(f"simulating {scenario.name!r}: {_count(len(scenario.muscles), 'muscle')}, "
                  f"{scenario.duration:g} s ...")
        t0 = time.perf_counter()
        result = simulate(scenario, progress=not _QUIET)     # a bar on stderr once a run takes 2 s
        _progress(f"      {_count(result.stats['steps'], 'step')} in {time.perf_counter() - t0:.2f} s")
        _write_simulate(out, result)
        folder.finish()
        _progress(f"wrote {out / 'timeseries.csv'}, {out / 'pressures.png'}, {out / 'summary.json'}, "
                  f"{out / 'manifest.json'}")
        return 0
    return _finishing(folder, work)


def _patched(args):
    """The scenario to run: SCENARIO as named, or with ``--patch``'s controllers' settings laid
    over it (:func:`frogsim.scenario.load.with_patch`)."""
    if getattr(args, "patch", None) is None:
        return args.scenario
    from frogsim.scenario.load import with_patch
    return with_patch(args.scenario, args.patch)


def _inputs(scenario, args, extra: str = "patch") -> list:
    """The manifest's described inputs of a run: the scenario's files, and the file of the option
    ``extra`` (--patch, --spec) when given."""
    from frogsim.io.outputs import scenario_inputs
    from frogsim.sweep.spec import describe_inputs
    path = getattr(args, extra, None)
    return scenario_inputs(scenario, args.scenario) + (describe_inputs([(extra, Path(path))]) if path else [])


def _write_simulate(out: Path, result, extra: dict | None = None) -> None:
    """What simulate writes: timeseries.csv, pressures.png, summary.json (plus ``extra`` sections)."""
    from frogsim._files import write_csv, write_figure, write_json
    from frogsim.io.results import plot_run, run_summary
    from frogsim.scenario.tables import unit_headers
    write_csv(out / "timeseries.csv", unit_headers(result.to_dataframe(units="display")))
    write_figure(out / "pressures.png", lambda p: plot_run(result, p))
    write_json(out / "summary.json", {**run_summary(result), **(extra or {})})


def cmd_swim(args) -> int:
    from frogsim.io.outputs import scenario_record
    from frogsim.robot.scenario import load_robot_scenario
    from frogsim.errors import ScenarioError
    out = out_folder(args.out)
    interval = _time_text("--output-interval", args.output_interval)
    try:
        rs = load_robot_scenario(_patched(args), cycles=args.cycles,   # all validation before any write
                                 output_interval=interval)
    except ScenarioError as exc:
        if interval is None or exc.field != "output_interval":
            raise
        raise ScenarioError("--output-interval", args.output_interval, exc.allowed) from None
    planned = ["timeseries.csv", "swim.png", "frog.xml", "summary.json"] + ([] if args.no_animation else
                                                                           ["animation.gif"])
    folder = _folder(args, "swim", files=planned, scenario=scenario_record(rs.name, _inputs(rs.pneumatic, args)))
    return _finishing(folder, lambda: _swim_into(args, folder, out, rs))


def _swim_into(args, folder, out: Path, rs) -> int:
    from frogsim.engine.coupled_loop import run_steps
    from frogsim.engine.swim import swim
    from frogsim.studies.robot import write_outputs
    _compiling(run_steps, "swim")
    _progress(f"running {rs.name!r}: {_count(len(rs.muscles), 'muscle')} in {rs.options.environment}, "
              f"{_count(rs.gait.cycles, 'cycle')} of {rs.gait.period:g} s ...")
    tick = _every(lambda f: f"      {100 * f:.0f} % ({f * rs.duration:.1f} s of {rs.duration:g} s simulated)")
    result = swim(rs, progress=tick)
    _progress(f"      {result.stats['mujoco_steps']} MuJoCo steps in {result.wall_s:.2f} s "
              f"({result.t[-1] / result.wall_s:.3g} x real time; compiling {result.compile_s:.2f} s "
              "before them, not counted)")
    files, s = write_outputs(result, out, animation=not args.no_animation, progress=_progress)
    files["manifest"] = folder.finish(extra_files=[Path(p).name for p in files.values()])
    if s["base"] == "fixed":             # nothing moves: a speed of zero would read as a measured one
        motion = f"base fixed in {s['environment']}: no swimming speed; {s['air_used_per_cycle_L_std']:.3f} L "
    else:
        motion = (f"mean speed {s['mean_speed_m_per_s']:.3f} m/s ({s['mean_speed_body_lengths_per_s']:.2f} "
                  f"body lengths/s), {s['distance_per_cycle_m']:.3f} m and {s['air_used_per_cycle_L_std']:.3f} L ")
    _progress(motion + f"(standard) of air per cycle, source {s['source_pressure_after_cycles_bar_gauge']:.2f} "
                       f"bar gauge after {_count(s['cycles'], 'cycle')}")
    if "animation_skipped" in s:
        _warn(f"animation skipped: {s['animation_skipped']}")
    _progress("wrote " + ", ".join(str(p) for p in files.values()))
    return 0


def _firmware_target(source, cycles=None):
    """(kind "pneumatic" | "robot", the scenario or robot scenario, the plant's model, the firmware
    plan): every input checked, nothing run or written. ``cycles``: a robot's gait cycles. A
    scenario without a ``[firmware]`` section runs on the board's defaults (as if ``[firmware]``
    were written: :func:`frogsim.scenario.load.with_firmware`), which is said on stderr."""
    from frogsim.control import firmware as fw
    from frogsim.errors import ScenarioError
    from frogsim.scenario.load import load_scenario, merged_raw, with_firmware
    if "firmware" not in merged_raw(source)[0]:
        _progress("note: the scenario has no [firmware] section: the board's defaults (docs/control.md, "
                  "\"The robot's board\")")
    raw = with_firmware(source)
    try:
        scenario = load_scenario(raw)
    except ScenarioError as exc:
        if exc.field != "gait":
            raise
        from frogsim.robot.scenario import load_robot_scenario
        rs = load_robot_scenario(raw, cycles=cycles)
        from frogsim.circuit.model import build_model
        return "robot", rs, None, fw.firmware_plan(build_model(rs.pneumatic))
    if cycles is not None:
        raise ScenarioError("--cycles", cycles, "only a robot scenario (with a [gait]) has gait cycles")
    from frogsim.circuit.model import build_model
    model = build_model(scenario)
    return "pneumatic", scenario, model, fw.firmware_plan(model)


def _firmware_fit(args, plan, sc, export):
    """The plan's fit on the board (frogsim.export.fit), before anything is written: with --build
    the sketch is built in a temporary folder and its interrupt timed on the emulated board (the
    ELF and HEX are kept for the export), without it the cycle estimate. ScenarioError (exit 2)
    if it does not fit and --allow-overrun is not given. Returns (fit, the temporary build or None)."""
    import tempfile

    from frogsim.export import fit as fitting
    from frogsim.export import sketch
    from frogsim.scenario.firmware import log_line_bytes
    from frogsim.scenario.motion import command_sample
    if not args.build:
        n_enc = sum(1 for ch in plan.channels if getattr(ch, "pins", ()))
        line = log_line_bytes(len(plan.channels), len(plan.muscles), command_sample(sc.duration, plan.rate),
                              plan.adc.bits, n_encoders=n_enc,
                              log_every=plan.log_every if sketch.history_samples(plan) or sketch.event_slots(plan)
                              else 10 ** 9, events=sketch.event_slots(plan))
        return fitting.check_fit(fitting.estimate(plan, line), plan, args.allow_overrun), None
    from frogsim.export.emulator import check_tools
    from frogsim.export.sil import interrupt_timing
    check_tools()
    tmp = Path(tempfile.mkdtemp(prefix="frogsim-fw-"))
    try:
        sketch.write_sketch(plan, tmp, sc.name, export)
        _progress("building with arduino-mk (BOARD_TAG=mega, BOARD_SUB=atmega2560) ...")
        built = sketch.build_sketch(tmp, plan.name)
        _progress(f"      {built.describe()}")
        _progress("timing the control interrupt on the emulated ATmega2560 (200 samples of random counts) ...")
        rec = sketch.read_plan_record(tmp)
        timing = interrupt_timing(rec, built.elf)
        _progress(f"      interrupt mean {timing['mean_percent']:.1f} %, max {timing['max_percent']:.1f} % of the "
                  f"{timing['period_cycles']}-cycle period, chip awake {timing['awake_percent']:.1f} %")
        fit = fitting.check_fit(fitting.emulated(timing), plan, args.allow_overrun)
    except BaseException:
        import shutil
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return dict(fit, timing=timing), (tmp, built)


def cmd_firmware(args) -> int:
    import shutil

    from frogsim._files import write_json
    from frogsim.export import sketch
    from frogsim.io.outputs import scenario_record
    out = out_folder(args.out)
    kind, sc, model, plan = _firmware_target(_patched(args), args.cycles)   # all validation before any write
    pneumatic = sc if kind == "pneumatic" else sc.pneumatic
    if args.build:
        from frogsim.export.emulator import require
        for tool in ("make", "avr-gcc", "avr-size", "avr-objdump"):
            require(tool)
    files = [f"{plan.name}/{f}" for f in (f"{plan.name}.ino", "frogsim_board.h", "frogsim_laws.h", "frogsim_laws.c",
                                          "Makefile", "README.md")] + ["firmware.json"] + \
        ([f"build/{plan.name}.elf", f"build/{plan.name}.hex"] if args.build else [])
    inputs = _inputs(pneumatic, args)
    export = {"scenario": sc.name, "cycles": sc.gait.cycles if kind == "robot" else None, "inputs": inputs,
              "scenario_file": next((f["path"] for f in inputs if f["role"] == "scenario"), None)}
    fit, built_tmp = _firmware_fit(args, plan, pneumatic, export)       # refused here: nothing written
    try:
        folder = _folder(args, "firmware", files=files, folders=["build"] if args.build else [],
                         scenario=scenario_record(sc.name, inputs))
    except BaseException:
        if built_tmp:
            shutil.rmtree(built_tmp[0], ignore_errors=True)
        raise

    def work():
        try:
            written = sketch.write_sketch(plan, out, sc.name, export)
            _progress(f"{plan.name}: {_count(len(plan.muscles), 'muscle')}, {_count(len(plan.channels), 'channel')} at "
                      f"{plan.rate:g} Hz, ADC prescaler {plan.adc.prescaler} ({plan.adc.bits} bits) -> "
                      f"{written['ino']}")
            rec = sketch.read_plan_record(out)
            timing = fit.pop("timing", None)
            rec["fit"] = fit
            if fit.get("allowed_overrun"):
                _warn(f"the firmware does not fit its period ({fit['method']}: interrupt up to "
                      f"{fit['interrupt_max_percent']:.0f} %, log {fit['log_percent']:.0f} %): written anyway "
                      "(--allow-overrun), and firmware.json says so; on the board its samples come late")
            else:
                _progress(f"      fits: interrupt up to {fit['interrupt_max_percent']:.1f} % and the serial log "
                          f"{fit['log_percent']:.1f} % of the period ({fit['method']})")
            if built_tmp:
                tmp, built = built_tmp
                # the build's folder as it is (arduino-mk's paths in it are relative), each file with
                # a new mtime: newer than the sources just written, so make and sil see it current
                for f in sorted((tmp / "build").rglob("*")):
                    dest = out / "build" / f.relative_to(tmp / "build")
                    if f.is_dir():
                        dest.mkdir(parents=True, exist_ok=True)
                    else:
                        dest.parent.mkdir(parents=True, exist_ok=True)
                        shutil.copy(f, dest)
                rec["flash_bytes"], rec["ram_bytes"] = built.flash_bytes, built.ram_bytes
                rec["elf"] = f"build/{built.elf.name}"
                rec["interrupt"] = timing
                _progress(f"      {out / rec['elf']}: {built.describe()}")
            write_json(out / "firmware.json", rec)
            folder.finish()
            _progress(f"wrote {out / plan.name}/, {out / 'firmware.json'}" + (f", {out / 'build'}/" if args.build
                                                                               else ""))
            return 0
        finally:
            if built_tmp:
                shutil.rmtree(built_tmp[0], ignore_errors=True)
    return _finishing(folder, work)


def cmd_sil(args) -> int:
    from frogsim.errors import ScenarioError
    from frogsim.export import sil
    from frogsim.export.serial_log import COMMANDS_CSV, parse_log, write_commands_csv, write_log_csv
    from frogsim.export.sketch import find_elf, read_plan_record
    from frogsim.io.outputs import scenario_record
    out = out_folder(args.out)
    rec = read_plan_record(args.firmware)      # a plan frogsim wrote, every key SIL reads checked
    elf = find_elf(args.firmware)              # built, not older than its sources, an ATmega2560 ELF
    kind, sc, model, plan = _firmware_target(_patched(args), args.cycles)
    pneumatic = sc if kind == "pneumatic" else sc.pneumatic
    inputs = _inputs(pneumatic, args)
    sil.check_plan(rec, plan, sc.name, sc.gait.cycles if kind == "robot" else None, inputs)
    if args.board_process == "yes":
        if args.timing != "cycle":
            raise ScenarioError("--board-process", "yes", "needs --timing cycle: with 'grid' the plant takes each "
                                                          "decision at its own sample, which a board a period behind "
                                                          "cannot give")
        v = pneumatic.valves
        if sil.pipeline_depth(rec, min(v.charge.dead_time, v.discharge.dead_time)) < 1:
            raise ScenarioError("--board-process", "yes", "the valves' dead time does not cover the period the board "
                                                          "would run behind (two periods with encoders, one without): "
                                                          "use 'no' or 'auto'")
    from frogsim.export.emulator import check_tools
    check_tools()                          # simavr missing: refused before anything is written
    if kind == "pneumatic":
        files = ["timeseries.csv", "pressures.png", "summary.json", "serial.csv"]
    else:
        files = ["timeseries.csv", "swim.png", "frog.xml", "summary.json", "serial.csv"] + \
            ([] if args.no_animation else ["animation.gif"])
    with_commands = _carries_commands(rec)
    if with_commands:
        files.append(COMMANDS_CSV)
    folder = _folder(args, "sil", files=files, scenario=scenario_record(sc.name, inputs))

    def work():
        _progress(f"software in the loop: {rec['name']} ({elf}) on an emulated ATmega2560 against "
                  f"{sc.name!r} ({'the robot' if kind == 'robot' else 'the pneumatics'}), {sc.duration:g} s ...")
        runner = sil.run_robot if kind == "robot" else sil.run_pneumatic
        from frogsim.control.firmware import adc_counts
        run = runner(sc if kind == "robot" else model, rec, elf, plan, adc_counts, progress=_progress,
                     timing=args.timing, parallel={"auto": None, "yes": True, "no": False}[args.board_process])
        s = run.sil
        s["timing"] = args.timing
        where = (f"the board in its own process: emulated AVR {s['avr_wall_s']:.1f} s, plant "
                 f"{s['plant_wall_s']:.1f} s, waiting for the board {s['plant_waited_s']:.1f} s"
                 if s["board_process"] else
                 f"emulated AVR {s['avr_wall_s']:.1f} s, plant {s['plant_wall_s']:.1f} s")
        _progress(f"      {_count(s['samples'], 'sample')} in {s['wall_s']:.1f} s "
                  f"({s['real_time_factor']:.2f} x real time; {where})")
        log = parse_log(run.serial, rec)
        write_log_csv(out / "serial.csv", log, rec, last_sample=s["samples"] - 1)
        if with_commands:
            _write_commands(out, log, rec, last_sample=s["samples"] - 1)
        if kind == "robot":
            from frogsim.studies.robot import write_outputs
            write_outputs(run.result, out, animation=not args.no_animation, progress=_progress,
                          extra={"sil": s})
        else:
            _write_simulate(out, run.result, {"sil": s})
        folder.finish()
        load = s["cpu_load_percent"]
        _progress(f"mismatched samples {s['mismatched_samples']} of {s['firmware_samples']}, interrupt load mean "
                  f"{load['mean']:.1f} % max {load['max']:.1f} %, chip awake {s['awake_percent']:.1f} %, "
                  f"{s['effective_rate_hz']:.1f} Hz effective, overruns {s['overruns']}, log records "
                  f"{s['log_records']['received']} of {s['log_records']['made']} received; wrote "
                  f"{out / 'summary.json'}, {out / 'serial.csv'}, {out / 'timeseries.csv'}")
        for text in s["warnings"]:
            _warn(text)
        if s.get("adc_read_differs_samples"):
            _warn(f"at {s['adc_read_differs_samples']} on-time samples the firmware read other counts than the "
                  "plant gave it (the emulation's fault, not the firmware's)")
        return 0
    return _finishing(folder, work)


def _time_text(flag: str, text: str | None) -> float | None:
    """A flag's time [s] from "10 ms" (any time unit) or a bare number of seconds, finite and > 0;
    None if not given. ScenarioError naming the flag otherwise."""
    import math

    from frogsim.errors import ScenarioError
    from frogsim.scenario.units import to_si
    if text is None:
        return None
    try:
        x = float(text)
    except ValueError:
        x = to_si(text, "time", flag)
    if not (math.isfinite(x) and x > 0):
        raise ScenarioError(flag, text, "must be a finite time > 0, e.g. '1 ms' or 0.001 (seconds)")
    return x


def _seconds(flag: str, value) -> None:
    """ScenarioError unless ``value`` (a flag's float, or None: not given) is a finite time > 0."""
    import math

    from frogsim.errors import ScenarioError
    if value is not None and not (math.isfinite(value) and value > 0):
        raise ScenarioError(flag, value, "must be a finite time in seconds > 0")


def _carries_commands(rec: dict | None) -> bool:
    """Whether a firmware's log can carry every valve command (format 3, a history as long as
    log_every): commands.csv is then written beside serial.csv."""
    from frogsim.export.serial_log import HISTORY_MAX
    if bool(rec) and rec.get("format", 0) == 4:
        return True
    return bool(rec) and rec.get("format", 0) >= 3 and int(rec["log_every"]) <= HISTORY_MAX and \
        rec.get("history_samples", 1) > 0


def _write_commands(out, log, rec, last_sample=None) -> None:
    """commands.csv (every valve command of the log, :func:`frogsim.export.serial_log.commands_table`),
    or a warning saying why the log does not carry them all."""
    from frogsim.export.serial_log import COMMANDS_CSV, commands_gap, commands_missing, write_commands_csv
    why = commands_missing(log, rec)
    if why:
        _warn(f"{COMMANDS_CSV} not written: {why}")
        return
    write_commands_csv(out / COMMANDS_CSV, log, rec, last_sample)
    gap = commands_gap(log, rec, last_sample)
    if gap:
        _warn(f"{COMMANDS_CSV} has gaps (empty cells, a fit refuses to replay it): {gap}")


def cmd_log(args) -> int:
    from frogsim._files import write_json
    from frogsim.errors import SimulationError
    from frogsim.export.serial_log import (describe_empty, first_lines, log_summary, log_warnings, open_port,
                                           record_port, spec_of, write_log_csv)
    from frogsim.export.sketch import read_plan_record
    out = out_folder(args.out)
    _seconds("--duration", args.duration)
    _seconds("--idle-timeout", args.idle_timeout)
    rec = read_plan_record(args.firmware) if args.firmware else None
    if rec is not None:
        spec_of(rec)                           # firmware.json that cannot check a record: refused now
    folder = _folder(args, "log", files=["serial.csv", "summary.json"] + (["commands.csv"] if _carries_commands(rec)
                                                                            else []))
    link = open_port(args.port, rec)           # a port that cannot be opened: refused before any write

    def work():
        what = (f"{rec['baud']} baud ({rec['name']}: {', '.join(ch['signal'] for ch in rec['channels'])})" if rec
                else "115200 baud (no --firmware: the channels from the board's header line, as raw counts)")
        until = f"for {args.duration:g} s" if args.duration else "until Ctrl-C"
        _progress(f"reading {args.port} at {what} {until} (or {args.idle_timeout:g} s without a byte) ...")
        log = record_port(args.port, rec, args.duration, progress=_progress, link=link,
                          idle_timeout=args.idle_timeout)
        plan = rec or log.plan
        if not log.records:                    # nothing to write: the run fails, no serial.csv
            hint = ("" if plan is not None else ": the board sends its header line when it starts; give "
                    "--firmware DIR, or reset the board while logging")
            raise SimulationError(f"--port {args.port}: no valid record in the capture ({describe_empty(log)}){hint}")
        write_log_csv(out / "serial.csv", log, plan)
        if _carries_commands(plan) and rec is not None:
            _write_commands(out, log, plan)
        summary = {"port": args.port, "firmware": args.firmware, **log_summary(log, plan)}
        write_json(out / "summary.json", {"log": summary})
        folder.finish()
        for msg in log_warnings(log, plan, checked_header=rec is not None):
            _warn(msg)
        s = summary
        _progress(f"{first_lines(log)} (t = {s['first']['time_s']:g} .. {s['last']['time_s']:g} s), "
                  f"{log.bytes_read} bytes in {log.capture_s:.1f} s, stopped by {log.stopped_by}; wrote "
                  f"{out / 'serial.csv'}, {out / 'summary.json'}")
        return 0
    return _finishing(folder, work)


def cmd_compare(args) -> int:
    from frogsim.io import compare
    out = out_folder(args.out)
    runs = compare.prepare(args.inputs, args.signal)         # every input and the signal, before any run
    folder = _folder(args, "compare", files=compare.file_names(runs, args.signal),
                     scenario=compare.inputs_record(runs))
    if any(r.table is None for r in runs):                  # a scenario to run
        from frogsim.engine.integrator import advance
        _compiling(advance, "pneumatic")
    compare.run_inputs(runs, progress=None if _QUIET else _progress)   # may fail (exit 1) before anything is written

    def work():
        files = compare.write(runs, args.signal, out)
        folder.finish()
        _progress(f"wrote {files['csv']}, {files['figure']}, {out / 'manifest.json'}")
        return 0
    return _finishing(folder, work)


def cmd_params(args) -> int:
    from frogsim.scenario.load import PARAMS_DIR, parameter_set_names, read_toml
    if args.name not in parameter_set_names():
        return _err(f"name = {args.name!r}: must be one of {', '.join(parameter_set_names())}", 2)
    raw = read_toml(PARAMS_DIR / f"{args.name}.toml", "parameters")
    meta = raw.pop("meta", {})
    print(f"# {args.name}: {meta.get('title', '')}")

    def walk(node, prefix):
        for key, val in node.items():
            path = f"{prefix}.{key}" if prefix else key
            if isinstance(val, dict) and "value" not in val:
                walk(val, path)
            elif isinstance(val, dict):
                print(f"{path:<42} {str(val['value']):<16} {val.get('source', '')}")
            else:
                print(f"{path:<42} {str(val):<16} (no source given)")
    walk(raw, "")
    return 0


def cmd_sweep(args) -> int:
    import json
    from frogsim.sweep.runner import run_sweep
    if args.workers is not None and args.workers < 1:
        return _err(f"--workers = {args.workers}: must be a whole number >= 1", 2)
    from frogsim._files import out_file
    from frogsim.sweep.spec import load_spec
    out_file(args.out, ".nc")
    _seconds("--connect-timeout", args.connect_timeout)
    t0 = time.perf_counter()
    spec = load_spec(args.spec)
    for note in spec.notes:
        _progress(f"note: {note}")
    if args.scheduler is None:              # (a scheduler's workers compile on their machines)
        from frogsim.engine.integrator import run_schedule
        _compiling(run_schedule, "batched pneumatic")
    ds = run_sweep(spec, out=args.out, workers=args.workers, scheduler=args.scheduler,
                   progress=not args.quiet, overwrite=args.overwrite, connect_timeout=args.connect_timeout)
    n, failed, read = ds.attrs["n_points"], ds.attrs["n_failed"], ds.attrs.get("n_points_read", 0)
    took = f"{time.perf_counter() - t0:.2f} s"
    if read >= n:
        _progress(f"all {_count(n, 'point')} already done in {args.out}: nothing run ({took})")
    elif read:
        _progress(f"{_count(n - read, 'point')} run in {took}, {read} read from the earlier run -> {args.out}")
    else:
        _progress(f"{_count(n, 'point')} in {took} -> {args.out}")
    if failed:
        first = next(iter(json.loads(ds.attrs["failures"]).values()), "")
        _warn(f"{_count(failed, 'point')} failed ({'its' if failed == 1 else 'their'} metrics are NaN); "
              f"first: {first}")
    return 0


def cmd_plot(args) -> int:
    from frogsim.errors import ScenarioError
    from frogsim.sweep.plot import plot_sweep
    from frogsim.sweep.runner import read_results
    from frogsim._files import out_file
    path = Path(args.results)
    out = out_file(args.out, ".png", overwrite=args.overwrite)
    if not path.is_file():
        return _err(f"results = {str(path)!r}: " + ("is a directory, not a file" if path.is_dir()
                                                      else "file not found"), 2)
    try:
        ds = read_results(path)
    except Exception as exc:  # xarray/netCDF4 raise many types for foreign files
        return _err(f"results = {str(path)!r}: not a readable NetCDF file ({type(exc).__name__})", 2)
    select = {}
    for item in args.select:
        if "=" not in item:
            raise ScenarioError("--select", item, "expected PARAM=VALUE, e.g. 'supply.branch_limit=45 L/min'")
        key, value = item.split("=", 1)
        select[key.strip()] = value.strip()
    plot_sweep(ds, args.x, args.metric, out, y=args.y, select=select, reduce=args.reduce)
    _progress(f"wrote {out}")
    return 0


def cmd_fit(args) -> int:
    from frogsim.fit import load_fit_spec
    from frogsim.fit.report import planned_files
    out_folder(args.out)
    spec = load_fit_spec(args.spec, starts=args.starts, threads=args.workers)   # traces too: before any write
    folder = _folder(args, "fit", files=planned_files(spec))
    return _finishing(folder, lambda: _fit_into(args, folder, spec))


def _fit_into(args, folder, spec) -> int:
    from frogsim.fit import fit
    from frogsim.fit.report import write_outputs
    tables = f" and {_count(len(spec.force_tables), 'force table')}" if spec.force_tables else ""
    _progress(f"fitting {_count(len(spec.parameters), 'parameter')} to {_count(len(spec.experiments), 'trace')}"
              f"{tables}, {_count(spec.starts, 'start')} ...")
    if spec.experiments:                    # traces: the pneumatic model runs (force tables alone do not)
        from frogsim.engine.integrator import run_schedule
        _compiling(run_schedule, "batched pneumatic")
    res = fit(spec, progress=not args.quiet)
    files = write_outputs(res, args.out)
    folder.finish()
    for j, path in enumerate(res.paths):
        prm = spec.parameters[j]
        ci = (f"[{prm.shown(res.ci_low[j])} .. {prm.shown(res.ci_high[j])}]" if path not in res.unidentifiable
              else "unidentifiable: " + res.unidentifiable[path])
        _progress(f"  {path} = {prm.shown(res.values[j])}  {ci}"
                  + (f"  profile [{prm.shown(res.profile[path][0])} .. {prm.shown(res.profile[path][1])}]"
                     if path in res.profile else ""))
    for c in res.force_curves:
        _progress(f"  {c['name']}: worst |fitted - measured| per pressure: " + ", ".join(
            f"{w['pressure_Pa_gauge'] / 1e5:g} bar {w['worst_abs_error_N']:.1f} N at {w['worst_at_contraction'] * 100:.3g} %"
            for w in c["worst"]))
    for w in res.warnings:
        _warn(str(w))
    _progress(f"{res.model_runs} model runs in {res.wall_s:.1f} s; wrote "
              + ", ".join(str(p) for p in files.values()))
    return 0


def cmd_optimize_gait(args) -> int:
    from frogsim.io.outputs import read_manifest, scenario_inputs, scenario_record
    from frogsim.optimize import gait as G
    out = out_folder(args.out)
    # every input checked before anything is written or run
    search = G.prepare(args.scenario, args.objective, args.trials, cycles=args.cycles,
                       seed=args.seed, workers=args.workers)
    study_db = out / "study.db"
    prev = read_manifest(out) if out.exists() else None
    resume = (not args.overwrite and prev is not None and prev["command"] == "optimize-gait"
              and study_db.exists())
    done = G.check_resumable(search, study_db) if resume else 0
    files = ["best-gait.toml", "trials.csv", "trials.png", "study.db"]
    folder = _folder(argparse.Namespace(out=args.out, argv=args.argv, overwrite=args.overwrite or resume),
                     "optimize-gait", files=files,
                     scenario=scenario_record(search.rs.name, scenario_inputs(search.rs.pneumatic,
                                                                              args.scenario)))
    if resume:   # continuing: the study stays, everything else is written again
        folder.keep("study.db")
    elif study_db.exists() and not args.overwrite and prev is None:
        return _err(f"--out = {str(out)!r}: holds a study.db of no optimize-gait run; use --overwrite", 2)

    def work():
        from frogsim._files import atomic_write, write_csv, write_json
        _progress(("continuing" if done else "starting") +
                  f" a gait search on {search.rs.name!r}: objective {search.objective}, "
                  f"{_count(search.trials, 'trial')} ({done} done), {_count(search.cycles, 'cycle')} of "
                  f"{search.period:g} s each, {_count(search.workers, 'worker')} ...")
        from frogsim.engine.coupled_loop import run_steps
        _compiling(run_steps, "swim")
        res = G.run_search(search, study_db, fresh=not resume, progress=_progress)
        best, base = res["best"].value, res["baseline"].value
        unit = G.OBJECTIVES[search.objective][1]
        text = G.best_scenario_text(res, search)
        atomic_write(out / "best-gait.toml", lambda tmp: Path(tmp).write_text(text))
        table = G.trials_table(res["study"], search)
        write_csv(out / "trials.csv", table)
        G.plot_trials(table, search, base, out / "trials.png", res["steadiness"])
        s = G.summary_of(res, search, {"best_gait": "best-gait.toml", "trials": "trials.csv",
                                       "figure": "trials.png", "study": "study.db"})
        write_json(out / "summary.json", s)
        folder.finish()
        _progress(f"best {best:.4g} {unit} (trial {res['best'].number}) against {base:.4g} {unit} for "
                  f"the scenario's own gait: margin {best - base:+.4g} {unit} "
                  f"({s['margin_percent']:+.1f} %); run it with: frogsim swim {out / 'best-gait.toml'} "
                  "--out DIR")
        _progress("wrote " + ", ".join(str(out / f) for f in files + ["summary.json", "manifest.json"]))
        return 0
    return _finishing(folder, work)


def cmd_tune(args) -> int:
    from frogsim.io.outputs import read_manifest, scenario_record
    from frogsim.optimize import study as S
    from frogsim.optimize import tune as T
    out = out_folder(args.out)
    # every input checked before anything is written or run
    tune = T.prepare(args.scenario, args.trials, workers=args.workers, seed=args.seed, timeout=args.timeout,
                     pareto=args.pareto, spec=args.spec)
    db = out / "study.db"
    url = args.storage or S.sqlite_url(db)
    local = args.storage is None or S.is_sqlite_file(args.storage, db)
    prev = read_manifest(out) if out.exists() else None
    resume = not args.overwrite and prev is not None and prev["command"] == "tune"
    if local and not args.overwrite and db.exists() and prev is None:
        return _err(f"--out = {str(out)!r}: holds a study.db of no tune run; use --overwrite", 2)
    if not (local and (args.overwrite or not db.exists())):
        S.storage(url)                     # a URL that cannot be opened: refused before anything is written
    done = T.check_resumable(tune, url) if (not local or (resume and db.exists())) else 0
    figure = "pareto.png" if args.pareto else "history.png"
    files = ["best.toml", "trials.csv", figure, "summary.json"] + (["study.db"] if local else [])
    inputs = _inputs(tune.pneumatic, args, "spec")
    folder = _folder(argparse.Namespace(out=args.out, argv=args.argv, overwrite=args.overwrite or resume),
                     "tune", files=files, scenario=scenario_record(tune.name, inputs))
    if resume and local:      # continuing: the study stays, everything else is written again
        folder.keep("study.db")

    def work():
        from frogsim._files import atomic_write, write_csv, write_json
        _progress(("continuing" if done else "starting") + f" a gains search on {tune.name!r}: "
                  f"{_count(len(tune.searched), 'gain')} searched, {tune.objective_text()}, "
                  f"{_count(tune.trials, 'trial')} ({done} done), {_count(tune.workers, 'worker')} ...")
        if tune.robot:
            from frogsim.engine.coupled_loop import run_steps
            _compiling(run_steps, "swim")
        else:
            from frogsim.engine.integrator import advance
            _compiling(advance, "pneumatic")
        res = T.run_search(tune, url, fresh_file=db if (local and not resume) else None, progress=not _QUIET,
                           say=_progress)
        st = res["study"]
        best = T.best_trial(st, tune)
        table = T.trials_table(st, tune)
        write_csv(out / "trials.csv", table)
        if args.pareto:
            T.plot_pareto(st, tune, res["baseline"].terms, out / figure)
        else:
            T.plot_history(table, tune, T.score(tune, res["baseline"].terms), out / figure)
        written = {"trials": "trials.csv", "figure": figure, "summary": "summary.json"}
        if best is not None:
            text = T.best_patch_text(tune, best, args.scenario)
            atomic_write(out / "best.toml", lambda tmp: Path(tmp).write_text(text))
            written["best"] = "best.toml"
        if local:
            written["study"] = "study.db"
        s = T.summary_of(res, tune, written, _storage_shown(url))
        write_json(out / "summary.json", s)
        folder.finish()
        if res["timed_out"]:
            _warn(f"--timeout {args.timeout:g} s reached after {_count(res['ran'], 'trial')}: the study holds "
                  f"{s['trials']} of the {tune.trials} asked; run the same command again to continue it")
        if best is None:
            _warn("no trial finished without failing" + (" within the bounds of [tune.at_most]" if tune.at_most else "")
                  + ": no best.toml (trials.csv says why each failed)")
            return 1
        word = "" if not args.pareto else ", the front's best by the weights"
        w_best = T.weighted(s["best"]["terms"], tune.weights)
        w_start = T.weighted(s["start"]["terms"], tune.weights)
        _progress(f"best trial {best.number}{word}: {tune.objective_text() if not args.pareto else 'weighted sum'} "
                  f"{w_best:.4g} against {w_start:.4g} for the starting gains; trials {s['trials_complete']} complete, {s['trials_pruned']} pruned, "
                  f"{s['trials_failed']} failed; run it with: frogsim {'swim' if tune.robot else 'simulate'} "
                  f"{args.scenario} --patch {out / 'best.toml'} --out DIR")
        _progress("wrote " + ", ".join(str(out / f) for f in list(written.values()) + ["manifest.json"]))
        return 0
    return _finishing(folder, work)


def _storage_shown(url: str) -> str:
    """A storage URL as the summary records it: its password hidden."""
    try:
        from sqlalchemy.engine import make_url
        return make_url(url).render_as_string(hide_password=True)
    except Exception:
        return "(a storage URL)"


#: every option's meaning, the same in every command that has it (README, "Flags", lists them;
#: tests/test_cli_flags.py checks the table against each command's --help)
FLAGS = {
    "--out": "where the command writes (required)",
    "--overwrite": "replace what --out holds from an earlier run or another command (its files "
                   "deleted first)",
    "--workers": "how many runs go side by side on this machine",
    "--quiet": "no progress messages or bars on stderr (errors and warnings still shown)",
    "--cycles": "gait cycles of each robot run",
    "--signal": "the signal of every input without its own RUN:SIGNAL, e.g. 'hip_left pressure'",
    "--no-animation": "skip the offscreen animation",
    "--output-interval": "time between recorded rows, e.g. '1 ms' (a bare number is seconds): finite, > 0 and "
                         "a whole number of robot.timestep steps",
    "--allow-overrun": "write a firmware whose interrupt and serial log do not fit the controller period "
                       "(firmware.json records it); without it such a plan is refused",
    "--timing": "when the plant receives the firmware's valve writes: 'cycle', at the emulated cycle the "
                "firmware set each pin (the board's truth, late samples included), or 'grid', each sample's "
                "decision at the sample's own time as the compiled model has it (a check of the harness)",
    "--board-process": "run the emulated board in a process of its own, a period behind the plant, on "
                       "another core: 'yes', 'no', or 'auto' (where the valves' dead time covers the extra "
                       "period and a second core is idle; the run is the same either way)",
    "--scheduler": "run the chunks on a Dask distributed scheduler, e.g. tcp://host:8786 (--workers: "
                   "threads per Dask task, default 1)",
    "--connect-timeout": "seconds to wait for the scheduler, finite and > 0",
    "--x": "swept parameter on the x axis (dotted path)",
    "--y": "second swept parameter: a heatmap",
    "--metric": "recorded metric, e.g. rise_time",
    "--select": "fix another swept parameter (value as written, e.g. '45 L/min'); repeatable",
    "--reduce": "average over the swept parameters neither on an axis nor selected",
    "--starts": "least-squares starts",
    "--trials": "trials in all (>= 1)",
    "--patch": "a TOML file of [controllers.NAME] settings laid over the scenario's (frogsim tune's best.toml)",
    "--storage": "the Optuna storage URL of the study, e.g. postgresql://host/db to share it between machines",
    "--timeout": "seconds after which no new trials are started, finite and > 0",
    "--pareto": "search the Pareto front of the objectives instead of their weighted sum",
    "--spec": "a TOML file whose [tune] section replaces the scenario's",
    "--objective": "speed or distance-per-litre",
    "--seed": "sampler seed",
    "--build": "compile the sketch for the ATmega2560 (arduino-mk) into DIR/build and report flash and RAM",
    "--firmware": "a folder written by frogsim firmware (its firmware.json; for sil, built with --build)",
    "--port": "the board's serial port, e.g. /dev/ttyACM0",
    "--duration": "seconds to record, finite and > 0 (default: until Ctrl-C or the idle timeout)",
    "--idle-timeout": "stop when no byte came from the port for this many seconds, finite and > 0",
}


def _flag(s, name: str, default_text: str | None = None, **kw) -> None:
    """Add option ``name`` to subparser ``s`` with its one meaning (FLAGS), plus its default."""
    text = FLAGS[name] + (f" (default: {default_text})" if default_text else "")
    s.add_argument(name, help=text, **kw)


def _writes(s, metavar: str = "DIR", workers: str | None = None, overwrite: bool = True) -> None:
    """The flags of a command that writes: --out (required), --overwrite, --quiet, --workers."""
    what = {"RESULTS.nc": ": the results file, a new one or this sweep's to resume",
            "FIG.png": ": the PNG file"}.get(metavar, ": a new folder, or one this command wrote before")
    s.add_argument("--out", help=FLAGS["--out"] + what, required=True, metavar=metavar)
    if overwrite:
        _flag(s, "--overwrite", action="store_true")
    if workers:
        _flag(s, "--workers", workers, type=int, default=None, metavar="N")
    _flag(s, "--quiet", action="store_true")


class _Parser(argparse.ArgumentParser):
    """argparse with frogsim's one-line refusal: "frogsim: error: ..." and exit 2, no usage block."""

    def error(self, message):
        from frogsim.errors import clip
        where = self.prog if self.prog != "frogsim" else "frogsim"
        self.exit(2, f"frogsim: error: {clip(message, 300)} (see: {where} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    from frogsim import __version__
    p = _Parser(prog="frogsim", description=DESCRIPTION,
                                epilog="\n\n".join(__doc__.split("\n\n")[2:]).strip(),
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"frogsim {__version__}",
                   help="print frogsim's version and stop")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    s = sub.add_parser("studies", help="list the registered studies")
    s.set_defaults(func=cmd_studies)
    s = sub.add_parser("scenarios", help="list the shipped scenarios: name, the command that runs it, "
                                         "what it is")
    s.set_defaults(func=cmd_scenarios)
    s = sub.add_parser("reproduce", help="reproduce the paper's studies: a PNG and a CSV per study, "
                                         "DIR/summary.json (the studies in DIR) and DIR/manifest.json")
    s.add_argument("studies", nargs="*", metavar="STUDY",
                   help="studies to run (default: the paper's pneumatic studies; name leg-in-air "
                        "for the robot's in-air study)")
    _writes(s, workers="one per core")
    s.set_defaults(func=cmd_reproduce)
    for name, what, func in (("design", "the design studies (main tubes, endurance, valves)", cmd_design),
                             ("control", "the closed-loop control studies (control-pressure, control-joint, "
                                         "hysteresis, heat, control-tune)", cmd_control)):
        s = sub.add_parser(name, help=f"run {what}: a PNG and a CSV per study, DIR/summary.json with written "
                                      "conclusions")
        s.add_argument("studies", nargs="*", metavar="STUDY",
                       help=f"studies to run, of {', '.join(GROUP_STUDIES[name])} (default: all {name} studies)")
        _writes(s, workers="one per core")
        s.set_defaults(func=func)
    s = sub.add_parser("simulate", help="run one scenario: timeseries.csv, pressures.png, summary.json")
    s.add_argument("scenario", metavar="SCENARIO", help="scenario TOML file, or a shipped name "
                                                        "(`frogsim scenarios` lists them)")
    _flag(s, "--patch", "none", default=None, metavar="PATCH.toml")
    _writes(s)
    s.set_defaults(func=cmd_simulate)
    s = sub.add_parser("swim", help="run the robot in MuJoCo (swim, leg-in-air): timeseries.csv, swim.png, "
                                    "summary.json, frog.xml, animation.gif")
    s.add_argument("scenario", metavar="SCENARIO", help="robot scenario TOML file, or a shipped name "
                                                        "(`frogsim scenarios` lists them)")
    _flag(s, "--cycles", "the scenario's", type=int, default=None, metavar="N")
    _flag(s, "--output-interval", "the scenario's", default=None, metavar="T")
    _flag(s, "--no-animation", action="store_true")
    _flag(s, "--patch", "none", default=None, metavar="PATCH.toml")
    _writes(s)
    s.set_defaults(func=cmd_swim)
    s = sub.add_parser("compare", help="overlay one signal of several runs (folders of frogsim simulate or "
                                       "swim, CSV tables) or scenarios (run here): SIGNAL.csv and SIGNAL.png in DIR",
                       description="Overlay one time series of several runs in one figure (PNG) and one CSV "
                                   "(time + one column per run, units in the header), labelled by run name "
                                   "(a folder's name, a file's stem, a shipped scenario's name).",
                       epilog="signals: 'source pressure', 'exhaust pressure', 'hip_left pressure', "
                              "'hip_left volume', 'hip_left charge flow', 'hip_left charged air', "
                              "'hip_left charge valve', 'pump on', ... or a column name of timeseries.csv; "
                              "a wrong name lists those available; a muscle's name alone is its pressure. RUN:SIGNAL "
                              "takes that run's own signal (muscles named differently): frogsim compare "
                              "one-hip:hip paper-cycle:hip_left --out cmp. Example: frogsim compare runs/slow "
                              "runs/fast paper-cycle --signal 'hip_left pressure' --out cmp")
    s.add_argument("inputs", nargs="+", metavar="RUN[:SIGNAL]",
                   help="a folder written by frogsim simulate or swim (its timeseries.csv is read), a CSV "
                        "table with a 'time [s]' column, or a scenario TOML file or shipped name (it is "
                        "run); ':SIGNAL' names the signal to take from it")
    _flag(s, "--signal", default=None, metavar="NAME")
    _writes(s)
    s.set_defaults(func=cmd_compare)
    s = sub.add_parser("firmware", help="the scenario's valve controllers as an Arduino Mega 2560 sketch: "
                                        "DIR/NAME/NAME.ino, generated headers, DIR/firmware.json (docs/firmware.md)")
    s.add_argument("scenario", metavar="SCENARIO", help="scenario TOML file or shipped name, pneumatic or robot")
    _flag(s, "--build", action="store_true")
    _flag(s, "--cycles", "the scenario's; the program tables cover them", type=int, default=None, metavar="N")
    _flag(s, "--allow-overrun", action="store_true")
    _flag(s, "--patch", "none", default=None, metavar="PATCH.toml")
    _writes(s)
    s.set_defaults(func=cmd_firmware)
    s = sub.add_parser("sil", help="software in the loop: the built firmware on an emulated ATmega2560 "
                                   "(simavr) in lockstep with the plant: what simulate or swim writes, "
                                   "summary.json 'sil', serial.csv")
    s.add_argument("scenario", metavar="SCENARIO", help="the scenario the firmware was exported from")
    _flag(s, "--firmware", required=True, metavar="DIR")
    _flag(s, "--cycles", "the scenario's; as exported", type=int, default=None, metavar="N")
    _flag(s, "--timing", "cycle", choices=("cycle", "grid"), default="cycle")
    _flag(s, "--board-process", "auto", choices=("auto", "yes", "no"), default="auto")
    _flag(s, "--no-animation", action="store_true")
    _flag(s, "--patch", "none; as exported", default=None, metavar="PATCH.toml")
    _writes(s)
    s.set_defaults(func=cmd_sil)
    s = sub.add_parser("log", help="record a board's serial log (pyserial): serial.csv (the records that "
                                   "passed the checks, a trace frogsim fit reads), summary.json 'log' (lines "
                                   "discarded by reason, overruns, drops, faults)")
    _flag(s, "--port", required=True, metavar="PORT")
    _flag(s, "--firmware", "none: the channels come from the board's header line, as raw counts",
          default=None, metavar="DIR")
    _flag(s, "--duration", type=float, default=None, metavar="S")
    _flag(s, "--idle-timeout", "5", type=float, default=5.0, metavar="S")
    _writes(s)
    s.set_defaults(func=cmd_log)
    s = sub.add_parser("params", help="show a parameter set with the source of every value")
    s.add_argument("name", nargs="?", default="fan2017", help="parameter set (default: fan2017)")
    s.set_defaults(func=cmd_params)
    s = sub.add_parser("sweep", help="run a parameter sweep from a spec; results as NetCDF, written as it "
                                     "goes and resumed by running the same command again")
    s.add_argument("spec", metavar="SPEC", help="sweep spec TOML file (see docs/sweeps.md)")
    _flag(s, "--scheduler", default=None, metavar="ADDRESS")
    _flag(s, "--connect-timeout", "5", type=float, default=5.0, metavar="S")
    _writes(s, "RESULTS.nc", workers="one per core")
    s.set_defaults(func=cmd_sweep)
    s = sub.add_parser("plot", help="plot a sweep metric against one swept parameter (line) or two (heatmap)")
    s.add_argument("results", metavar="RESULTS.nc", help="results of frogsim sweep")
    _flag(s, "--x", required=True, metavar="PARAM")
    _flag(s, "--y", default=None, metavar="PARAM")
    _flag(s, "--metric", required=True, metavar="NAME")
    _flag(s, "--select", action="append", default=[], metavar="PARAM=VALUE")
    _flag(s, "--reduce", choices=["mean"], default=None)
    _writes(s, "FIG.png")
    s.set_defaults(func=cmd_plot)
    s = sub.add_parser("fit", help="fit parameters to measured traces and force tables: fitted-parameters.toml, figures, "
                                   "report.html, summary.json (see docs/fitting.md)")
    s.add_argument("spec", metavar="FIT.toml", help="fit spec: base scenario, experiments, parameters")
    _flag(s, "--starts", "the spec's", type=int, default=None, metavar="N")
    _writes(s, workers="the spec's threads, else one per core")
    s.add_argument("--threads", type=int, dest="workers", help=argparse.SUPPRESS)   # the older name
    s.set_defaults(func=cmd_fit)
    s = sub.add_parser("optimize-gait", help="search the gait's phase timing (Optuna TPE) for speed or distance "
                                             "per litre: best-gait.toml, trials.csv, trials.png, summary.json; "
                                             "running again continues the search")
    s.add_argument("scenario", metavar="SCENARIO", help="robot scenario TOML file or shipped name (swim)")
    _flag(s, "--trials", type=int, required=True, metavar="N")
    _flag(s, "--objective", required=True, metavar="OBJ")
    _flag(s, "--cycles", "the scenario's", type=int, default=None, metavar="N")
    _flag(s, "--seed", "0", type=int, default=0, metavar="N")
    _writes(s, workers="2; the trials of a batch are asked together, so N changes the search")
    s.set_defaults(func=cmd_optimize_gait, workers=2)
    s = sub.add_parser("tune", help="search the gains of the scenario's controllers (Optuna TPE) for tracking, "
                                    "switchings and air: best.toml, trials.csv, history.png or pareto.png, "
                                    "summary.json; running again continues the search (docs/control.md)")
    s.add_argument("scenario", metavar="SCENARIO", help="scenario TOML file or shipped name with closed-loop "
                                                        "controllers (robot or pneumatic)")
    _flag(s, "--trials", type=int, required=True, metavar="N")
    _flag(s, "--seed", "0", type=int, default=0, metavar="N")
    _flag(s, "--storage", "an SQLite file, DIR/study.db", default=None, metavar="URL")
    _flag(s, "--timeout", "none", type=float, default=None, metavar="S")
    _flag(s, "--pareto", action="store_true")
    _flag(s, "--spec", "the scenario's own [tune]", default=None, metavar="TUNE.toml")
    _writes(s, workers="1; the trials of a batch are asked together, so N changes the search")
    s.set_defaults(func=cmd_tune, workers=1)
    return p


#: the studies ``frogsim design`` and ``frogsim control`` run, named in their --help (written out, not
#: read from the registry, which would make every command import the studies; a test compares them)
GROUP_STUDIES = {"design": ("design-tubes", "design-endurance", "design-valve", "design-valve-type"),
                 "control": ("control-pressure", "control-joint", "hysteresis", "heat", "control-tune")}
#: what ``frogsim --help`` says first (the module docstring's first line is for programmers)
DESCRIPTION = textwrap.fill("frogsim simulates the frog-inspired swimming robot powered by pneumatic muscles (Chinese "
               "Journal of Mechanical Engineering, 2017): the paper's studies, single runs, the robot "
               "swimming in MuJoCo, closed-loop valve control, parameter sweeps, fits to measured traces "
               "and the controllers as Arduino firmware. 'frogsim COMMAND --help' gives a command's options.",
                            100)
_QUIET = False


def main(argv=None) -> int:
    global _QUIET
    from frogsim.errors import FrogsimError, ScenarioError, SimulationError
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)
    args.argv = argv
    _QUIET = bool(getattr(args, "quiet", False))
    try:
        return args.func(args)
    except ScenarioError as exc:
        return _err(str(exc), 2)
    except SimulationError as exc:
        return _err(str(exc), 1)
    except FrogsimError as exc:     # a firmware tool missing (exit 2) or a build that failed (exit 1)
        from frogsim.export.emulator import ToolMissing
        return _err(str(exc), 2 if isinstance(exc, ToolMissing) else 1)
    except OSError as exc:          # a write the checks could not foresee (disk full, a file vanished)
        from frogsim.errors import clip
        where = f"{exc.filename}: " if exc.filename else ""
        return _err(clip(f"cannot write or read {where}{exc.strerror or exc}", 300), 2)
    except KeyboardInterrupt:
        return _err("interrupted", 130)
    finally:
        _QUIET = False


if __name__ == "__main__":
    sys.exit(main())
