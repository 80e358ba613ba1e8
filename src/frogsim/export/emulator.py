"""An emulated Arduino Mega 2560 that runs a firmware's own machine code: simavr's ATmega2560
core (Debian ``simavr``, ``libsimavr-dev``), driven cycle by cycle from Python.

The C side (``board_sim.c`` beside this module) is compiled on first use with the host's gcc,
linked against libsimavr, and kept in frogsim's user cache folder under a hash of its source, so
an edit rebuilds it. :class:`EmulatedBoard` loads an ELF and gives the plant's side of the wires:
analog input voltages, driven digital inputs, the firmware's pin changes with the AVR cycle at
which they happened, and the bytes it sends on the serial port (USART0).

Missing tools are refused with the Debian packages to install (:data:`APT_LINE`).
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import struct
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from frogsim._files import user_cache_folder
from frogsim.errors import FrogsimError, ScenarioError, clip
from frogsim.export.board import F_CPU, FLASH_BYTES, Pin

#: the Debian packages the firmware path needs: the AVR tool chain, the Arduino AVR core, simavr
APT_PACKAGES = ("gcc-avr", "avr-libc", "binutils-avr", "arduino-core-avr", "arduino-mk", "simavr",
                "libsimavr-dev")
APT_LINE = "apt-get update && apt-get install -y " + " ".join(APT_PACKAGES)
_SOURCE = Path(__file__).with_name("board_sim.c")
_SIMAVR_HEADER = Path("/usr/include/simavr/sim_avr.h")


def millivolts_for_count(count, vref_mv: int = 5000):
    """The whole millivolts at which simavr's 10-bit ADC reads ``count``.

    simavr converts an input of v millivolts to floor(v x 1023 / V_ref) (its scale is 1023, the
    datasheet's ideal converter's is 1024: ADC = V_in 1024 / V_ref, Sec. 26.7), and takes whole
    millivolts. To give the firmware the count the ideal converter makes from the plant's voltage,
    software in the loop computes that count and feeds the smallest voltage simavr reads as it:
    ceil(count x V_ref / 1023). An int, or an integer array elementwise."""
    return -(-count * vref_mv // 1023)


def _count_outside(channels, counts, i: int, shift: int) -> ValueError:
    """The refusal of analog count ``counts[i]`` on input A<channels[i]>: outside the converter's range."""
    return ValueError(f"analog input A{int(channels[i])}: count {int(counts[i])} is outside the "
                      f"converter's 0..{1023 >> int(shift)}")


class ToolMissing(FrogsimError):
    """A tool of the firmware path is not installed."""


def require(tool: str) -> str:
    """The path of an executable on PATH, or ToolMissing naming the packages to install."""
    path = shutil.which(tool)
    if path is None:
        raise ToolMissing(f"{tool} not found: the firmware tools are Debian packages ({APT_LINE})")
    return path


def _library() -> Path:
    """The compiled harness (built once per source version into the user cache)."""
    if not _SIMAVR_HEADER.exists():
        raise ToolMissing(f"simavr's headers ({_SIMAVR_HEADER}) not found: install them ({APT_LINE})")
    cc = require("gcc")
    tag = hashlib.sha256(_SOURCE.read_bytes() + _SIMAVR_HEADER.read_bytes()).hexdigest()[:16]
    folder = Path(user_cache_folder("board") or tempfile.gettempdir())
    lib = folder / f"board_sim-{tag}.so"
    if lib.exists():
        return lib
    folder.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".so", dir=folder)
    os.close(fd)
    run = subprocess.run([cc, "-O2", "-shared", "-fPIC", "-o", tmp, str(_SOURCE), "-lsimavr", "-lm"],
                         capture_output=True, text=True)
    if run.returncode != 0:
        os.unlink(tmp)
        raise ToolMissing(f"building the emulated board failed (is libsimavr-dev installed? {APT_LINE}):\n"
                          f"{run.stderr.strip()}")
    os.replace(tmp, lib)              # atomic: a parallel build of the same source is harmless
    return lib


_LIB = None


