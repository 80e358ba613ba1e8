"""Weighted nonlinear least squares of the pneumatic model against measured traces.

The residual of experiment e, signal s at output time t_k is

    r = weight_s * sqrt(f_e) * (simulated_s(t_k) - measured_s(t_k)) / noise_s

(``f_e`` <= 1 discounts a trace sampled more coarsely than the model's output grid, see
:func:`frogsim.fit.traces.information_factor`); that of row i of a force table is

    r = (F_model(p_i, eps_i) - F_i) / sigma_i,   sigma_i = max(noise, relative_noise * |F_i|)

(:mod:`frogsim.fit.force`), both kinds in one vector when a spec has both. The parameters are fitted in the unit box: each
runs from 0 at its ``min`` to 1 at its ``max`` (:func:`scipy.optimize.least_squares`, trust
region reflective, bounds [0, 1]). Every Jacobian is one batch of variants run by the batched
engine (:func:`frogsim.engine.batch.run_models`): forward differences of ``diff_step`` (a fraction
of each parameter's range; backward at the upper bound) during the search, central differences for
the final covariance. Several starts (the given start plus Latin-hypercube points,
:class:`scipy.stats.qmc.LatinHypercube`) guard against local minima; the lowest cost wins.

Uncertainty: cov = s^2 (J^T J)^-1 in the unit box, s^2 = sum r^2 / (n - p) the residual variance
(n: the number of independent data points), mapped to SI; the intervals are value +- q * std with
q the two-sided Student-t (default) or normal quantile. These are linearised intervals: they
assume independent errors and a model that fits; the warnings say when the data cannot separate
the parameters, when a value sits on its bound, when the residuals are far from the stated noise
or correlated in time.

Profile intervals (``profile = ["path", ...]`` in the spec), a check on the linearised ones for
the parameters named: parameter j is fixed at values around its estimate and the others are
fitted again; the interval is where the profile's sum of squares S_j(x) stays within
S_min + q^2 s^2 (the same q and s^2 as above). For a model linear in its parameters the two
intervals coincide; where they differ, the profile one follows the model's curvature.
"""
from __future__ import annotations

import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from frogsim._parallel import default_threads
from frogsim.engine.batch import build_models, run_models
from frogsim.fit.force import PREFIX, worst_errors
from frogsim.fit.spec import FitSpec
from frogsim.fit.traces import information_factor, model_grid, simulated

#: a lag-1 autocorrelation above this many of its standard errors (1/sqrt(n) for independent errors)
#: makes the residuals correlated (residual_correlation)
CORRELATED_SE = 3.0
#: the global stage's Latin-hypercube points per fitted parameter (FIT.toml global_points), and
#: how many of them one batch runs
GLOBAL_PER_PARAMETER = 10
GLOBAL_BATCH = 32
#: |correlation| above which two parameters are reported as indistinguishable
CORRELATION_LIMIT = 0.95
#: condition number of the column-normalised J^T J above which it is reported as near-singular
CONDITION_LIMIT = 1.0e4
#: above this the matrix is singular for all purposes: no interval is given
SINGULAR_LIMIT = 1.0e12
#: a fitted value within this fraction of its range of a bound "sits on" it
BOUND_TOLERANCE = 1.0e-3


@dataclass
class Start:
    """One least-squares start: where it began and ended (unit box), cost, evaluations, message."""
    theta0: np.ndarray
    theta: np.ndarray
    cost: float
    evaluations: int
    jacobians: int
    message: str


@dataclass
class FitResult:
    """A finished fit. Values are SI; ``std`` the standard errors; ``ci_low``/``ci_high`` the
    two-sided ``spec.confidence`` intervals (NaN where the data cannot determine them)."""
    spec: FitSpec
    values: np.ndarray
    start_values: np.ndarray
    std: np.ndarray
    ci_low: np.ndarray
    ci_high: np.ndarray
    correlation: np.ndarray
    condition_number: float
    residual_variance: float
    dof: float
    n_points: float
    quantile: float
    rms_residual: dict                  # (experiment, signal) -> rms of sim - measured [SI], after
    rms_residual_before: dict
    warnings: list
    starts: list
    model_runs: int
    wall_s: float
    on_bound: dict                      # path -> "lower" / "upper"
    curves: list = field(default_factory=list, repr=False)  # per experiment: t, measured, before, after
    force_curves: list = field(default_factory=list, repr=False)  # per force table: rows, before, after
    profile: dict = field(default_factory=dict)  # path -> (low, high) profile interval [SI], NaN if open
    interval_method: list = field(default_factory=list)  # per parameter: how its interval was made
    unidentifiable: dict = field(default_factory=dict)   # path -> why the data cannot fix it
    residual_correlation: dict = field(default_factory=dict)  # residual_correlation()'s figures
    global_stage: dict = field(default_factory=dict)     # the screened points (start_points)

    @property
    def paths(self) -> list[str]:
        return [p.path for p in self.spec.parameters]


