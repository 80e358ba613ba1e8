"""The firmware as an Arduino sketch: the scenario's valve controllers on the Mega 2560.

:func:`write_sketch` turns a firmware plan (:func:`frogsim.control.firmware.firmware_plan`: the
laws as C, the pins, the sensor channels, the ADC clock) into a folder the Arduino IDE opens::

    DIR/NAME/NAME.ino           the runtime below (setup, loop, the timer interrupt)
    DIR/NAME/frogsim_board.h    generated: rate, pins, channels, ADC settings, valve writes
    DIR/NAME/frogsim_laws.h     generated: the plan's C source (the laws and program tables)
    DIR/NAME/frogsim_laws.c     includes it as C, with the tables in flash (PROGMEM)
    DIR/NAME/Makefile           arduino-mk's: ``make -C DIR/NAME`` builds into DIR/build
    DIR/NAME/README.md          the wiring table and the three ways to build and flash it
    DIR/firmware.json           the plan as data: what `frogsim sil` and `frogsim log` read

Every path in the folder is relative (the Makefile's OBJDIR is ``../build``): the export folder
can be copied or moved and built where it lies.

The runtime. Timer1 in CTC mode (WGM12) with the smallest prescaler whose compare value fits
16 bits interrupts at exactly F_CPU / (N (1 + OCR1A)) = the controller rate (datasheet Sec.
17.9.2). Its interrupt (sample k):

1. raises the busy pin and, interrupts still off, copies the quadrature encoders' counters;
2. masks its own interrupt and enables the others (encoder edges, the serial port) for its work;
3. starts the first analog conversion: the ADC converts the channels one after the other in the
   background (single conversions, AVcc reference, the plan's ADC prescaler; with an 8-bit plan
   the result left adjusted and ADCH read: Sec. 26.8), its conversion-complete interrupt storing
   each count and starting the next input;
4. calls ``frogsim_sample(k, adc, modes)`` (each law's channels checked for a sensor fault,
   then the laws, integer arithmetic only, see the plan): a law reads a channel through
   ``FS_CH`` (frogsim_laws.c), which waits for that channel's conversion only (asleep in idle
   mode, woken by the ADC's interrupt), so the laws' arithmetic runs while the converter works;
   then waits for the last conversion;
5. writes the valve pins: first every valve that closes, then every valve that opens
   (mode +1: charge pin high, discharge low; -1 the other way round; 0 both low);
6. shifts each muscle's command into its valve history (a uint32 per muscle, two bits a sample:
   1 charge, 2 vent, 0 hold; the newest sample in the lowest bits), and every ``log_every``
   samples copies (k, counts, valve bits, fault bits, the overrun and dropped counters, each
   muscle's history of the last log_every samples; none when log_every is above 16, a history
   that could not carry every command, or when the baud rate cannot carry the longer lines:
   :func:`history_samples`; where the histories do not fit, log format 4: each muscle whose
   command changed is stored as an event 64 i + 4 j + c in the record being filled, up to
   :func:`event_slots` a record, the rest counted as lost) into a ring of records; a record that
   finds the ring full is counted in the dropped counter, which the next record carries;
7. unmasks its interrupt (interrupts off), counts an overrun when Timer1's compare flag OCF1A is
   already set again (the next period began before this one's work ended; the flag is cleared
   on entry to the interrupt; the counters saturate at 65535), and lowers the busy pin.

``loop()`` formats the queued records as text lines ``k,count_0,...,count_n-1,valvebits,
faultbits,overruns,dropped,history_0,...,history_m-1`` (valve bit 2j: muscle j's charge valve, 2j+1
its discharge valve; history_j muscle j's commands since the last record, so that the log carries
every valve command the board issued although it is written at a tenth of the control rate;
decimal digits by subtraction, no division) and writes them to Serial, then sleeps (idle mode:
timers and the serial port keep running) until the next interrupt. The first line sent is
``# frogsim NAME rate=... channels=... muscles=... log_every=... format=3 plan=...`` (format=4 with
valve events: the records end in ``events,lost,event_1,...`` instead of the histories). Timer0's
overflow interrupt (Arduino's millis) is switched off so that it never delays the control
interrupt; the sketch uses neither millis nor delay.

Where the fixed-point arithmetic lives: the laws' C source (the plan's); this runtime only moves
counts and modes.
"""
from __future__ import annotations

import hashlib
import json
import math
import re
import subprocess
from dataclasses import dataclass
from pathlib import Path

from frogsim.components import atmega2560 as chip
from frogsim.errors import FrogsimError, ScenarioError, shown_value
from frogsim.export import board

LOG_FORMAT = "k,count_0,...,count_n-1,valvebits,faultbits,overruns,dropped,history_0,...,history_m-1"
LOG_FORMAT_VERSION = 3       # firmware.json "format" and the header's format= (4: valve events)
LOG_FORMAT_EVENTS = "k,count_0,...,count_n-1,valvebits,faultbits,overruns,dropped,events,lost,event_1,...,event_events"
#: the most samples a record's valve history holds: two bits a sample in a uint32
HISTORY_MAX = 16
RING_RECORDS = 16           # log records queued between the interrupt and loop()
TIMER1_PRESCALERS = ((1, 0b001), (8, 0b010), (64, 0b011), (256, 0b100), (1024, 0b101))
AVAILABLE_FLASH = board.FLASH_BYTES - board.BOOTLOADER_BYTES


def history_samples(plan) -> int:
    """The samples a record's valve history holds: the ``log_every`` since the last record; 0 (no
    history fields) for a log written more rarely than every :data:`HISTORY_MAX` samples, whose
    records could not carry every command, or one whose lines with the histories the baud rate
    could not carry (the longest line, k of 10 digits, :func:`frogsim.scenario.firmware.
    log_line_bytes`): the firmware then logs as before, and
    :func:`frogsim.export.serial_log.commands_missing` says why the log carries no commands.
    ``plan``: a FirmwarePlan or firmware.json's record."""
    from frogsim.scenario.firmware import log_line_bytes
    if isinstance(plan, dict):
        every, rate, baud = int(plan["log_every"]), float(plan["rate_hz"]), int(plan["baud"])
        n_ch, n_m, bits = len(plan["channels"]), len(plan["muscles"]), int(plan["adc"]["bits"])
        n_enc = sum(1 for ch in plan["channels"] if "analog_input" not in ch)
    else:
        every, rate, baud = int(plan.log_every), float(plan.rate), int(plan.baud)
        n_ch, n_m, bits = len(plan.channels), len(plan.muscles), int(plan.adc.bits)
        n_enc = sum(1 for ch in plan.channels if getattr(ch, "pins", ()))
    if every > HISTORY_MAX:
        return 0
    line = log_line_bytes(n_ch, n_m, 2 ** 32 - 1, bits, n_encoders=n_enc, log_every=every)
    return every if line * rate / every <= baud / 10.0 else 0


#: the most valve events a record holds (its slots in each of the ring's records: 2 bytes each)
EVENTS_MAX = 48
#: the longest record window an event's offset can say: bits 6..15 of a uint16
EVENTS_LOG_EVERY_MAX = 1024
#: the log format of a firmware whose records carry valve events instead of histories
EVENTS_FORMAT = 4
#: an event's most digits in a line's fields "events,lost" (the lost counter is a saturating uint16)
LOST_MAX = 65535


def event_value(offset: int, muscle: int, mode: int) -> int:
    """A valve event as the log writes it: 64 x offset + 4 x muscle + code (code 1 charge, 2 vent, 0
    hold; offset i: the event is at sample k - i of the record at k; muscle: its index, below 16)."""
    return 64 * int(offset) + 4 * int(muscle) + {1: 1, -1: 2, 0: 0}[int(mode)]


