"""The firmware's serial log read back: the lines ``k,count_0,...,count_n-1,valvebits,overruns``
(:mod:`frogsim.export.sketch`) turned into a table with units in its header (the convention of
:mod:`frogsim.scenario.tables`), the same for a real board (:func:`record_port`, pyserial) and
for the emulated one (software in the loop).

Columns: ``time [s]`` (k / rate: the sample's time since the firmware started), one per channel
(``hip pressure [bar gauge]``, ``hip_left angle [deg]``: count x unit_per_count + offset, the
channel's scale in firmware.json, whose offset puts the value in the middle of the count's step:
the estimate the converter's rounding down does not bias), then
``<muscle> charge valve [1 = open]`` and ``<muscle> discharge valve [1 = open]`` per muscle (the
overrun counter goes to the run's summary, not into the table). The valve and pressure columns are the ones ``frogsim simulate`` writes, so the
CSV is a trace ``frogsim fit`` reads as it is (it leaves the valve columns out by their names).
"""
from __future__ import annotations

import re
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from frogsim.errors import ScenarioError
from frogsim.scenario.tables import header

BAR = 1e5
DEFAULT_BAUD = 115200       # the [firmware] section's default baud rate
_HEADER = re.compile(r"# frogsim (\S+) rate=(\S+) channels=(.*) muscles=(.*)$")


@dataclass
class Log:
    """Parsed log: records (k, count_0 .. count_n-1, valvebits, overruns), the header line, the
    firmware's count of dropped lines and the lines that could not be read."""
    records: list = field(default_factory=list)
    header: str = ""
    dropped: int = 0
    bad: int = 0
    plan: dict | None = None      # made from the header line when no firmware.json was given


def plan_from_header(line: str) -> dict | None:
    """A plan record made from the firmware's header line alone (no firmware.json at hand): the
    channels' signals and the muscles, counts without a scale (quantity "count"); None if the
    line is not a frogsim header."""
    m = _HEADER.match(line.strip())
    if not m:
        return None
    try:
        rate = float(m.group(2))
    except ValueError:
        return None
    channels = []
    for item in filter(None, m.group(3).split(";")):
        signal, _, pin = item.rpartition("@A")
        channels.append({"signal": signal, "quantity": "count", "name": signal, "analog_input": int(pin or 0),
                         "unit_per_count": 1.0, "offset": 0.0, "unit": "count"})
    return {"format": 1, "name": m.group(1), "rate_hz": rate, "channels": channels,
            "muscles": [x for x in m.group(4).split(";") if x], "baud": DEFAULT_BAUD}


def parse_lines(lines, rec: dict | None, log: Log | None = None) -> Log:
    """Add text lines (without their newline) to ``log``: a line is kept when it has exactly the
    plan's number of fields, all whole numbers; '#' lines are the header and the dropped count.
    Without a plan (``rec`` None) the header line makes one (:func:`plan_from_header`, kept in
    ``log.plan``); lines before it are not read."""
    log = log or Log()
    for line in lines:
        line = line.strip()
        if not line:
            continue
        if line.startswith("#"):
            if line.startswith("# frogsim"):
                log.header = line
                if rec is None and log.plan is None:
                    log.plan = plan_from_header(line)
            elif line.startswith("# dropped"):
                try:
                    log.dropped = int(line.split()[-1])
                except ValueError:
                    log.bad += 1
            continue
        plan = rec if rec is not None else log.plan
        if plan is None:
            log.bad += 1
            continue
        parts = line.split(",")
        if len(parts) != len(plan["channels"]) + 3 or not all(p.isdigit() for p in parts):
            log.bad += 1
            continue
        log.records.append(tuple(int(p) for p in parts))
    return log


def parse_log(data: bytes, rec: dict) -> Log:
    """The whole lines in ``data`` (a trailing partial line is left out)."""
    text = data.decode("ascii", errors="replace")
    lines = text.split("\n")
    return parse_lines(lines[:-1], rec)


def columns(rec: dict) -> list[str]:
    """The table's headers (module docstring)."""
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
    rows = [r for r in log.records if last_sample is None or r[0] <= last_sample]
    rate = float(rec["rate_hz"])
    n_ch, n_m = len(rec["channels"]), len(rec["muscles"])
    a = np.array(rows, dtype=np.int64).reshape(len(rows), n_ch + 3)
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


def write_log_csv(path, log: Log, rec: dict, last_sample: int | None = None) -> Path:
    """Write the table as CSV (frogsim's one CSV writer); returns the path."""
    from frogsim._files import write_csv
    write_csv(Path(path), log_table(log, rec, last_sample), progress=False)
    return Path(path)


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
                opener=None, link=None) -> Log:
    """Read the firmware's lines from serial port ``port`` (pyserial; or from ``link``, a port
    :func:`open_port` opened) for ``duration`` [s] (None: until interrupted with Ctrl-C), then
    close it. Without a plan (``rec`` None) the header line makes one. ScenarioError naming the
    port if it cannot be opened."""
    if link is None:
        link = open_port(port, rec, baud, opener)
    log = Log()
    pending = b""
    t0 = time.monotonic()
    shown = t0
    try:
        while duration is None or time.monotonic() - t0 < duration:
            chunk = link.read(4096)
            if chunk:
                pending += chunk
                *whole, pending = pending.split(b"\n")
                parse_lines((w.decode("ascii", errors="replace") for w in whole), rec, log)
            now = time.monotonic()
            if progress is not None and now - shown > 2.0:
                shown = now
                progress(f"      {len(log.records)} lines in {now - t0:.0f} s")
    except KeyboardInterrupt:
        pass
    finally:
        link.close()
    return log


def first_lines(log: Log) -> str:
    """A one-line description of what was read."""
    if not log.records:
        return "no log lines"
    k0, k1 = log.records[0][0], log.records[-1][0]
    return f"{len(log.records)} lines, samples {k0}..{k1}" + (f", {log.bad} unreadable" if log.bad else "") + \
        (f", {log.dropped} dropped by the firmware" if log.dropped else "")

