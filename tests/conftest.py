"""Shared helpers for the frogsim tests: air constants and small scenario dicts.

The constants below are the paper's and the ISO reference values, written out here on purpose
(not read from frogsim) so that the tests compare the code against independent numbers.
"""
from __future__ import annotations

import copy
import math
import tomllib

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
def study():
    """study(name) -> StudyData, each registered study computed once per test session (the paper
    and design tests and the README check share the runs)."""
    from frogsim.studies import run_study
    cache = {}

    def get(name):
        if name not in cache:
            cache[name] = run_study(name)
        return cache[name]
    return get
