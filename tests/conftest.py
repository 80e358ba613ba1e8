"""Shared helpers for the frogsim tests: air constants and small scenario dicts.

The constants below are the paper's and the ISO reference values, written out here on purpose
(not read from frogsim) so that the tests compare the code against independent numbers.
"""
from __future__ import annotations

import copy
import math
import os
import pickle
import tomllib

try:
    import fcntl
except ImportError:                   # no flock: each xdist worker computes its own
    fcntl = None

import pytest

# paper Eq. (2): R = 287 J/(kg K), k = 1.4
R_AIR = 287.0
K_AIR = 1.4
# ISO 8778 / ISO 6358 standard reference atmosphere (ANR): 100 kPa, 293.15 K
P_REF = 1.0e5
T_REF = 293.15
RHO_REF = P_REF / (R_AIR * T_REF)          # ideal gas: rho = p/(R T)
# standard atmosphere
P_ATM = 101325.0
# paper Sec. 3.3: FESTO MHJ9-LF, C = 0.4 L/(s bar) = 0.4e-3 m^3 / (s * 1e5 Pa), b = 0.38
C_MHJ9 = 0.4e-3 / 1.0e5
B_MHJ9 = 0.38
# paper Sec. 4.1: source pressurised to 6 bar (gauge)
P_SOURCE0 = P_ATM + 6.0e5
# paper Sec. 4 / Eq. (9): 4 mm main-pipe bore, one pipe, six branches
MAIN_BORE = 4.0e-3
N_BRANCHES = 6
# speed of sound sqrt(k R T) at 293.15 K = 343.2 m/s (paper's Eq. (9) velocity, fan2017.toml)
SONIC_VELOCITY = math.sqrt(K_AIR * R_AIR * T_REF)


def steps(*pairs) -> dict:
    """A program table from (time_s, state) pairs, e.g. steps((0, "charge"), (1, "vent"))."""
    return {"steps": [{"at": f"{t!r} s", "state": s} for t, s in pairs]}


def one_muscle_scenario(program: dict, duration: float, *, muscle_type: str = "hip",
                        motion: dict | None = None, output_interval: str = "1 ms",
                        n_muscles: int = 1, **sections) -> dict:
    """A scenario dict over the fan2017 parameter set with n identical muscles named m0, m1, ...

    ``sections`` are laid over the parameter set (e.g. source={"volume": "1000 L"},
    supply={"mode": "none"}, solver={"rtol": 1e-10}).
    """
    d = {
        "name": "test",
        "parameters": "fan2017",
        "duration": f"{duration!r} s",
        "output_interval": output_interval,
        "controller": {"rate": "1 kHz"},
        "muscles": {
            f"m{i}": {"type": muscle_type, "program": copy.deepcopy(program),
                      "motion": copy.deepcopy(motion or {"kind": "constant"})}
            for i in range(n_muscles)
        },
    }
    d.update(copy.deepcopy(sections))
    return d


def paper_cycle_dict() -> dict:
    """The shipped paper-cycle scenario as a raw dict (to be modified by a test)."""
    from frogsim.scenario.load import SCENARIOS_DIR
    with open(SCENARIOS_DIR / "paper-cycle.toml", "rb") as fh:
        return tomllib.load(fh)


@pytest.fixture
def paper_cycle_raw() -> dict:
    return paper_cycle_dict()


@pytest.fixture(scope="session")
def study(tmp_path_factory):
    """study(name) -> StudyData, each registered study computed once per test run (the paper and
    design tests, the figures and the README check share the runs): in one process, or across
    pytest-xdist's workers, where the first to need a study computes it and the others read it."""
    from frogsim.studies import run_study
    shared = _run_folder(tmp_path_factory, "studies")
    cache = {}

    def get(name):
        if name not in cache:
            cache[name] = run_study(name) if shared is None else _computed_once(shared, name, run_study)
        return cache[name]
    return get


def _run_folder(tmp_path_factory, name: str):
    """A folder every xdist worker of this test run sees (None without xdist, or without flock)."""
    uid = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    if uid is None or fcntl is None:
        return None
    folder = tmp_path_factory.getbasetemp().parent / f"{name}-{uid}"
    folder.mkdir(exist_ok=True)
    return folder