def event_slots(plan) -> int:
    """The valve events a record holds (format 4): 0 where the record carries histories
    (:func:`history_samples`), where log_every is above :data:`EVENTS_LOG_EVERY_MAX`, or where the
    baud rate cannot carry a line with one event; else as many as the baud rate carries in a line
    at its longest (every event at its most digits, the k of 10 digits), :data:`EVENTS_MAX` at most.
    A switching that finds the slots full is counted in the record's ``lost`` field, never dropped
    unsaid. ``plan``: a FirmwarePlan or firmware.json's record."""
    from frogsim.scenario.firmware import log_line_bytes
    if history_samples(plan):
        return 0
    if isinstance(plan, dict):
        every, rate, baud = int(plan["log_every"]), float(plan["rate_hz"]), int(plan["baud"])
        n_ch, n_m, bits = len(plan["channels"]), len(plan["muscles"]), int(plan["adc"]["bits"])
        n_enc = sum(1 for ch in plan["channels"] if "analog_input" not in ch)
    else:
        every, rate, baud = int(plan.log_every), float(plan.rate), int(plan.baud)
        n_ch, n_m, bits = len(plan.channels), len(plan.muscles), int(plan.adc.bits)
        n_enc = sum(1 for ch in plan.channels if getattr(ch, "pins", ()))
    if every > EVENTS_LOG_EVERY_MAX or n_m == 0:
        return 0
    budget = baud / 10.0 * every / rate          # [bytes] the line may take between two records
    for slots in range(EVENTS_MAX, 0, -1):
        if log_line_bytes(n_ch, n_m, 2 ** 32 - 1, bits, n_encoders=n_enc, log_every=every,
                          events=slots) <= budget:
            return slots
    return 0


def log_format(plan) -> int:
    """The plan's log format: 4 where its records carry valve events, else 3."""
    return EVENTS_FORMAT if event_slots(plan) else LOG_FORMAT_VERSION


def history_mask(samples: int) -> int:
    """The bits of a record's valve history of ``samples`` samples: two a sample."""
    return 4 ** int(samples) - 1


def timer1_setting(period_cycles: int) -> tuple[int, int, int]:
    """(prescaler N, CS12:0 bits, OCR1A) with F_CPU / (N (1 + OCR1A)) = F_CPU / period_cycles
    exactly: the smallest N that divides the period and leaves OCR1A within 16 bits; ValueError
    if none does."""
    for n, bits in TIMER1_PRESCALERS:
        if period_cycles % n == 0 and 1 <= period_cycles // n <= 65536:
            return n, bits, period_cycles // n - 1
    raise ValueError(f"a control period of {period_cycles} CPU cycles is no whole number of Timer1 ticks "
                     "below 65536 at any prescaler (1, 8, 64, 256, 1024)")


# -- the plan as data --------------------------------------------------------------------------------
def _channel(ch, bits: int) -> dict:
    unit = "Pa gauge" if ch.quantity == "pressure" else "rad"
    out = {"signal": ch.signal, "quantity": ch.quantity, "name": ch.name}
    if getattr(ch, "pins", ()):
        out.update({"sensor": "quadrature encoder", "pin": int(ch.pins[0]), "pins": [int(p) for p in ch.pins],
                    "start_count": int(ch.start_count), "count_range": [0, int(ch.full) - 1]})
    else:
        out.update({"sensor": "analog", "analog_input": int(ch.analog_input), "count_range": [0, 2 ** int(bits) - 1]})
    out.update({"unit_per_count": float(ch.unit_per_count), "offset": float(ch.offset), "unit": unit})
    return out


def _fault_limits(plan, i: int) -> dict:
    """{"fault_limits": [lo, hi]} of channel i (the counts outside which a law reading it faults),
    or {} when no law checks it (an encoder, a hand-written plan)."""
    for law in getattr(plan, "laws", None) or []:
        plo, phi, alo, ahi = getattr(law, "faults", (-1, 0, -1, 0))
        if law.pressure == i and plo >= 0:
            return {"fault_limits": [int(plo), int(phi)]}
        if law.angle == i and alo >= 0:
            return {"fault_limits": [int(alo), int(ahi)]}
    return {}


def channel_token(ch) -> str:
    """A channel in the log's header line: SIGNAL@A<input> (analog) or SIGNAL@D<A pin> (encoder)."""
    pins = getattr(ch, "pins", ())
    return f"{ch.signal}@D{int(pins[0])}" if pins else f"{ch.signal}@A{int(ch.analog_input)}"


def plan_record(plan) -> dict:
    """firmware.json's content: everything SIL and `frogsim log` need, and ``plan_sha256``, a
    digest of what the firmware is made of (a plan of another scenario, or of the same scenario
    edited since, has another)."""
    adc = plan.adc
    rec = {
        "format": log_format(plan),
        "name": plan.name,
        "f_cpu_hz": board.F_CPU,
        "rate_hz": float(plan.rate),
        "period_cycles": int(plan.period_cycles),
        "muscles": list(plan.muscles),
        "valve_pins": [[int(c), int(d)] for c, d in plan.valve_pins],
        "channels": [dict(_channel(ch, adc.bits), **_fault_limits(plan, i)) for i, ch in enumerate(plan.channels)],
        "adc": {"prescaler": int(adc.prescaler), "bits": int(adc.bits),
                "adc_clocks_first": int(adc.first_cycles), "adc_clocks": int(adc.cycles),
                "conversion_cpu_cycles": int(adc.cycles) * int(adc.prescaler)},
        "busy_pin": int(plan.busy_pin),
        "baud": int(plan.baud),
        "log_every": int(plan.log_every),
        "log_line": LOG_FORMAT,
        "valve_bits": "bit 2j: charge valve of muscles[j], bit 2j+1: its discharge valve",
        "history_samples": history_samples(plan),
        "valve_history": "history_j: muscles[j]'s command at sample k - i in bits 2i, 2i+1 (1 charge, 2 vent, "
                         "0 hold), i = 0 .. history_samples - 1",
    }
    if event_slots(plan):
        rec["log_line"] = LOG_FORMAT_EVENTS
        rec["event_slots"] = event_slots(plan)
        rec["valve_events"] = ("events: the switchings since the last record (at most event_slots), lost: those "
                               "that found the slots full; each event 64 i + 4 j + c: muscles[j]'s command "
                               "became c (1 charge, 2 vent, 0 hold) at sample k - i; oldest first")
    digest = hashlib.sha256(json.dumps(rec, sort_keys=True).encode() + plan.c_source.encode()).hexdigest()
    rec["plan_sha256"] = digest
    return rec


# -- the generated files ---------------------------------------------------------------------------------
def _pin(number: int) -> board.Pin:
    pins = board.pin_map()
    if number not in pins:
        raise ScenarioError("firmware pin", number, f"the Mega 2560 has digital pins 0..{board.DIGITAL_PINS - 1}")
    return pins[number]


def _conversion_order(plan) -> list:
    """[(channel index, channel)] of the plan's analog channels in the order the firmware converts
    them: the order ``frogsim_sample`` reads them (each law's pressure, then its angle), the
    channels no law reads last, so that each law waits for its own conversion only while the
    converter works on the next ones."""
    order = []
    for law in getattr(plan, "laws", None) or []:
        for i in (law.pressure, law.angle):
            if i is not None and i >= 0 and i not in order:
                order.append(i)
    order += [i for i in range(len(plan.channels)) if i not in order]
    return [(i, plan.channels[i]) for i in order if not getattr(plan.channels[i], "pins", ())]


