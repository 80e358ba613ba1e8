"""A fit's outputs: the fitted parameter set, figures, a one-page HTML report, summary.json.

``fitted-parameters.toml``  the base parameter set with the fitted values merged in, every one
                            written with its unit and ``source = "fitted to <trace> on <date>,
                            95 % CI ..."``; usable as ``parameters = "fitted-parameters.toml"``
``fit-<k>-<name>.png``      per experiment and signal: measured and simulated (at the start and
                            fitted values) against time, and the residuals after the fit
                            (pressures in bar gauge, temperatures in K)
``force-<k>-<name>.png``    per force table: measured force and the law (start and fitted values)
                            against contraction, one colour per pressure, and the residuals
``report.html``             one page: parameters, intervals, correlations, warnings, the figures
                            embedded as base64 PNG (no network needed)
``summary.json``            every number, SI units named in the keys
"""
from __future__ import annotations

import base64
import datetime
import html
import re
from pathlib import Path

import numpy as np

from frogsim._files import atomic_write, out_folder, write_figure, write_json
from frogsim._plotting import figure, legend_in, save
from frogsim.fit.core import FitResult
from frogsim.fit.traces import signal_kind
from frogsim.scenario.load import PARAM_SECTIONS, load_parameter_set
from frogsim.scenario.units import SI_UNITS, display_factor
from frogsim.sweep.spec import dumps_toml

PARAMETER_FILE = "fitted-parameters.toml"
#: a trace of at most this many samples also has them drawn as markers (the grid's points are
#: interpolated between them)
SAMPLE_MARKERS = 200


def _display(x: float, meta: dict, digits: int = 6) -> str:
    disp, kind = meta.get("display"), meta.get("kind")
    if disp and kind:
        return f"{x / display_factor(disp, kind):.{digits}g} {disp}"
    return f"{x:.{digits}g}"


def overrides_text(overrides: dict, variables: dict) -> str:
    """An experiment's overrides as a reader writes them: "source.initial_pressure_gauge = 4 bar"
    (each SI value in its setting's display unit; a value without one as it is)."""
    parts = []
    for path, v in overrides.items():
        meta = variables.get(path, {})
        shown = _display(v, meta) if isinstance(v, (int, float)) and not isinstance(v, bool) else repr(v)
        parts.append(f"{path} = {shown}")
    return ", ".join(parts)


def _ci_text(res: FitResult, j: int) -> str:
    meta = res.spec.parameters[j].meta
    conf = f"{res.spec.confidence * 100:g} % CI"
    lo, hi = res.ci_low[j], res.ci_high[j]
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return f"{conf} not determined (the data cannot fix this parameter; see the fit's warnings)"
    disp, kind = meta.get("display"), meta.get("kind")
    f = display_factor(disp, kind) if disp else 1.0
    return f"{conf} {lo / f:.4g} .. {hi / f:.4g}" + (f" {disp}" if disp else "")


def _profile_text(res: FitResult, j: int) -> str:
    prm = res.spec.parameters[j]
    if prm.path not in res.profile:
        return ""
    lo, hi = res.profile[prm.path]
    f = lambda x: _display(x, prm.meta, 4) if np.isfinite(x) else "open (beyond the bound)"  # noqa: E731
    return f"; profile {f(lo)} .. {f(hi)}"


def parameter_file_text(res: FitResult, date: str) -> tuple[str, list[str]]:
    """(TOML text of the fitted parameter set, fitted paths that are run settings and not in it)."""
    base = res.spec.base
    raw = load_parameter_set(base.parameters, base.base_dir)
    traces = ", ".join([e.trace.name for e in res.spec.experiments] +
                       [f.table.name for f in res.spec.force_tables])
    left_out = []
    for j, prm in enumerate(res.spec.parameters):
        keys = prm.path.split(".")
        if keys[0] not in PARAM_SECTIONS:
            left_out.append(prm.path)
            continue
        node = raw
        for key in keys[:-1]:
            node = node.setdefault(key, {})
        note = _ci_text(res, j)
        if prm.path in res.on_bound:
            note += f"; on its {res.on_bound[prm.path]} bound"
        node[keys[-1]] = {"value": _display(res.values[j], prm.meta),
                          "source": f"fitted to {traces} on {date}, {note}"}
    name = f"{Path(base.parameters).stem}-fitted"
    meta = {"meta": {"name": name, "title": f"{base.parameters} with {len(res.spec.parameters) - len(left_out)} "
                                             f"values fitted to {traces} ({date})"}}
    head = (f"# Parameter set {name!r}: {base.parameters} with values fitted by `frogsim fit "
            f"{Path(res.spec.path).name}` on {date}.\n# Every fitted value's source gives its trace(s) and "
            "confidence interval; the other values are the base set's.\n")
    return head + dumps_toml({**meta, **raw}), left_out


