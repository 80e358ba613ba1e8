"""The firmware's serial log read back and checked: its lines turned into a table with units in its
header (the convention of :mod:`frogsim.scenario.tables`), the same for a real board
(:func:`record_port`, pyserial) and for the emulated one (software in the loop).

The log (format 3)::

    # frogsim NAME rate=R channels=SIG@A0;SIG@D2 muscles=M;M log_every=L format=3 plan=HEX12
    k,count_0,...,count_n-1,valvebits,faultbits,overruns,dropped,history_0,...,history_m-1

The header comes once, when the firmware starts (HEX12: the first 12 hex digits of firmware.json's
``plan_sha256``; a channel's pin is an analog input ``A<n>`` or a digital pin ``D<n>``). Each
record: the sample index k (a multiple of log_every, since the first record is k = 0), each
channel's count, the valve bits (bit 2j: muscle j's charge valve, 2j+1 its discharge valve), the
fault bits (bit i: channel i was read in fault), and the firmware's overrun and dropped-record
counters (uint16, saturating at 65535), and each muscle's valve history: its commands at the
samples k - i, i = 0 .. H - 1 (H = log_every up to 16, firmware.json's ``history_samples``; above
16 H = 0 and the records have no history fields) in
bits 2i, 2i + 1 (1 charge, 2 vent, 0 hold), so that the log carries every command the board issued
although it is written every log_every samples (:func:`commands`). Format 4 (where the histories do
not fit: ``format=4`` in the header) ends each record in ``events,lost,event_1,...,event_events``
instead: the switchings since the last record, each 64 i + 4 j + c (muscle j's command became c at
sample k - i), at most firmware.json's ``event_slots``, and ``lost`` those that found the slots
full; a record with lost events is a gap in the commands (:func:`commands_gap`), marked in
commands.csv by empty cells. Format 2 (the same without the histories) is still read. Format 1 (the older firmware: ``k,counts,valvebits,
overruns``, a header without log_every, format and plan, drops told in ``# dropped N`` lines) is
still read.

Nothing is read on trust: the bytes before a capture's first newline are a partial line (unless
they are a whole header: only a header starts with '#'), and every record is checked (field count,
digits only, each count within its channel's ``count_range``, valve and fault bits in range, no
muscle with both valves open, a history below 4^H without a pair 3 whose newest pair is the
record's valve bits, k strictly increasing on the log_every grid, counters never going
down). A line that fails is counted by reason (:data:`REASONS`), the first few kept as examples,
and never reaches the table. A header that disagrees with firmware.json (name, format, rate,
channels, muscles, log_every, plan digest) is a ScenarioError: a log from another firmware is not
read as this one. A header after records means the board restarted: the records of the earlier
run are set aside (counted as ``before_restart``), since one table holds one run's time axis.

Columns: ``time [s]`` (k / rate: the sample's time since the firmware started), one per channel
(``hip pressure [bar gauge]``, ``hip_left angle [deg]``: count x unit_per_count + offset, the
channel's scale in firmware.json, whose offset puts the value in the middle of the count's step:
the estimate the converter's rounding down does not bias), then ``<muscle> charge valve
[1 = open]`` and ``<muscle> discharge valve [1 = open]`` per muscle. Fault bits, overruns and
drops go to the capture's summary (:func:`log_summary`), not into the table. The valve and
pressure columns are the ones ``frogsim simulate`` writes, so the CSV is a trace ``frogsim fit``
reads as it is (it leaves the valve columns out by their names).
"""
from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from frogsim.errors import ScenarioError, clip

UNKNOWN_TEXT = "(not all carried)"

BAR = 1e5
DEFAULT_BAUD = 115200       # the [firmware] section's default baud rate
DEFAULT_IDLE_TIMEOUT = 5.0  # [s] without a byte from the port, the capture stops
COUNTER_MAX = 65535         # the firmware's overrun and dropped counters are uint16, saturating
K_MAX = 2**32 - 1           # the firmware's sample index is uint32
ANALOG_MAX = 1023           # the ATmega2560's ADC has 10 bits: no analog count is larger
MAX_LINE = 1024             # [bytes] a line longer than this is garbage (a record is far shorter)
EXAMPLES = 5                # discarded lines kept as examples
FORMATS = (1, 2, 3, 4)
EVENTS_FORMAT = 4           # records carry valve events (the switchings) instead of histories
HISTORY_MAX = 16            # the samples a uint32 history holds (two bits each)
EVENTS_LOG_EVERY_MAX = 1024 # an event's offset within its record: bits 6..15 of a uint16

# why a line was discarded (the summary's "discarded" keys)
REASONS = {
    "partial_first_line": "the capture began inside this line",
    "partial_last_line": "the capture ended inside this line",
    "line_too_long": f"more than {MAX_LINE} bytes without a newline",
    "empty_line": "an empty line",
    "before_header": "a record before any header line (no --firmware: the header gives the channels)",
    "before_restart": "a record of the board's earlier run (a header line came after it: the board restarted)",
    "bad_header": "a '# frogsim' line that is not a readable header",
    "comment_line": "a '#' line that is not the header",
    "field_count": "the wrong number of fields",
    "not_a_number": "a field that is not an unsigned decimal integer",
    "k_out_of_range": f"k above {K_MAX}",
    "count_out_of_range": "a count outside its channel's count_range",
    "valvebits_out_of_range": "valve bits >= 4**muscles",
    "both_valves_open": "a muscle with its charge and discharge valves both open",
    "faultbits_out_of_range": "fault bits >= 2**channels",
    "history_out_of_range": "a valve history >= 4**history_samples, or with both valves of a sample open",
    "history_disagrees": "a valve history whose newest sample is not the record's valve bits",
    "event_out_of_range": "a valve event of a sample outside the record's window (or before sample 0), of a "
                          "muscle beyond the last, or with both valves open; more events than event_slots",
    "events_out_of_order": "valve events not in the order the board issues them (older samples first, then by muscle)",
    "events_disagree": "a muscle's last valve event that is not its valve bits, two events of a muscle that change "
                       "nothing, or events lost while slots were free",
    "counter_out_of_range": f"an overrun or dropped counter above {COUNTER_MAX}",
    "k_off_grid": "k not a multiple of log_every",
    "k_not_increasing": "k not above the last record's",
    "counter_decreased": "an overrun or dropped counter below the last record's",
}