def _lib():
    global _LIB
    if _LIB is None:
        lib = ctypes.CDLL(str(_library()))
        u64, i32, vp = ctypes.c_uint64, ctypes.c_int32, ctypes.c_void_p
        lib.board_open.restype = vp
        lib.board_open.argtypes = [ctypes.c_char_p, ctypes.c_uint32, ctypes.c_uint32]
        lib.board_close.argtypes = [vp]
        lib.board_watch.argtypes = [vp, ctypes.c_char, ctypes.c_int, ctypes.c_int]
        lib.board_watch_vector.argtypes = [vp, ctypes.c_int, ctypes.c_int]
        lib.board_sleep_cycles.restype = u64
        lib.board_sleep_cycles.argtypes = [vp]
        lib.board_sleep_busy_cycles.restype = u64
        lib.board_sleep_busy_cycles.argtypes = [vp]
        lib.board_set_adc_mv.argtypes = [vp, ctypes.c_int, ctypes.c_uint32]
        lib.board_set_adc_many.argtypes = [vp, ctypes.c_int, vp, vp]
        lib.board_set_adc_counts.restype = ctypes.c_long
        lib.board_set_adc_counts.argtypes = [vp, ctypes.c_int, vp, vp, ctypes.c_int, ctypes.c_uint32]
        lib.board_set_pin.argtypes = [vp, ctypes.c_char, ctypes.c_int, ctypes.c_int]
        lib.board_run_until.argtypes = [vp, u64]
        lib.board_read_ram.restype = ctypes.c_long
        lib.board_read_ram.argtypes = [vp, ctypes.c_uint32, ctypes.c_char_p, ctypes.c_long]
        lib.board_run_until_pin.restype = ctypes.c_int
        lib.board_run_until_pin.argtypes = [vp, ctypes.c_int, ctypes.c_int, u64]
        lib.board_cycle.restype = u64
        lib.board_cycle.argtypes = [vp]
        ptr = np.ctypeslib.ndpointer
        lib.board_events.restype = ctypes.c_long
        lib.board_events.argtypes = [vp, ptr(np.uint64), ptr(np.int32), ptr(np.int32), ctypes.c_long]
        lib.board_uart_read.restype = ctypes.c_long
        lib.board_uart_read.argtypes = [vp, ptr(np.uint8), ptr(np.uint64), ctypes.c_long]
        lib.board_lost.restype = ctypes.c_long
        lib.board_lost.argtypes = [vp]
        lib.board_track.restype = ctypes.c_int
        lib.board_track.argtypes = [vp, ctypes.c_int, ctypes.c_int, ctypes.c_int, vp, vp, vp, vp, vp, vp,
                                    ctypes.c_long, vp, vp, vp, vp, ctypes.c_long, vp, ctypes.c_long]
        lib.board_drain.restype = ctypes.c_long
        lib.board_drain.argtypes = [vp]
        lib.board_frame_setup.restype = ctypes.c_int
        lib.board_frame_setup.argtypes = [vp, ctypes.c_int, vp, vp, ctypes.c_int, ctypes.c_uint32, ctypes.c_int,
                                          vp, vp, vp, vp, vp, vp, ctypes.c_long, ctypes.c_int, ctypes.c_uint32,
                                          ctypes.c_int, vp, ctypes.c_long]
        lib.board_frame.restype = ctypes.c_long
        lib.board_frame.argtypes = [vp, u64, u64]
        del i32
        _LIB = lib
    return _LIB


EM_AVR = 83                   # e_machine of an AVR ELF
AVR_ARCH_MASK = 0x7f          # e_flags & this: the AVR architecture (avr5 = 5, ...)
ATMEGA2560_ARCH = 6           # avr6: more than 128 KB of flash (a 3-byte program counter)
#: avr-gcc's architectures and a part of each, for the refusal's message
AVR_ARCHS = {1: "avr1 (e.g. ATtiny11)", 2: "avr2 (e.g. ATtiny22)", 25: "avr25 (e.g. ATtiny85)",
             3: "avr3 (e.g. ATmega103)", 31: "avr31", 35: "avr35 (e.g. ATmega16U2)",
             4: "avr4 (e.g. ATmega8)", 5: "avr5 (e.g. ATmega328P)", 51: "avr51 (e.g. ATmega1284P)",
             6: "avr6 (ATmega2560)", 100: "avrtiny", 102: "avrxmega2", 103: "avrxmega3",
             104: "avrxmega4", 105: "avrxmega5", 106: "avrxmega6", 107: "avrxmega7"}