def board_header(plan) -> str:
    """frogsim_board.h: the plan's numbers and the pin writes, as C."""
    n_ch, n_m = len(plan.channels), len(plan.muscles)
    prescaler, cs_bits, ocr = timer1_setting(int(plan.period_cycles))
    adps = {2: 1, 4: 2, 8: 3, 16: 4, 32: 5, 64: 6, 128: 7}[int(plan.adc.prescaler)]
    busy = _pin(plan.busy_pin)
    lines = [
        "/* Generated by frogsim from the scenario's [firmware] section: do not edit (export again). */",
        "#ifndef FROGSIM_BOARD_H",
        "#define FROGSIM_BOARD_H",
        "#include <stdint.h>",
        "#include <avr/io.h>",
        "",
        f'#define FS_NAME "{plan.name}"',
        f"#define FS_RATE_HZ {float(plan.rate):g}",
        f"#define FS_PERIOD_CYCLES {int(plan.period_cycles)}UL",
        f"#define FS_TIMER1_PRESCALER {prescaler}  /* CS12:0 = {cs_bits:03b} */",
        f"#define FS_TIMER1_CS {cs_bits}",
        f"#define FS_OCR1A {ocr}",
        f"#define FS_CHANNELS {n_ch}",
        f"#define FS_MUSCLES {n_m}",
        f"#define FS_ADC_PRESCALER {int(plan.adc.prescaler)}",
        f"#define FS_ADC_ADPS {adps}",
        f"#define FS_ADC_BITS {int(plan.adc.bits)}",
        f"#define FS_BAUD {int(plan.baud)}UL",
        f"#define FS_LOG_EVERY {int(plan.log_every)}UL",
        f"#define FS_HISTORY {1 if history_samples(plan) else 0}  /* valve histories in the records */",
        f"#define FS_HISTORY_MASK 0x{history_mask(history_samples(plan)):X}UL  /* two bits a sample, the last "
        f"{history_samples(plan)} samples */",
        f"#define FS_EVENTS {event_slots(plan)}  /* valve events a record holds (0: none logged) */",
        "/* muscle j's command changed: an event 64 i + 4 j + c (c: 1 charge, 2 vent, 0 hold; -1 & 3 = 3, less",
        "   3 >> 1: 2) into the record being filled (n its events so far, e = 64 i), or counted as lost */",
        "#define FS_EVENT_OF(j) if (fs_modes[j] != fs_last[j]) { int8_t m_ = fs_modes[j]; fs_last[j] = m_; "
        "if (n < FS_EVENTS) { uint8_t c_ = (uint8_t)m_ & 3u; fs_ev[n++] = (uint16_t)(e + 4u * (j)) | "
        "(uint8_t)(c_ - (c_ >> 1)); } else if (fs_lost != 0xFFFFu) fs_lost++; }",
        "#define FS_LOG_EVENTS " + " ".join(f"FS_EVENT_OF({j})" for j in range(len(plan.muscles))),
        f"#define FS_RING {RING_RECORDS}",
        "",
        f"/* busy pin D{busy.number} = P{busy.port}{busy.bit} */",
        f"#define FS_BUSY_DDR DDR{busy.port}",
        f"#define FS_BUSY_PORT PORT{busy.port}",
        f"#define FS_BUSY_BIT {busy.bit}",
        "",
        "/* the channels, in the order frogsim_sample reads them: analog inputs converted one after the",
        "   other, quadrature encoders' counts as the encoder interrupts left them */",
        "",
    ]
    encoders = [ch for ch in plan.channels if getattr(ch, "pins", ())]
    lines.append(f"#define FS_ENCODERS {len(encoders)}")
    lines.append('extern "C" { extern uint16_t fs_adc[]; }   /* the counts of the sample (the .ino) */')
    lines.append("volatile uint16_t fs_enc[FS_ENCODERS > 0 ? FS_ENCODERS : 1];   /* encoder counts */")
    read = ["static inline void fs_copy_encoders(void) {   /* interrupts off: the counts at the sample */"]
    analog = [(i, int(ch.analog_input)) for i, ch in _conversion_order(plan)]
    conv = [f"#define FS_ANALOG {len(analog)}",
            "/* the analog inputs in the order they are converted (the order frogsim_sample reads them: the",
            "   laws' FS_PLACE_i, frogsim_laws.c) and each one's channel (its index in fs_adc) */",
            f"static const uint8_t fs_analog_input[{max(1, len(analog))}] = "
            f"{{{', '.join(str(a) for _, a in analog) or '0'}}};   /* "
            + ", ".join(f"{plan.channels[i].signal} A{a}" for i, a in analog) + " */",
            f"static const uint8_t fs_analog_channel[{max(1, len(analog))}] = "
            f"{{{', '.join(str(i) for i, _ in analog) or '0'}}};",
            ""]
    enc_setup = ["static inline void fs_encoders_setup(void) {"]
    isrs = []
    e = 0
    for i, ch in enumerate(plan.channels):
        if getattr(ch, "pins", ()):
            a, b_ = _pin(int(ch.pins[0])), _pin(int(ch.pins[1]))
            n = chip.EXTERNAL_INTERRUPT[a.number]
            reg, bit = ("EICRA", 2 * n) if n < 4 else ("EICRB", 2 * (n - 4))
            read.append(f"    fs_adc[{i}] = fs_enc[{e}];   /* {ch.signal}: encoder A D{a.number} (INT{n}), "
                        f"B D{b_.number} */")
            enc_setup += [f"    DDR{a.port} &= (uint8_t)~(1u << {a.bit}); DDR{b_.port} &= (uint8_t)~(1u << {b_.bit});",
                          f"    fs_enc[{e}] = {int(ch.start_count)}u;   /* the count at angle 0, the start pose */",
                          f"    {reg} = ({reg} & (uint8_t)~(3u << {bit})) | (uint8_t)(1u << {bit});   "
                          f"/* INT{n} on any edge */",
                          f"    EIFR = (uint8_t)(1u << {n});",
                          f"    EIMSK |= (uint8_t)(1u << {n});"]
            isrs += [f"/* {ch.signal}: every edge of A counts, B gives the direction (A == B after the edge: +1) */",
                     f"ISR(INT{n}_vect) {{",
                     f"    uint8_t a = (PIN{a.port} >> {a.bit}) & 1u, b = (PIN{b_.port} >> {b_.bit}) & 1u;",
                     f"    if (a == b) fs_enc[{e}]++; else fs_enc[{e}]--;",
                     "}"]
            e += 1
    lines += read + ["}", ""] + conv + enc_setup + ["}", ""] + isrs + [""]
    setup = ["static inline void fs_valve_pins_output(void) {"]
    close = ["/* close first, then open: a muscle's two valves are never commanded open together */",
             "static inline void fs_write_valves(const int8_t *modes) {"]
    opens = []
    for j, (m, (pc, pd)) in enumerate(zip(plan.muscles, plan.valve_pins)):
        c, d = _pin(int(pc)), _pin(int(pd))
        setup.append(f"    DDR{c.port} |= (uint8_t)(1u << {c.bit}); DDR{d.port} |= (uint8_t)(1u << {d.bit});"
                     f"  /* {m}: charge D{c.number}, discharge D{d.number} */")
        close.append(f"    if (modes[{j}] <= 0) PORT{c.port} &= (uint8_t)~(1u << {c.bit});"
                     f"  /* {m} charge D{c.number} */")
        close.append(f"    if (modes[{j}] >= 0) PORT{d.port} &= (uint8_t)~(1u << {d.bit});"
                     f"  /* {m} discharge D{d.number} */")
        opens.append(f"    if (modes[{j}] > 0) PORT{c.port} |= (uint8_t)(1u << {c.bit});")
        opens.append(f"    if (modes[{j}] < 0) PORT{d.port} |= (uint8_t)(1u << {d.bit});")
    setup.append("}")
    lines += setup + [""] + close + opens + ["}", "", "#endif", ""]
    return "\n".join(lines)


