"""One layout of the flat arrays: where every volume's and muscle's state lives, every valve's entry
of the valve vector u (and of the right-hand side's flows aux and an output row), every field of
the right-hand side's scratch work, every law's block and queue in the controllers' state cs, and
every record column of the coupled engine, is said in the layout modules only
(frogsim.circuit.layout, frogsim.control.signals, frogsim.engine.coupled_layout), and what they
say matches the physics.

The source scan reads every module of the package (as tests/test_layers.py does) and fails where one
outside the layout modules names the raw offsets (the first muscle's block, the record's variable
part, the block width, the controllers' blocks and queues) or indexes a state, valve, flow, scratch or
record array with arithmetic on a variable (``y[j + 1]``, ``u[2 * i + 1]``, ``work[n + i]``,
``rr[c + n + i]``): those offsets belong to the layout's index functions. A test plants such offsets
in a copy of the package and checks the scan finds each. (``y[k - 1]``, a series' row before k,
is not an offset.)
"""
from __future__ import annotations

import ast
import functools
import shutil
from pathlib import Path

import numpy as np
import pytest

import frogsim
from frogsim.circuit import layout as L
from frogsim.engine import coupled_layout as C

from conftest import P_ATM, R_AIR

PACKAGE = Path(__file__).resolve().parent.parent / "src" / "frogsim"
LAYOUT_MODULES = ("circuit/layout.py", "engine/coupled_layout.py", "control/signals.py")
#: names only the layout modules may use: raw starts of variable blocks and block widths
RAW_OFFSETS = {"Y_MUSCLE0", "R_FIXED", "MUSCLE_WIDTH", "CS_SIZE", "B_Q0"}
#: names under which the package holds state vectors, state histories and record rows
STATE_ARRAYS = {"y", "y0", "y_end", "yn", "yt", "ys", "dydt", "out_y", "oy", "atol", "scale", "rec", "rr", "Y"}
#: ... valve vectors (and their histories, schedules, dead times), the right-hand side's flows and
#: its scratch
VALVE_ARRAYS = {"u", "u0", "u_prev", "u_cmd", "out_u", "ou", "sched_u", "valves", "dead", "aux", "flows", "work",
                "_diagnostics"}
INDEXED = STATE_ARRAYS | VALVE_ARRAYS
#: the layout's fixed columns: a constant one plus a variable is a hand-made offset too
FIXED_COLUMNS = {n for n in vars(L) if n.startswith("Y_")} | {n for n in vars(C) if n.startswith("R_")}


def _name(node) -> str | None:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return node.attr
    return None


def _constant(node) -> bool:
    """A literal or an ALL_CAPS name (a compile-time constant), or arithmetic on those only."""
    if isinstance(node, ast.Constant):
        return True
    name = _name(node)
    if name is not None:
        return name.isupper() or name.lstrip("_").isupper()
    if isinstance(node, ast.BinOp):
        return _constant(node.left) and _constant(node.right)
    if isinstance(node, ast.UnaryOp):
        return _constant(node.operand)
    return False


def _array_name(node) -> str | None:
    """The name of the array a subscript indexes: ``u`` of ``u[j]``, ``self.u[k, j]`` and
    ``self._diagnostics[0][:, j]`` alike."""
    while isinstance(node, ast.Subscript):
        node = node.value
    return _name(node)


def _row_before(node) -> bool:
    """``k - 1``: the row before k in a series, not a column offset."""
    return isinstance(node.op, ast.Sub) and isinstance(node.left, ast.Name) and _constant(node.right)


def offset_violations(root: Path) -> list[str]:
    """``file:line: text`` of every hand-made state or record offset outside the layout modules."""
    bad = []
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        if rel not in LAYOUT_MODULES:
            bad.extend(_file_violations(rel, path.read_text()))
    return bad


@functools.lru_cache(maxsize=None)
def _file_violations(rel: str, text: str) -> tuple[str, ...]:
    """One module's offsets (a function of its path and text alone: a file read again unchanged,
    in the package or a copy of it, is not parsed again)."""
    bad = []
    for node in ast.walk(ast.parse(text)):
        hit = False
        if _name(node) in RAW_OFFSETS and not isinstance(node, ast.alias):
            hit = True
        elif isinstance(node, ast.alias) and node.name in RAW_OFFSETS:
            hit = True
        elif isinstance(node, ast.Subscript) and _array_name(node.value) in INDEXED:
            hit = any(isinstance(s, ast.BinOp) and not _constant(s) and not _row_before(s)
                      for s in ast.walk(node.slice))
        elif isinstance(node, ast.BinOp) and not _constant(node):
            hit = any(_name(side) in FIXED_COLUMNS for side in (node.left, node.right))
        if hit:
            bad.append(f"{rel}:{node.lineno}: {ast.get_source_segment(text, node)}")
    return tuple(bad)