class Evaluator:
    """Residual vectors of many parameter points at once, on the batched engine."""

    def __init__(self, spec: FitSpec):
        self.spec = spec
        self.paths = [p.path for p in spec.parameters]
        self.lower = np.array([p.lower for p in spec.parameters])
        self.span = np.array([p.upper - p.lower for p in spec.parameters])
        self.blocks = []       # per experiment: (times, [(signal, measured, scale)], information factor)
        self.at = []           # per experiment: the model grid's indices compared (None: all of them)
        self.n_points = 0.0
        for e in spec.experiments:
            t = model_grid(e.scenario)
            f = information_factor(e.trace, e.scenario)
            at = on_grid(e.trace, t) if f < 1.0 else None
            if at is not None:              # a coarse trace whose samples are grid points: compared there only
                inside = e.trace.time <= t[-1] + 1e-12
                meas = {s_: v[inside] for s_, v in e.trace.signals.items()}
                t, f = t[at], 1.0
            else:
                meas = e.trace.resample(t)
            self.at.append(at)
            rows = []
            for s in sorted(meas):
                scale = spec.weights[s] * np.sqrt(f) / spec.noise[s]
                rows.append((s, meas[s], scale))
                self.n_points += f * t.size
            self.blocks.append((t, rows, f))
        self.scenario_paths = [p for p in self.paths if not p.startswith(PREFIX)]
        for ft in spec.force_tables:
            self.n_points += ft.table.force.size
        self.model_runs = 0
        self.threads = spec.threads
        self._lock = threading.Lock()

    def x(self, theta) -> np.ndarray:
        """SI values of a point of the unit box."""
        return self.lower + np.asarray(theta, dtype=float) * self.span

    def theta(self, x) -> np.ndarray:
        return (np.asarray(x, dtype=float) - self.lower) / self.span

    def point(self, theta) -> dict:
        """Dotted path -> SI value of a point of the unit box."""
        return dict(zip(self.paths, map(float, self.x(theta))))

    def results(self, thetas) -> list[list]:
        """Results [point][experiment, then force table]: a Result per experiment, all points and
        experiments run as one batch; the model forces [N] at its rows per force table."""
        points = [self.point(th) for th in thetas]
        n, m = len(points), len(self.spec.experiments)
        runs = []
        if m:
            scen_points = [{p: pt[p] for p in self.scenario_paths} for pt in points]
            models = []
            for e in self.spec.experiments:
                models.extend(build_models(e.scenario, scen_points))
            runs = run_models(models, threads=self.threads)
            with self._lock:
                self.model_runs += len(models)
        return [[runs[k * n + j] for k in range(m)] + [ft.model.forces(points[j]) for ft in self.spec.force_tables]
                for j in range(n)]

    def residual(self, runs) -> np.ndarray:
        parts = []
        for (t, rows, _), at, r in zip(self.blocks, self.at, runs):
            for s, meas, scale in rows:
                sim = simulated(r, s)
                parts.append(scale * ((sim if at is None else sim[at]) - meas))
        for ft, forces in zip(self.spec.force_tables, runs[len(self.blocks):]):
            parts.append((forces - ft.table.force) / ft.sigma)
        return np.concatenate(parts)

    def residuals(self, thetas) -> np.ndarray:
        return np.array([self.residual(runs) for runs in self.results(thetas)])

    def jacobian(self, theta, f0, step: float) -> np.ndarray:
        """Forward differences (backward where a step would leave the box), one batch."""
        p = len(theta)
        h = np.where(theta + step <= 1.0, step, -step)
        pts = [theta + h[j] * np.eye(p)[j] for j in range(p)]
        fs = self.residuals(pts)
        return ((fs - f0) / h[:, None]).T

    def partial_jacobian(self, theta, f0, step: float, free) -> np.ndarray:
        """Forward differences in the ``free`` coordinates only, one batch."""
        h = np.where(theta[free] + step <= 1.0, step, -step)
        pts = []
        for k, j in enumerate(free):
            th = theta.copy()
            th[j] += h[k]
            pts.append(th)
        fs = self.residuals(pts)
        return ((fs - f0) / h[:, None]).T

    def central_jacobian(self, theta, step: float) -> np.ndarray:
        """Central differences, one-sided at a bound; one batch of 2p points."""
        p = len(theta)
        up = np.minimum(theta + step, 1.0)
        down = np.maximum(theta - step, 0.0)
        pts = [np.where(np.arange(p) == j, up[j], theta) for j in range(p)] + \
              [np.where(np.arange(p) == j, down[j], theta) for j in range(p)]
        fs = self.residuals(pts)
        return ((fs[:p] - fs[p:]) / (up - down)[:, None]).T