LAWS_C = """/* Generated by frogsim: the laws (frogsim_laws.h) compiled as C, their tables in flash. */
#include <stdint.h>
#include <avr/pgmspace.h>
#include <avr/interrupt.h>
#include <avr/sleep.h>
#define FS_TABLE PROGMEM
#define FS_READ16(p) pgm_read_word(p)
#define FS_READ32(p) pgm_read_dword(p)
/* A channel's count: an encoder's as the interrupt copied it, an analog input's once the ADC has
 * converted it (the .ino converts them in the background, in the order FS_PLACE_i gives; 255: an
 * encoder's, not converted) */
extern volatile uint8_t fs_converted;
extern uint16_t fs_adc[];
/* wait, asleep (idle: the timers, the ADC and the serial port run on), until `place` + 1 channels
 * are converted; the ADC's interrupt (or an encoder's, or the serial port's) wakes the CPU. The
 * check and the sleep cannot miss the interrupt: interrupts are off between them, and the
 * instruction after SEI (the SLEEP) runs before a pending interrupt is taken. */
static inline void fs_wait_converted(uint8_t place) __attribute__((always_inline, unused));
static inline void fs_wait_converted(uint8_t place) {
    while (fs_converted <= place) {
        cli();
        if (fs_converted <= place) {
            sleep_enable();
            sei();
            sleep_cpu();
            sleep_disable();
        }
        sei();
    }
    __asm__ __volatile__("" ::: "memory");        /* read fs_adc after the ADC interrupt wrote it */
}
static inline uint16_t fs_count(uint8_t place, uint8_t i) __attribute__((always_inline));
static inline uint16_t fs_count(uint8_t place, uint8_t i) {
    if (place != 255)
        fs_wait_converted(place);
    return fs_adc[i];
}
#define FS_CH(i) fs_count(FS_PLACE_##i, i)
%(places)s
#include "frogsim_laws.h"
"""


def laws_c(plan) -> str:
    """frogsim_laws.c: the plan's laws (frogsim_laws.h) as C, tables in flash, each channel's place
    in the conversions as a constant (FS_PLACE_i) so that a law's read of it is a few cycles."""
    place = {i: q for q, (i, _) in enumerate(_conversion_order(plan))}
    places = "\n".join(f"#define FS_PLACE_{i} {place.get(i, 255)}" for i in range(len(plan.channels)))
    return LAWS_C % {"places": places}