def test_no_module_outside_the_layout_computes_an_offset():
    bad = offset_violations(PACKAGE)
    assert not bad, "offsets computed outside the layout modules (use the index functions of " \
                    "frogsim.circuit.layout / frogsim.control.signals / frogsim.engine.coupled_layout): " + \
                    "; ".join(bad)


@pytest.mark.parametrize("planted", [
    "from frogsim.circuit.layout import Y_MUSCLE0\n",
    "def f(y, i):\n    return y[L.Y_MUSCLE0 + 2 * i + 1]\n",
    "def f(y, i):\n    j = 4 + 2 * i\n    return y[j + 1]\n",
    "def f(rr, n, i, x):\n    rr[c + n + i] = x\n",
    "def f(y, i):\n    return y[:, L.Y_PS + i]\n",
    "def f(n):\n    return C.R_FIXED + 2 * n\n",
    "def f(u, i):\n    return u[2 * i + 1]\n",
    "def f(r, i):\n    return r.u[:, 2 * i]\n",
    "def f(self, i):\n    return self._diagnostics[0][:, 2 * i + 1]\n",
    "def f(aux, n, x):\n    aux[2 * n] = x\n",
    "def f(work, n, i):\n    return work[2 * n + i]\n",
    "def f(sched_u, i):\n    sched_u[:, 2 * i:2 * i + 2] = 0.0\n",
    "def f(cs, c):\n    return cs[int(S.CS_SIZE + c * cs[3])]\n",
    "from frogsim.control.signals import B_Q0\n",
])
def test_the_scan_finds_a_planted_offset(package_copy, planted):
    target = package_copy / "engine" / "result.py"
    clean = target.read_text()
    target.write_text(clean + "\n\n" + planted)
    try:
        found = offset_violations(package_copy)
    finally:
        target.write_text(clean)
    assert found and all(f.startswith("engine/result.py:") for f in found)


@pytest.fixture(scope="module")
def package_copy(tmp_path_factory):
    """One copy of the package for the planted offsets, clean as the package is; each test plants
    its offset in it and puts the file back."""
    copy = tmp_path_factory.mktemp("package") / "frogsim"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    assert offset_violations(copy) == []
    yield copy
    assert offset_violations(copy) == []          # every plant was taken out again


def test_labels_follow_the_documented_order():
    names = ["a", "b", "c"]
    labels = L.state_labels(names)
    n = len(names)
    assert len(labels) == L.state_size(n) == 4 + 4 * n + 1         # 4 chamber entries, 2 + 2 per muscle, pump
    assert [lab for lab, _ in labels[:4]] == ["source mass", "source pressure", "exhaust mass", "exhaust pressure"]
    assert [lab for lab, _ in labels[4:4 + 2 * n]] == ["a mass", "a pressure", "b mass", "b pressure",
                                                       "c mass", "c pressure"]
    assert [lab for lab, _ in labels[4 + 2 * n:]] == ["a charged mass", "b charged mass", "c charged mass",
                                                      "a vented mass", "b vented mass", "c vented mass",
                                                      "pumped mass"]
    for i, name in enumerate(names):
        assert labels[L.mass_index(i)] == (f"{name} mass", "kg")
        assert labels[L.pressure_index(i)] == (f"{name} pressure", "Pa abs")
        assert labels[L.charged_index(i, n)][0] == f"{name} charged mass"
        assert labels[L.vented_index(i, n)][0] == f"{name} vented mass"
    assert labels[L.pump_index(n)][0] == "pumped mass"
    assert L.physical_size(n) == 4 + 2 * n and L.muscle_count(L.state_size(n)) == n
    y = np.arange(L.state_size(n))
    assert list(y[L.mass_slice(n)]) == [L.mass_index(i) for i in range(n)]
    assert list(y[L.pressure_slice(n)]) == [L.pressure_index(i) for i in range(n)]
    assert list(y[L.charged_slice(n)]) == [L.charged_index(i, n) for i in range(n)]


@pytest.fixture(scope="module")
def pumped_run():
    """The paper's six muscles through one cycle, one muscle started at 1 bar gauge, with the pump
    on (it refills the source below 5.5 bar gauge)."""
    sc = frogsim.load_scenario("paper-cycle").replace({"pump.enabled": True,
                                                       "muscles.knee_left.initial_pressure_gauge": 1e5})
    return sc, frogsim.simulate(sc)


