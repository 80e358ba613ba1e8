"""The Optuna plumbing every search of frogsim shares (``frogsim optimize-gait``,
``frogsim tune``): where a study is stored, its sampler and pruner, continuing an interrupted
study, running its trials in batches on a thread pool, and the progress bar.

* Storage: an SQLite file in the output folder by default (:func:`sqlite_url`), or any Optuna
  storage URL (``postgresql://...``, ``mysql://...``) so that several machines share one study.
  An SQLite file waits up to :data:`SQLITE_TIMEOUT_S` for a lock, as the threads of a batch write
  their trials' reports at once.
* Sampler: Optuna's TPE, seeded, multivariate, with the "constant liar" (the trials of a batch
  asked together are kept apart), :data:`STARTUP_TRIALS` random trials first; the same sampler
  for one objective and for a Pareto front (several directions).
* Pruner (one objective only: Optuna prunes no multi-objective study): the median rule on the
  intermediate values a trial reports, after :data:`PRUNE_STARTUP_TRIALS` finished trials and
  from a trial's step :data:`PRUNE_WARMUP_STEPS` on. It compares with finished trials only; as
  the trials of a batch are told after the whole batch ran, a search is the same for the same
  seed and worker count, pruned trials included.
* Continuing: a study carries a ``key`` (what it was made for: scenario, objective, search
  space, seed, ...); a stored study with another key is refused (:func:`check_key`); trials an
  interrupted run left running are marked failed and asked again (:func:`close_unfinished`).
* Batches (:func:`run_batches`): ``workers`` trials asked together, run side by side on threads
  (the engines' compiled loops and MuJoCo's step release the GIL) and told in the order asked.
"""
from __future__ import annotations

import math
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from frogsim.errors import ScenarioError

STARTUP_TRIALS = 10          # TPE's random trials before it models the space
PRUNE_STARTUP_TRIALS = 5     # finished trials before the median rule prunes
PRUNE_WARMUP_STEPS = 4       # a trial's first reports are never pruned
SQLITE_TIMEOUT_S = 60.0


def quiet_optuna() -> None:
    import optuna
    optuna.logging.set_verbosity(optuna.logging.WARNING)


def sqlite_url(path: Path) -> str:
    """The Optuna storage URL of an SQLite file."""
    return f"sqlite:///{Path(path)}"


def is_sqlite_file(url: str, path: Path) -> bool:
    return url == sqlite_url(path)


def storage(url: str):
    """The Optuna storage of ``url`` (an SQLite file waits for a lock rather than failing);
    ScenarioError naming --storage when it cannot be opened."""
    import optuna
    quiet_optuna()
    kw = {"connect_args": {"timeout": SQLITE_TIMEOUT_S}} if url.startswith("sqlite:") else {}
    try:
        return optuna.storages.RDBStorage(url, engine_kwargs=kw)
    except Exception as exc:      # a bad URL, a driver missing, a server that does not answer
        from frogsim.errors import clip
        raise ScenarioError("--storage", url, clip(f"cannot open this Optuna storage ({type(exc).__name__}: "
                                                   f"{exc})", 200)) from None


def sampler(seed: int):
    """The TPE sampler every search uses (module docstring). It reads the constraints a search
    sets on a trial before telling it (``trial.set_constraint``: feasible where every value is
    <= 0) and models the infeasible trials apart."""
    import optuna
    return optuna.samplers.TPESampler(seed=seed, n_startup_trials=STARTUP_TRIALS, constant_liar=True,
                                      multivariate=True)


def median_pruner():
    import optuna
    return optuna.pruners.MedianPruner(n_startup_trials=PRUNE_STARTUP_TRIALS, n_warmup_steps=PRUNE_WARMUP_STEPS)