INO = r"""/* {name}: frogsim's valve controllers on an Arduino Mega 2560 (ATmega2560, 16 MHz).
 *
 * Generated by `frogsim firmware` from scenario {scenario!r}; export again rather than editing.
 * Controller rate {rate:g} Hz (Timer1 CTC interrupt), {n_ch} ADC channel(s), {n_m} muscle(s).
 * The laws are in frogsim_laws.h (integer arithmetic only), the pins in frogsim_board.h.
 * Serial log at {baud} baud, one record every {log_every} samples:
 *     k,count_0,...,count_n-1,valvebits,faultbits,overruns,dropped,history_0,...,history_m-1
 * See README.md beside this file for the wiring, docs/firmware.md in frogsim for the rest.
 */
#include <avr/io.h>
#include <avr/interrupt.h>
#include <avr/sleep.h>
#include "frogsim_board.h"

extern "C" void frogsim_sample(uint32_t k, const uint16_t *adc, int8_t *modes);
extern "C" uint32_t frogsim_faults(void);

struct fs_record {{
    uint32_t k;
    uint16_t adc[FS_CHANNELS > 0 ? FS_CHANNELS : 1];
    uint32_t valves;
    uint32_t faults;
    uint16_t overruns;
    uint16_t dropped;
#if FS_HISTORY
    uint32_t history[FS_MUSCLES > 0 ? FS_MUSCLES : 1];
#endif
#if FS_EVENTS
    uint8_t events;                           /* the switchings since the last record ... */
    uint16_t lost;                            /* ... and those that found event[] full (saturates) */
    uint16_t event[FS_EVENTS];                /* 64 i + 4 j + c: muscle j's command became c at sample k - i */
#endif
}};

/* not static, C names: software in the loop reads them from the emulated RAM by symbol */
extern "C" {{
volatile uint32_t fs_k = 0;                 /* samples taken */
volatile uint16_t fs_overruns = 0;          /* samples whose work ran into the next period (saturates) */
volatile uint16_t fs_dropped = 0;           /* log records the full ring could not take (saturates) */
uint16_t fs_adc[FS_CHANNELS > 0 ? FS_CHANNELS : 1];   /* the counts of the last sample */
volatile uint8_t fs_head = 0, fs_tail = 0;  /* the record ring: the ISR writes at head, loop() reads at tail */
}}
static int8_t fs_modes[FS_MUSCLES];
#if FS_HISTORY
static uint32_t fs_history[FS_MUSCLES > 0 ? FS_MUSCLES : 1];  /* each muscle's commands, 2 bits a sample */
#endif
#if FS_EVENTS
static int8_t fs_last[FS_MUSCLES];          /* each muscle's command at the sample before (0: every valve shut) */
static uint16_t fs_at = 0;                  /* 64 i: this sample is sample k - i of the record it goes into */
static uint8_t fs_nev = 0;                  /* the events of the record being filled ... */
static uint16_t fs_lost = 0;                /* ... and those that found its slots full (saturates) */
static uint16_t *fs_ev;                     /* its slots: ring slot head's (loop() reads only those before it) */
#endif
static uint32_t fs_log_count = 0;
static struct fs_record fs_ring[FS_RING];

/* The analog channels are converted in the background: the control interrupt starts the first
 * conversion, the ADC-complete interrupt stores each result and starts the next input, and a law
 * that reads a channel waits only for that channel's conversion (FS_CH): the laws' arithmetic
 * runs while the converter works. */
extern "C" {{ volatile uint8_t fs_converted = 0; }}   /* analog channels converted so far in this sample */

static inline void fs_start_conversion(uint8_t input) {{
    /* AVcc reference; input 8..15 sets MUX5 in ADCSRB (datasheet Table 26-4) */
    ADCSRB = (input & 8) ? (1 << MUX5) : 0;
    ADMUX = (1 << REFS0) | ((FS_ADC_BITS == 8) ? (1 << ADLAR) : 0) | (input & 7);
    ADCSRA |= (1 << ADSC);
}}

#if FS_ANALOG > 0
ISR(ADC_vect) {{
    uint8_t n = fs_converted;
    fs_adc[fs_analog_channel[n]] = (FS_ADC_BITS == 8) ? ADCH : ADC;
    n++;
    fs_converted = n;
    if (n < FS_ANALOG) fs_start_conversion(fs_analog_input[n]);
}}
#endif

ISR(TIMER1_COMPA_vect) {{
    FS_BUSY_PORT |= (1 << FS_BUSY_BIT);
#if FS_ANALOG > 0
    fs_converted = 0;
    fs_start_conversion(fs_analog_input[0]);  /* the converter starts at once */
#endif
    uint32_t k = fs_k;
    fs_copy_encoders();                       /* interrupts are off: the encoders' counts at the sample */
    TIMSK1 &= (uint8_t)~(1 << OCIE1A);        /* this interrupt does not nest in itself ... */
    sei();                                    /* ... but the ADC, encoder edges and the serial port are served */
    frogsim_sample(k, fs_adc, fs_modes);
#if FS_ANALOG > 0
    while (fs_converted < FS_ANALOG) {{       /* every count of the sample (the log's, a channel no law read) */
        cli();                                /* asleep until the next conversion ends, as the laws wait */
        if (fs_converted < FS_ANALOG) {{
            sleep_enable();
            sei();
            sleep_cpu();
            sleep_disable();
        }}
        sei();
    }}
    __asm__ __volatile__("" ::: "memory");
#endif
    fs_write_valves(fs_modes);
#if FS_HISTORY
    for (uint8_t j = 0; j < FS_MUSCLES; j++)  /* 1 charge, 2 vent, 0 hold: the newest in the low bits */
        fs_history[j] = (fs_history[j] << 2) | (fs_modes[j] > 0 ? 1u : (fs_modes[j] < 0 ? 2u : 0u));
#endif
#if FS_EVENTS
    {{                                        /* each switching into the record being filled: 64 i + 4 j + c */
        uint8_t n = fs_nev;
        uint16_t e = fs_at;
        FS_LOG_EVENTS                         /* unrolled, one muscle after the other (frogsim_board.h) */
        fs_nev = n;
    }}
#endif
    if (fs_log_count == 0) {{
        uint8_t next = (uint8_t)((fs_head + 1) % FS_RING);
        if (next == fs_tail) {{
            if (fs_dropped != 0xFFFFu) fs_dropped++;
        }} else {{
            struct fs_record *r = &fs_ring[fs_head];
            r->k = k;
            for (uint8_t i = 0; i < FS_CHANNELS; i++) r->adc[i] = fs_adc[i];
            uint32_t bits = 0;
            for (uint8_t j = 0; j < FS_MUSCLES; j++) {{
                if (fs_modes[j] > 0) bits |= 1UL << (2 * j);
                if (fs_modes[j] < 0) bits |= 1UL << (2 * j + 1);
            }}
            r->valves = bits;
            r->faults = frogsim_faults();
            r->overruns = fs_overruns;
            r->dropped = fs_dropped;
#if FS_HISTORY
            for (uint8_t j = 0; j < FS_MUSCLES; j++) r->history[j] = fs_history[j] & FS_HISTORY_MASK;
#endif
#if FS_EVENTS
            r->events = fs_nev;
            r->lost = fs_lost;
#endif
            fs_head = next;
        }}
#if FS_EVENTS
        fs_ev = fs_ring[fs_head].event;       /* the next record's events start empty (a dropped record's */
        fs_nev = 0;                           /* go with it: the gap in k says so) */
        fs_lost = 0;
#endif
    }}
    if (++fs_log_count >= FS_LOG_EVERY) fs_log_count = 0;
#if FS_EVENTS
    fs_at = fs_at ? (uint16_t)(fs_at - 64u) : (uint16_t)((FS_LOG_EVERY - 1) << 6);
#endif
    cli();
    TIMSK1 |= (1 << OCIE1A);
    fs_k = k + 1;
    /* the next period has begun already */
    if ((TIFR1 & (1 << OCF1A)) && fs_overruns != 0xFFFFu) fs_overruns++;
    FS_BUSY_PORT &= ~(1 << FS_BUSY_BIT);
}}

/* A number in decimal without division (the AVR has none: avr-gcc's 32-bit division takes some
 * 600 cycles a digit): powers of ten subtracted, at most 9 subtractions a digit. */
static const uint32_t fs_pow10[10] = {{1000000000UL, 100000000UL, 10000000UL, 1000000UL, 100000UL,
                                      10000UL, 1000UL, 100UL, 10UL, 1UL}};

static uint8_t fs_format(char *out, uint32_t x) {{
    uint8_t n = 0, started = 0;
    for (uint8_t i = 0; i < 10; i++) {{
        char d = '0';
        uint32_t p = fs_pow10[i];
        while (x >= p) {{ x -= p; d++; }}
        if (d != '0' || started || i == 9) {{ out[n++] = d; started = 1; }}
    }}
    return n;
}}

#if FS_EVENTS
/* the same for a 16-bit event, in 16-bit arithmetic from 10^4 down: a line of events formats in
 * a third of the cycles fs_format would take */
static const uint16_t fs_pow10_16[5] = {{10000u, 1000u, 100u, 10u, 1u}};

static uint8_t fs_format16(char *out, uint16_t x) {{
    uint8_t n = 0, started = 0;
    for (uint8_t i = 0; i < 5; i++) {{
        char d = '0';
        uint16_t p = fs_pow10_16[i];
        while (x >= p) {{ x -= p; d++; }}
        if (d != '0' || started || i == 4) {{ out[n++] = d; started = 1; }}
    }}
    return n;
}}
#endif

static char fs_line[16 + 11 * (FS_CHANNELS + 5 + (FS_HISTORY ? FS_MUSCLES : 0)) + (FS_EVENTS ? 12 + 6 * FS_EVENTS : 0)];

void setup() {{
    TIMSK0 = 0;                               /* no millis() interrupt: nothing delays the control ISR */
    /* Timers 2 to 5 stopped: the Arduino core starts them for analogWrite(), which this firmware
     * does not use. (simavr 1.6 also gives their 8-bit phase-correct mode TOP = ICRn, 0, instead
     * of 0xFF: an overflow and three compare matches every 64 cycles, half of simavr's time in
     * software in the loop.) */
    TCCR2B = 0;
    TCCR3B = 0;
    TCCR4B = 0;
    TCCR5B = 0;
    FS_BUSY_DDR |= (1 << FS_BUSY_BIT);
    fs_valve_pins_output();
    for (uint8_t j = 0; j < FS_MUSCLES; j++) fs_modes[j] = 0;
#if FS_EVENTS
    fs_ev = fs_ring[0].event;                 /* sample 0's events go into the first record */
#endif
    fs_write_valves(fs_modes);                /* every valve shut */
    fs_encoders_setup();
    ADCSRA = (1 << ADEN) | (1 << ADIE) | FS_ADC_ADPS;   /* the conversion-complete interrupt on */
    Serial.begin(FS_BAUD);
    Serial.print(F("# frogsim " FS_NAME " rate={rate:g} channels={channels} muscles={muscles} "
                   "log_every={log_every} format={log_format} plan={plan}\n"));
    Serial.flush();
    set_sleep_mode(SLEEP_MODE_IDLE);          /* the control interrupt idles while the ADC converts, loop() between */
    cli();
    TCCR1A = 0;
    TCCR1B = 0;
    TCNT1 = 0;
    OCR1A = FS_OCR1A;
    TIFR1 = (1 << OCF1A);
    TIMSK1 = (1 << OCIE1A);
    TCCR1B = (1 << WGM12) | FS_TIMER1_CS;    /* CTC on OCR1A: the timer starts here (sample 0) */
    sei();
}}

void loop() {{
    while (fs_tail != fs_head) {{
        struct fs_record r = fs_ring[fs_tail];  /* a copy: the ISR may refill the slot afterwards */
        fs_tail = (uint8_t)((fs_tail + 1) % FS_RING);
        uint16_t n = fs_format(fs_line, r.k);     /* a line of events may pass 255 bytes */
        for (uint8_t i = 0; i < FS_CHANNELS; i++) {{
            fs_line[n++] = ',';
            n += fs_format(fs_line + n, r.adc[i]);
        }}
        fs_line[n++] = ',';
        n += fs_format(fs_line + n, r.valves);
        fs_line[n++] = ',';
        n += fs_format(fs_line + n, r.faults);
        fs_line[n++] = ',';
        n += fs_format(fs_line + n, r.overruns);
        fs_line[n++] = ',';
        n += fs_format(fs_line + n, r.dropped);
#if FS_HISTORY
        for (uint8_t j = 0; j < FS_MUSCLES; j++) {{
            fs_line[n++] = ',';
            n += fs_format(fs_line + n, r.history[j]);
        }}
#endif
#if FS_EVENTS
        fs_line[n++] = ',';
        n += fs_format(fs_line + n, r.events);
        fs_line[n++] = ',';
        n += fs_format(fs_line + n, r.lost);
        for (uint8_t i = 0; i < r.events; i++) {{
            fs_line[n++] = ',';
            n += fs_format16(fs_line + n, r.event[i]);
        }}
#endif
        fs_line[n++] = '\n';
        Serial.write((const uint8_t *)fs_line, n);
    }}
    cli();
    if (fs_tail == fs_head) {{
        sleep_enable();
        sei();
        sleep_cpu();                           /* woken by the next interrupt */
        sleep_disable();
    }}
    sei();
}}
"""


def _c_identifier(name: str) -> bool:
    return re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name or "") is not None


#: arduino-cli's name of the board and processor (the IDE's Tools > Board, Tools > Processor)
FQBN = "arduino:avr:mega:cpu=atmega2560"


def _hz(x: float) -> str:
    return f"{x / 1000:g} kHz" if x >= 1000 else f"{x:g} Hz"


