"""The board's log of valve events (format 4): where the fixed valve histories do not fit (a record
rarer than every 16 samples, or a line the baud rate cannot carry with them), each record carries
the switchings since the last one, ``events,lost,event_1,...``, each event 64 i + 4 j + c (muscle j's
command became c, 1 charge, 2 vent, 0 hold, at sample k - i), at most ``event_slots`` of them; a
switching that finds the slots full is counted in ``lost``. The reader turns the events back into
the commands of every sample (the same commands.csv as histories give), marks a record whose events
were lost as a gap, and a fit refuses to replay a gap.

Every expected value comes from the command sequences the tests make up and encode here with the
encoding docs/firmware.md states, or, on the emulated board, from the valve pins the firmware
drove (the emulator's pin events), never from the reader's output."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from frogsim.errors import ScenarioError
from frogsim.export.serial_log import commands, commands_gap, commands_table, parse_log, spec_of

from test_board_commands import REC as REC3, HEADER as HEADER3, encode as encode_histories, made_up
from test_serial_log import REC as REC2, lines

CODE = {1: 1, -1: 2, 0: 0}
REC = REC2 | {"format": 4, "log_every": 20, "event_slots": 8, "muscles": ["hip", "knee"],
              "valve_pins": [[22, 23], [24, 25]]}
HEADER = b"# frogsim stub rate=1000 channels=hip pressure@A0 muscles=hip;knee log_every=20 format=4 plan=0123456789ab\n"


def ev(i: int, j: int, mode: int) -> int:
    """docs/firmware.md: an event is 64 i + 4 j + c."""
    return 64 * i + 4 * j + CODE[int(mode)]


def encode(modes: np.ndarray, every: int = 20, slots: int = 8, count: int = 300) -> bytes:
    """The records a board makes from a command a sample and muscle (modes[k, j]: 1, 0, -1; every
    valve shut before sample 0): one every ``every`` samples, each with the switchings of its window
    (samples after the last record's up to its own), oldest first, muscles in order; those beyond
    ``slots`` counted as lost."""
    modes = np.asarray(modes).reshape(len(modes), -1)
    out, prev = [], np.zeros(modes.shape[1], int)
    for k in range(0, len(modes), every):
        events, lost = [], 0
        for s in range(max(0, k - every + 1), k + 1):
            for j in range(modes.shape[1]):
                if modes[s, j] != prev[j]:
                    prev[j] = modes[s, j]
                    if len(events) < slots:
                        events.append(ev(k - s, j, modes[s, j]))
                    else:
                        lost += 1
        bits = sum(CODE[int(modes[k, j])] << (2 * j) for j in range(modes.shape[1]))
        out.append((k, count, bits, 0, 0, 0, len(events), lost, *events))
    return lines(*out)


def two_muscles(n: int = 401, seed: int = 0) -> np.ndarray:
    return np.stack([made_up(n, seed), made_up(n, seed + 100)], axis=1)


def test_every_command_comes_back_from_the_switchings():
    modes = two_muscles()
    # runs of 1..5 samples: up to 8 slots is too few for some windows at 20 samples; 40 are enough
    log = parse_log(HEADER + encode(modes, slots=40), REC | {"event_slots": 40})
    assert log.bad == 0 and len(log.records) == 21 and log.events_lost == 0
    k, got = commands(log, REC | {"event_slots": 40})
    assert np.array_equal(k, np.arange(401)) and np.array_equal(got, modes)


def test_the_events_give_the_same_commands_csv_as_the_histories():
    """One muscle logged both ways every 10 samples: format 3's histories and format 4's events of
    the same commands read back into the same table."""
    modes = made_up(301, seed=7)
    rec4 = REC2 | {"format": 4, "log_every": 10, "event_slots": 10}
    header4 = HEADER3.replace(b"format=3", b"format=4")
    from_events = commands_table(parse_log(header4 + encode(modes, every=10, slots=10), rec4), rec4)
    from_histories = commands_table(parse_log(HEADER3 + encode_histories(modes), REC3), REC3)
    pd.testing.assert_frame_equal(from_events, from_histories)


def test_a_record_whose_slots_were_full_is_a_gap_named_by_its_record(tmp_path):
    modes = np.repeat(two_muscles(41), 10, axis=0)[:401]   # runs of 10..50 samples: at most 4 switchings in 20
    modes[200:220] = [[1, -1], [-1, 1]] * 10          # 40 switchings in the window of the record at 220
    log = parse_log(HEADER + encode(modes), REC)
    assert log.bad == 0 and log.events_lost > 0 and log.first_lost[0] == 220
    assert log.first_lost[1] > 0
    with pytest.raises(ScenarioError, match="k = 220"):
        commands(log, REC)
    assert "k = 220" in commands_gap(log, REC)
    tab = commands_table(log, REC)
    t = tab["time [s]"].to_numpy()
    gap = tab.iloc[:, 1].isna().to_numpy()
    assert gap.any() and np.allclose(t[gap][0], 0.201) and np.all(tab.iloc[:, 1:].isna().to_numpy()[gap])
    # outside the gaps each row's commands hold until the next row: the sequence made up
    ks = np.rint(t * 1000).astype(int)
    idx = np.searchsorted(ks, np.arange(401), side="right") - 1
    unknown = gap[idx]
    assert unknown.sum() >= 19                           # samples 201..219 at least
    for j in range(2):
        col = tab.iloc[:, 1 + j].to_numpy()[idx]
        assert np.array_equal(col[~unknown].astype(int), modes[~unknown, j])
    # the fit's replay refuses a gap, naming where it begins
    import frogsim
    from frogsim.fit.replay import read_commands
    sc = tmp_path / "rig.toml"
    sc.write_text('name = "rig"\nparameters = "fan2017"\nduration = "0.4 s"\n[controller]\nrate = "1 kHz"\n'
                  '[muscles.hip]\ntype = "hip"\nmotion = { kind = "constant" }\n'
                  '[muscles.knee]\ntype = "knee"\nmotion = { kind = "constant" }\n'
                  + "".join(f'[controllers.{m}]\nkind = "bang-bang"\nmuscle = "{m}"\n'
                            'setpoint = { kind = "constant", value = "3 bar" }\nband = "0.1 bar"\n'
                            for m in ("hip", "knee")))
    tab.to_csv(tmp_path / "commands.csv", index=False)
    with pytest.raises(ScenarioError, match=r"empty from 0\.201") as e:
        read_commands(tmp_path / "commands.csv", frogsim.load_scenario(sc))
    assert "lost valve commands" in str(e.value)


@pytest.mark.parametrize("record, reason", [
    ((40, 300, 1, 0, 0, 0, 1, 0, ev(20, 0, 1)), "event_out_of_range"),         # older than the window
    ((40, 300, 1, 0, 0, 0, 1, 0, 64 * 3 + 4 * 2 + 1), "event_out_of_range"),   # a third muscle
    ((40, 300, 1, 0, 0, 0, 1, 0, 64 * 3 + 3), "event_out_of_range"),           # both valves open
    ((40, 300, 1, 0, 0, 0, 9, 0, *[ev(i, 0, (-1) ** i) for i in range(9, 0, -1)]), "event_out_of_range"),  # 9 > 8 slots
    ((40, 300, 1, 0, 0, 0, 2, 0, ev(3, 0, 1), ev(5, 1, 0)), "events_out_of_order"),
    ((40, 300, 1, 0, 0, 0, 2, 0, ev(5, 0, 1), ev(3, 0, 1)), "events_disagree"),      # a change to the same
    ((40, 300, 1, 0, 0, 0, 1, 0, ev(5, 0, -1)), "events_disagree"),                  # last event: vent; bits: charge
    ((40, 300, 1, 0, 0, 0, 1, 3, ev(5, 0, 1)), "events_disagree"),                   # lost with 7 slots free
    ((40, 300, 1 | 4, 0, 0, 0, 1, 0, ev(5, 0, 1)), "events_disagree"),               # knee moved without an event
    ((40, 300, 1, 0, 0, 0, 2, 0, ev(5, 0, 1)), "field_count"),                       # says 2, carries 1
    ((40, 300, 1, 0, 0, 0), "field_count"),                                          # a format-2 record
])
def test_bad_events_are_discarded_by_their_reason(record, reason):
    log = parse_log(HEADER + lines((0, 300, 0, 0, 0, 0, 0, 0), (20, 300, 0, 0, 0, 0, 0, 0), record), REC)
    assert log.discarded == {reason: 1} and len(log.records) == 2


def test_a_log_without_its_firmware_json_reads_by_its_header():
    modes = two_muscles(seed=2)
    log = parse_log(HEADER + encode(modes, slots=40), None)
    assert log.bad == 0 and len(log.records) == 21 and log.plan["format"] == 4


def test_a_format_3_log_against_a_format_4_plan_is_refused_by_name():
    with pytest.raises(ScenarioError, match="format") as e:
        parse_log(HEADER.replace(b"format=4", b"format=3") + lines((0, 300, 0, 0, 0, 0)), REC)
    assert "3" in str(e.value) and "4" in str(e.value)


def test_a_plan_without_its_event_slots_is_refused():
    with pytest.raises(ScenarioError, match="event_slots"):
        spec_of(REC | {"event_slots": 0})
    with pytest.raises(ScenarioError, match="log_every"):
        spec_of(REC | {"log_every": 2000})


# -- on the emulated board ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def swim_board(tmp_path_factory):
    """swim-board's firmware, exported and built (its log: 50 Hz, 12 muscles, 250000 baud)."""
    from avr_tools import need_avr_tools
    from frogsim.cli import main
    need_avr_tools()
    out = tmp_path_factory.mktemp("swimboard") / "fw"
    assert main(["firmware", "swim-board", "--out", str(out), "--build", "--quiet"]) == 0
    return out


def test_swim_boards_line_at_its_longest_fits_its_baud_rate(swim_board):
    """firmware.json says format 4; its longest line (every field at its most digits, every event
    slot full) fits the bytes the baud rate carries between two records (10 bits a byte)."""
    rec = json.loads((swim_board / "firmware.json").read_text())
    assert rec["format"] == 4 and rec["history_samples"] == 0 and rec["event_slots"] >= len(rec["muscles"])
    n_m, every = len(rec["muscles"]), rec["log_every"]
    fields = [2**32 - 1] + [ch["count_range"][1] for ch in rec["channels"]] + \
        [4**n_m - 1, 2**len(rec["channels"]) - 1, 65535, 65535, rec["event_slots"], 65535] + \
        [64 * (every - 1) + 4 * (n_m - 1) + 2] * rec["event_slots"]
    longest = len(",".join(map(str, fields))) + 1
    assert longest <= rec["baud"] / 10 * every / rec["rate_hz"], longest


def _board_commands(fw, samples: int, step: float, seed: int = 1):
    """swim-board's firmware on the emulated board for ``samples`` periods, its channels reading a
    random walk of ``step`` of their line a sample: (the valve modes the pins showed at each
    interrupt's end [sample, muscle], the log read back, firmware.json)."""
    from frogsim.export import sil, sketch
    rec = sketch.read_plan_record(fw)
    run = sil.BoardRun(rec, sketch.find_elf(fw))
    rng = np.random.default_rng(seed)
    lo = np.array([ch["fault_limits"][0] for ch in rec["channels"] if "fault_limits" in ch] or [0], float)
    hi = np.array([ch["fault_limits"][1] for ch in rec["channels"] if "fault_limits" in ch] or [1], float)
    assert len(lo) == sum("analog_input" in ch for ch in rec["channels"])
    x = (lo + hi) / 2
    for _ in range(samples):
        x = np.clip(x + rng.normal(0.0, step, len(x)) * (hi - lo), lo, hi)
        counts = np.array([int(rec["channels"][i]["start_count"]) for i in range(len(rec["channels"]))
                           if "pins" in rec["channels"][i]], np.int64)
        full = np.zeros(len(rec["channels"]), np.int64)
        a = [i for i, ch in enumerate(rec["channels"]) if "analog_input" in ch]
        full[a] = np.rint(x).astype(np.int64)
        full[[i for i, ch in enumerate(rec["channels"]) if "pins" in ch]] = counts
        run.frame(full)
    run.finish()
    assert run.overruns == 0 and run.dropped == 0
    return np.array(run.decisions), parse_log(bytes(run.serial), rec), rec


def test_the_log_carries_every_valve_write_of_swim_boards_firmware(swim_board):
    """The commands read back from the log are the valve pins' states the firmware wrote at every
    sample (the emulator's pin events), although only every 20th sample is logged."""
    pins, log, rec = _board_commands(swim_board, 600, 0.02)
    assert log.bad == 0 and log.events_lost == 0
    k, modes = commands(log, rec, last_sample=599)
    assert k[0] == 0 and k[-1] == 580
    assert np.array_equal(modes, pins[:581])
    switchings = int(np.sum(pins[1:581] != pins[:580]))
    snapshots = int(np.sum(pins[20:581:20] != pins[:561:20]))
    assert switchings > 100 and switchings > 3 * snapshots


def test_a_burst_beyond_the_slots_is_counted_and_marked_not_guessed(swim_board):
    """Counts jumping over the sensors' lines make every relay chatter: more switchings than a
    record's slots. The lost counter says so, the gap's samples are unknown, every other sample's
    command is still the pins'."""
    pins, log, rec = _board_commands(swim_board, 300, 1.0)
    assert log.bad == 0 and log.events_lost > 0
    # the pins' own count of switchings a record's window held, where the log says some were lost
    n_ch = len(rec["channels"])
    for r in log.records[1:]:
        k = r[0]
        made = int(np.sum(pins[k - 19:k + 1] != pins[k - 20:k]))
        assert r[n_ch + 5] + r[n_ch + 6] == made, (k, r[n_ch + 5], r[n_ch + 6], made)
    with pytest.raises(ScenarioError, match="k = "):
        commands(log, rec, last_sample=299)
    tab = commands_table(log, rec, last_sample=299)
    ks = np.rint(tab["time [s]"].to_numpy() * 1000).astype(int)
    known = ~tab.iloc[:, 1].isna().to_numpy()
    idx = np.searchsorted(ks, np.arange(ks[-1] + 1), side="right") - 1
    ok = known[idx]
    assert 0 < ok.sum() < len(idx)
    got = tab.iloc[:, 1:].to_numpy()[idx][ok].astype(int)
    assert np.array_equal(got, pins[:ks[-1] + 1][ok])


@pytest.mark.slow
def test_swim_board_in_sil_writes_every_command_it_issued(swim_board, tmp_path):
    """`frogsim sil swim-board` (one gait cycle, the plant in the loop): commands.csv without a gap,
    from sample 0 to the last record's, whose command at each record's sample is that record's
    valve bits in serial.csv (read from the records' own field, not from the events)."""
    from frogsim.cli import main
    out = tmp_path / "sil"
    assert main(["sil", "swim-board", "--cycles", "1", "--firmware", str(swim_board), "--out", str(out),
                 "--no-animation", "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["sil"]["overruns"] == 0 and summary["sil"]["log_records"]["dropped"] == 0
    cmd = pd.read_csv(out / "commands.csv")
    serial = pd.read_csv(out / "serial.csv")
    assert not cmd.isna().any().any()
    ks = np.rint(cmd["time [s]"].to_numpy() * 1000).astype(int)
    rec_k = np.rint(serial["time [s]"].to_numpy() * 1000).astype(int)
    assert ks[0] == 0 and ks[-1] == rec_k[-1] == 1980
    idx = np.searchsorted(ks, rec_k, side="right") - 1
    for col in cmd.columns[1:]:
        m = col.split(" command ")[0]
        bits = serial[f"{m} charge valve [1 = open]"].to_numpy() - serial[f"{m} discharge valve [1 = open]"].to_numpy()
        assert np.array_equal(cmd[col].to_numpy()[idx], bits), m
    # far more switchings than the records' snapshots see
    assert len(cmd) > 5 * len(serial)
