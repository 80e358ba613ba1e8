"""The board's log carries every valve command it issued (format 3): each record's valve history
per muscle (two bits a sample, 1 charge, 2 vent, 0 hold, the newest sample in the lowest bits)
read back into the commands of every sample, checked, written as commands.csv, and replayed by
`frogsim fit` open loop.

Every expected value comes from the command sequence each test makes up and encodes here (the
encoding is the one docs/firmware.md states), not from the reader's output. The older format 2
still reads; a format-2 log against a format-3 firmware.json is refused by name."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

import frogsim
from frogsim.cli import main
from frogsim.errors import ScenarioError
from frogsim.export.serial_log import commands, commands_missing, commands_table, parse_log

from test_serial_log import DIGEST, REC as REC2, UPC, OFFSET, lines  # noqa: F401

REC = REC2 | {"format": 3, "history_samples": 10}
HEADER = b"# frogsim stub rate=1000 channels=hip pressure@A0 muscles=hip log_every=10 format=3 plan=0123456789ab\n"
BITS = {1: 1, -1: 2, 0: 0}


def encode(modes: np.ndarray, every: int = 10, count: int = 300) -> bytes:
    """The records a board makes from a command a sample (modes[k]: 1, 0, -1), one every ``every``."""
    out = []
    for k in range(0, len(modes), every):
        h = 0
        for i in range(min(every, k + 1)):
            h |= BITS[int(modes[k - i])] << (2 * i)
        out.append((k, count, BITS[int(modes[k])], 0, 0, 0, h))
    return lines(*out)


def made_up(n: int = 201, seed: int = 0) -> np.ndarray:
    """A bang-bang-like command sequence: runs of 1..5 samples of a random mode."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        out += [int(rng.integers(-1, 2))] * int(rng.integers(1, 6))
    return np.array(out[:n])


def test_every_command_comes_back_from_a_tenth_of_the_samples():
    modes = made_up()
    log = parse_log(HEADER + encode(modes), REC)
    assert log.bad == 0 and len(log.records) == 21
    k, got = commands(log, REC)
    assert np.array_equal(k, np.arange(201)) and np.array_equal(got[:, 0], modes)
    # the valve bits alone (what format 2 logs) see only every tenth: most switchings are missed
    switchings = int(np.sum(modes[1:] != modes[:-1]))
    seen = int(np.sum(modes[10::10] != modes[:-10:10]))
    assert switchings > 2 * seen


def test_commands_csv_has_a_row_per_change():
    modes = made_up(seed=3)
    tab = commands_table(parse_log(HEADER + encode(modes), REC), REC)
    assert list(tab.columns) == ["time [s]", "hip command [1 = charge, 0 = hold, -1 = vent]"]
    changes = 1 + int(np.sum(modes[1:] != modes[:-1]))
    last_is_change = modes[-1] != modes[-2]
    assert len(tab) == changes + (0 if last_is_change else 1)
    # holding each row's command until the next row gives the sequence back
    t = tab["time [s]"].to_numpy()
    idx = np.searchsorted(np.rint(t * 1000).astype(int), np.arange(201), side="right") - 1
    assert np.array_equal(tab.iloc[:, 1].to_numpy()[idx], modes)


@pytest.mark.parametrize("record, reason", [
    ((10, 300, 1, 0, 0, 0, 4 ** 10), "history_out_of_range"),           # beyond 10 samples
    ((10, 300, 1, 0, 0, 0, 1 | (3 << 4)), "history_out_of_range"),      # both valves open at k - 2
    ((10, 300, 1, 0, 0, 0, 2), "history_disagrees"),                    # newest: vent; valve bits: charge
    ((10, 300, 1, 0, 0, 0), "field_count"),                             # a format-2 record
])
def test_a_bad_history_is_discarded_by_its_reason(record, reason):
    log = parse_log(HEADER + lines((0, 300, 1, 0, 0, 0, 1), record), REC)
    assert log.discarded == {reason: 1} and len(log.records) == 1


def test_a_log_with_a_gap_does_not_claim_every_command():
    modes = made_up()
    data = encode(modes).split(b"\n")
    del data[5]                                      # record k = 50 lost
    log = parse_log(HEADER + b"\n".join(data), REC)
    why = commands_missing(log, REC)
    assert why is not None and "1 record(s) missing" in why
    with pytest.raises(ScenarioError, match="missing"):
        commands(log, REC)


def test_a_format_2_log_still_reads_but_carries_no_commands():
    from test_serial_log import HEADER as HEADER2
    log = parse_log(HEADER2 + lines((0, 300, 1, 0, 0, 0), (10, 300, 0, 0, 0, 0)), REC2)
    assert len(log.records) == 2 and log.bad == 0
    assert "format 2" in commands_missing(log, REC2)


def test_a_format_2_log_against_a_format_3_plan_is_refused_by_name():
    from test_serial_log import HEADER as HEADER2
    with pytest.raises(ScenarioError, match="format") as e:
        parse_log(HEADER2 + lines((0, 300, 1, 0, 0, 0)), REC)
    assert "'2'" in str(e.value) or "= 2" in str(e.value)