def channel_pins(ch: dict) -> str:
    """Where a channel of firmware.json is wired: its analog input ("A0"), or the digital pins of
    a channel read through pins (``pin``: one number or a list: "D2, D3")."""
    if ch.get("analog_input") is not None:
        return f"A{int(ch['analog_input'])}"
    pins = ch.get("pin")
    return ", ".join(f"D{int(p)}" for p in (pins if isinstance(pins, (list, tuple)) else [pins]))


def _scale(ch: dict, bits: int) -> str:
    upc, off = float(ch["unit_per_count"]), float(ch["offset"])
    if ch.get("quantity") == "pressure":
        what = f"{off / 1e5:.4g} bar gauge + c x {upc / 100:.4g} mbar"
    elif ch.get("quantity") == "angle":
        what = f"{math.degrees(off):.4g} deg + c x {math.degrees(upc):.4g} deg"
    else:
        what = f"{off:g} + c x {upc:g} {ch.get('unit', '')}".rstrip()
    return f"{bits}-bit count c reads {what} (the middle of the count's step)"


def readme_text(rec: dict) -> str:
    """The sketch folder's README.md from the plan's record (:func:`plan_record` and what
    :func:`write_sketch` adds): the wiring table (every valve pin, every channel's input, the
    busy pin, the serial port), the rate, Timer1 and ADC settings, and the build three ways
    (arduino-mk, arduino-cli, the Arduino IDE)."""
    name = rec["name"]
    scenario = rec.get("scenario") or name
    rate, period = float(rec["rate_hz"]), int(rec["period_cycles"])
    adc = rec["adc"]
    bits, prescaler = int(adc["bits"]), int(adc["prescaler"])
    n, _, ocr = timer1_setting(period)
    log_every = int(rec["log_every"])
    rows = []
    for m, (c, d) in zip(rec["muscles"], rec["valve_pins"]):
        rows.append(f"| {m} charge valve | D{int(c)} | HIGH = open, through the valve's driver (a pin gives "
                    "20 mA at most: a logic-level MOSFET or a driver board) |")
        rows.append(f"| {m} discharge valve | D{int(d)} | HIGH = open, as above |")
    for k, ch in enumerate(rec["channels"]):
        rows.append(f"| {ch['signal']} (channel {k}) | {channel_pins(ch)} | {_scale(ch, bits)} |")
    rows.append(f"| busy pin | D{int(rec['busy_pin'])} | high while the control interrupt runs: a scope on "
                "it shows the CPU load |")
    rows.append(f"| serial log | USB (USART0: D0 RX, D1 TX) | {int(rec['baud'])} baud, 8N1: a line every "
                f"{log_every} samples ({_hz(rate / log_every)}); D0 and D1 are never valve pins |")
    clocks = adc.get("adc_clocks", 13)
    log_line = rec.get("log_line", LOG_FORMAT)
    lines = [
        f"# {name}: frogsim's valve controllers on an Arduino Mega 2560",
        "",
        f"Generated by `frogsim firmware` from the scenario `{scenario}`: export it again rather than",
        "editing these files. `../firmware.json` holds the same plan as data (what `frogsim sil` and",
        "`frogsim log` read); frogsim's docs/firmware.md explains the runtime.",
        "",
        "## Wiring",
        "",
        "| signal | Mega 2560 pin | notes |",
        "|---|---|---|",
        *rows,
        "",
        f"- Controller rate: {_hz(rate)}. Timer1 in CTC mode, prescaler {n}, OCR1A = {ocr}: 16 MHz / "
        f"({n} x {ocr + 1}) = {16e6 / (n * (ocr + 1)):g} Hz exactly, a period of {period} CPU cycles.",
        f"- ADC: prescaler {prescaler} (a {16e3 / prescaler:g} kHz ADC clock), {bits}-bit results"
        + (" (the left-adjusted high byte ADCH)" if bits == 8 else "")
        + f", AVcc as the reference: a conversion takes {clocks} ADC clocks ({clocks * prescaler} CPU "
        f"cycles); the channels are converted one after the other at each sample. Power the "
        "sensors from the board's 5 V, so that their output follows the reference.",
        f"- Serial log: one line `{log_line}` every {log_every} samples (valve bit 2j: muscle j's "
        "charge valve, 2j+1 its discharge valve), after a first line `# frogsim ...`; "
        "`frogsim log --port PORT --firmware .. --out DIR` records it.",
        "",
        "## Build and flash",
        "",
        "Three ways; each builds the same sources. Replace `/dev/ttyACM0` by the board's port.",
        "",
        "### arduino-mk (Debian: `apt-get install gcc-avr avr-libc arduino-core-avr arduino-mk`)",
        "",
        "From the folder that holds this one (the export folder):",
        "",
        "```",
        f"make -C {name}                                   # ELF and HEX in build/, beside {name}/",
        f"make -C {name} upload MONITOR_PORT=/dev/ttyACM0",
        "```",
        "",
        "The Makefile's paths are relative (`OBJDIR = ../build`): a copy of the export folder builds",
        "into its own `build/`. arduino-mk is looked for in /usr/share/arduino; elsewhere, add",
        "`ARDMK_DIR=/its/folder` to the make command. Or flash the HEX with avrdude:",
        "",
        "```",
        f"avrdude -p atmega2560 -c wiring -P /dev/ttyACM0 -b 115200 -D -U flash:w:build/{name}.hex:i",
        "```",
        "",
        "### arduino-cli",
        "",
        "```",
        "arduino-cli core install arduino:avr",
        f"arduino-cli compile --fqbn {FQBN} {name}",
        f"arduino-cli upload -p /dev/ttyACM0 --fqbn {FQBN} {name}",
        "```",
        "",
        "### The Arduino IDE",
        "",
        f"Open `{name}/{name}.ino` (the IDE opens the folder with its headers), choose *Tools > Board >",
        "Arduino AVR Boards > Arduino Mega or Mega 2560*, *Tools > Processor > ATmega2560 (Mega 2560)*,",
        "*Tools > Port*, then *Upload*.",
        "",
        "### When the build needs `-DDECIMAL_DIG=__DECIMAL_DIG__`",
        "",
        "The Arduino AVR core 1.8 uses `DECIMAL_DIG` in C++ (WString.cpp). avr-gcc 7, which the IDE",
        "and arduino-cli install with the core, defines it for C++; Debian's avr-gcc 5.4 defines it",
        "for C only, and the core fails to compile (`'DECIMAL_DIG' was not declared`). So the define",
        "is needed with Debian's compiler only: the Makefile passes it to C++ (`CXXFLAGS_STD`); with",
        "arduino-cli on Debian's compiler add",
        "`--build-property compiler.cpp.extra_flags=-DDECIMAL_DIG=__DECIMAL_DIG__` to the compile",
        "command; Debian's Arduino IDE (its core in /usr/share/arduino/hardware/arduino/avr) takes the",
        "line `compiler.cpp.extra_flags=-DDECIMAL_DIG=__DECIMAL_DIG__` in a `platform.local.txt` beside",
        "that folder's `platform.txt`. The IDE and arduino-cli from arduino.cc need nothing.",
        "",
    ]
    return "\n".join(lines)