def test_initial_state_is_ideal_gas_at_ambient_temperature(pumped_run):
    """At t = 0 each volume holds m = p V/(R T) at the ambient 293.15 K, with the pressures the
    scenario gives (6 bar gauge source, atmospheric exhaust and muscles, 1 bar gauge knee_left)."""
    sc, r = pumped_run
    y0 = r.y[0]
    n = r.n
    T = 293.15
    assert y0[L.Y_PS] == pytest.approx(P_ATM + 6e5, rel=1e-12)
    assert y0[L.Y_PE] == pytest.approx(P_ATM, rel=1e-12)
    assert y0[L.Y_MS] == pytest.approx((P_ATM + 6e5) * 4e-3 / (R_AIR * T), rel=1e-12)     # 4 L source
    assert y0[L.Y_ME] == pytest.approx(P_ATM * 6e-3 / (R_AIR * T), rel=1e-12)             # 6 L exhaust
    for i, name in enumerate(r.names):
        p0 = P_ATM + (1e5 if name == "knee_left" else 0.0)
        assert y0[L.pressure_index(i)] == pytest.approx(p0, rel=1e-12)
        assert y0[L.mass_index(i)] == pytest.approx(p0 * r.volumes[0, i] / (R_AIR * T), rel=1e-12)
        assert y0[L.charged_index(i, n)] == 0.0 and y0[L.vented_index(i, n)] == 0.0
    assert y0[L.pump_index(n)] == 0.0


def test_cumulative_masses_balance_each_volume(pumped_run):
    """Mass balance of every volume, from the counters alone: a muscle gains what it was charged less
    what it vented, the source what the pump moved less all charges, the exhaust all vents less what
    the pump moved (each step moves mass between volumes, so these hold to rounding)."""
    _, r = pumped_run
    y, n = r.y, r.n
    Q = np.stack([y[:, L.charged_index(i, n)] for i in range(n)], axis=1)
    D = np.stack([y[:, L.vented_index(i, n)] for i in range(n)], axis=1)
    P = y[:, L.pump_index(n)]
    assert P[-1] > 1e-4                 # the pump ran (> 0.1 g), so its column is tested
    assert Q[-1].max() > 1e-4 and D[-1].max() > 1e-4
    scale = y[0, L.Y_MS]
    for i in range(n):
        m = y[:, L.mass_index(i)]
        assert np.abs(m - m[0] - (Q[:, i] - D[:, i])).max() < 1e-9 * scale
    assert np.abs(y[:, L.Y_MS] - y[0, L.Y_MS] - (P - Q.sum(axis=1))).max() < 1e-9 * scale
    assert np.abs(y[:, L.Y_ME] - y[0, L.Y_ME] - (D.sum(axis=1) - P)).max() < 1e-9 * scale


def test_record_blocks_tile_the_row_and_agree_with_the_fixed_columns():
    """The record's blocks cover the columns after the fixed ones once each; in a run the muscles'
    charged masses sum to the total the kernel keeps separately, each muscle starts at the
    atmospheric pressure the scenario gives, and the leg joints' angles are MuJoCo positions."""
    n, npal, nj, nq = 5, 2, 6, 19
    cols = C.record_columns(n, npal, nj, nq)
    widths = {"pressure": n, "length": n, "tension": n, "charged": n, "valves": 2 * n, "palm": npal,
              "angle": nj, "omega": nj, "qpos": nq}
    taken = np.zeros(cols["size"], int)
    for name, w in widths.items():
        s = cols[name]
        assert s.stop - s.start == w
        taken[s] += 1
    assert (taken[:C.R_PUMP_ON + 1] == 0).all() and (taken[C.R_PUMP_ON + 1:] == 1).all()
    run = frogsim.swim("swim", cycles=1)
    rec, cm = run.rec, run.model
    cols = cm.columns
    assert rec.shape[1] == cols["size"]
    assert rec[:, cols["charged"]].sum(axis=1) == pytest.approx(rec[:, C.R_CHARGED], rel=1e-12, abs=1e-15)
    assert rec[-1, C.R_CHARGED] > 0
    assert rec[0, cols["pressure"]] == pytest.approx(np.full(len(cm.muscle_names), P_ATM), rel=1e-12)
    qpos = rec[:, cols["qpos"]]
    leg_qpos = cm.arrays["leg_qpos"]
    assert np.array_equal(rec[:, cols["angle"]], qpos[:, leg_qpos])


# --- the valve vector, the flows aux and the scratch work ---------------------------------------------
def test_valve_offsets_tile_the_vector_and_aux():
    n = 4
    entries = sorted([L.charge_valve(i) for i in range(n)] + [L.vent_valve(i) for i in range(n)])
    assert entries == list(range(L.valve_size(n))) == list(range(2 * n))      # two paths per muscle
    assert L.pump_entry(n) == L.valve_size(n) and L.flows_size(n) == 2 * n + 1   # then the pump
    u = np.arange(L.valve_size(n))
    assert list(u[L.charge_slice(n)]) == [L.charge_valve(i) for i in range(n)]
    assert list(u[L.vent_slice(n)]) == [L.vent_valve(i) for i in range(n)]
    assert list(u[L.muscle_valve_slice(2)]) == [L.charge_valve(2), L.vent_valve(2)]
    dead = L.per_valve(n, 2e-3, 5e-3)
    assert (dead[L.charge_slice(n)] == 2e-3).all() and (dead[L.vent_slice(n)] == 5e-3).all()
    blocks = sorted(L.work_index(f, i, n) for f in (L.WORK_T, L.WORK_V, L.WORK_DV, L.WORK_L) for i in range(n))
    assert blocks == list(range(L.work_size(n))) == list(range(4 * n))