def _bar_gauge(p: np.ndarray, patm: float) -> np.ndarray:
    return (p - patm) / 1e5


def _shown_signal(signal: str, patm: float) -> tuple:
    """(values in display units, residuals in display units, axis unit, residual unit) of a signal:
    pressures in bar gauge (residuals in bar), temperatures in K."""
    if signal_kind(signal) == "temperature":
        return (lambda x: x), (lambda x: x), "K", "K"
    return (lambda p: _bar_gauge(p, patm)), (lambda d: d / 1e5), "bar gauge", "bar"


def draw_experiment(res: FitResult, k: int, path: str) -> None:
    c = res.curves[k]
    e = res.spec.experiments[k]
    patm = e.scenario.air.atmospheric_pressure_abs
    sigs = list(c["signals"])
    # the legends in a column of their own: measured points and residuals fill their panels
    fig, grid = figure(2 * len(sigs), 2, width=10.5, height=2.6 * 2 * len(sigs), sharex=True,
                       gridspec_kw={"width_ratios": [1, 0.3]})
    axes, legends = grid[:, :1], grid[:, 1]
    t = c["t"]
    for i, s in enumerate(sigs):
        d = c["signals"][s]
        shown, diff, unit, runit = _shown_signal(s, patm)
        ax, axr = axes[2 * i, 0], axes[2 * i + 1, 0]
        sparse = e.trace.time.size <= SAMPLE_MARKERS
        ax.plot(t, shown(d["measured"]), ".", ms=2, color="0.55",
                label="measured, interpolated onto the model's grid" if sparse else "measured")
        if sparse:                                        # its own samples as well
            inside = e.trace.time <= t[-1]
            ax.plot(e.trace.time[inside], shown(e.trace.signals[s][inside]), "o", ms=4, mfc="none",
                    color="k", label="measured, the trace's samples")
        ax.plot(t, shown(d["before"]), "--", color="tab:blue", lw=1.2, label="model, start values")
        ax.plot(t, shown(d["after"]), "-", color="tab:red", lw=1.4, label="model, fitted")
        ax.set_ylabel(f"{s} [{unit}]")
        legend_in(legends[2 * i], ax, fontsize=8)
        ax.set_title(f"{e.name}: {s}", fontsize=10)
        axr.plot(t, diff(d["after"] - d["measured"]), ".", ms=2, color="tab:red", label="fitted - measured")
        axr.axhline(0.0, color="k", lw=0.8)
        noise = diff(res.spec.noise[s])
        axr.axhspan(-2 * noise, 2 * noise, color="tab:green", alpha=0.1, lw=0, label="+-2 x stated noise")
        axr.set_ylabel(f"residual [{runit}]")
        legend_in(legends[2 * i + 1], axr, fontsize=8)
    axes[-1, 0].set_xlabel("time [s]")
    save(fig, path, source_note=f"trace {e.trace.name}; scenario {e.scenario.name}")