def write_sketch(plan, out: Path, scenario_name: str = "", export: dict | None = None) -> dict:
    """Write the sketch folder (the sources, its Makefile and README.md) and firmware.json into
    ``out`` (an output folder already checked); returns {file kind: path}. ``export``: what the
    plan was made from (scenario name and file, gait cycles, the inputs' digests), kept in
    firmware.json under "export" so that `frogsim sil` can say why a plan differs."""
    if not _c_identifier(plan.name):
        raise ScenarioError("firmware.name", plan.name, "must be a C identifier (letters, digits, _; "
                                                        "not starting with a digit)")
    timer1_setting(int(plan.period_cycles))
    folder = Path(out) / plan.name
    from frogsim._files import atomic_write, write_json
    files = {
        "ino": folder / f"{plan.name}.ino",
        "board_header": folder / "frogsim_board.h",
        "laws_header": folder / "frogsim_laws.h",
        "laws_c": folder / "frogsim_laws.c",
        "plan": Path(out) / "firmware.json",
    }
    channels = ";".join(channel_token(ch) for ch in plan.channels)
    record = plan_record(plan)
    texts = {
        "ino": INO.format(name=plan.name, scenario=scenario_name or plan.name, rate=float(plan.rate),
                          n_ch=len(plan.channels), n_m=len(plan.muscles), baud=int(plan.baud),
                          log_every=int(plan.log_every), channels=channels,
                          muscles=";".join(plan.muscles), log_format=log_format(plan),
                          plan=record["plan_sha256"][:12]),
        "board_header": board_header(plan),
        "laws_header": plan.c_source,
        "laws_c": laws_c(plan),
    }
    folder.mkdir(parents=True, exist_ok=True)
    for key, text in texts.items():
        atomic_write(files[key], lambda tmp, text=text: Path(tmp).write_text(text))
    record["scenario"] = scenario_name
    record["sketch"] = f"{plan.name}/{plan.name}.ino"
    if export is not None:
        record["export"] = dict(export)
    files["makefile"], files["readme"] = folder / "Makefile", folder / "README.md"
    for key, text in (("makefile", makefile_text(plan.name)), ("readme", readme_text(record))):
        atomic_write(files[key], lambda tmp, text=text: Path(tmp).write_text(text))
    write_json(files["plan"], record)
    return files


#: the formats of firmware.json this frogsim reads: 2 (a board flashed before the valve history,
#: whose log is still read) and this runtime's two (3: valve histories or none, 4: valve events)
PLAN_FORMATS = (2, LOG_FORMAT_VERSION, EVENTS_FORMAT)