def on_grid(trace, grid) -> np.ndarray | None:
    """The indices of the model grid ``grid`` at the trace's samples (those within the run), if
    every one of them is a grid point (a board's log: every log_every-th sample of the controller,
    on the output grid): the fit then compares the model with the trace at the trace's own samples,
    not with the trace interpolated between them (which would put a line through the valve pulses a
    coarse log steps over). None if some sample lies between grid points."""
    tt = trace.time[trace.time <= grid[-1] + 1e-12]
    if tt.size < 2:
        return None
    k = np.searchsorted(grid, tt - 1e-9)
    k = np.minimum(k, grid.size - 1)
    tol = 1e-6 * (grid[1] - grid[0]) if grid.size > 1 else 1e-12
    if np.all(np.abs(grid[k] - tt) <= tol):
        return k
    return None


def _least_squares(ev: Evaluator, theta0, spec: FitSpec, bar) -> Start:
    from scipy.optimize import least_squares
    cache = {}
    counts = {"f": 0, "j": 0}

    def fun(theta):
        key = theta.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = ev.residuals([theta])[0]
            counts["f"] += 1
            if bar is not None:
                bar.update(1)
                bar.set_postfix(cost=f"{0.5 * float(cache[key] @ cache[key]):.4g}", refresh=False)
        return cache[key]

    def jac(theta):
        f0 = fun(theta)
        counts["j"] += 1
        return ev.jacobian(theta, f0, spec.diff_step)

    sol = least_squares(fun, np.asarray(theta0, dtype=float), jac=jac, bounds=(0.0, 1.0), method="trf",
                        x_scale=1.0, max_nfev=spec.max_evaluations)
    return Start(np.asarray(theta0, dtype=float), sol.x, float(sol.cost), counts["f"], counts["j"], sol.message)


def start_points(spec: FitSpec, ev: Evaluator) -> tuple:
    """(the starts, the global stage's figures): the given start, then the ``starts - 1`` best of
    ``global_points`` Latin-hypercube points of the unit box (seeded; default 10 per parameter,
    at least ``starts - 1``), their costs computed in batches before any local search: a global
    stage that puts the local starts in the cost's lowest valleys. ``global_points = 0``: the
    ``starts - 1`` hypercube points themselves (no screening)."""
    first = ev.theta([p.start for p in spec.parameters])
    if spec.starts == 1:
        return first[None, :], {"points": 0}
    from scipy.stats import qmc
    n = spec.global_points if spec.global_points is not None else GLOBAL_PER_PARAMETER * len(first)
    lhs = qmc.LatinHypercube(d=len(first), seed=spec.seed).random(max(n, spec.starts - 1))
    if n == 0:
        return np.vstack([first, lhs]), {"points": 0}
    costs = []
    for k in range(0, len(lhs), GLOBAL_BATCH):
        fs = ev.residuals(list(lhs[k:k + GLOBAL_BATCH]))
        costs.extend(0.5 * np.einsum("ij,ij->i", fs, fs))
    costs = np.array(costs)
    costs[~np.isfinite(costs)] = np.inf
    order = np.argsort(costs, kind="stable")[:spec.starts - 1]
    return np.vstack([first, lhs[order]]), {
        "points": int(len(lhs)), "method": "Latin hypercube of the bounds' box, the lowest costs start the local "
                                           "searches", "best_cost": float(costs[order[0]]),
        "median_cost": float(np.median(costs[np.isfinite(costs)])) if np.isfinite(costs).any() else None}