_DIGITS = re.compile(r"[0-9]+\Z")
_HEX12 = re.compile(r"[0-9a-fA-F]{12}\Z")
_HEADER2 = re.compile(r"# frogsim (\S+) rate=(\S+) channels=(.*) muscles=(\S*) log_every=(\S+) format=(\S+) "
                      r"plan=(\S+)\Z")
_HEADER1 = re.compile(r"# frogsim (\S+) rate=(\S+) channels=(.*) muscles=(\S*)\Z")
_PIN = re.compile(r"([AD])([0-9]+)\Z")


@dataclass
class Log:
    """A checked log: ``records`` the lines that passed, each as its integers in the line's order
    (format 3: k, counts, valvebits, faultbits, overruns, dropped, histories; format 2 the same
    without the histories; format 1: k, counts, valvebits,
    overruns); ``header`` the header line; ``dropped`` the records the firmware dropped (its
    dropped counter's last value); ``bad`` the lines discarded, ``discarded`` them by reason
    (:data:`REASONS`) and ``examples`` the first few; ``plan`` the plan made from the header when
    no firmware.json was given. The rest describes the capture (see :func:`log_summary`)."""
    records: list = field(default_factory=list)
    header: str = ""
    dropped: int = 0
    bad: int = 0
    plan: dict | None = None
    discarded: dict = field(default_factory=dict)
    examples: list = field(default_factory=list)
    format: int | None = None
    lines: int = 0
    restarts: int = 0
    overruns_first: int | None = None
    overruns_last: int | None = None
    dropped_first: int | None = None
    missing_from_k_gaps: int = 0
    events_lost: int = 0                     # format 4: valve events that found a record's slots full ...
    records_with_lost: int = 0               # ... in so many records ...
    first_lost: tuple | None = None          # ... the first of them: (k, events lost in it)
    fault_samples: int = 0
    faults_per_channel: list = field(default_factory=list)
    bytes_read: int = 0
    capture_s: float | None = None
    stopped_by: str = ""
    idle_timeout: float | None = None
    idle_timeout_hit: bool = False
    _prev: tuple | None = field(default=None, repr=False)      # (k, overruns, dropped) of the last record
    _dropped1: int = field(default=0, repr=False)              # format 1: the last '# dropped N'
    _prev_valves: int = field(default=0, repr=False)           # the last record's valve bits
    _spec: object = field(default=None, repr=False)


def _discard(log: Log, reason: str, text: str) -> None:
    log.bad += 1
    log.discarded[reason] = log.discarded.get(reason, 0) + 1
    if len(log.examples) < EXAMPLES:
        log.examples.append({"line": log.lines, "reason": reason, "text": clip(text, 80)})


# -- the plan's side: what a record must look like ------------------------------------------------------
@dataclass(frozen=True)
class _Spec:
    format: int
    ranges: tuple          # (lo, hi or None) per channel
    muscles: int
    log_every: int | None  # None: a format-1 header alone does not say it
    history: int = 0       # samples each record's valve history holds (format 3)
    events: int = 0        # the valve events a record holds at most (format 4)
    events_known: bool = True   # False: a plan from a header alone (event_slots unknown: up to 255)

    @property
    def width(self) -> int:
        """The fields of a record (format 4: before its events)."""
        return 1 + len(self.ranges) + (4 if self.format >= 2 else 2) + (self.muscles if self.history else 0) + \
            (2 if self.events else 0)