def _computed_once(folder, name: str, compute):
    """compute(name), pickled into folder by whichever worker gets there first; the others wait on
    its lock and read that."""
    path = folder / f"{name}.pickle"
    with open(folder / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if path.exists():
            return pickle.loads(path.read_bytes())
        data = compute(name)
        part = path.with_name(path.name + ".part")
        part.write_bytes(pickle.dumps(data))
        os.replace(part, path)
        return data


# --- CSV headers ----------------------------------------------------------------------------------
#: every unit a frogsim CSV may name in a header, as a reader of the file would decode it: SI and
#: display units, pressures gauge or abs, "std" the ISO 8778 standard state, "1 = open"-style 0/1
#: states, "-" a pure number, "period" a fraction of the gait period, "1/min" a rate
CSV_UNITS = {"s", "K", "m", "mm", "m/s", "N", "kg", "kg/s", "deg", "deg/s", "rad/s", "%", "cm^3", "L",
             "L/min", "L std", "L/min std", "bar gauge", "Pa abs", "L/(s bar)", "1/min", "-", "period",
             "m/L", "1 = open", "1 = on", "1 = yes",
             # tune's trials.csv: pressure differences, the gains in their declared units, rates
             "bar", "1/s", "bar/rad", "bar*s/rad", "bar/(rad*s)", "ms", "Hz"}
#: the unitless label columns frogsim documents (docs/metrics.md, "CSV columns")
CSV_LABELS = {"mode", "experiment", "controller", "valve", "joint", "trial", "state", "failure"}


def assert_unit_headers(path):
    """Check a CSV frogsim wrote: read by read_table, every header ``name [unit]`` in the one
    convention with a unit of CSV_UNITS and a column of numbers, or a label column; the table."""
    from frogsim.scenario.tables import read_table, split_header
    table = read_table(path, numbers=False)
    for col in table.columns:
        name, unit = split_header(col)
        if col in CSV_LABELS:
            assert unit == "", col
            continue
        assert col == f"{name} [{unit}]", f"{path.name}: {col!r} is not written as 'name [unit]'"
        assert unit in CSV_UNITS, f"{path.name}: {col!r} has an unknown unit {unit!r}"
        assert table[col].dtype.kind == "f", f"{path.name}: {col!r} holds text"
    return table


# --- the order the test files are handed to pytest-xdist's workers --------------------------------
#: the test files that take longest, longest first (each run on its own, `python3 -m pytest
#: tests/FILE`, by CPU time; every other file takes under 20 s). `--dist loadfile` hands a worker
#: the next whole file when it runs short of work; pytest-xdist's own order puts the files with
#: the most tests first, which leaves long files of few tests (a fuzzer, a compilation from scratch,
#: a killed sweep) for the end, where one worker runs them while the other has nothing left. Handed
#: out longest first, the short files come last and fill in. A file missing here only runs later.
LONGEST_FIRST = (
    "test_doc_blocks.py", "test_optimize_gait.py", "test_firmware_laws.py", "test_controller_kinds.py",
    "test_warmup.py", "test_firmware_e2e.py", "test_firmware_numbers.py", "test_figure_layout.py",
    "test_studies.py", "test_cli_rules.py", "test_sweep_run.py", "test_sweep_resume.py",
    "test_firmware_faults.py", "test_firmware_encoders.py", "test_control.py", "test_progress.py",
    "test_cli.py", "test_fuzz.py", "test_outputs.py", "test_firmware_laws_avr.py", "test_fit_force.py",
    "test_swim_cli.py", "test_csv_headers.py", "test_tables.py", "test_output_grid.py",
)


def pytest_configure(config):
    # keep the collection's order of files (below) rather than xdist's reordering by test count
    if getattr(config.option, "loadscopereorder", None) is not None:
        config.option.loadscopereorder = False


def pytest_collection_modifyitems(config, items):
    """The files in LONGEST_FIRST's order, then the others, most tests first (as xdist would have
    them); each file's tests keep their order."""
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    count: dict = {}
    for item in items:
        count[item.path] = count.get(item.path, 0) + 1
    position = {id(item): k for k, item in enumerate(items)}
    items.sort(key=lambda item: (rank.get(item.path.name, len(rank)), -count[item.path], position[id(item)]))
