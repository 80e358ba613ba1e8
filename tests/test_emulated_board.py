"""The emulated Mega 2560 (simavr) against the ATmega2560 datasheet, with a probe firmware
(tests/firmware/probe.c) compiled by avr-gcc: the timer interrupt's period, the ADC's result and
conversion time, the serial port's bytes and pacing, an input pin driven from outside.

Expected values are the datasheet's formulas, not the harness's output:
* Timer1 CTC: interrupts at f_clk / (N (1 + OCR1A)) = 16 MHz / (64 x 250) = 1 kHz (Sec. 17.9.2);
* ADC: ADC = V_in 1024 / V_ref (Sec. 26.7), 13 ADC clocks a conversion, 25 for the first;
* USART0 with U2X0: BAUD = f_osc / (8 (UBRR0 + 1)) (Table 22-1).
"""
import subprocess

import numpy as np
import pytest
from avr_tools import need_avr_tools

from frogsim.export import board
from frogsim.export.emulator import EmulatedBoard, millivolts_for_count
from pathlib import Path

PROBE = Path(__file__).with_name("firmware") / "probe.c"
PERIOD = 16_000             # cycles of a 1 ms period at 16 MHz


@pytest.fixture(scope="module")
def probe_elf(tmp_path_factory):
    need_avr_tools()
    elf = tmp_path_factory.mktemp("probe") / "probe.elf"
    subprocess.run(["avr-gcc", "-mmcu=atmega2560", "-Os", "-DF_CPU=16000000UL", "-o", str(elf), str(PROBE)],
                   check=True)
    return elf


def frames(data: bytes) -> tuple[list, list]:
    """The probe's frames: (channel, count) after 0xA5, edge counts after 0x5A."""
    conversions, edges = [], []
    k = 0
    while k < len(data):
        if data[k] == 0xA5 and k + 3 < len(data):
            conversions.append((data[k + 1], data[k + 2] << 8 | data[k + 3]))
            k += 4
        elif data[k] == 0x5A and k + 2 < len(data):
            edges.append(data[k + 1] << 8 | data[k + 2])
            k += 3
        else:
            raise AssertionError(f"unexpected byte {data[k]:#x} at {k}")
    return conversions, edges


def pulses(c, i, v, index):
    """(rise cycle, width) of each complete high pulse of watched pin ``index``."""
    ev = [(int(cc), int(vv)) for cc, ii, vv in zip(c, i, v) if ii == index]
    out, up = [], None
    for cc, vv in ev:
        if vv and up is None:
            up = cc
        elif not vv and up is not None:
            out.append((up, cc - up))
            up = None
    return out