def _whole(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _pin_number(v) -> bool:
    return _whole(v) and 0 <= v < board.DIGITAL_PINS


def _pins(v) -> bool:
    return _pin_number(v) or (isinstance(v, list) and len(v) > 0 and all(_pin_number(p) for p in v))


#: what SIL and `frogsim log` read from firmware.json: key -> (test, what it must be). Keys not
#: named here are allowed (a later format adds its own: add them here with their test).
PLAN_KEYS = {
    "format": (lambda v: _whole(v) and v in PLAN_FORMATS, f"one of {', '.join(map(str, PLAN_FORMATS))}"),
    "name": (lambda v: isinstance(v, str) and _c_identifier(v), "a C identifier"),
    "f_cpu_hz": (lambda v: _whole(v) and v > 0, "a whole number of Hz > 0"),
    "rate_hz": (lambda v: _finite(v) and v > 0, "a finite number of Hz > 0"),
    "period_cycles": (lambda v: _whole(v) and v > 0, "a whole number of CPU cycles > 0"),
    "muscles": (lambda v: isinstance(v, list) and all(isinstance(m, str) and m for m in v), "a list of names"),
    "valve_pins": (lambda v: isinstance(v, list) and all(isinstance(p, list) and len(p) == 2
                                                         and all(_pin_number(x) for x in p) for p in v),
                   f"a list of [charge pin, discharge pin] pairs, pins 0..{board.DIGITAL_PINS - 1}"),
    "channels": (lambda v: isinstance(v, list) and all(isinstance(c, dict) for c in v), "a list of tables"),
    "adc": (lambda v: isinstance(v, dict), "a table"),
    "busy_pin": (_pin_number, f"a digital pin 0..{board.DIGITAL_PINS - 1}"),
    "baud": (lambda v: _whole(v) and v > 0, "a whole number > 0"),
    "log_every": (lambda v: _whole(v) and v >= 1, "a whole number of samples >= 1"),
    "plan_sha256": (lambda v: isinstance(v, str) and re.fullmatch(r"[0-9a-f]{64}", v) is not None,
                    "64 hexadecimal digits"),
}
#: each channel's keys (and "analog_input" or "pin", below)
CHANNEL_KEYS = {
    "signal": (lambda v: isinstance(v, str) and v, "a name"),
    "quantity": (lambda v: isinstance(v, str) and v, "a name"),
    "name": (lambda v: isinstance(v, str) and v, "a name"),
    "unit_per_count": (lambda v: _finite(v) and v != 0, "a finite number, not 0"),
    "offset": (_finite, "a finite number"),
    "unit": (lambda v: isinstance(v, str), "text"),
}
ADC_KEYS = {
    "bits": (lambda v: _whole(v) and v in (8, 10), "8 or 10"),
    "prescaler": (lambda v: _whole(v) and v in board.ADC_PRESCALERS,
                  f"one of {', '.join(map(str, board.ADC_PRESCALERS))}"),
}


def validate_plan_record(rec, folder) -> None:
    """ScenarioError in one line, naming --firmware, firmware.json and the key, unless ``rec`` has
    every key SIL and `frogsim log` read with its type and range (:data:`PLAN_KEYS`,
    :data:`CHANNEL_KEYS`, :data:`ADC_KEYS`; a channel has an analog input 0..15 or ``pin``, digital
    pins; one valve pin pair per muscle). Other keys are allowed."""
    where = str(folder)

    def bad(key: str, why: str):
        raise ScenarioError("--firmware", where, f"firmware.json's {key} {why}: not a firmware plan frogsim "
                                                 "wrote; export it again (frogsim firmware SCENARIO --out DIR "
                                                 "--build)")

    def check(table: dict, keys: dict, prefix: str) -> None:
        for key, (test, what) in keys.items():
            if key not in table:
                bad(prefix + key, "is missing")
            if not test(table[key]):
                bad(prefix + key, f"= {shown_value(table[key])} must be {what}")

    if not isinstance(rec, dict):
        raise ScenarioError("--firmware", where, "firmware.json is not a frogsim firmware plan (not a JSON "
                                                 "table)")
    check(rec, PLAN_KEYS, "")
    if len(rec["valve_pins"]) != len(rec["muscles"]):
        bad("valve_pins", f"has {len(rec['valve_pins'])} pairs for {len(rec['muscles'])} muscles: one pair "
                          "per muscle")
    check(rec["adc"], ADC_KEYS, "adc.")
    if rec["format"] >= 3:
        hs = rec.get("history_samples")
        if not (_whole(hs) and hs == history_samples(rec)):
            bad("history_samples", f"= {shown_value(hs)} must be log_every up to {HISTORY_MAX} where the baud "
                                   f"rate carries the histories, else 0: {history_samples(rec)}")
        slots = event_slots(rec)
        if rec["format"] == EVENTS_FORMAT and not (_whole(rec.get("event_slots")) and rec["event_slots"] == slots
                                                   and slots > 0):
            bad("event_slots", f"= {shown_value(rec.get('event_slots'))} must be the events a line carries at this "
                               f"baud rate and log rate: {slots}")
    for k, ch in enumerate(rec["channels"]):
        check(ch, CHANNEL_KEYS, f"channels[{k}].")
        if ch.get("analog_input") is not None:
            ai = ch["analog_input"]
            if not (_whole(ai) and 0 <= ai < board.ANALOG_INPUTS):
                bad(f"channels[{k}].analog_input", f"= {shown_value(ai)} must be an analog input "
                                                   f"0..{board.ANALOG_INPUTS - 1}")
        elif "pin" in ch:
            if not _pins(ch["pin"]):
                bad(f"channels[{k}].pin", f"= {shown_value(ch['pin'])} must be a digital pin "
                                          f"0..{board.DIGITAL_PINS - 1} or a list of them")
        else:
            bad(f"channels[{k}].analog_input", "is missing (nor has the channel a pin)")
        if "pins" in ch:
            if not (isinstance(ch["pins"], list) and len(ch["pins"]) == 2 and all(_pin_number(p) for p in ch["pins"])):
                bad(f"channels[{k}].pins", f"= {shown_value(ch['pins'])} must be an encoder's [A pin, B pin]")
            if not (_whole(ch.get("start_count")) and 0 <= ch["start_count"] <= 65535):
                bad(f"channels[{k}].start_count", f"= {shown_value(ch.get('start_count'))} must be a count 0..65535")
        cr = ch.get("count_range")
        if not (isinstance(cr, list) and len(cr) == 2 and all(_whole(x) for x in cr) and 0 <= cr[0] <= cr[1] <= 65535):
            bad(f"channels[{k}].count_range", f"= {shown_value(cr)} must be [lowest, highest] counts within 0..65535")


def read_plan_record(folder) -> dict:
    """firmware.json of an exported firmware folder, checked (:func:`validate_plan_record`);
    ScenarioError if absent, unreadable or not a plan frogsim wrote."""
    path = Path(folder) / "firmware.json"
    if not path.is_file():
        raise ScenarioError("--firmware", str(folder), "holds no firmware.json: export the firmware "
                                                        "first (frogsim firmware SCENARIO --out DIR --build)")
    try:
        rec = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ScenarioError("--firmware", str(folder), f"firmware.json is not readable JSON ({type(exc).__name__})") \
            from None
    if isinstance(rec, dict) and rec.get("format") in (1,):
        raise ScenarioError("--firmware", str(folder), f"firmware.json is a plan of format {rec['format']} (an older "
                                                        f"frogsim's), this frogsim's runtime is format "
                                                        f"{LOG_FORMAT_VERSION}: export and build the firmware again")
    validate_plan_record(rec, folder)
    return rec


# -- the build -------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Build:
    """A built firmware: the ELF, its flash and RAM use [B], the architecture avr-objdump names."""
    elf: Path
    hex: Path | None
    flash_bytes: int
    ram_bytes: int
    architecture: str

    def describe(self) -> str:
        return (f"flash {self.flash_bytes} B of {AVAILABLE_FLASH} B ({100 * self.flash_bytes / AVAILABLE_FLASH:.1f} %; "
                f"256 KB less the 8 KB bootloader), RAM {self.ram_bytes} B of {board.SRAM_BYTES} B "
                f"({100 * self.ram_bytes / board.SRAM_BYTES:.1f} %, static data; the stack takes more), "
                f"{self.architecture}")


ARDUINO_MK = Path("/usr/share/arduino/Arduino.mk")

#: the folder the sketch's objects, ELF and HEX go to, relative to the sketch folder (arduino-mk
#: runs in it): DIR/build beside DIR/NAME, wherever the export folder lies
OBJDIR = "../build"

MAKEFILE = """# Generated by frogsim: build this sketch with arduino-mk (Debian: arduino-mk):
#     make -C {name}            (from the folder above; or `make` in this one)
# The objects, ELF and HEX go to ../build. Every path here is relative to this folder but
# arduino-mk's own (ARDMK_DIR: give ARDMK_DIR=... to make where it is installed elsewhere).
BOARD_TAG = mega
BOARD_SUB = atmega2560
TARGET = {name}
ARDUINO_LIBS =
OBJDIR = {objdir}
# Debian's avr-gcc 5.4 defines DECIMAL_DIG for C99 only; the AVR core 1.8's WString.cpp (written
# for the IDE's avr-gcc 7) uses it in C++: give C++ the compiler's own value
CXXFLAGS_STD = -std=gnu++11 -fno-threadsafe-statics -flto -DDECIMAL_DIG=__DECIMAL_DIG__
ARDMK_DIR ?= {ardmk_dir}
include $(ARDMK_DIR)/Arduino.mk
"""


def makefile_text(name: str) -> str:
    """The sketch's Makefile for arduino-mk (BOARD_TAG=mega, BOARD_SUB=atmega2560, OBJDIR
    ../build)."""
    return MAKEFILE.format(name=name, objdir=OBJDIR, ardmk_dir=ARDUINO_MK.parent)


def build_sketch(out: Path, name: str, progress=None) -> Build:
    """Compile DIR/NAME with arduino-mk (its Makefile, :func:`makefile_text`) into DIR/build;
    the sizes from avr-size (flash: .text + .data, RAM: .data + .bss) and the architecture from
    `avr-objdump -f`, which must say avr6 (the ATmega2560's core). FrogsimError with the
    compiler's last lines if the build fails; ToolMissing if a tool is not installed."""
    from frogsim.export.emulator import APT_LINE, ToolMissing, require
    make = require("make")
    require("avr-gcc")
    size_tool, objdump = require("avr-size"), require("avr-objdump")
    if not ARDUINO_MK.exists():
        raise ToolMissing(f"{ARDUINO_MK} not found: install arduino-mk ({APT_LINE})")
    sketch = Path(out) / name
    objdir = (sketch / OBJDIR).resolve()
    mk = sketch / "Makefile"
    if not mk.is_file():                  # a sketch folder written by other means than write_sketch
        mk.write_text(makefile_text(name))
    run = subprocess.run([make, "-s", "-C", str(sketch)], capture_output=True, text=True)
    if run.returncode != 0:
        tail = "\n".join((run.stderr or run.stdout).strip().splitlines()[-12:])
        raise FrogsimError(f"building the sketch failed (make -C {sketch}):\n{tail}")
    elf = objdir / f"{name}.elf"
    if not elf.exists():
        raise FrogsimError(f"building the sketch made no {elf}")
    hexfile = elf.with_suffix(".hex")
    sizes = subprocess.run([size_tool, "-A", str(elf)], capture_output=True, text=True, check=True).stdout
    sec = {}
    for line in sizes.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[0].startswith(".") and parts[1].isdigit():
            sec[parts[0]] = int(parts[1])
    flash = sec.get(".text", 0) + sec.get(".data", 0)
    ram = sec.get(".data", 0) + sec.get(".bss", 0) + sec.get(".noinit", 0)
    info = subprocess.run([objdump, "-f", str(elf)], capture_output=True, text=True, check=True).stdout
    arch = re.search(r"architecture:\s*([^,\s]+)", info)
    arch = arch.group(1) if arch else "unknown"
    if arch != "avr:6":
        raise FrogsimError(f"{elf}: avr-objdump -f says architecture {arch}, not avr:6 (the ATmega2560's)")
    return Build(elf=elf, hex=hexfile if hexfile.exists() else None, flash_bytes=flash, ram_bytes=ram,
                 architecture="avr6")


#: the files in the sketch folder the build reads (arduino-mk's sources, the headers, the Makefile)
BUILD_INPUTS = ("*.ino", "*.pde", "*.c", "*.cpp", "*.cc", "*.S", "*.h", "*.hpp", "Makefile")


def find_elf(folder) -> Path:
    """The built ELF of an exported firmware folder, checked: ScenarioError if it was not built,
    if a file the build reads in the sketch folder (:data:`BUILD_INPUTS`) is newer than it (the
    ELF is not what the sources make: rebuild it), or if it is not an ATmega2560 ELF
    (:func:`frogsim.export.emulator.check_avr_elf`)."""
    from frogsim.export.emulator import check_avr_elf
    rec = read_plan_record(folder)
    elf = Path(folder) / "build" / f"{rec['name']}.elf"
    if not elf.is_file():
        raise ScenarioError("--firmware", str(folder), f"holds no build/{rec['name']}.elf: build it "
                                                        "(frogsim firmware SCENARIO --out DIR --build)")
    built = elf.stat().st_mtime
    sources = Path(folder) / rec["name"]
    newer = sorted({p.name for pattern in BUILD_INPUTS for p in sources.glob(pattern)
                    if p.is_file() and p.stat().st_mtime > built})
    if newer:
        shown = ", ".join(f"{sources.name}/{n}" for n in newer[:3]) + (", ..." if len(newer) > 3 else "")
        raise ScenarioError("--firmware", str(folder), f"build/{elf.name} is older than its sketch's {shown}: "
                                                       f"rebuild it (make -C {sources}, or frogsim firmware "
                                                       "SCENARIO --out DIR --build)")
    check_avr_elf(elf, folder)
    return elf
