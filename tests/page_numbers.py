"""Reading a number a page writes and comparing it with the run's: the page is under test, the run
is the truth. A number is compared at the precision the page writes it (its decimals), so a page
that rounds differently from the run, or a run that moved, fails."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NUM = r"([−-]?\d+(?:\.\d+)?)"


def page(name: str) -> str:
    """The text of docs/NAME (or of a path relative to the repository)."""
    path = ROOT / "docs" / name if "/" not in name else ROOT / name
    return path.read_text()


def section(text: str, start: str, end: str | None = None) -> str:
    """The text from the line holding ``start`` up to (not including) ``end`` (or the next heading)."""
    i = text.index(start)
    if end is None:
        m = re.compile(r"^#", re.M).search(text, text.index("\n", i) + 1)
        return text[i:m.start() if m else len(text)]
    return text[i:text.index(end, i)]


def table_rows(text: str, after: str) -> dict:
    """{first cell: [cells]} of the first Markdown table after the line containing ``after``."""
    start = text.index(after)
    rows = {}
    for line in text[start:].splitlines()[1:]:
        if not line.startswith("|"):
            if rows:
                break
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if set(cells[0]) <= set("-: "):
            continue
        rows[cells[0]] = cells
    return rows


def as_float(text: str) -> float:
    return float(text.replace("−", "-").replace(",", ""))


def same_as_written(text: str, value: float) -> bool:
    """value rounded to the decimals of text equals text (a minus sign either way; a written plus
    sign asks for a positive value)."""
    text = text.replace("−", "-")
    if text.startswith("+"):
        return value > 0 and same_as_written(text[1:], value)
    decimals = len(text.split(".")[1]) if "." in text else 0
    got = f"{value:.{decimals}f}"
    return got == text or (got == "-" + text.lstrip("-") and float(text) == 0.0)


def same_to_figures(text: str, value: float) -> bool:
    """value rounded to the significant figures of text equals text; an integer's trailing zeros
    are not significant ("13100" is 131 hundreds)."""
    text = text.replace("−", "-")
    digits = text.lstrip("-").replace(".", "").lstrip("0")
    figures = len(digits if "." in text else digits.rstrip("0")) or 1
    return float(f"{value:.{figures}g}") == float(text)


def check(text: str, patterns: list) -> None:
    """Each (regex with one number group, value) must match ``text`` once and read ``value`` at its
    written precision."""
    for pattern, value in patterns:
        found = re.findall(pattern, text)
        assert len(found) == 1, f"{pattern!r} matches {len(found)} times in {text[:300]!r}"
        assert same_as_written(found[0], value), f"the page writes {found[0]} for {pattern!r}, the run gives {value!r}"


# --- wall-clock figures ------------------------------------------------------------------------------
# How long a computation takes, how fast it runs against real time, how many steps it makes a
# second: such a figure is true of one machine under one load, and no test may time it (a timed
# test fails on a busy machine and passes a slow change on a fast one). So a page states one only
# as the output of a benchmark: the passage holding it names the benchmark that prints it
# (``bench_NAME.py`` of benchmarks/, in the passage or in its section's heading) and says on which
# machine it was measured. A target the benchmark checks ("target: 50x real time") names the
# benchmark and needs no machine. ``timing_problems`` applies the rule to a page's text.
BENCHMARKS = ROOT / "benchmarks"
_R = r"\d[\d,]*(?:\.\d+)?(?:\s?[-–]\s?\d[\d,]*(?:\.\d+)?)?"                 # 2.4, 2,700-3,200, 15-17
_WORDS = r"(?:one|two|three|four|five|six|seven|eight|nine|ten|a few)"
#: a duration, not one of simulated time ("10 s simulated", "2 s runs", "the 2 s hip-muscle cycle")
_DURATION = (rf"(?:{_R}\s?(?:µs|us|ms|s|min|minutes?|seconds?|hours?)|{_WORDS} (?:minutes|seconds|hours))\b"
             r"(?!\s(?:simulated|of simulated|[\w-]*\s?(?:cycles?|runs?|traces?|scenarios?|periods?)\b))")
#: figure kind -> the figure as a page writes it
WALL_CLOCK = {
    # 54.5x, 1,000-1,100x real time, about 70 x), (1.36 x slower), | about 60 x |
    "factor": re.compile(rf"(?<![\w.]){_R}(?:[x×](?!\w)|\s[x×](?=\s*(?:real[- ]time|faster|slower|$|[|);,.:])))",
                         re.M),
    # 2,700-3,200 steps/s, 27,000 MuJoCo steps/s, 400 runs per second
    "rate": re.compile(rf"(?<![\w.]){_R} (?:[\w-]+ )?(?:steps|runs|points|calls|samples|scenarios)"
                       r"(?:/s\b| per (?:wall )?second\b| a second\b)"),
    # 17.6 us per MuJoCo step, 2.4 ms per run, 0.1 ms each, 90 ms per 10 s
    "per work": re.compile(rf"(?<![\w.]){_R}\s?(?:(?:µs|us)(?: CPU)? (?:per|a|each)\b"
                           r"|(?:ms|s)(?: CPU)? (?:per|a) (?:MuJoCo step|run|model run|point|call|sample)\b"
                           rf"|(?:µs|us|ms) each\b|(?:ms|s) per {_R} s\b)"),
    # 15 % slower, add 8-10 % to the loop's time
    "share": re.compile(rf"(?<![\w.]){_R} ?% (?:slower|faster|to the (?:\w+'s )?time|of the (?:\w+'s )?wall time)"),
    # takes 3.5 s cold, took 31.5 us, take about 8 µs
    "took": re.compile(rf"\b(?:takes?|took|taking) (?:about |some |under |at most )?{_DURATION}"),
    # about two minutes: nothing the robot does lasts minutes
    "minutes": re.compile(rf"(?<![\w./]){_R}\s?(?:min|minutes|hours?)\b|\b{_WORDS} (?:minutes|hours)\b"),
    # `frogsim control hysteresis --out DIR` (about 30 s), (in under 2 s)
    "aside": re.compile(rf"\((?:about|in under|under|in) {_DURATION}\)"),
}
#: a sentence about computing time: any duration in it is a wall-clock figure
_WALL_WORDS = re.compile(r"\bwall[- ](?:time|clock|seconds?)\b|\bcold\b|\bwarm\b|compil(?:ation|es|ing)\b"
                         r"|once compiled|real[- ]time|/usr/bin/time"
                         r"|\bcores?\b|\bCPU\b", re.I)
_DURATIONS = re.compile(rf"(?<![\w.]){_DURATION}")
#: figure kind -> what a benchmark that prints such a figure has in its source
PRINTS = {"factor": r"\}\s?x\b|x real[- ]time", "rate": r"/s\b|per second", "per work": r"\bus\b|µs|ms per|per point",
          "share": r"slower|faster|ratio|%", "took": r"perf_counter|wall", "minutes": r"perf_counter|wall", "aside": r"perf_counter|wall",
          "wall": r"perf_counter|wall"}
_BENCH = re.compile(r"\bbench_\w+\.py\b")


def _pieces(text: str) -> list:
    """(offset, piece, context): a page's sentences and table rows, each with the text that says
    what its durations are (a row: itself and its table's header row)."""
    out, pos, header = [], 0, None
    for line in text.split("\n"):
        if line.lstrip().startswith("|"):
            header = header or line
            out.append((pos, line, line + " " + header))
        else:
            header = None
        pos += len(line) + 1
    prose = re.sub(r"^\s*\|.*$", lambda m: " " * len(m.group(0)), text, flags=re.M)
    for m in re.finditer(r"\S.*?(?:[.;!?](?=\s+[A-Z`(*]|\s*$)|\Z)", prose, re.S):
        out.append((m.start(), m.group(0), m.group(0)))
    return out


def wall_clock_figures(text: str) -> list:
    """[(offset, kind, figure)] of every wall-clock figure in ``text`` (see WALL_CLOCK)."""
    found = {(m.start(), kind, m.group(0)) for kind, rx in WALL_CLOCK.items() for m in rx.finditer(text)}
    for at, piece, context in _pieces(text):
        if _WALL_WORDS.search(context):
            found |= {(at + m.start(), "wall", m.group(0)) for m in _DURATIONS.finditer(piece)}
    return sorted(found)


def passages(text: str) -> list:
    """[(line, heading, passage)]: a page's paragraphs, lists, tables and code blocks (runs of lines
    between blank lines; a fenced block whole), a paragraph ending in ':' taken with the table,
    list or code block it introduces; ``heading`` is the heading of the section it lies in."""
    blocks, cur, heading, fence = [], [], "", False
    for n, line in enumerate(text.split("\n"), 1):
        if line.startswith("```"):
            fence = not fence
        if not fence and line.startswith("#") and not cur:
            heading = line
            continue
        if line.strip() or fence:
            if not cur:
                blocks.append([n, heading, None])
            cur.append(line)
            continue
        if cur:
            blocks[-1][2] = "\n".join(cur)
            cur = []
    if cur:
        blocks[-1][2] = "\n".join(cur)
    out = []
    for line, head, body in blocks:
        if out and out[-1][2].rstrip().endswith(":") and out[-1][1] == head and body[:1] in "|*-`":
            out[-1] = (out[-1][0], head, out[-1][2] + "\n\n" + body)
        else:
            out.append((line, head, body))
    return out


def _is_target(passage: str, at: int) -> bool:
    """The figure at ``at`` is a target: "target" earlier in its clause, or the figure's table
    column is headed "target"."""
    start = max(passage.rfind(c, 0, at) for c in ".;\n") + 1
    if re.search(r"\btargets?\b", passage[start:at], re.I) or re.match(r"[^.;\n]{0,12}\btarget\b", passage[at:]):
        return True
    lines = passage[:at].split("\n")
    row = lines[-1]
    if row.lstrip().startswith("|"):
        column = row.count("|") - 1
        table = [ln for ln in lines if ln.lstrip().startswith("|")]
        cells = [c.strip() for c in table[0].strip().strip("|").split("|")]
        return column < len(cells) and cells[column].lower().startswith("target")
    return False


def timing_problems(text: str, benchmarks: Path = BENCHMARKS) -> list:
    """Every wall-clock figure of a page's text that breaks the rule above, one line each."""
    problems = []
    for line, heading, body in passages(text):
        figures = wall_clock_figures(body)
        if not figures:
            continue
        named = sorted(set(_BENCH.findall(body)) | set(_BENCH.findall(heading)))
        missing = [b for b in named if not (benchmarks / b).is_file()]
        sources = [(benchmarks / b).read_text() for b in named if b not in missing]
        machine = re.search(r"\bmachine\b", body + " " + heading)
        for at, kind, figure in figures:
            where = f"line {line + body[:at].count(chr(10))}: {figure!r}"
            if missing:
                problems.append(f"{where}: names {', '.join(missing)}, not in benchmarks/")
            elif not sources:
                problems.append(f"{where}: a wall-clock figure ({kind}) no benchmark named beside it prints")
            elif not any(re.search(PRINTS[kind], s) for s in sources):
                problems.append(f"{where}: {', '.join(named)} prints no figure of this kind ({kind})")
            elif not machine and not _is_target(body, at):
                problems.append(f"{where}: measured by {', '.join(named)}, but on which machine?")
    return problems