@pytest.fixture(scope="module")
def run(probe_elf):
    pins = board.pin_map()
    with EmulatedBoard(probe_elf) as b:
        busy, conv = b.watch(pins[22]), b.watch(pins[23])
        volts = {0: 1000, 1: 2500, 2: 4999}
        for ch, mv in volts.items():
            b.set_analog(ch, mv)
        # INT4's pin starts high (simavr fires a pin that is low when its interrupt is enabled
        # as if it were level-triggered, until its first edge), then falls at 0.5 ms and rises
        # at 1.5 ms, 3.5 ms, ...: half-way between the probe's samples
        b.set_pin(pins[2], 1)
        for k in range(400):
            b.run_until(k * PERIOD + PERIOD // 2)
            b.set_pin(pins[2], k % 2)
            b.run_until((k + 1) * PERIOD)
        c, i, v = b.events()
        data, cyc = b.serial()
        assert b.lost == 0
    return dict(events=(c, i, v), busy=busy, conv=conv, data=data, cyc=cyc, volts=volts)


def test_timer_interrupt_runs_at_the_datasheets_rate(run):
    rises = [r for r, _ in pulses(*run["events"], run["busy"])]
    gaps = np.diff(rises)
    assert len(rises) >= 399
    assert abs(np.mean(gaps) - PERIOD) < 0.05            # 1 kHz on average, to the cycle
    assert np.all(np.abs(gaps - PERIOD) <= 8)            # interrupt latency: a few cycles


def test_conversion_takes_13_adc_clocks_and_25_the_first(run):
    widths = [w for _, w in pulses(*run["events"], run["conv"])]
    first, rest = widths[0], np.array(widths[1:])
    # the conversion starts at the next rising ADC clock edge: up to one ADC clock later; the
    # probe's polling loop adds a few cycles
    assert 25 * 128 <= first <= 26 * 128 + 16
    assert np.all(rest >= 13 * 128) and np.all(rest <= 14 * 128 + 16)


def test_adc_counts_near_the_ideal_converter(run):
    """The emulated ADC returns floor(mV x 1023 / V_ref) (simavr's scale), one count below the
    datasheet's V_in 1024 / V_ref at most: frogsim's SIL feeds each channel the voltage whose
    emulated count is the ideal one (:func:`test_millivolts_for_every_count_round_trip`)."""
    conversions, _ = frames(run["data"])
    for ch, count in conversions:
        ideal = int(run["volts"][ch] * 1024 / 5000)
        assert ideal - 1 <= count <= ideal


def test_serial_bytes_are_paced_by_the_baud_rate(run):
    # within a frame the probe waits for the data register, so bytes leave one byte time apart:
    # 10 bit times (start, 8 data, stop) of 8 (UBRR0 + 1) = 136 cycles is the datasheet's least;
    # simavr paces a byte at 11 bit times (documented in docs/firmware.md: the emulated link is
    # about 10 % slower than a real one, so a log that fits in SIL fits on the board)
    gaps = np.diff(run["cyc"].astype(np.int64)[:4])
    assert np.all(gaps >= 10 * 8 * 17)
    assert np.all(gaps <= 11 * 8 * 17 + 8)


def test_an_input_pin_driven_from_outside_reaches_the_firmware(run):
    _, edges = frames(run["data"])
    # reports at periods 100, 200, 300 (the 400th is still being sent when the run stops): a
    # rising edge every 2 ms
    assert edges == [50, 100, 150]


def test_millivolts_for_every_count_round_trip(probe_elf):
    """Each of the 1024 counts, fed as millivolts_for_count(count), is read back as that count by
    the firmware's own conversion on the emulated ADC."""
    pins = board.pin_map()
    data = b""
    with EmulatedBoard(probe_elf) as b:
        b.set_pin(pins[2], 1)
        for count in range(1024):
            for ch in range(3):
                b.set_analog(ch, millivolts_for_count(count))
            b.run_until((count + 1) * PERIOD + PERIOD // 2)    # period count + 1 samples it
            data += b.serial()[0]
        b.run_until(1026 * PERIOD)
        data += b.serial()[0]
    conversions, _ = frames(data)
    read = [c for _, c in conversions][:1024]
    assert read == list(range(1024)), [(k, c) for k, c in enumerate(read) if c != k][:5]


@pytest.mark.parametrize("shift", [0, 2])
def test_counts_set_in_one_call_read_back_as_those_counts(probe_elf, shift):
    """set_analog_counts (software in the loop's: a sample's counts in one call) sets the voltage
    each count reads back as: every count of a 10-bit (shift 0) or 8-bit (shift 2) channel, fed to
    the three inputs the probe converts, is read back as count << shift. A count outside the
    converter's range is refused, and nothing is set."""
    pins = board.pin_map()
    data = b""
    top = 1023 >> shift
    inputs = np.array([0, 1, 2], np.int32)
    with EmulatedBoard(probe_elf) as b:
        b.set_pin(pins[2], 1)
        for count in range(top + 1):
            b.set_analog_counts(inputs, np.full(3, count, np.int64), shift)
            b.run_until((count + 1) * PERIOD + PERIOD // 2)
            data += b.serial()[0]
        for bad in (-1, top + 1):
            with pytest.raises(ValueError, match=f"count {bad} is outside"):
                b.set_analog_counts(inputs, np.array([0, bad, 0], np.int64), shift)
        b.run_until((top + 5) * PERIOD)
        data += b.serial()[0]
    conversions, _ = frames(data)
    read = [c for _, c in conversions]
    assert read[:top + 1] == [c << shift for c in range(top + 1)], \
        [(k, c) for k, c in enumerate(read[:top + 1]) if c != k << shift][:5]
    # after the refused calls every input still reads the last count set (the refused 0 for A0
    # and A2 was not set either)
    assert read[top + 1:top + 3] == [top << shift] * 2


SLEEPER = Path(__file__).with_name("firmware") / "sleeper.c"


def sleeper_elf(tmp_path, period: int) -> Path:
    need_avr_tools()
    elf = tmp_path / f"sleeper-{period}.elf"
    subprocess.run(["avr-gcc", "-mmcu=atmega2560", "-Os", "-DF_CPU=16000000UL", f"-DPERIOD_CYCLES={period}",
                    "-o", str(elf), str(SLEEPER)], check=True)
    return elf


def test_sleep_is_counted_from_the_sleep_instruction(tmp_path):
    """A firmware that does the same work at each interrupt and sleeps between them is awake the
    same number of cycles per interrupt whatever the period: the sleep is counted from the SLEEP
    instruction on, also the stretch simavr skips in the step that runs it (left out, a core whose
    only event is its timer would read as awake all the time)."""
    pins = board.pin_map()
    per_interrupt = {}
    for period in (2000, 8000):
        with EmulatedBoard(sleeper_elf(tmp_path, period)) as b:
            busy = b.watch(pins[22])
            b.run_until(10 * period)                  # setup done, the timer running
            c0, s0 = b.cycle, b.sleep_cycles
            b.run_until(c0 + 100 * period)
            awake = (b.cycle - c0) - (b.sleep_cycles - s0)
            rises = [c for c, i, v in zip(*b.events()) if i == busy and v == 1 and c >= c0]
        assert len(rises) == 100
        per_interrupt[period] = awake / 100
    # the same work per interrupt, within a cycle; and it is a small part of the short period
    assert per_interrupt[2000] == pytest.approx(per_interrupt[8000], abs=1.0), per_interrupt
    assert per_interrupt[2000] < 0.25 * 2000, per_interrupt


def test_a_sleeping_core_stops_and_takes_an_input_at_the_cycle_asked(tmp_path):
    """run_until stops at the cycle asked, also inside a long sleep (simavr skips a sleeping core
    to its next event, past the cycle), and an edge driven there reaches the firmware then: the
    external interrupt's pin write follows the edge by the same number of cycles wherever in the
    sleep the edge falls (the datasheet's interrupt response from sleep, Sec. 7.8.1, plus the
    handler's first instructions)."""
    pins = board.pin_map()
    period = 8000
    with EmulatedBoard(sleeper_elf(tmp_path, period)) as b:
        mark = b.watch(pins[23])
        b.run_until(4 * period)
        delays = []
        for k, offset in enumerate((1000, 2500, 4111, 6007)):
            at = (5 + 2 * k) * period + offset
            b.run_until(at)
            assert b.cycle == at
            b.set_pin(pins[2], 1)
            b.run_until(at + 500)
            assert b.cycle == at + 500
            b.set_pin(pins[2], 0)
            rises = [int(c) for c, i, v in zip(*b.events()) if i == mark and v == 1]
            assert len(rises) == 1, rises
            delays.append(rises[0] - at)
    assert len(set(delays)) == 1 and 0 < delays[0] < 40, delays


def test_the_periods_reader_gives_what_the_raw_pin_events_show(probe_elf):
    """The SIL reads the pin events of each period in C (``track``/``drain``: executions of the
    interrupt, Timer1's compare matches, valve mode changes). The same run read as raw events
    gives the expected values: an execution is a high pulse of the busy pin, its decision the
    valve's mode at the pulse's end, its write the last mode change inside it; a compare match is
    the vector's flag raised; a mode change is each edge of the "charge" pin (here the probe's
    conversion pin, its "discharge" pin one that stays low; the mode starts at 0). The reader's arrays hold one entry
    each, so every drain leaves events queued and is called again."""
    pins = board.pin_map()

    def run_probe(tracked: bool):
        with EmulatedBoard(probe_elf) as b:
            busy, conv, low = b.watch(pins[22]), b.watch(pins[23]), b.watch(pins[24])
            tick = b.watch_vector(17)
            for ch, mv in {0: 1000, 1: 2500, 2: 4999}.items():
                b.set_analog(ch, mv)
            if tracked:
                b.track(busy, tick, [(conv, low)], changes=1, executions=1, ticks=1)
            ex, ticks, changes, drains = [], [], [], 0
            for k in range(60):
                b.run_until((k + 1) * PERIOD)
                if not tracked:
                    continue
                more = True
                while more:
                    more = b.drain()
                    drains += 1
                    n = b.counters
                    s, e, w, d = b.executions
                    ex += [(int(s[j]), int(e[j]), int(w[j]), int(d[j, 0])) for j in range(n[b.TR_EXECUTIONS])]
                    ticks += [int(x) for x in b.ticks[:n[b.TR_TICKS]]]
                    c, m, mode = b.changes
                    changes += [(int(c[j]), int(m[j]), int(mode[j])) for j in range(n[b.TR_CHANGES])]
            if tracked:
                return ex, ticks, changes, drains, int(b.counters[b.TR_BOTH_OPEN])
            return b.events(), busy, conv, tick

    ex, ticks, changes, drains, both = run_probe(True)
    (c, i, v), busy, conv, tick = run_probe(False)
    edges = [(int(cc), int(vv)) for cc, ii, vv in zip(c, i, v) if ii == conv]
    want_changes, mode = [], 0                    # a mode change: the mode differs from the last
    for cc, vv in edges:
        if (1 if vv else 0) != mode:
            mode = 1 if vv else 0
            want_changes.append((cc, 0, mode))
    want_ex = []
    for rise, width in pulses(c, i, v, busy):
        end = rise + width
        before = [(cc, vv) for cc, vv in edges if cc <= end]
        level = before[-1][1] if before else 0
        inside = [cc for cc, _ in before if cc >= rise]
        want_ex.append((rise, end, inside[-1] if inside else -1, 1 if level else 0))
    want_ticks = [int(cc) for cc, ii, vv in zip(c, i, v) if ii == tick and vv == 1]
    assert len(want_ex) >= 59 and len(want_changes) >= 118
    assert ex == want_ex
    assert ticks == want_ticks
    assert changes == want_changes
    assert both == 0
    # a drain reads at most one change (one-entry arrays): two a period needed a second drain
    assert drains >= len(want_changes) > 60