def fit_spec(spec: FitSpec, progress: bool = False) -> FitResult:
    """Fit a loaded spec (see :func:`frogsim.fit.spec.load_fit_spec`); writes nothing."""
    t0 = time.perf_counter()
    ev = Evaluator(spec)
    thetas0, global_stage = start_points(spec, ev)
    workers = min(default_threads(spec.threads), len(thetas0))
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(desc=f"{len(thetas0)} start(s)", unit=" eval", file=sys.stderr, dynamic_ncols=True)
    try:
        if workers > 1:
            # the starts side by side, one thread each, each running its batches on that thread:
            # more of the cores busy than with small batches spread over the pool one at a time
            ev.threads = 1
            with ThreadPoolExecutor(workers) as pool:
                starts = list(pool.map(lambda th0: _least_squares(ev, th0, spec, bar), thetas0))
            ev.threads = spec.threads
        else:
            starts = [_least_squares(ev, th0, spec, bar) for th0 in thetas0]
    finally:
        if bar is not None:
            bar.close()
    best = min(starts, key=lambda s: s.cost)
    theta = best.theta
    before_runs, after_runs = ev.results([thetas0[0], theta])
    f = ev.residual(after_runs)
    J = ev.central_jacobian(theta, spec.diff_step)
    res = _uncertainty(spec, ev, theta, f, J)
    res.update(_bound_and_start_warnings(spec, ev, theta, starts, best, res["warnings"]))
    res["warnings"] += _residual_warnings(spec, ev, after_runs, res["residual_variance"])
    res["warnings"] += list(spec.notes)
    curves, rms_after, rms_before = [], {}, {}
    for e, (t, rows, _), at, rb, ra in zip(spec.experiments, ev.blocks, ev.at, before_runs, after_runs):
        c = {"name": e.name, "t": t, "signals": {}}
        for s, meas, _ in rows:
            sb, sa = simulated(rb, s), simulated(ra, s)
            if at is not None:
                sb, sa = sb[at], sa[at]
            c["signals"][s] = {"measured": meas, "before": sb, "after": sa}
            rms_after[(e.name, s)] = float(np.sqrt(np.mean((sa - meas) ** 2)))
            rms_before[(e.name, s)] = float(np.sqrt(np.mean((sb - meas) ** 2)))
        curves.append(c)
    force_curves = []
    m = len(spec.experiments)
    for ft, fb, fa in zip(spec.force_tables, before_runs[m:], after_runs[m:]):
        force_curves.append({"name": ft.name, "before": fb, "after": fa, "point_before": ev.point(thetas0[0]),
                             "point_after": ev.point(theta), "worst": worst_errors(ft.table, fa),
                             "worst_before": worst_errors(ft.table, fb)})
        if ft.table.dropped:
            res["warnings"].append(f"{ft.name}: {ft.table.dropped} row(s) with a negative force (a push) were "
                                   "left out: the muscle law is tension-only")
    res["profile"] = {}
    for path in spec.profile:
        j = [q_.path for q_ in spec.parameters].index(path)
        res["profile"][path] = profile_interval(ev, spec, theta, j, float(f @ f), res)
    return FitResult(spec=spec, values=ev.x(theta), start_values=ev.x(thetas0[0]), starts=starts,
                     model_runs=ev.model_runs, wall_s=time.perf_counter() - t0, curves=curves,
                     force_curves=force_curves, global_stage=global_stage,
                     rms_residual=rms_after, rms_residual_before=rms_before, **res)