def draw_force_table(res: FitResult, k: int, path: str) -> None:
    """Measured force and the law at the start and fitted values against contraction, per pressure;
    below, the residuals (fitted - measured) with +-2 x each row's stated noise."""
    ft = res.spec.force_tables[k]
    c = res.force_curves[k]
    tab = ft.table
    fig, axes = figure(2, 1, width=8.0, height=8.0, sharex=True)
    ax, axr = axes[0, 0], axes[1, 0]
    lo, hi = min(tab.contraction.min(), 0.0), tab.contraction.max()
    grid = np.linspace(lo, hi, 200)
    # a table with a direction column is a loop: the fitted law is drawn branch by branch over each
    # pressure's rows (loading solid, unloading dotted), the rows marked by their branch
    looped = tab.direction is not None and ft.model.hysteresis(c["point_after"]) is not None
    for i, p in enumerate(tab.pressures()):
        color = f"C{i % 10}"
        idx = tab.pressure == p
        pp = np.full_like(grid, p)
        ax.plot(grid * 100, ft.model.forces(c["point_before"], pp, grid), "--", color=color, lw=0.9)
        if looped:
            for d, marker, ls, word in ((-1, "o", "-", "loading"), (1, "v", ":", "unloading")):
                rows = idx & (tab.direction == d)
                ax.plot(tab.contraction[rows] * 100, tab.force[rows], marker, color=color, mfc="none", ms=5,
                        label=f"{p / 1e5:g} bar {word}" if i == 0 else (f"{p / 1e5:g} bar" if d < 0 else None))
                span = np.linspace(tab.contraction[idx].min(), tab.contraction[idx].max(), 100)
                ax.plot(span * 100, ft.model.forces(c["point_after"], np.full_like(span, p), span,
                                                    np.full(span.size, d)), ls, color=color, lw=1.3)
        else:
            ax.plot(tab.contraction[idx] * 100, tab.force[idx], "o", color=color, mfc="none",
                    label=f"{p / 1e5:g} bar measured")
            ax.plot(grid * 100, ft.model.forces(c["point_after"], pp, grid), "-", color=color, lw=1.4)
        axr.plot(tab.contraction[idx] * 100, (c["after"] - tab.force)[idx], "o", color=color, ms=4)
    order = np.argsort(tab.contraction)
    axr.fill_between(tab.contraction[order] * 100, -2 * ft.sigma[order], 2 * ft.sigma[order], color="tab:green",
                     alpha=0.1, lw=0, label="+-2 x stated noise")
    axr.axhline(0.0, color="k", lw=0.8)
    ax.set_ylabel("force [N]")
    ax.set_title(f"{c['name']}: measured and the law with fitted constants\n"
                 + ("(loading: o and solid, unloading: v and dotted)" if looped else "(o and solid)")
                 + ", with start constants (dashed)", fontsize=10)
    ax.legend(fontsize=7, ncol=2, loc="best")
    axr.set_ylabel("fitted - measured [N]")
    axr.set_xlabel("contraction [%] (negative: stretched)")
    axr.legend(fontsize=8, loc="best")
    save(fig, path, source_note=f"force table {tab.name}; muscle type {ft.model.muscle_type}")


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", text).strip("-") or "experiment"


def summary(res: FitResult, date: str, left_out: list) -> dict:
    spec = res.spec
    params = {}
    for j, prm in enumerate(spec.parameters):
        unit = SI_UNITS[prm.meta["kind"]][0] or "1"
        params[prm.path] = {
            "si_unit": unit, "display_unit": prm.meta.get("display") or "",
            "value_si": res.values[j], "value": _display(res.values[j], prm.meta),
            "std_si": res.std[j], "ci_low_si": res.ci_low[j], "ci_high_si": res.ci_high[j],
            "start_si": res.start_values[j], "min_si": prm.lower, "max_si": prm.upper,
            "on_bound": res.on_bound.get(prm.path), "in_parameter_file": prm.path not in left_out,
            "identifiable": prm.path not in res.unidentifiable,
            "unidentifiable_because": res.unidentifiable.get(prm.path),
            "interval_method": res.interval_method[j] if res.interval_method else None,
        }
        if prm.path in res.profile:
            lo, hi = res.profile[prm.path]
            params[prm.path].update(profile_ci_low_si=lo, profile_ci_high_si=hi)
    exps = []
    for e, c in zip(spec.experiments, res.curves):
        exps.append({"name": e.name, "trace": _rel(e.trace.path, spec), "overrides_si": e.overrides,
                     "commands": _rel(e.commands, spec) if e.commands else None,
                     "command_delay_s": e.command_delay,
                     "trace_samples": int(e.trace.time.size), "trace_median_step_s": e.trace.median_step,
                     "model_points": int(c["t"].size),
                     "signals": {s: _signal_summary(res, e, s) for s in c["signals"]}})
    forces = []
    for ft, c in zip(spec.force_tables, res.force_curves):
        forces.append({"name": ft.name, "table": _rel(ft.table.path, spec), "muscle_type": ft.model.muscle_type,
                       "rows": int(ft.table.force.size), "rows_left_out_negative_force": ft.table.dropped,
                       "columns": ft.table.columns, "noise_N": ft.noise, "relative_noise": ft.relative_noise,
                       "per_pressure": c["worst"],
                       "per_pressure_start": c["worst_before"]})
    return {
        "fit_spec": Path(spec.path).name, "date": date, "base_scenario": spec.base.name, "parameter_set": spec.base.parameters,
        "parameters": params,
        "confidence": spec.confidence, "interval": spec.interval, "quantile": res.quantile,
        "independent_points": res.n_points, "degrees_of_freedom": res.dof,
        "residual_variance": res.residual_variance,
        "residual_variance_meaning": ("reduced chi-square: mean squared residual in units of the stated noise"
                                      if spec.noise_given else
                                      "mean squared residual in units of 1 kPa (no noise was stated)"
                                      if not any(signal_kind(x) == "temperature" for x in spec.noise) else
                                      "mean squared residual in units of each signal's stated noise, 1 kPa "
                                      "for a pressure without one (no noise was stated for it)"),
        "condition_number": res.condition_number,
        "residual_correlation": res.residual_correlation,
        "global_stage": res.global_stage,
        "correlation": {"paths": res.paths, "matrix": res.correlation.tolist()},
        "warnings": list(res.warnings),
        "experiments": exps,
        "force_tables": forces,
        "starts": [{"start_si": dict(zip(res.paths, _x(res, s.theta0))), "end_si": dict(zip(res.paths, _x(res, s.theta))),
                    "cost": s.cost, "evaluations": s.evaluations, "jacobians": s.jacobians, "message": s.message}
                   for s in res.starts],
        "model_runs": res.model_runs, "wall_s": res.wall_s,
        "not_in_parameter_file": left_out,
    }


