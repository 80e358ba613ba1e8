"""The ``frogsim`` command: a thin layer over the registries and the engine (no physics here).

    frogsim studies                         list the registered studies
    frogsim reproduce [STUDY ...] --out DIR reproduce the paper's studies (all by default)
    frogsim design [STUDY ...] --out DIR    the design studies (main tubes, endurance, valves)
    frogsim simulate SCENARIO --out DIR     run one scenario (TOML path or shipped name)
    frogsim params [NAME]                   show a parameter set with the source of every value

Exit codes: 0 success, 1 simulation failure, 2 bad input (one-line message, nothing written).
"""
from __future__ import annotations

import argparse
import sys
import textwrap
import time
from pathlib import Path


def _err(msg: str, code: int) -> int:
    print(f"frogsim: error: {msg}", file=sys.stderr)
    return code


def _progress(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def cmd_studies(args) -> int:
    from frogsim.studies import STUDIES, studies_in
    width = max(len(n) for n in STUDIES)
    for group, command in (("paper", "frogsim reproduce"), ("design", "frogsim design")):
        print(f"# {command}")
        for name in studies_in(group):
            print(f"{name:<{width}}  {STUDIES[name].title}")
    return 0


def cmd_reproduce(args) -> int:
    return _run_studies(args, "paper")


def cmd_design(args) -> int:
    return _run_studies(args, "design")


def _run_studies(args, group: str) -> int:
    from frogsim._jit import cache_is_warm
    from frogsim.io.results import write_csv, write_figure, write_json
    from frogsim.studies import STUDIES, studies_in
    names = args.studies or studies_in(group)
    unknown = [n for n in names if n not in STUDIES]
    if unknown:
        return _err(f"study = {unknown[0]!r}: must be one of {', '.join(STUDIES)}", 2)
    if not cache_is_warm():
        _progress("first run: compiling the engine (about 8 s, cached afterwards)")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        return _err(f"--out = {str(out)!r}: exists and is not a directory", 2)
    summary = {}
    t_all = time.perf_counter()
    for k, name in enumerate(names, 1):
        study = STUDIES[name]
        t0 = time.perf_counter()
        _progress(f"[{k}/{len(names)}] {name}: {study.title} ...")
        data = study.compute()
        write_csv(out / f"{name}.csv", data.table)
        write_figure(out / f"{name}.png", lambda p, s=study, d=data: s.draw(d, p))
        summary.update(data.summary)
        _progress(f"      done in {time.perf_counter() - t0:.2f} s -> {out / name}.png, .csv")
        for entry in data.summary.values():
            if isinstance(entry, dict) and "conclusion" in entry:
                _progress(textwrap.fill(entry["conclusion"], 100, initial_indent="      ",
                                        subsequent_indent="      "))
    write_json(out / "summary.json", summary)
    _progress(f"{len(names)} studies in {time.perf_counter() - t_all:.1f} s; summary: {out / 'summary.json'}")
    return 0


def cmd_simulate(args) -> int:
    from frogsim.engine.pneumatic import simulate
    from frogsim.io.results import plot_run, run_summary, write_csv, write_figure, write_json
    from frogsim.io.scenario import load_scenario
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        return _err(f"--out = {str(out)!r}: exists and is not a directory", 2)
    scenario = load_scenario(args.scenario)          # all validation happens here, before any write
    _progress(f"simulating {scenario.name!r}: {len(scenario.muscles)} muscles, {scenario.duration:g} s ...")
    t0 = time.perf_counter()
    result = simulate(scenario)
    _progress(f"      {result.stats['steps']} steps in {time.perf_counter() - t0:.2f} s")
    write_csv(out / "timeseries.csv", result.to_dataframe(units="display"))
    write_figure(out / "pressures.png", lambda p: plot_run(result, p))
    write_json(out / "summary.json", run_summary(result))
    _progress(f"wrote {out / 'timeseries.csv'}, {out / 'pressures.png'}, {out / 'summary.json'}")
    return 0


def cmd_params(args) -> int:
    from frogsim.io.scenario import PARAMS_DIR, parameter_set_names, read_toml
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


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="frogsim", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    s = sub.add_parser("studies", help="list the registered studies")
    s.set_defaults(func=cmd_studies)
    s = sub.add_parser("reproduce", help="reproduce the paper's studies: a PNG and a CSV per study, "
                                         "and DIR/summary.json")
    s.add_argument("studies", nargs="*", metavar="STUDY", help="studies to run (default: all)")
    s.add_argument("--out", default="results", metavar="DIR", help="output folder (default: results)")
    s.set_defaults(func=cmd_reproduce)
    s = sub.add_parser("design", help="run the design studies (main tubes, endurance, valves): a PNG and "
                                      "a CSV per study, DIR/summary.json with written conclusions")
    s.add_argument("studies", nargs="*", metavar="STUDY", help="studies to run (default: all design studies)")
    s.add_argument("--out", default="design", metavar="DIR", help="output folder (default: design)")
    s.set_defaults(func=cmd_design)
    s = sub.add_parser("simulate", help="run one scenario: timeseries.csv, pressures.png, summary.json")
    s.add_argument("scenario", metavar="SCENARIO", help="scenario TOML file, or a shipped name (paper-cycle)")
    s.add_argument("--out", required=True, metavar="DIR", help="output folder")
    s.set_defaults(func=cmd_simulate)
    s = sub.add_parser("params", help="show a parameter set with the source of every value")
    s.add_argument("name", nargs="?", default="fan2017", help="parameter set (default: fan2017)")
    s.set_defaults(func=cmd_params)
    return p


def main(argv=None) -> int:
    from frogsim.errors import ScenarioError, SimulationError
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ScenarioError as exc:
        return _err(str(exc), 2)
    except SimulationError as exc:
        return _err(str(exc), 1)
    except KeyboardInterrupt:
        return _err("interrupted", 130)


if __name__ == "__main__":
    sys.exit(main())
