"""No page states a wall-clock figure a benchmark does not print: how long a computation takes,
how fast it runs against real time, how many steps it makes a second is true of one machine under
one load, so no test times it and no page states it but as a benchmark's output, naming the
benchmark (``benchmarks/bench_NAME.py``, in the passage or its section's heading, a benchmark that
prints such a figure) and the machine it was measured on (a target the benchmark checks needs no
machine). The finder is tried on the figures the pages have held and on simulated times it must
leave alone, and the rule on a page made to break it each way."""
from __future__ import annotations

import pytest

from page_numbers import ROOT, timing_problems, wall_clock_figures

PAGES = sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md", ROOT / "benchmarks" / "README.md"]


@pytest.mark.parametrize("path", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_wall_clock_figure_on_the_page_is_a_benchmarks_output(path):
    problems = timing_problems(path.read_text())
    assert not problems, f"{path.relative_to(ROOT)}:\n" + "\n".join(problems)


@pytest.mark.parametrize("text, figure", [
    ("a scenario with controllers pays about 6 s of compilation on its first run", "6 s"),
    ("`frogsim control control-joint --out DIR` (about 3 s once compiled): `hip-angle-in-air`", "3 s"),
    ("`frogsim control hysteresis --out DIR` (about 30 s): the `control-joint` step", "(about 30 s)"),
    ("refused before anything was made\n\n(in under 2 s). The figures are estimates", "(in under 2 s)"),
    ("(its first run compiles the MuJoCo engine, about 10 s), and adds", "10 s"),
    ("runs 10,000 two-second scenarios in about 3 s on two cores.", "3 s"),
    ("A one-point sweep takes 3.5 s cold: imports", "takes 3.5 s"),
    ("variant before anything runs (about 0.1 ms each), so", "0.1 ms each"),
    ("**54.5x and 58.8x real time** in two runs", "54.5x"),
    ("about 9-10 ms, about 1,000-1,100x real time, 10,319 steps", "1,000-1,100x"),
    ("`Swim-v0` about 2,700-3,200 steps/s\n(27,000-32,000 MuJoCo steps/s, 27-32 x real time)", "2,700-3,200 steps/s"),
    ("(18-21 x real time; `run_coupled` open loop: about\n70 x)", "70 x"),
    ("| real-time factor (one core) | about 60 x | about 55 x |", "60 x"),
    ("compiled loop 17.6 us per MuJoCo step, 56.7 x real time", "17.6 us per"),
    ("Python loop 24.0 us, 41.7 x (1.36 x slower)", "1.36 x"),
    ("about 2.4 ms per run, **about 4,200x real time**", "2.4 ms per run"),
    ("about 90 ms per 10 s (about 110x real time)", "90 ms per 10 s"),
    ("the six\ncontrollers add 8-10 % to the loop's time.", "8-10 % to the loop's time"),
    ("Each run of the 2 s scenario takes about 1-2 ms, so the fit is", "takes about 1-2 ms"),
    ("| sweep | points | cold command | warm, in process |\n|---|---|---|---|\n| one hip | 336 | 3.4 s (2.0 s) | 0.22 s |",
     "0.22 s"),
    ("python benchmarks/bench_engine.py                  # everything, about two minutes\n", "two minutes"),
    ("heat on at most 15 % slower", "15 % slower"),
])
def test_the_finder_finds_the_wall_clock_figures_pages_have_held(text, figure):
    assert figure in [f for _, _, f in wall_clock_figures(text)], wall_clock_figures(text)


@pytest.mark.parametrize("text", [
    "The faster gait vents the drive earlier (at about 0.91 s) and folds the palms about 0.55 s into",
    "* `Swim-v0`: the shipped `swim` robot, 10 ms per\n  step, `duration` 4 s; options `scenario`",
    "one conversion of the ATmega2560's ADC takes 13 ADC clocks, 13 µs at the fastest",
    "the chip awake at most 90 % of the time, no overrun",
    "`benchmarks/bench_sil.py` runs it for 10 s and checks it against the compiled float laws' RMS",
    'method = "grid"                        # every combination: 7 x 8 x 6 = 336 points',
    "the test allows 0.62 x 3.2 Ns, the rebound; a band of +-2 x the stated noise",
    "during the discharge (minimum 256.4 K at 23 s; the fitted model 242 K at 18 s), the wall temperature",
    "One hip muscle under compiled bang-bang (sine setpoint, 10 s simulated, output every 10 ms)",
    "times a cold `frogsim reproduce` on the 2 s hip-muscle cycle",
    "| `log_records` | unsent (still queued 2 s after the run) |",
    "With the same gains the stiffer joint uses 1.5 times the air",
])
def test_the_finder_leaves_simulated_times_and_products_alone(text):
    assert wall_clock_figures(text) == []


def test_the_rule_fails_a_figure_without_its_benchmark_or_machine(tmp_path):
    (tmp_path / "bench_fast.py").write_text('print(f"{ratio:.1f} x real time, {rate:,.0f} steps/s")\n')
    (tmp_path / "bench_slow.py").write_text('t0 = time.perf_counter()\n')

    def problems(text):
        return timing_problems(text, benchmarks=tmp_path)
    figure = "The loop runs at 55x real time."
    assert problems("## Cost\n\n" + figure)[0].endswith("a wall-clock figure (factor) no benchmark named beside it prints")
    assert "on which machine?" in problems(f"## Cost\n\n{figure} (`python benchmarks/bench_fast.py`)")[0]
    assert "not in benchmarks/" in problems(f"{figure} (`bench_gone.py`, this machine)")[0]
    assert "prints no figure of this kind (factor)" in problems(f"{figure} (`bench_slow.py`, this machine)")[0]
    # named in the passage or in its section's heading, with the machine: true
    assert problems(f"{figure} (`python benchmarks/bench_fast.py` on this project's 2-core machine)") == []
    assert problems(f"## Cost (benchmarks/bench_fast.py)\n\nOn this machine: 55x real time.") == []
    # another passage's citation does not carry over
    cited = "`python benchmarks/bench_fast.py` on this machine: 55x real time."
    assert len(problems(f"{cited}\n\nAnd 2,000 steps/s.")) == 1
    # a table with the paragraph that introduces it is one passage
    table = "| case | rate |\n|---|---|\n| swim | 2,000 steps/s |"
    assert problems(f"Measured by `bench_fast.py` on this machine:\n\n{table}") == []
    assert len(problems(f"Measured by `bench_fast.py` on this machine.\n\n{table}")) == 1
    # a target the benchmark checks names the benchmark, and no machine
    assert problems("## `bench_fast.py`\n\nOne muscle (target: 2000x real time).") == []
    assert problems("## `bench_fast.py`\n\n| check | target |\n|---|---|\n| speed | >= 50 x |") == []
    assert len(problems("One muscle (target: 2000x real time).")) == 1