def _rel(path, spec) -> str:
    """An input file's path as the spec names it: relative to the spec's folder (POSIX slashes),
    or absolute where it lies on another drive."""
    import os
    base = Path(spec.path).resolve().parent
    try:
        return Path(os.path.relpath(Path(path).resolve(), base)).as_posix()
    except ValueError:
        return str(path)


def _signal_summary(res: FitResult, e, s: str) -> dict:
    """A signal's column, noise, weight and rms residuals, the SI unit in each key (Pa for a
    pressure, K for a temperature)."""
    u = "K" if signal_kind(s) == "temperature" else "Pa"
    return {"column": e.trace.columns[s], f"noise_{u}": res.spec.noise[s], "weight": res.spec.weights[s],
            f"rms_residual_start_{u}": res.rms_residual_before[(e.name, s)],
            f"rms_residual_fitted_{u}": res.rms_residual[(e.name, s)]}


def _x(res: FitResult, theta) -> list:
    return [p.lower + t * (p.upper - p.lower) for p, t in zip(res.spec.parameters, theta)]


def _html(res: FitResult, s: dict, figures: list) -> str:
    esc = html.escape
    spec = res.spec
    rows = []
    for j, prm in enumerate(spec.parameters):
        d = s["parameters"][prm.path]
        rows.append(f"<tr><td><code>{esc(prm.path)}</code></td><td>{esc(d['value'])}</td>"
                    f"<td>{esc(_ci_text(res, j))}{esc(_profile_text(res, j))}</td><td>{esc(_display(res.start_values[j], prm.meta, 4))}</td>"
                    f"<td>{esc(_display(prm.lower, prm.meta, 4))} .. {esc(_display(prm.upper, prm.meta, 4))}</td>"
                    f"<td>{esc(d['on_bound'] or '')}</td></tr>")
    corr_head = "".join(f"<th>{j + 1}</th>" for j in range(len(res.paths)))
    corr_rows = "".join(
        f"<tr><th>{i + 1} <code>{esc(p)}</code></th>" + "".join(
            f"<td>{'' if not np.isfinite(c) else f'{c:+.3f}'}</td>" for c in res.correlation[i]) + "</tr>"
        for i, p in enumerate(res.paths))
    warn = "".join(f"<li>{esc(w)}</li>" for w in res.warnings) or "<li>none</li>"
    variables = res.spec.base.variable_paths()
    exps = "".join(f"<li>{esc(e['name'])}: <code>{esc(Path(e['trace']).name)}</code>, {e['trace_samples']} samples"
                   + (f", overrides {esc(overrides_text(e['overrides_si'], variables))}" if e['overrides_si'] else "")
                   + "</li>" for e in s["experiments"])
    imgs = "".join(f"<figure><img alt=\"{esc(name)}\" src=\"data:image/png;base64,{b64}\"/>"
                   f"<figcaption>{esc(name)}</figcaption></figure>" for name, b64 in figures)
    meaning = esc(s["residual_variance_meaning"])
    force_html = ""
    if s["force_tables"]:
        trs = "".join(f"<tr><td>{esc(f['name'])}</td><td>{w['pressure_Pa_gauge'] / 1e5:g}</td><td>{w['rows']}</td>"
                      f"<td>{w['rms_error_N']:.1f}</td><td>{w['worst_abs_error_N']:.1f}</td>"
                      f"<td>{w['worst_at_contraction'] * 100:.3g}</td><td>{w['worst_measured_N']:.1f}</td>"
                      f"<td>{w['worst_model_N']:.1f}</td></tr>"
                      for f in s["force_tables"] for w in f["per_pressure"])
        force_html = f"""<h2>Force law against the force tables</h2>
<table><tr><th>table</th><th>pressure [bar gauge]</th><th>rows</th><th>rms error [N]</th><th>worst |error| [N]</th>
<th>at contraction [%]</th><th>measured there [N]</th><th>model there [N]</th></tr>{trs}</table>
<p>Error = law with the fitted constants - measured. Each row's noise: max(noise, relative_noise &times; |force|).</p>"""
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>frogsim fit: {esc(Path(spec.path).name)}</title>
<style>body{{font-family:sans-serif;max-width:60em;margin:1em auto;padding:0 1em}}
table{{border-collapse:collapse}}td,th{{border:1px solid #bbb;padding:2px 6px;text-align:left}}
img{{max-width:100%}}li{{margin:0.3em 0}}.w li{{color:#a40}}</style></head><body>
<h1>Fit of {esc(spec.base.name)} to {len(spec.experiments)} measured run(s) and {len(spec.force_tables)} force table(s)</h1>
<p>{esc(s['date'])}: <code>{esc(Path(spec.path).name)}</code>, parameter set {esc(spec.base.parameters)};
{len(res.starts)} start(s), {res.model_runs} model runs in {res.wall_s:.1f} s.</p>
<h2>Fitted values</h2>
<table><tr><th>parameter</th><th>fitted</th><th>interval</th><th>start</th><th>bounds</th><th>on bound</th></tr>
{''.join(rows)}</table>
<p>Intervals: value &plusmn; {res.quantile:.3f} &times; standard error ({esc(spec.interval)} quantile,
{res.dof:.0f} degrees of freedom); covariance s&sup2;(J<sup>T</sup>J)<sup>-1</sup> from the Jacobian at the fit
and the residual variance s&sup2; = {res.residual_variance:.4g} ({meaning}). They are linearised: they hold when
the errors are independent and the model fits.</p>
<h2>Warnings</h2><ul class="w">{warn}</ul>
<h2>Correlation of the estimates</h2>
<table><tr><th></th>{corr_head}</tr>{corr_rows}</table>
<p>Condition number of the column-scaled J<sup>T</sup>J: {res.condition_number:.3g}.</p>
{force_html}
<h2>Experiments</h2><ul>{exps or "<li>none</li>"}</ul>
<h2>Measured and simulated</h2>{imgs}
</body></html>
"""


def planned_files(spec) -> list[str]:
    """The names of the files :func:`write_outputs` writes for a fit spec (known before the fit)."""
    names = [f"fit-{k + 1}-{_slug(e.name)}.png" for k, e in enumerate(spec.experiments)]
    names += [f"force-{k + 1}-{_slug(ft.name)}.png" for k, ft in enumerate(getattr(spec, "force_tables", ()))]
    return names + [PARAMETER_FILE, "report.html", "summary.json"]


def write_outputs(res: FitResult, out) -> dict:
    """Write every output into the folder ``out``; returns {what: path}."""
    out = out_folder(out)
    date = datetime.date.today().isoformat()
    text, left_out = parameter_file_text(res, date)
    s = summary(res, date, left_out)
    files = {}
    figures = []
    for k, e in enumerate(res.spec.experiments):
        p = out / f"fit-{k + 1}-{_slug(e.name)}.png"
        write_figure(p, lambda tmp, k=k: draw_experiment(res, k, tmp))
        files[f"figure {k + 1}"] = p
        figures.append((p.name, base64.b64encode(p.read_bytes()).decode("ascii")))
    for k, ft in enumerate(res.spec.force_tables):
        p = out / f"force-{k + 1}-{_slug(ft.name)}.png"
        write_figure(p, lambda tmp, k=k: draw_force_table(res, k, tmp))
        files[f"force figure {k + 1}"] = p
        figures.append((p.name, base64.b64encode(p.read_bytes()).decode("ascii")))
    atomic_write(out / PARAMETER_FILE, lambda tmp: Path(tmp).write_text(text))
    files["parameters"] = out / PARAMETER_FILE
    atomic_write(out / "report.html", lambda tmp: Path(tmp).write_text(_html(res, s, figures)))
    files["report"] = out / "report.html"
    write_json(out / "summary.json", s)
    files["summary"] = out / "summary.json"
    return files