def open_study(store, name: str, directions, seed: int, pruner=None, fresh_file: Path | None = None):
    """The study ``name`` in ``store`` (a URL or a storage), made if absent, else loaded to be
    continued. ``directions``: one ("minimize" / "maximize") or several (a Pareto front).
    ``fresh_file``: an SQLite file deleted first (a search started afresh)."""
    import optuna
    quiet_optuna()
    if fresh_file is not None and Path(fresh_file).exists():
        Path(fresh_file).unlink()
    if isinstance(store, str):
        store = storage(store)
    dirs = [directions] if isinstance(directions, str) else list(directions)
    kw = {"direction": dirs[0]} if len(dirs) == 1 else {"directions": dirs}
    return optuna.create_study(study_name=name, storage=store, sampler=sampler(seed),
                               pruner=pruner or optuna.pruners.NopPruner(), load_if_exists=True, **kw)


def existing(store, name: str):
    """The stored study ``name``, or None if ``store`` has none of that name."""
    import optuna
    quiet_optuna()
    if isinstance(store, str):
        store = storage(store)
    try:
        return optuna.load_study(study_name=name, storage=store)
    except KeyError:
        return None


def check_key(study, key: dict, what: str, where: str, hint: str) -> None:
    """ScenarioError at ``where`` when ``study`` was made for another ``key`` (naming what differs)."""
    stored = study.user_attrs.get("key")
    if stored is None or stored == key:
        return
    diff = [k for k in key if stored.get(k) != key[k]] or [k for k in stored if k not in key]
    raise ScenarioError(where, "(a stored study)",
                        f"holds a {what} with another {', '.join(diff)} "
                        f"({', '.join(f'{k} = {stored.get(k)!r}' for k in diff)}); {hint}")


def close_unfinished(study) -> None:
    """Trials an interrupted run left running or waiting are failed (they are asked again)."""
    from optuna.trial import TrialState
    for t in study.trials:
        if t.state in (TrialState.RUNNING, TrialState.WAITING):
            study._storage.set_trial_state_values(t._trial_id, TrialState.FAIL)


def count(study, states=("COMPLETE",)) -> int:
    """Trials of ``study`` in one of ``states`` (TrialState names)."""
    return sum(t.state.name in states for t in study.get_trials(deepcopy=False))


def run_batches(study, total: int, workers: int, ask, evaluate, tell, done=None, after_batch=None,
                stop=None) -> int:
    """Run trials until ``done()`` (default: complete trials) reaches ``total``: ``workers`` at a
    time, ``ask(study) -> (trial, job)``, ``evaluate(trial, job) -> outcome`` on a thread pool,
    then ``tell(trial, outcome)`` for each in the order asked; ``after_batch()`` after each batch;
    no new batch once ``stop()`` is true (a time limit). Returns the trials run."""
    done = done or (lambda: count(study))
    ran = 0
    with ThreadPoolExecutor(workers) as pool:
        while done() < total and not (stop is not None and stop()):
            batch = [ask(study) for _ in range(min(workers, total - done()))]
            outcomes = list(pool.map(lambda tj: evaluate(*tj), batch))
            for (trial, _), outcome in zip(batch, outcomes):
                tell(trial, outcome)
            ran += len(batch)
            if after_batch is not None:
                after_batch()
    return ran


class Progress:
    """A bar on stderr over a search's trials, the best so far beside it (nothing when not
    ``shown``): ``update(done, best_text)``; ``close()``."""

    def __init__(self, total: int, start: int, label: str, shown: bool = True):
        self.bar = None
        if shown:
            from tqdm import tqdm
            self.bar = tqdm(total=total, initial=start, file=sys.stderr, desc=label, unit="trial",
                            dynamic_ncols=True, leave=True,
                            bar_format="{desc}: {n_fmt}/{total_fmt} trials |{bar}| [{elapsed}<{remaining}]{postfix}")

    def update(self, done: int, best: str = "") -> None:
        if self.bar is None:
            return
        if best:
            self.bar.set_postfix_str(best, refresh=False)
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def finite_or_nan(x) -> float:
    return float(x) if x is not None and math.isfinite(float(x)) else math.nan