def test_the_history_is_as_long_as_the_plan_says(tmp_path):
    """firmware.json's history_samples is log_every up to 16; above, 0: the records have no history
    fields (a uint32 holds 16 samples: such a log could not carry every command) and the log says
    it carries no commands; another value is refused."""
    from frogsim.export.serial_log import spec_of
    with pytest.raises(ScenarioError, match="history_samples"):
        spec_of(REC | {"history_samples": 9})
    rec40 = REC | {"log_every": 40, "history_samples": 0}
    assert spec_of(rec40).history == 0 and spec_of(rec40).width == 6
    with pytest.raises(ScenarioError, match="history_samples"):
        spec_of(REC | {"log_every": 40, "history_samples": 16})
    log = parse_log(HEADER.replace(b"log_every=10", b"log_every=40") + lines((0, 300, 1, 0, 0, 0), (40, 300, 1, 0, 0, 0)),
                    rec40)
    assert len(log.records) == 2 and log.bad == 0
    assert "16 samples at most" in commands_missing(log, rec40)


def _replay_files(tmp_path, modes):
    """A scenario of one hip muscle fed from a 4 L source and a commands.csv of ``modes``."""
    sc = tmp_path / "rig.toml"
    sc.write_text('name = "rig"\nparameters = "fan2017"\nduration = "0.2 s"\noutput_interval = "1 ms"\n'
                  '[controller]\nrate = "1 kHz"\n[supply]\nmode = "none"\n'
                  '[muscles.hip]\ntype = "hip"\nmotion = { kind = "constant" }\n'
                  '[controllers.hold]\nkind = "bang-bang"\nmuscle = "hip"\n'
                  'setpoint = { kind = "constant", value = "3 bar" }\nband = "0.1 bar"\n')
    tab = commands_table(parse_log(HEADER + encode(modes), REC), REC)
    tab.to_csv(tmp_path / "commands.csv", index=False)
    return sc


def test_the_replay_runs_the_recorded_commands_through_the_dead_time(tmp_path):
    """The replayed scenario's valves: open where the command was charge, a dead time later
    (fan2017: 2 ms), whatever the controller would have done; the controller is gone."""
    from frogsim.fit.replay import replayed
    modes = made_up(seed=5)
    sc = replayed(frogsim.load_scenario(_replay_files(tmp_path, modes)), tmp_path / "commands.csv")
    assert sc.controllers == {} and sc.firmware is None
    r = frogsim.simulate(sc)
    dead = int(round(sc.valves.charge.dead_time * 1000))
    charge = r.to_dataframe()["hip_charge_valve"].to_numpy()
    # the valve state at t_k + dead + half a sample: the command of sample k
    assert np.array_equal(charge[dead + 1:201], (modes[:201 - dead - 1] == 1).astype(int)) or \
        np.array_equal(charge[dead:200], (modes[:200 - dead] == 1).astype(int))


def test_commands_are_checked(tmp_path):
    from frogsim.fit.replay import replayed
    sc = frogsim.load_scenario(_replay_files(tmp_path, made_up()))
    bad = tmp_path / "bad.csv"
    pd.DataFrame({"time [s]": [0.0, 0.01], "knee command [1 = charge, 0 = hold, -1 = vent]": [1, 0]}).to_csv(bad, index=False)
    with pytest.raises(ScenarioError, match="knee command"):
        replayed(sc, bad)
    pd.DataFrame({"time [s]": [0.0, 0.0105], "hip command [1 = charge, 0 = hold, -1 = vent]": [1, 0]}).to_csv(bad, index=False)
    with pytest.raises(ScenarioError, match="sample grid"):
        replayed(sc, bad)
    pd.DataFrame({"time [s]": [0.0, 0.01], "hip command [1 = charge, 0 = hold, -1 = vent]": [1, 2]}).to_csv(bad, index=False)
    with pytest.raises(ScenarioError, match="must be -1"):
        replayed(sc, bad)


def test_a_command_delay_without_commands_is_refused(tmp_path, capsys):
    sc = _replay_files(tmp_path, made_up())
    r = frogsim.simulate(frogsim.load_scenario(sc))
    import pandas as pd_
    pd_.DataFrame({"time [s]": r.t, "hip pressure [bar gauge]": (r.muscle_pressure("hip") - 101325.0) / 1e5}).to_csv(tmp_path / "t.csv", index=False)
    (tmp_path / "FIT.toml").write_text('scenario = "rig.toml"\n[[experiments]]\ntrace = "t.csv"\n'
                                       'command_delay = "0.1 ms"\n[parameters]\n'
                                       '"valves.charge.critical_ratio" = { min = "0.1", max = "0.6" }\n')
    assert main(["fit", str(tmp_path / "FIT.toml"), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "command_delay" in err[0] and "needs commands" in err[0]
    assert not (tmp_path / "o").exists()