def _positive_int(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value > 0


def _whole(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _finite_positive(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value > 0


def _channel_pin(ch: dict) -> str:
    """A channel's pin as the header writes it: A<n> for an analog input, D<n> for a digital pin."""
    if "analog_input" in ch:
        return f"A{ch['analog_input']}"
    pin = ch.get("pin")
    return pin if isinstance(pin, str) else f"D{pin}"


def spec_of(plan: dict) -> _Spec:
    """What a record of ``plan`` (firmware.json, or a plan made from a header) must look like;
    ScenarioError naming firmware.json's field if the plan cannot say it."""
    fmt = plan.get("format")
    if fmt not in FORMATS:
        raise ScenarioError("firmware.json format", fmt, f"this frogsim reads log formats {FORMATS}: export again")
    channels, muscles = plan.get("channels"), plan.get("muscles")
    if not isinstance(channels, list) or not all(isinstance(c, dict) and isinstance(c.get("signal"), str)
                                                 for c in channels):
        raise ScenarioError("firmware.json channels", channels, "a list of channels, each with its signal")
    if not isinstance(muscles, list) or not all(isinstance(m, str) for m in muscles):
        raise ScenarioError("firmware.json muscles", muscles, "a list of muscle names")
    if not _finite_positive(plan.get("rate_hz")):
        raise ScenarioError("firmware.json rate_hz", plan.get("rate_hz"), "a rate in Hz > 0")
    every = plan.get("log_every")
    if not (_positive_int(every) or (every is None and fmt == 1)):
        raise ScenarioError("firmware.json log_every", every, "a whole number of samples >= 1")
    digest = plan.get("plan_sha256", plan.get("plan_sha256_prefix"))     # the latter: a plan from a header
    if fmt >= 2 and not (isinstance(digest, str) and _HEX12.match(digest[:12])):
        raise ScenarioError("firmware.json plan_sha256", plan.get("plan_sha256"), "the plan's SHA-256 in hex")
    adc = plan.get("adc")
    bits = adc.get("bits") if isinstance(adc, dict) else None
    ranges = []
    for i, ch in enumerate(channels):
        r = ch.get("count_range")
        if r is None:
            analog = "analog_input" in ch
            hi = (2**bits - 1 if _positive_int(bits) else ANALOG_MAX) if analog else None
            r = (0, hi)
        elif not (isinstance(r, (list, tuple)) and len(r) == 2 and all(_whole(x) for x in r) and 0 <= r[0] <= r[1]):
            raise ScenarioError(f"firmware.json channels[{i}].count_range", r, "[lo, hi]: whole numbers, 0 <= lo <= hi")
        ranges.append(tuple(r))
    history = 0
    if fmt == 3:
        history = plan.get("history_samples", every if every <= HISTORY_MAX else 0)
        if not (_whole(history) and history in ((0, every) if every <= HISTORY_MAX else (0,))):
            raise ScenarioError("firmware.json history_samples", history,
                                f"0, or log_every ({every}) when it is {HISTORY_MAX} at most")
    events = 0
    if fmt == EVENTS_FORMAT:
        events = plan.get("event_slots", 255)
        if not (_whole(events) and 1 <= events <= 255):
            raise ScenarioError("firmware.json event_slots", events, "the valve events a record holds: 1..255")
        if plan.get("history_samples", 0) != 0:
            raise ScenarioError("firmware.json history_samples", plan.get("history_samples"),
                                "0: a log of valve events (format 4) carries no histories")
        if every > EVENTS_LOG_EVERY_MAX:
            raise ScenarioError("firmware.json log_every", every,
                                f"{EVENTS_LOG_EVERY_MAX} at most in a log of valve events (format 4): an event "
                                "says its sample in 10 bits")
    return _Spec(int(fmt), tuple(ranges), len(muscles), every, history, events, "event_slots" in plan)


# -- the header ----------------------------------------------------------------------------------------
def parse_header(line: str) -> dict | None:
    """The header line's fields (name, rate_hz, channels as [(signal, pin)], muscles, log_every,
    format, plan), or None if it is not a readable frogsim header."""
    line = line.strip()
    m = _HEADER2.match(line)
    if m:
        name, rate, chans, muscles, every, fmt, plan = m.groups()
        if not (_DIGITS.match(every) and int(every) > 0 and _DIGITS.match(fmt) and _HEX12.match(plan)):
            return None
        every, fmt = int(every), int(fmt)
    else:
        m = _HEADER1.match(line)
        if not m:
            return None
        name, rate, chans, muscles = m.groups()
        every, fmt, plan = None, 1, None
    try:
        rate = float(rate)
    except ValueError:
        return None
    if not _finite_positive(rate):
        return None
    channels = []
    for item in filter(None, chans.split(";")):
        signal, at, pin = item.rpartition("@")
        if not at or not signal or not _PIN.match(pin):
            return None
        channels.append((signal, pin))
    return {"name": name, "rate_hz": rate, "channels": channels, "muscles": [x for x in muscles.split(";") if x],
            "log_every": every, "format": fmt, "plan": plan}


def plan_from_header(line: str) -> dict | None:
    """A plan record made from the firmware's header line alone (no firmware.json at hand): the
    channels' signals and the muscles, counts without a scale (quantity "count"; an analog count
    within the ADC's 10 bits); None if the line is not a readable frogsim header."""
    h = parse_header(line)
    if h is None or h["format"] not in FORMATS:
        return None
    channels = []
    for signal, pin in h["channels"]:
        kind, number = pin[0], int(pin[1:])
        ch = {"signal": signal, "quantity": "count", "name": signal, "unit_per_count": 1.0, "offset": 0.0,
              "unit": "count"}
        if kind == "A":
            ch["analog_input"] = number
            ch["count_range"] = [0, ANALOG_MAX]
        else:
            ch["pin"] = number            # an encoder's count: no upper bound known
        channels.append(ch)
    plan = {"format": h["format"], "name": h["name"], "rate_hz": h["rate_hz"], "channels": channels,
            "muscles": h["muscles"], "baud": DEFAULT_BAUD, "log_every": h["log_every"]}
    if h["plan"]:
        plan["plan_sha256_prefix"] = h["plan"].lower()
    return plan


def check_header(line: str, rec: dict) -> None:
    """ScenarioError if the header line says another firmware than ``rec`` (firmware.json): the
    first field that differs with both values, and the others that differ."""
    h = parse_header(line)
    if h is None:
        return
    want = {"name": rec.get("name"), "format": rec.get("format"), "rate": f"{float(rec['rate_hz']):g}",
            "channels": ";".join(f"{c['signal']}@{_channel_pin(c)}" for c in rec["channels"]),
            "muscles": ";".join(rec["muscles"])}
    got = {"name": h["name"], "format": h["format"], "rate": f"{h['rate_hz']:g}",
           "channels": ";".join(f"{s}@{p}" for s, p in h["channels"]), "muscles": ";".join(h["muscles"])}
    if h["format"] >= 2 and (rec.get("format") or 0) >= 2:
        want |= {"log_every": rec.get("log_every"), "plan": str(rec.get("plan_sha256", ""))[:12].lower()}
        got |= {"log_every": h["log_every"], "plan": h["plan"].lower()}
    differ = [k for k in want if want[k] != got[k]]
    if differ:
        key = differ[0]
        also = f" (also differ: {', '.join(differ[1:])})" if differ[1:] else ""
        raise ScenarioError(f"the serial log's header {key}", got[key],
                            f"firmware.json (--firmware) has {want[key]!r}{also}: the board runs another "
                            "firmware; flash this one, or give the folder its firmware was exported to")


# -- the lines -----------------------------------------------------------------------------------------
def _header_line(log: Log, rec: dict | None, line: str) -> None:
    h = parse_header(line)
    if h is None:
        _discard(log, "bad_header", line)
        return
    if rec is not None:
        check_header(line, rec)
    elif h["format"] not in FORMATS:
        raise ScenarioError("the serial log's header format", h["format"],
                            f"this frogsim reads log formats {', '.join(map(str, FORMATS))}: update frogsim")
    if log.records:                       # the board restarted: one table holds one run
        n = len(log.records)
        log.restarts += 1
        log.records.clear()
        log.bad += n
        log.discarded["before_restart"] = log.discarded.get("before_restart", 0) + n
        if len(log.examples) < EXAMPLES:
            log.examples.append({"line": log.lines, "reason": "before_restart",
                                 "text": f"{n} records before this header: {clip(line, 60)}"})
        log._prev = None
        log.overruns_first = log.overruns_last = log.dropped_first = None
        log.missing_from_k_gaps = log.fault_samples = log._dropped1 = 0
        log.events_lost = log.records_with_lost = 0
        log.first_lost = None
        log.faults_per_channel = []
    log.header = line
    log.format = h["format"]
    if rec is None:
        log.plan = plan_from_header(line)
        log._spec = spec_of(log.plan)


def _record(log: Log, spec: _Spec, line: str) -> str | None:
    """Check a record line against ``spec`` and keep it; the reason it fails, else None."""
    parts = line.split(",")
    if spec.events:
        if len(parts) < spec.width or not _DIGITS.match(parts[spec.width - 2]) or \
                len(parts) != spec.width + int(parts[spec.width - 2]):
            return "field_count"
    elif len(parts) != spec.width:
        return "field_count"
    if not all(_DIGITS.match(p) for p in parts):
        return "not_a_number"
    v = [int(p) for p in parts]
    n_ch = len(spec.ranges)
    k, counts, valves = v[0], v[1:1 + n_ch], v[1 + n_ch]
    if k > K_MAX:
        return "k_out_of_range"
    if any(c < lo or (hi is not None and c > hi) for c, (lo, hi) in zip(counts, spec.ranges)):
        return "count_out_of_range"
    if valves >= 4**spec.muscles:
        return "valvebits_out_of_range"
    if any((valves >> (2 * j)) & 3 == 3 for j in range(spec.muscles)):
        return "both_valves_open"
    if spec.format >= 2:
        faults, overruns, dropped = v[2 + n_ch:5 + n_ch]
        if faults >= 1 << n_ch:
            return "faultbits_out_of_range"
        if spec.history:
            for j, h in enumerate(v[5 + n_ch:]):
                if h >= 4**spec.history or any((h >> (2 * i)) & 3 == 3 for i in range(spec.history)):
                    return "history_out_of_range"
                if h & 3 != (valves >> (2 * j)) & 3:
                    return "history_disagrees"
        if spec.events:
            why = _check_events(spec, k, valves, v[spec.width - 2], v[spec.width - 1], v[spec.width:])
            if why:
                return why
    else:
        faults, overruns, dropped = 0, v[2 + n_ch], log._dropped1
    if overruns > COUNTER_MAX or dropped > COUNTER_MAX:
        return "counter_out_of_range"
    if spec.log_every and k % spec.log_every:
        return "k_off_grid"
    if log._prev is not None:
        pk, po, pd = log._prev
        if k <= pk:
            return "k_not_increasing"
        if overruns < po or dropped < pd:
            return "counter_decreased"
        if spec.events and k - pk == spec.log_every and not v[spec.width - 1]:
            moved = {(e >> 2) & 15 for e in v[spec.width:]}   # a muscle without an event kept its valves
            if any((valves >> (2 * j)) & 3 != (log._prev_valves >> (2 * j)) & 3
                   for j in range(spec.muscles) if j not in moved):
                return "events_disagree"
        if spec.log_every:
            log.missing_from_k_gaps += (k - pk) // spec.log_every - 1
    else:
        log.overruns_first, log.dropped_first = overruns, dropped
        log.faults_per_channel = [0] * n_ch
    log._prev = (k, overruns, dropped)
    log._prev_valves = valves
    log.overruns_last, log.dropped = overruns, dropped
    if faults:
        log.fault_samples += 1
        for i in range(n_ch):
            log.faults_per_channel[i] += (faults >> i) & 1
    if spec.events and v[spec.width - 1]:
        lost = v[spec.width - 1]
        log.events_lost += lost
        log.records_with_lost += 1
        if log.first_lost is None:
            log.first_lost = (k, lost)
    log.records.append(tuple(v))
    return None


def _check_events(spec: _Spec, k: int, valves: int, n: int, lost: int, events: list) -> str | None:
    """The reason a record's valve events fail (:data:`REASONS`), else None."""
    if n > spec.events or lost > COUNTER_MAX:
        return "event_out_of_range" if n > spec.events else "counter_out_of_range"
    last, prev = {}, None
    for e in events:
        i, j, c = e >> 6, (e >> 2) & 15, e & 3
        if i >= spec.log_every or i > k or j >= spec.muscles or c == 3:
            return "event_out_of_range"
        if prev is not None and (-i, j) <= prev:
            return "events_out_of_order"
        if last.get(j) == c:
            return "events_disagree"
        prev, last[j] = (-i, j), c
    if lost and n < spec.events and spec.events_known:
        return "events_disagree"
    if not lost and any(c != (valves >> (2 * j)) & 3 for j, c in last.items()):
        return "events_disagree"
    return None


def _line(log: Log, rec: dict | None, raw: str) -> None:
    log.lines += 1
    line = raw.strip()
    if not line:
        _discard(log, "empty_line", raw)
        return
    if len(line) > MAX_LINE:             # garbage (and no int() of thousands of digits)
        _discard(log, "line_too_long", line)
        return
    if line.startswith("#"):
        if line.startswith("# frogsim "):
            _header_line(log, rec, line)
        elif line.startswith("# dropped ") and (log.format or (rec or {}).get("format")) == 1:
            n = line[len("# dropped "):]
            if _DIGITS.match(n) and log._dropped1 <= int(n) <= COUNTER_MAX:
                log._dropped1 = int(n)
            else:
                _discard(log, "comment_line", line)
        else:
            _discard(log, "comment_line", line)
        return
    if log._spec is None:
        if rec is None:
            _discard(log, "before_header", line)
            return
        log._spec = spec_of(rec)
    reason = _record(log, log._spec, line)
    if reason:
        _discard(log, reason, line)


def parse_lines(lines, rec: dict | None, log: Log | None = None) -> Log:
    """Add whole text lines (without their newline) to ``log``, each checked (module docstring).
    Without a plan (``rec`` None) the header line makes one (:func:`plan_from_header`, kept in
    ``log.plan``); records before it are discarded. ScenarioError if a header says another
    firmware than ``rec``."""
    log = log if log is not None else Log()
    for line in lines:
        _line(log, rec, line)
    return log


class LineReader:
    """Bytes in, checked lines out: resynchronises on the first newline (what came before it is a
    partial line, unless a whole header), and refuses run-on lines longer than MAX_LINE."""

    def __init__(self, rec: dict | None, log: Log | None = None):
        self.rec = rec
        self.log = log if log is not None else Log()
        self.pending = b""
        self.first = True          # no newline seen yet: the pending bytes may be a line's tail
        self.skipping = False      # inside a run-on line already counted

    def _text(self, raw: bytes) -> str:
        return raw.decode("ascii", errors="replace")

    def feed(self, data: bytes) -> None:
        log = self.log
        log.bytes_read += len(data)
        *whole, self.pending = (self.pending + data).split(b"\n")
        for raw in whole:
            text = self._text(raw)
            if self.skipping:
                self.skipping = False
            elif self.first and not text.strip().startswith("#"):
                if text.strip():
                    log.lines += 1
                    _discard(log, "partial_first_line", text)
            else:
                _line(log, self.rec, text)
            self.first = False
        if len(self.pending) > MAX_LINE:
            if not self.skipping:
                log.lines += 1
                _discard(log, "partial_first_line" if self.first else "line_too_long", self._text(self.pending))
            self.pending, self.skipping = b"", True

    def finish(self) -> Log:
        """The capture ended: its unterminated last line is discarded (a partial line)."""
        text = self._text(self.pending)
        if text.strip() and not self.skipping:
            self.log.lines += 1
            _discard(self.log, "partial_first_line" if self.first else "partial_last_line", text)
        self.pending = b""
        return self.log


def parse_log(data: bytes, rec: dict | None) -> Log:
    """A whole capture's bytes read and checked (:class:`LineReader`; a trailing partial line is
    left out and counted)."""
    reader = LineReader(rec)
    reader.feed(bytes(data))
    return reader.finish()


# -- the table -----------------------------------------------------------------------------------------
def columns(rec: dict) -> list[str]:
    """The table's headers (module docstring)."""
    from frogsim.scenario.tables import header
    cols = [header("time", "s")]
    for ch in rec["channels"]:
        cols.append(header(ch["signal"], {"pressure": "bar gauge", "angle": "deg"}.get(ch["quantity"], "count")))
    for m in rec["muscles"]:
        cols += [header(f"{m} charge valve", "1 = open"), header(f"{m} discharge valve", "1 = open")]
    return cols


def log_table(log: Log, rec: dict, last_sample: int | None = None):
    """The records as a pandas DataFrame with unit headers (module docstring); records past
    ``last_sample`` left out (the emulated board runs on a little after the plant stops)."""
    import pandas as pd
    rows = [r[:len(rec["channels"]) + 2] for r in log.records if last_sample is None or r[0] <= last_sample]
    rate = float(rec["rate_hz"])
    n_ch, n_m = len(rec["channels"]), len(rec["muscles"])
    a = np.array(rows, dtype=np.int64).reshape(len(rows), n_ch + 2)
    names = columns(rec)
    data = {names[0]: a[:, 0] / rate}
    for i, ch in enumerate(rec["channels"]):
        name = names[1 + i]
        if ch["quantity"] == "count":
            data[name] = a[:, 1 + i]
            continue
        si = a[:, 1 + i] * ch["unit_per_count"] + ch["offset"]
        data[name] = si / BAR if ch["quantity"] == "pressure" else np.degrees(si)
    bits = a[:, 1 + n_ch]
    for j in range(n_m):
        data[names[1 + n_ch + 2 * j]] = (bits >> (2 * j)) & 1
        data[names[2 + n_ch + 2 * j]] = (bits >> (2 * j + 1)) & 1
    return pd.DataFrame(data)


#: a commands table's column of muscle m: its command at each sample from the row's time on
COMMAND_UNIT = "1 = charge, 0 = hold, -1 = vent"
COMMANDS_CSV = "commands.csv"


def commands_missing(log: Log, rec: dict) -> str | None:
    """Why ``log`` does not carry every valve command between its first and last record (None if it
    does): a format without valve histories or events, histories shorter than log_every, records
    missing. Commands lost in a record whose event slots were full are a gap, not a reason here
    (:func:`commands_gap`): commands.csv marks them."""
    every = rec.get("log_every")
    fmt = log.format or rec.get("format")
    if fmt == EVENTS_FORMAT and (rec.get("format") or EVENTS_FORMAT) == EVENTS_FORMAT:
        pass
    elif fmt != 3 or (rec.get("format") or 3) < 3:
        return (f"the log is format {fmt}: its records carry the valve bits of "
                "every log_every-th sample only (format 3 carries each muscle's history, 4 its switchings; "
                "export and flash the firmware again)")
    elif (rec.get("history_samples") == 0 and every is not None and every <= HISTORY_MAX):
        return ("the firmware logs no valve histories: its baud rate cannot carry the longer lines at this log "
                "rate (raise firmware.baud)")
    elif every is None or every > HISTORY_MAX:
        return (f"a record every {every} samples: the firmware logs valve histories for a record every "
                f"{HISTORY_MAX} samples at most (a log rate of at least the controller rate / {HISTORY_MAX} "
                "carries every command)")
    if not log.records:
        return "no records"
    gaps = log.missing_from_k_gaps
    if gaps:
        return f"{gaps} record(s) missing (gaps in k): the commands in those gaps are unknown"
    return None


def commands_gap(log: Log, rec: dict, last_sample: int | None = None) -> str | None:
    """The first record (up to ``last_sample``) whose valve events did not all fit its slots
    (format 4), said in words with how many there are in all; None if every command was logged."""
    if log.first_lost is None or (last_sample is not None and log.first_lost[0] > last_sample):
        return None
    k, n = log.first_lost
    every, rate = int(rec["log_every"]), float(rec["rate_hz"])
    slots = rec.get("event_slots")
    return (f"the record at k = {k} (t = {k / rate:g} s) lost {n} valve command(s) that found its "
            f"{slots if slots is not None else 'event'} slots full: the commands of samples {max(0, k - every + 1)}.."
            f"{k - 1} are unknown ({log.events_lost} lost in {log.records_with_lost} record(s) in all)")


def _commands(log: Log, rec: dict, last_sample: int | None = None):
    """(samples k, modes [k, muscle], known [k]: False where a record's events were lost): the
    commands of every sample from the first record's (format 3: its history's first) to the last
    record's. ScenarioError if the log does not carry them (:func:`commands_missing`)."""
    why = commands_missing(log, rec)
    if why:
        raise ScenarioError("the serial log's valve commands", UNKNOWN_TEXT, why)
    every = int(rec["log_every"])
    n_ch, n_m = len(rec["channels"]), len(rec["muscles"])
    rows = [r for r in log.records if last_sample is None or r[0] <= last_sample]
    if not rows:
        raise ScenarioError("the serial log's valve commands", UNKNOWN_TEXT, f"no record up to sample {last_sample}")
    of_bits = np.array([0, 1, -1, 0], dtype=np.int8)
    if (log.format or rec.get("format")) == EVENTS_FORMAT:
        k0, k1 = rows[0][0], rows[-1][0]
        modes = np.zeros((k1 - k0 + 1, n_m), dtype=np.int8)
        known = np.ones(k1 - k0 + 1, dtype=bool)
        base = 1 + n_ch + 4
        modes[0] = [of_bits[(rows[0][1 + n_ch] >> (2 * j)) & 3] for j in range(n_m)]
        for prev, r in zip(rows, rows[1:]):
            kp, k = prev[0], r[0]
            cur, pos = modes[kp - k0].copy(), kp + 1
            for e in r[base + 2:]:
                s = k - (e >> 6)
                modes[pos - k0:s - k0] = cur
                cur[(e >> 2) & 15] = of_bits[e & 3]
                pos = s
            modes[pos - k0:k - k0 + 1] = cur
            if r[base + 1]:                      # lost events: the window is unknown, its last sample not
                known[kp + 1 - k0:k - k0] = False
                modes[k - k0] = [of_bits[(r[1 + n_ch] >> (2 * j)) & 3] for j in range(n_m)]
        return np.arange(k0, k1 + 1), modes, known
    k0 = max(0, rows[0][0] - every + 1)
    k1 = rows[-1][0]
    modes = np.zeros((k1 - k0 + 1, n_m), dtype=np.int8)
    for r in rows:
        k = r[0]
        for j, h in enumerate(r[5 + n_ch:5 + n_ch + n_m]):
            for i in range(min(every, k - k0 + 1)):
                modes[k - i - k0, j] = of_bits[(h >> (2 * i)) & 3]
    return np.arange(k0, k1 + 1), modes, np.ones(k1 - k0 + 1, dtype=bool)


def commands(log: Log, rec: dict, last_sample: int | None = None):
    """Every valve command the board issued from the log's first covered sample to its last record's
    (``last_sample`` at most): (samples k [int array], modes [k, muscle]: 1 charge, 0 hold, -1
    vent), from the records' valve histories (format 3) or events (format 4; :data:`REASONS`
    checked them). ScenarioError naming the log if it does not carry them all
    (:func:`commands_missing`) or naming the first gap (:func:`commands_gap`)."""
    k, modes, known = _commands(log, rec, last_sample)
    if not known.all():
        raise ScenarioError("the serial log's valve commands", UNKNOWN_TEXT, commands_gap(log, rec, last_sample))
    return k, modes


def commands_table(log: Log, rec: dict, last_sample: int | None = None):
    """The commands (:func:`commands`) as a DataFrame: ``time [s]`` (k / rate) and a column
    ``<muscle> command [1 = charge, 0 = hold, -1 = vent]`` per muscle, one row at the first sample,
    at each sample where a command changes and at the last sample (a command holds until the next
    row). Where a record's events were lost (:func:`commands_gap`) a row at the gap's first sample
    has every command empty: unknown until the next row (the record's own sample)."""
    import pandas as pd
    from frogsim.scenario.tables import header
    k, modes, known = _commands(log, rec, last_sample)
    change = np.ones(len(k), dtype=bool)
    change[1:] = (np.any(modes[1:] != modes[:-1], axis=1) & known[1:]) | (known[1:] != known[:-1])
    change[-1] = True
    data = {header("time", "s"): k[change] / float(rec["rate_hz"])}
    for j, m in enumerate(rec["muscles"]):
        col = pd.array(modes[change, j].astype(int), dtype="Int64")
        col[~known[change]] = pd.NA
        data[header(f"{m} command", COMMAND_UNIT)] = col
    return pd.DataFrame(data)


def write_commands_csv(path, log: Log, rec: dict, last_sample: int | None = None) -> Path:
    """Write :func:`commands_table` as CSV (atomic); returns the path."""
    from frogsim._files import write_csv
    write_csv(Path(path), commands_table(log, rec, last_sample), progress=False)
    return Path(path)


def write_log_csv(path, log: Log, rec: dict, last_sample: int | None = None) -> Path:
    """Write the table as CSV (frogsim's one CSV writer, atomic); returns the path."""
    from frogsim._files import write_csv
    write_csv(Path(path), log_table(log, rec, last_sample), progress=False)
    return Path(path)


# -- the port ------------------------------------------------------------------------------------------
def open_port(port, rec: dict | None, baud: int | None = None, opener=None):
    """The serial port ``port`` opened with pyserial at the plan's baud rate (without a plan the
    default 115200), or ScenarioError naming the port (nothing is read yet)."""
    if opener is None:
        try:
            import serial
        except ImportError:
            raise ScenarioError("--port", port, "reading a serial port needs pyserial (pip install pyserial)") \
                from None
        opener = serial.Serial
    try:
        return opener(port, baud or int((rec or {}).get("baud", DEFAULT_BAUD)), timeout=0.2)
    except Exception as exc:     # pyserial raises SerialException, OSError, ValueError
        raise ScenarioError("--port", port, f"cannot be opened: {exc}") from None


def record_port(port, rec: dict | None, duration: float | None = None, progress=None, baud: int | None = None,
                opener=None, link=None, idle_timeout: float | None = DEFAULT_IDLE_TIMEOUT) -> Log:
    """Read and check the firmware's lines from serial port ``port`` (pyserial; or from ``link``,
    anything with ``read(n)`` and ``close()``, e.g. a port :func:`open_port` opened) for
    ``duration`` [s] (None: until Ctrl-C), stopping early when no byte came for ``idle_timeout``
    [s] (None: never), then close it. Without a plan (``rec`` None) the header line makes one.
    ScenarioError naming the port if it cannot be opened, or if the header says another firmware."""
    if link is None:
        link = open_port(port, rec, baud, opener)
    reader = LineReader(rec)
    log = reader.log
    log.idle_timeout = idle_timeout
    t0 = time.monotonic()
    shown = last_byte = t0
    try:
        while True:
            now = time.monotonic()
            if duration is not None and now - t0 >= duration:
                log.stopped_by = "duration"
                break
            if idle_timeout is not None and now - last_byte >= idle_timeout:
                log.stopped_by, log.idle_timeout_hit = "idle timeout", True
                break
            chunk = link.read(4096)
            if chunk:
                last_byte = time.monotonic()
                reader.feed(bytes(chunk))
            elif time.monotonic() - now < 0.02:
                time.sleep(0.02)           # a link that returns at once when it has nothing: no busy loop
            now = time.monotonic()
            if progress is not None and now - shown > 2.0:
                shown = now
                progress(f"      {len(log.records)} records in {now - t0:.0f} s")
    except KeyboardInterrupt:
        log.stopped_by = "Ctrl-C"
    finally:
        link.close()
        log.capture_s = time.monotonic() - t0
    return reader.finish()


# -- what the capture held -----------------------------------------------------------------------------
def _reasons(log: Log) -> str:
    return ", ".join(f"{r} {n}" for r, n in sorted(log.discarded.items(), key=lambda x: -x[1]))


def first_lines(log: Log) -> str:
    """A one-line description of what was read."""
    if not log.records:
        return "no records"
    k0, k1 = log.records[0][0], log.records[-1][0]
    return f"{len(log.records)} records, samples {k0}..{k1}" + (f", {log.bad} lines discarded" if log.bad else "") + \
        (f", {log.dropped} dropped by the firmware" if log.dropped else "")


def describe_empty(log: Log) -> str:
    """What a capture without a single valid record held, on one line."""
    seen = [f"{log.bytes_read} bytes", f"{log.lines} lines",
            f"header {clip(log.header[2:], 60)!r}" if log.header else "no header line"]
    if log.discarded:
        seen.append(f"discarded: {_reasons(log)}")
    if log.idle_timeout_hit:
        seen.append(f"stopped after {log.idle_timeout:g} s without a byte (--idle-timeout)")
    return "; ".join(seen)


def log_summary(log: Log, plan: dict) -> dict:
    """The capture in numbers (summary.json "log"): records, first and last k and time, lines
    discarded by reason with examples, the overrun and dropped counters (first, last, increase),
    records missing from gaps in k, samples with a fault bit, the idle timeout, bytes, duration."""
    rate = float(plan["rate_hz"])
    every = plan.get("log_every")
    first = last = None
    if log.records:
        first = {"k": log.records[0][0], "time_s": log.records[0][0] / rate}
        last = {"k": log.records[-1][0], "time_s": log.records[-1][0] / rate}

    def counter(a, b):
        if a is None:
            return {"first": None, "last": None, "increase": None, "saturated": False}
        return {"first": a, "last": b, "increase": b - a, "saturated": b >= COUNTER_MAX}

    dropped = counter(log.dropped_first, log.dropped if log.records else None)
    dropped["missing_from_k_gaps"] = log.missing_from_k_gaps if every else None
    dropped["agree"] = None if not (every and log.records) else dropped["increase"] == log.missing_from_k_gaps
    return {
        "header": log.header or None,
        "format": log.format or plan.get("format"),
        "log_every": every,
        "records": len(log.records),
        "first": first,
        "last": last,
        "discarded_lines": log.bad,
        "discarded": dict(sorted(log.discarded.items())),
        "discarded_examples": list(log.examples),
        "restarts": log.restarts,
        "overruns": counter(log.overruns_first, log.overruns_last),
        "dropped": dropped,
        "faults": {"samples": log.fault_samples,
                   "per_channel": {ch["signal"]: (log.faults_per_channel[i] if log.faults_per_channel else 0)
                                   for i, ch in enumerate(plan["channels"])}},
        "valve_events": None if (log.format or plan.get("format")) != EVENTS_FORMAT else
        {"slots": plan.get("event_slots"), "lost": log.events_lost, "records_with_lost": log.records_with_lost,
         "first_lost_k": None if log.first_lost is None else log.first_lost[0]},
        "idle_timeout": {"seconds": log.idle_timeout, "hit": log.idle_timeout_hit},
        "stopped_by": log.stopped_by or None,
        "bytes_read": log.bytes_read,
        "lines_read": log.lines,
        "capture_s": log.capture_s,
    }


def log_warnings(log: Log, plan: dict, checked_header: bool) -> list[str]:
    """One warning per thing a capture should not have: discarded lines, overruns, drops (and
    the counter and the k gaps disagreeing), fault bits, a restart, the idle timeout, no header
    to check firmware.json against (``checked_header``: a firmware.json was given)."""
    s = log_summary(log, plan)
    out = []
    if log.discarded:
        ex = log.examples[0]
        out.append(f"{log.bad} lines discarded, not in serial.csv: {_reasons(log)} (the first, line {ex['line']}: "
                   f"{ex['reason']}: {ex['text']!r}; summary.json 'log' has more)")
    if log.restarts:
        out.append(f"the board restarted during the capture ({log.restarts} header lines after records): "
                   "serial.csv holds its last run only")
    ov = s["overruns"]
    if ov["last"]:
        out.append(f"the firmware overran its period {ov['increase']} times during the capture (its counter went "
                   f"{ov['first']} -> {ov['last']}{', saturated: at least' if ov['saturated'] else ''}): "
                   "those samples came late")
    dr = s["dropped"]
    gaps = dr["missing_from_k_gaps"]
    if dr["last"] or gaps:
        out.append(f"records dropped: the firmware's dropped counter went {dr['first']} -> {dr['last']} "
                   f"(+{dr['increase']}{', saturated' if dr['saturated'] else ''}), gaps in k miss "
                   f"{'?' if gaps is None else gaps} records: the log could not keep up (lower the log rate "
                   "or raise the baud rate)")
    if dr["agree"] is False:
        out.append(f"the gaps in k ({gaps} records missing) and the firmware's dropped counter (+{dr['increase']}) "
                   "disagree: records were lost on the link or discarded here")
    if log.fault_samples:
        per = ", ".join(f"{k} {v}" for k, v in s["faults"]["per_channel"].items() if v)
        out.append(f"{log.fault_samples} of {len(log.records)} records have a channel read in fault ({per})")
    if log.idle_timeout_hit:
        out.append(f"no byte came for {log.idle_timeout:g} s (--idle-timeout): the capture stopped after "
                   f"{log.capture_s:.1f} s")
    if checked_header and not log.header:
        out.append("no header line came (the board sends it when it starts): the records were checked against "
                   "firmware.json's channels, but its name and plan digest could not be compared")
    return out