def _uncertainty(spec: FitSpec, ev: Evaluator, theta, f, J) -> dict:
    """Standard errors, intervals and correlations (module docstring), with each parameter's
    verdict: the parameters the data cannot fix (no effect; or in a combination the data do not
    see, the one of it that weighs most in the direction J^T J does not see, until the rest is
    regular) are "unidentifiable", with the reason, and left out of the others' covariance (which
    then holds them at their fitted values); the covariance widened by the residuals'
    autocorrelation (:func:`residual_correlation`); an interval that would leave the parameter's
    bounds computed on the logit of its place between them."""
    from scipy import stats
    from scipy.special import expit
    p = len(theta)
    n = ev.n_points
    dof = n - p
    warnings = []
    paths = [q_.path for q_ in spec.parameters]
    norms = np.linalg.norm(J, axis=0)
    safe = np.where(norms > 0, norms, 1.0)
    Jn = J / safe
    verdict = {}
    for j in range(p):
        if not norms[j] > 0:
            verdict[j] = "it has no effect on the measured signals or forces"
            warnings.append(f"{paths[j]} has no effect on the measured signals or forces: it cannot be fitted from "
                            "them (unidentifiable; the other parameters' intervals do not depend on it)")
    keep = [j for j in range(p) if j not in verdict]
    # the condition number of the parameters that have an effect (those without one are said so above)
    sv = np.linalg.svd(Jn[:, keep], compute_uv=False) if keep else np.ones(1)
    cond = float((sv[0] / sv[-1]) ** 2) if sv[-1] > 0 else float("inf")
    if cond > CONDITION_LIMIT:
        v = np.linalg.svd(Jn[:, keep])[2][-1]            # the direction the data do not see
        involved = [paths[keep[i]] for i in range(len(keep)) if abs(v[i]) > 0.2 * np.abs(v).max()]
        extra = ("no interval can be given for the parameters said unidentifiable" if cond > SINGULAR_LIMIT
                 else "the intervals are unreliable")
        warnings.append(f"J^T J is near-singular (condition number {cond:.3g} after scaling its columns, "
                        f"limit {CONDITION_LIMIT:g}): the data determine only a combination of "
                        f"{' and '.join(involved)}, not each of them; {extra}")
    while len(keep) > 1:
        sk = np.linalg.svd(Jn[:, keep])
        if sk[1][-1] > 0 and (sk[1][0] / sk[1][-1]) ** 2 <= SINGULAR_LIMIT:
            break
        v = sk[2][-1]
        involved = [keep[i] for i in range(len(keep)) if abs(v[i]) > 0.2 * np.abs(v).max()]
        drop = keep[int(np.argmax(np.abs(v)))]
        others = [paths[i] for i in involved if i != drop]
        verdict[drop] = ("the data fix only a combination of it with " + " and ".join(others) if others else
                         "the data barely move the fit with it")
        warnings.append(f"{paths[drop]} is unidentifiable from these data: {verdict[drop]}; no interval is given for "
                        "it, and the other parameters' intervals hold it at its fitted value")
        keep.remove(drop)
    # the degrees of freedom: the points less the parameters the data fix (one without effect takes none)
    dof = n - len(keep)
    s2 = float(f @ f) / dof if dof > 0 else float("nan")
    corr_info = residual_correlation(ev, f)
    tau = corr_info["inflation"]
    dof_eff = n / tau - len(keep)
    q = float(stats.t.ppf(0.5 + spec.confidence / 2, dof_eff) if spec.interval == "t" and dof_eff > 0
              else stats.norm.ppf(0.5 + spec.confidence / 2))
    cov = np.full((p, p), np.nan)
    if keep and dof > 0:
        Jk = Jn[:, keep]
        cov_k = tau * s2 * np.linalg.inv(Jk.T @ Jk) / np.outer(safe[keep], safe[keep])
        cov[np.ix_(keep, keep)] = cov_k * np.outer(ev.span[keep], ev.span[keep])
    std = np.sqrt(np.diag(cov))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(std, std)
    for i in range(p):
        for j in range(i + 1, p):
            c = corr[i, j]
            if np.isfinite(c) and abs(c) > CORRELATION_LIMIT:
                warnings.append(f"{paths[i]} and {paths[j]} cannot be told apart well from these data "
                                f"(correlation {c:+.3f}): the data fix mainly a combination of the two, and a "
                                "change of one is largely made up by the other; fix one of them, or add an "
                                "experiment that moves them differently")
    if corr_info["correlated"]:
        warnings.append(f"the residuals are correlated in time (lag-1 autocorrelation up to "
                        f"{corr_info['lag1_autocorrelation']:.2f}, runs test z = {corr_info['runs_test_z']:.2f}): "
                        f"the intervals are widened by sqrt({tau:.3g}), the ratio of the points to the effective "
                        f"independent ones ({corr_info['effective_points']:.4g} of {n:.4g}); look at the residual "
                        "plots for what the model misses")
    x = ev.x(theta)
    lo, hi, how = x - q * std, x + q * std, ["linearised"] * p
    for j in range(p):
        if not np.isfinite(std[j]):
            how[j] = "none: unidentifiable" if j in verdict else "none"
            continue
        if lo[j] >= spec.parameters[j].lower and hi[j] <= spec.parameters[j].upper:
            continue
        t = float(theta[j])
        if BOUND_TOLERANCE < t < 1 - BOUND_TOLERANCE:
            su = std[j] / ev.span[j] / (t * (1 - t))         # the logit's standard error
            u = np.log(t / (1 - t))
            lo[j] = ev.lower[j] + ev.span[j] * expit(u - q * su)
            hi[j] = ev.lower[j] + ev.span[j] * expit(u + q * su)
            how[j] = "logit of the place between min and max (the linearised interval left them)"
        else:
            lo[j], hi[j] = max(lo[j], spec.parameters[j].lower), min(hi[j], spec.parameters[j].upper)
            how[j] = "linearised, cut at the bound the value sits on"
    return dict(std=std, ci_low=lo, ci_high=hi, correlation=corr, condition_number=cond,
                residual_variance=s2, dof=dof_eff, n_points=n, quantile=q, warnings=warnings,
                interval_method=how, unidentifiable={paths[j]: r for j, r in verdict.items()},
                residual_correlation=corr_info)