_ELF32_HEADER = struct.Struct("<16sHHIIIIIHHHHHH")     # 52 bytes
_PHDR = struct.Struct("<IIIIIIII")                      # 32 bytes: type, offset, vaddr, paddr, filesz, ...
_SHDR = struct.Struct("<IIIIIIIIII")                    # 40 bytes: name, type, flags, addr, offset, size, ...
_SYM = struct.Struct("<IIIBBH")                         # 16 bytes: name, value, size, info, other, shndx
_SHT_SYMTAB = 2
_SHT_NOBITS = 8


def check_avr_elf(path, folder=None) -> None:
    """ScenarioError (naming --firmware and the file) unless ``path`` is an ELF file simavr can
    load as the ATmega2560's firmware: the ELF magic, 32-bit, little-endian, an executable for
    e_machine 83 (EM_AVR) of architecture avr6 (e_flags & 0x7f; an ATmega328P's is avr5), a
    header, a program header table and a section header table of the sizes ELF32 gives and
    within the file, every loaded segment and every section's bytes within the file, the names of
    the sections and symbols within their string tables, .text and .data within the 256 KB of
    flash. Read here, before simavr sees the file: libsimavr's loader trusts all of these (a file
    of another machine, or a damaged one, crashes it or makes it abort), and a truncated file
    stops avr-nm. With ``folder`` (the firmware folder given as
    --firmware) the message names the folder and the ELF's path in it."""
    path = Path(path)
    value, what = str(path), ""
    if folder is not None:
        value = str(folder)
        what = (path.relative_to(folder).as_posix() if path.is_relative_to(folder) else str(path)) + " "

    def bad(why: str):
        raise ScenarioError("--firmware", value, f"{what}{why}: build it for the Mega 2560 (frogsim firmware "
                                                 "SCENARIO --out DIR --build)")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ScenarioError("--firmware", value, f"{what}cannot be read ({exc.strerror or exc})") from None
    size = len(data)
    if size < 4 or data[:4] != b"\x7fELF":
        bad("is not an ELF file (no ELF magic number)")
    if size < _ELF32_HEADER.size:
        bad(f"is a damaged ELF file ({size} bytes, shorter than an ELF header)")
    (ident, e_type, e_machine, e_version, _entry, e_phoff, e_shoff, e_flags, e_ehsize, e_phentsize,
     e_phnum, e_shentsize, e_shnum, e_shstrndx) = _ELF32_HEADER.unpack_from(data)
    if ident[4] != 1:
        bad(f"is a {'64-bit' if ident[4] == 2 else 'damaged'} ELF file, not a 32-bit one (an AVR's)")
    if ident[5] != 1:
        bad("is a big-endian or damaged ELF file, not a little-endian one (an AVR's)")
    if e_machine != EM_AVR:
        bad(f"is an ELF file for another machine (e_machine {e_machine}, not {EM_AVR}: AVR)")
    arch = e_flags & AVR_ARCH_MASK
    if arch != ATMEGA2560_ARCH:
        bad(f"is an AVR ELF file for {AVR_ARCHS.get(arch, f'architecture {arch}')}, not the ATmega2560's avr6")
    if e_type != 2:
        bad(f"is an AVR ELF file of type {e_type}, not an executable (an object file or a library?)")
    if e_version != 1 or e_ehsize != _ELF32_HEADER.size:
        bad("is a damaged ELF file (its header's version or size is not ELF32's)")
    if e_phnum == 0:
        bad("is an ELF file without program headers (nothing to load)")
    if e_phentsize != _PHDR.size or e_phnum > 64 or e_phoff + e_phnum * _PHDR.size > size:
        bad(f"is a damaged or truncated ELF file (its program header table, {e_phnum} entries at byte "
            f"{e_phoff}, does not lie within its {size} bytes)")
    if e_shnum and (e_shentsize != _SHDR.size or e_shnum > 4096 or e_shoff + e_shnum * _SHDR.size > size
                    or e_shstrndx >= e_shnum):
        bad(f"is a damaged or truncated ELF file (its section header table, {e_shnum} entries at byte "
            f"{e_shoff}, does not lie within its {size} bytes)")
    for k in range(e_phnum):
        _t, offset, _va, _pa, filesz = _PHDR.unpack_from(data, e_phoff + k * _PHDR.size)[:5]
        if offset + filesz > size:
            bad(f"is a truncated ELF file (segment {k} ends at byte {offset + filesz} of {size})")
    sections = [_SHDR.unpack_from(data, e_shoff + k * _SHDR.size) for k in range(e_shnum)]
    for k, sh in enumerate(sections):
        if sh[1] != _SHT_NOBITS and sh[4] + sh[5] > size:
            bad(f"is a truncated ELF file (section {k} ends at byte {sh[4] + sh[5]} of {size})")
    # what simavr's loader reads by section (libelf hands it NULL for a name or data it cannot
    # find, and it does not look): every section's name within the section name table, a symbol
    # table's entries of ELF32's size with their names in their string table, and the flash
    # image (.text and .data) bytes of the file that fit the ATmega2560's flash
    names = {}
    if e_shnum:
        strtab = sections[e_shstrndx]
        for k, sh in enumerate(sections):
            if strtab[1] == _SHT_NOBITS or sh[0] >= strtab[5] or data.find(b"\0", strtab[4] + sh[0],
                                                                              strtab[4] + strtab[5]) < 0:
                bad(f"is a damaged ELF file (section {k}'s name lies outside the section name table)")
            names[data[strtab[4] + sh[0]:data.index(b"\0", strtab[4] + sh[0])]] = sh
        for k, sh in enumerate(sections):
            if sh[1] == _SHT_SYMTAB:
                link = sections[sh[6]] if sh[6] < e_shnum else None
                if sh[9] != _SYM.size or link is None or link[1] == _SHT_NOBITS:
                    bad(f"is a damaged ELF file (its symbol table, section {k}, is not ELF32's)")
                for j in range(sh[5] // _SYM.size):
                    if _SYM.unpack_from(data, sh[4] + j * _SYM.size)[0] >= link[5]:
                        bad(f"is a damaged ELF file (symbol {j}'s name lies outside its string table)")
    flash = 0
    for name in (b".text", b".data"):
        sh = names.get(name)
        if sh is not None:
            if sh[1] == _SHT_NOBITS:
                bad(f"is a damaged ELF file (its {name.decode()} section holds no bytes)")
            flash += sh[5]
    if flash > FLASH_BYTES:
        bad(f"is an ELF file whose .text and .data take {flash} bytes, more than the ATmega2560's "
            f"{FLASH_BYTES} bytes of flash")


def symbol_address(elf, name: str) -> int:
    """The data-space address of variable ``name`` in ``elf`` (from ``avr-nm``; the AVR tool chain
    places data at 0x800000 + address); ScenarioError in one line if avr-nm cannot read the ELF,
    FrogsimError if the ELF has no such symbol."""
    run = subprocess.run([require("avr-nm"), str(elf)], capture_output=True, text=True)
    if run.returncode != 0:
        why = next((line.strip() for line in run.stderr.splitlines() if line.strip()), f"exit {run.returncode}")
        raise ScenarioError("--firmware", str(elf), f"avr-nm cannot read its symbols ({clip(why, 160)}): a "
                                                    "damaged ELF file; build it again")
    out = run.stdout
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[2] == name:
            return int(parts[0], 16) - 0x800000
    raise FrogsimError(f"{elf}: no symbol {name!r} (a firmware of another frogsim version?)")


def check_tools() -> None:
    """ToolMissing (with the apt line) unless the emulated board can be built and loaded and the
    ELF's symbols read: simavr's headers and library, gcc, avr-nm."""
    require("avr-nm")
    _lib()


class EmulatedBoard:
    """An ATmega2560 at ``f_cpu`` running the ELF ``elf``, AVcc = AREF = ``vref`` [V].

    Use :meth:`watch` for each output pin before running, then alternate :meth:`set_analog` /
    :meth:`set_pin` (the plant's side) with :meth:`run_until` (the firmware's), and read
    :meth:`events` and :meth:`serial`.
    """

    def __init__(self, elf, f_cpu: int = F_CPU, vref: float = 5.0):
        path = Path(elf)
        if not path.is_file():
            raise FrogsimError(f"firmware {str(path)!r}: no such file")
        check_avr_elf(path)
        self._lib = _lib()
        self._h = self._lib.board_open(str(path).encode(), int(f_cpu), int(round(vref * 1000)))
        if not self._h:
            raise FrogsimError(f"firmware {str(path)!r}: simavr could not load it as an ATmega2560 ELF")
        self.f_cpu = int(f_cpu)
        self.vref = float(vref)
        self.watched: list[Pin] = []

    def close(self) -> None:
        if self._h:
            self._lib.board_close(self._h)
            self._h = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        try:
            self.close()
        except Exception:            # noqa: BLE001  (interpreter shutdown)
            pass

    @property
    def cycle(self) -> int:
        """CPU cycles run so far."""
        return int(self._lib.board_cycle(self._h))

    def watch(self, pin: Pin) -> int:
        """Record every change of output ``pin``; returns its index in :meth:`events`."""
        index = len(self.watched)
        if self._lib.board_watch(self._h, pin.port.encode(), pin.bit, index) != 0:
            raise FrogsimError(f"pin {pin.number}: cannot watch port {pin.port} bit {pin.bit}")
        self.watched.append(pin)
        return index

    def watch_vector(self, vector: int) -> int:
        """Record interrupt vector ``vector`` (the datasheet's number: TIMER1_COMPA is 17 on the
        ATmega2560) among :meth:`events`: value 1 at the cycle its flag is raised (the hardware
        event: a compare match), 0 when the CPU takes it. Returns its index in :meth:`events`."""
        index = len(self.watched)
        if self._lib.board_watch_vector(self._h, int(vector), index) != 0:
            raise FrogsimError(f"interrupt vector {vector}: cannot watch it")
        self.watched.append(None)
        return index

    @property
    def sleep_cycles(self) -> int:
        """CPU cycles the core has spent asleep so far (after SLEEP, until an interrupt woke it)."""
        return int(self._lib.board_sleep_cycles(self._h))

    @property
    def sleep_busy_cycles(self) -> int:
        """Of :attr:`sleep_cycles`, those spent while the busy pin of the last :meth:`run_frame`
        was high (a firmware idling inside its interrupt, waiting for its conversions)."""
        return int(self._lib.board_sleep_busy_cycles(self._h))

    def set_analog(self, channel: int, millivolts: int) -> None:
        """The voltage at analog input A<channel> [mV, whole: simavr's unit], held until changed."""
        self._lib.board_set_adc_mv(self._h, int(channel), int(millivolts))

    def set_analog_many(self, channels: np.ndarray, millivolts: np.ndarray) -> None:
        """:meth:`set_analog` for several inputs at once: A<channels[i]> to ``millivolts[i]``
        (int32 and uint32 arrays, contiguous), each raised only where it changed."""
        self._lib.board_set_adc_many(self._h, int(channels.size), channels.ctypes.data, millivolts.ctypes.data)

    def set_analog_counts(self, channels: np.ndarray, counts: np.ndarray, shift: int = 0) -> None:
        """Inputs A<channels[i]> (int32) at the voltage simavr's 10-bit converter reads as
        ``counts[i] << shift`` (int64, contiguous): :func:`millivolts_for_count` of each, set in
        one call where it changed. ValueError (nothing set) for a count outside the converter's."""
        bad = self._lib.board_set_adc_counts(self._h, int(channels.size), channels.ctypes.data, counts.ctypes.data,
                                             int(shift), int(round(self.vref * 1000)))
        if bad >= 0:
            raise _count_outside(channels, counts, bad, shift)

    def set_pin(self, pin: Pin, value: int) -> None:
        """Drive input ``pin`` high (1) or low (0) from outside."""
        self._lib.board_set_pin(self._h, pin.port.encode(), pin.bit, 1 if value else 0)

    def run_until(self, cycle: int) -> None:
        """Run the firmware until the cycle counter reaches ``cycle``; FrogsimError if it stopped."""
        if self._lib.board_run_until(self._h, int(cycle)) != 0:
            raise FrogsimError(f"the firmware stopped or crashed at cycle {self.cycle}")

    def read_ram(self, address: int, size: int) -> bytes:
        """``size`` bytes of the AVR's data memory at ``address`` (data space; an ELF symbol's
        address less 0x800000, see :func:`symbol_address`)."""
        buf = ctypes.create_string_buffer(int(size))
        if self._lib.board_read_ram(self._h, int(address), buf, int(size)) != size:
            raise FrogsimError(f"data memory {address:#x}..{address + size:#x}: outside the ATmega2560's")
        return buf.raw

    def run_until_pin(self, index: int, value: int, max_cycle: int) -> bool:
        """Run the firmware until watched pin ``index`` (from :meth:`watch`) changes to ``value``
        (True; the change is among :meth:`events`) or the cycle counter reaches ``max_cycle``
        (False). FrogsimError if the firmware stopped."""
        st = self._lib.board_run_until_pin(self._h, int(index), 1 if value else 0, int(max_cycle))
        if st < 0:
            raise FrogsimError(f"the firmware stopped or crashed at cycle {self.cycle}")
        return st == 1

    def events(self, limit: int = 1 << 16) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The watched pins' changes since the last call: (cycle, watch index, value) arrays."""
        c = np.empty(limit, np.uint64)
        i = np.empty(limit, np.int32)
        v = np.empty(limit, np.int32)
        n = self._lib.board_events(self._h, c, i, v, limit)
        return c[:n], i[:n], v[:n]

    # -- a controller period in one call (frogsim.export.sil.BoardRun) ---------------------------
    #: board_track's counters: valve mode changes, executions and compare matches read by the last
    #: drain, valve-pin events with both valves of a muscle open, the busy pin's last rise (-1:
    #: low), the cycle of the last valve mode change (-1: none), 1 if events are still queued
    TR_CHANGES, TR_EXECUTIONS, TR_TICKS, TR_BOTH_OPEN, TR_RISE, TR_LAST_EDGE, TR_MORE = range(7)

    def track(self, busy: int, tick: int, valves, changes: int = 1 << 12, executions: int = 64,
              ticks: int = 64) -> None:
        """Read the queued pin events in C from now on (:meth:`drain`): watch ``busy`` is the
        firmware's busy pin (an execution of its interrupt from a rise to the next fall), watch
        ``tick`` Timer1's compare flag (a match at each raise), ``valves`` the (charge watch,
        discharge watch) of each muscle, whose mode is 1 (charge alone open), -1 (discharge
        alone) or 0. Each drain fills, from their starts, :attr:`changes` (cycle, muscle, mode
        arrays), :attr:`executions` (start, end, last valve change's cycle or -1, the modes at
        its end) and :attr:`ticks`, and the counters :attr:`counters` (``TR_*``)."""
        nv = len(valves)
        self._tr_charge = np.array([c for c, _ in valves], np.int32)
        self._tr_dis = np.array([d for _, d in valves], np.int32)
        self.counters = np.zeros(7, np.int64)
        self.changes = (np.zeros(changes, np.uint64), np.zeros(changes, np.int32), np.zeros(changes, np.int8))
        self.executions = (np.zeros(executions, np.uint64), np.zeros(executions, np.uint64),
                           np.zeros(executions, np.int64), np.zeros((executions, max(nv, 1)), np.int8))
        self.ticks = np.zeros(ticks, np.uint64)
        ch, ex = self.changes, self.executions
        if self._lib.board_track(self._h, int(busy), int(tick), nv, self._tr_charge.ctypes.data,
                                 self._tr_dis.ctypes.data, self.counters.ctypes.data, ch[0].ctypes.data,
                                 ch[1].ctypes.data, ch[2].ctypes.data, changes, ex[0].ctypes.data, ex[1].ctypes.data,
                                 ex[2].ctypes.data, ex[3].ctypes.data, executions, self.ticks.ctypes.data, ticks) != 0:
            raise FrogsimError(f"cannot track {nv} valves on watches {busy}, {tick}: outside the harness's range")

    def drain(self) -> bool:
        """Read the queued pin events (:meth:`track`); True if some are still queued (an array
        was full: drain again after reading these)."""
        return self._lib.board_drain(self._h) > 0

    def frame_setup(self, inputs: np.ndarray, counts: np.ndarray, shift: int, encoders, enc_counts: np.ndarray,
                    targets: np.ndarray, most: int, snap_index: int, snap_address: int, snaps: np.ndarray) -> None:
        """What :meth:`frame` does each period, with the caller's arrays read at each call (so
        the caller writes into them between calls): analog inputs A<inputs[i]> (int32) at
        ``counts[i] << shift`` (int64, :meth:`set_analog_counts`); ``encoders`` (A pin, B pin)
        moving from ``enc_counts`` to ``targets`` (int32; one edge a count, spread evenly over the
        period, B set before A; at most ``most`` counts); snapshots of ``snaps.shape[1]`` bytes at ``snap_address`` at each fall
        of watch ``snap_index`` into the rows of ``snaps`` (uint8)."""
        self._fr_shift = int(shift)
        self._fr = (inputs, counts, enc_counts, targets, snaps,
                    np.array([ord(a.port) for a, _ in encoders], np.uint8), np.array([a.bit for a, _ in encoders], np.int32),
                    np.array([ord(b.port) for _, b in encoders], np.uint8), np.array([b.bit for _, b in encoders], np.int32))
        _, _, _, _, _, ap, ab, bp, bb = self._fr
        for a in (inputs, counts, enc_counts, targets, snaps):
            if not a.flags.c_contiguous:
                raise ValueError("frame_setup: every array must be contiguous")
        if self._lib.board_frame_setup(self._h, int(inputs.size), inputs.ctypes.data, counts.ctypes.data, int(shift),
                                       int(round(self.vref * 1000)), len(encoders), ap.ctypes.data, ab.ctypes.data,
                                       bp.ctypes.data, bb.ctypes.data, enc_counts.ctypes.data, targets.ctypes.data,
                                       int(most), int(snap_index), int(snap_address), int(snaps.shape[1]),
                                       snaps.ctypes.data, int(snaps.shape[0])) != 0:
            raise ValueError(f"frame_setup: {inputs.size} analog inputs and {len(encoders)} encoders: at most 16 each")

    def frame(self, start: int, end: int) -> int:
        """One controller period as :meth:`frame_setup` says, from cycle ``start`` to ``end``,
        then :meth:`drain`. Returns the number of falls of the snap watch; FrogsimError if the
        firmware stopped; ``-1 - e`` (nothing run) if encoder e would move too far; ValueError
        (nothing run) for an analog count outside the converter's range."""
        got = self._lib.board_frame(self._h, start, end)
        if got >= 0:
            return got
        if got <= -1000:
            raise _count_outside(self._fr[0], self._fr[1], -1000 - got, self._fr_shift)
        if got <= -2:
            return got + 1
        raise FrogsimError(f"the firmware stopped or crashed at cycle {self.cycle}"
                           if got == -1 else "frame: call track and frame_setup first")

    def serial(self, limit: int = 1 << 20) -> tuple[bytes, np.ndarray]:
        """The bytes the firmware sent on USART0 since the last call, and the cycle of each."""
        b = np.empty(limit, np.uint8)
        c = np.empty(limit, np.uint64)
        n = self._lib.board_uart_read(self._h, b, c, limit)
        return b[:n].tobytes(), c[:n]

    @property
    def lost(self) -> int:
        """Pin events or serial bytes dropped because a queue was full (0 in a sound run)."""
        return int(self._lib.board_lost(self._h))