def test_rhs_fills_its_scratch_and_flows_where_the_layout_says():
    """One call of the right-hand side at t = 0 of the paper's cycle, knee_left at 1 bar gauge: every
    muscle at its rest length (the datasheet's 180 mm hip, 150 mm knee and ankle), its volume the
    DMSP-20's cylinder pi D0^2 L0 / 4 (Eq. (5) at rest) plus the 5 cm^3 of fittings, at rest
    (dV/dt = 0 before the contraction starts at 0.1 s), its air at the ambient 293.15 K. With every
    charge path open and the vent paths shut, air flows into the muscles at atmospheric pressure only
    through the charge entries of aux; with knee_left's vent path open instead, out of it only."""
    from frogsim.circuit.rhs import rhs
    sc = frogsim.load_scenario("paper-cycle").replace({"muscles.knee_left.initial_pressure_gauge": 1e5})
    m = frogsim.build_model(sc)
    n = m.n
    y = m.y0.copy()
    rest = {"hip": 0.180, "knee": 0.150, "ankle": 0.150}
    work, aux, dydt = np.full(L.work_size(n), np.nan), np.full(L.flows_size(n), np.nan), np.empty(y.size)
    u = np.zeros(L.valve_size(n))
    u[L.charge_slice(n)] = 1.0
    rhs(0.0, y, u, 0.0, *m.rhs_model, dydt, aux, work)
    for i, name in enumerate(m.names):
        L0 = rest[name.split("_")[0]]
        assert work[L.work_index(L.WORK_L, i, n)] == pytest.approx(L0, rel=1e-12)
        assert work[L.work_index(L.WORK_V, i, n)] == pytest.approx(np.pi * 0.020 ** 2 * L0 / 4 + 5e-6, rel=1e-9)
        assert work[L.work_index(L.WORK_DV, i, n)] == 0.0
        assert work[L.work_index(L.WORK_T, i, n)] == pytest.approx(293.15, rel=1e-12)
        assert aux[L.charge_valve(i)] > 1e-4             # choked from 6 bar gauge: grams per second
        assert aux[L.vent_valve(i)] == 0.0
        assert dydt[L.charged_index(i, n)] == aux[L.charge_valve(i)]
    assert aux[L.pump_entry(n)] == 0.0
    knee = m.names.index("knee_left")
    u[:] = 0.0
    u[L.vent_valve(knee)] = 1.0
    rhs(0.0, y, u, 0.0, *m.rhs_model, dydt, aux, work)
    assert aux[L.vent_valve(knee)] > 1e-4 and dydt[L.vented_index(knee, n)] == aux[L.vent_valve(knee)]
    assert np.count_nonzero(aux) == 1


def test_a_runs_valve_columns_and_flows_follow_the_paper_cycle():
    """paper-cycle opens every charge valve for 1 s, then every discharge valve for 1 s (each 2 ms
    after its command): the output's valve columns say so, and each path's flow, integrated over its
    second, is the mass the state's counters say went through it (the first second: nothing vented)."""
    r = frogsim.simulate(frogsim.load_scenario("paper-cycle"))
    n = r.n
    t = r.t
    mid1, mid2 = np.searchsorted(t, 0.5), np.searchsorted(t, 1.5)
    first, second = (t >= 0.0) & (t <= 1.0), (t >= 1.0) & (t <= 2.0)
    for i, name in enumerate(r.names):
        assert r.u[mid1, L.charge_valve(i)] == 1.0 and r.u[mid1, L.vent_valve(i)] == 0.0
        assert r.u[mid2, L.charge_valve(i)] == 0.0 and r.u[mid2, L.vent_valve(i)] == 1.0
        k1 = np.searchsorted(t, 1.0)
        charged = np.trapezoid(r.charge_flow(name)[first], t[first])
        assert charged == pytest.approx(r.y[k1, L.charged_index(i, n)], rel=1e-2)
        assert r.y[k1, L.vented_index(i, n)] == 0.0
        vented = np.trapezoid(r.discharge_flow(name)[second], t[second])
        assert vented == pytest.approx(r.y[-1, L.vented_index(i, n)], rel=1e-2)
    assert (r.u[:, L.pump_entry(n)] == 0.0).all()           # paper-cycle's pump is off