def residual_correlation(ev: Evaluator, f) -> dict:
    """The residuals' correlation in time, on each trace's own samples (not the interpolated
    grid points): lag-1 autocorrelation, the Wald-Wolfowitz runs test of their signs (z < -2:
    fewer sign changes than independent errors make), and the integrated autocorrelation time
    tau_b = 1 + 2 sum rho_k of each signal (the initial positive sequence: summed up to the first
    lag whose rho is not positive; the residuals not centred, their mean being 0 under the model). The
    residuals count as correlated when a signal's lag-1 autocorrelation exceeds 3/sqrt(its samples)
    (three times its standard error for independent errors: 0.1 % false alarms) or its runs test's
    z is below -3; then ``inflation`` = n / sum(n_b / tau_b), the points over the
    effective independent ones, by which the covariance is multiplied (an AR(1) error of lag-1
    autocorrelation rho gives (1 + rho)/(1 - rho)), else 1. A force table's rows are not a time
    series: they count as independent. The runs test sees what the autocorrelation misses when a
    few large residuals (a fast rise) dominate its sums and long stretches of small ones keep their
    sign (a converter's step held while the pressure holds): with z below -3 the signal counts as
    many independent points as it has runs, tau_b at least the expected runs over the runs seen."""
    pos, worst, worst_z, n_all, n_eff, correlated = 0, None, None, 0.0, 0.0, False
    for (t, rows, fe) in ev.blocks:
        step = max(1, int(round(1.0 / fe)))
        for _ in rows:
            r = f[pos:pos + t.size][::step]
            pos += t.size
            m = r.size
            d = r                      # not centred: under the model the residuals have mean 0, and a
            den = float(d @ d)         # lasting offset (a converter's step held) is a correlation too
            tau, rho1, z = 1.0, 0.0, 0.0
            if m > 3 and den > 0:
                acf = np.correlate(d, d, mode="full")[m - 1:] / den
                rho1 = float(acf[1])
                s = 0.0
                for k in range(1, m // 2):
                    if acf[k] <= 0:
                        break
                    s += acf[k]
                tau = max(1.0, 1.0 + 2.0 * s)
                signs = np.sign(r[r != 0])
                n1, n2 = int(np.sum(signs > 0)), int(np.sum(signs < 0))
                if n1 and n2:
                    runs = 1 + int(np.sum(signs[1:] != signs[:-1]))
                    mu = 2.0 * n1 * n2 / (n1 + n2) + 1.0
                    var = (mu - 1.0) * (mu - 2.0) / (n1 + n2 - 1.0)
                    z = (runs - mu) / np.sqrt(var) if var > 0 else 0.0
                    if z < -CORRELATED_SE:       # long runs of one sign: as many independent points as runs
                        tau = max(tau, mu / runs)
                if rho1 > CORRELATED_SE / np.sqrt(m) or z < -CORRELATED_SE:
                    correlated = True
            worst = rho1 if worst is None else max(worst, rho1)
            worst_z = z if worst_z is None else min(worst_z, z)
            n_all += m
            n_eff += m / tau
    n_force = ev.n_points - n_all
    inflation = (ev.n_points / (n_eff + n_force)) if correlated and n_eff > 0 else 1.0
    return {"lag1_autocorrelation": worst, "runs_test_z": None if worst_z is None else float(worst_z), "correlated": correlated,
            "effective_points": float(ev.n_points / inflation), "inflation": float(inflation),
            "method": ("effective sample size: the covariance multiplied by the points over the effective "
                       "independent ones (each signal's integrated autocorrelation time, or its expected "
                       "over its observed runs of one sign where the runs test finds too few)"
                       if correlated else "none: the residuals show no correlation in time")}


def _bound_and_start_warnings(spec, ev, theta, starts, best, warnings) -> dict:
    on_bound = {}
    for j, prm in enumerate(spec.parameters):
        side = "lower" if theta[j] < BOUND_TOLERANCE else "upper" if theta[j] > 1 - BOUND_TOLERANCE else None
        if side:
            on_bound[prm.path] = side
            b = prm.lower if side == "lower" else prm.upper
            warnings.append(f"{prm.path} = {prm.shown(ev.x(theta)[j])} sits on its {side} bound "
                            f"{prm.shown(b)}: the data would take it further; its interval means little "
                            "(widen the bounds, or check the model and the data)")
    worse = [s for s in starts if s.cost > best.cost * (1 + 1e-3) + 1e-12]
    if worse:
        warnings.append(f"{len(worse)} of {len(starts)} starts ended in a worse minimum (cost up to "
                        f"{max(s.cost for s in worse) / max(best.cost, 1e-300):.3g} x the best): the "
                        "problem has local minima; the best is reported")
    return {"on_bound": on_bound}


def _residual_warnings(spec, ev, runs, s2) -> list:
    out = []
    if spec.noise_given and np.isfinite(s2) and not 0.5 <= s2 <= 2.0:
        out.append(f"the residuals are {np.sqrt(s2):.3g} x the stated noise (reduced chi-square {s2:.3g}): "
                   + ("the model does not fit the data to within the noise, or the noise is understated"
                      if s2 > 2 else "the noise is overstated")
                   + "; the intervals use the residual variance, not the stated noise")
    return out


def profile_interval(ev: Evaluator, spec: FitSpec, theta, j: int, s_min: float, res: dict) -> tuple:
    """The profile interval of parameter j (module docstring): (low, high) in SI, each NaN if the
    profile stays below the threshold all the way to that bound, or if no threshold can be set."""
    from scipy.optimize import brentq, least_squares
    s2, q = res["residual_variance"], res["quantile"]
    if not (np.isfinite(s2) and s2 > 0):
        return (float("nan"), float("nan"))
    limit = q * q * s2 * res.get("residual_correlation", {}).get("inflation", 1.0)
    free = [k for k in range(len(theta)) if k != j]
    warm = {"theta": np.asarray(theta, dtype=float).copy()}

    def excess(tj: float) -> float:
        th = warm["theta"].copy()
        th[j] = tj
        if free:
            def fun(sub):
                full = th.copy()
                full[free] = sub
                return ev.residuals([full])[0]

            def jac(sub):
                full = th.copy()
                full[free] = sub
                return ev.partial_jacobian(full, fun(sub), spec.diff_step, free)
            sol = least_squares(fun, th[free], jac=jac, bounds=(0.0, 1.0), method="trf",
                                max_nfev=spec.max_evaluations)
            th[free] = sol.x
            r = sol.fun
        else:
            r = ev.residuals([th])[0]
        warm["theta"] = th
        return float(r @ r) - s_min - limit

    std_theta = res["std"][j] / ev.span[j]
    step = std_theta * q if np.isfinite(std_theta) and std_theta > 0 else 0.05
    ends = []
    for sign in (-1.0, 1.0):
        warm["theta"] = np.asarray(theta, dtype=float).copy()
        inner, outer = float(theta[j]), float(theta[j])
        found = False
        for _ in range(12):                   # widen until the profile crosses the threshold
            outer = min(1.0, max(0.0, inner + sign * step))
            if excess(outer) > 0:
                found = True
                break
            if outer in (0.0, 1.0):
                break
            inner, step = outer, 2.0 * step
        if not found:
            ends.append(float("nan"))
            continue
        a, b = sorted((inner, outer))
        warm["theta"] = np.asarray(theta, dtype=float).copy()
        tj = brentq(excess, a, b, xtol=1e-6 * max(b - a, 1e-12))
        ends.append(float(ev.lower[j] + tj * ev.span[j]))
    return tuple(ends)
