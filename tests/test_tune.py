"""`frogsim tune`: bad input (exit 2, one line, nothing written), a study that continues where it
stopped, tied gains equal in every trial, best.toml reproducing the best trial through
`simulate --patch`, a Pareto front that is non-dominated, and a physics check: on a one-muscle
bang-bang hold the tuned band is where Eq. (8) and the valve's dead time put the optimum.

The scenarios are one or two hip muscles at rest length (constant volume) without the supply, a
fraction of a second each, so a search of a few dozen trials takes seconds."""
from __future__ import annotations

import csv
import json
import math

import pytest

from conftest import B_MHJ9, C_MHJ9, K_AIR, P_ATM, R_AIR, RHO_REF, T_REF, assert_unit_headers
from frogsim.cli import main

BAR = 1e5
DT = 1e-3            # controller period at the default 1 kHz
DEAD = 2e-3          # fan2017's valve dead time
HIP_V = math.pi * 0.020 ** 2 * 0.180 / 4 + 5e-6   # DMSP-20 hip at rest: cylinder + 5 cm^3 dead volume
P_SOURCE = P_ATM + 6.0 * BAR                      # fan2017's source, full

HOLD = """name = "hold"
parameters = "fan2017"
duration = "0.6 s"
output_interval = "1 ms"

[supply]
mode = "none"

[muscles.hip]
type = "hip"
motion = { kind = "constant" }

[controllers.hold]
kind = "bang-bang"
muscle = "hip"
setpoint = { kind = "constant", value = "3 bar" }
band = "0.1 bar"
settle = "0.3 s"
"""

PAIR = """name = "pair"
parameters = "fan2017"
duration = "0.5 s"
output_interval = "1 ms"

[supply]
mode = "none"

[muscles.a]
type = "hip"
motion = { kind = "constant" }

[muscles.b]
type = "knee"
motion = { kind = "constant" }

[controllers.ca]
kind = "bang-bang"
muscle = "a"
setpoint = { kind = "sine", mean = "3 bar", amplitude = "1 bar", frequency = "4 Hz" }
band = "0.1 bar"
settle = "0.1 s"

[controllers.cb]
kind = "bang-bang"
muscle = "b"
setpoint = { kind = "sine", mean = "2 bar", amplitude = "0.5 bar", frequency = "4 Hz" }
band = "0.1 bar"
settle = "0.1 s"
"""


def write(tmp_path, text: str, name: str = "sc.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def run(argv) -> int:
    return main(["tune", *map(str, argv), "--quiet"])


def summary(out):
    return json.loads((out / "summary.json").read_text())


def tuned(tmp_path, text: str, *argv, folder: str = "t"):
    """The scenario ``text`` written to a file and searched by `frogsim tune ARGV --out
    tmp_path/folder --quiet` (which must succeed): (scenario path, output folder, summary.json)."""
    sc = write(tmp_path, text)
    out = tmp_path / folder
    assert run([sc, *argv, "--out", out]) == 0
    return sc, out, summary(out)


# --- bad input ------------------------------------------------------------------------------------
@pytest.mark.parametrize("tune, argv, field", [
    ('[tune.gains.hold]\nstrength = ["1 bar", "2 bar"]\n', [], "tune.gains.hold.strength"),
    ('[tune.gains.hold]\nband = ["0.5 bar", "0.1 bar"]\n', [], "tune.gains.hold.band"),
    ('[tune.gains.hold]\nband = { low = "0 bar", high = "0.5 bar", log = true }\n', [], "tune.gains.hold.band"),
    ('[tune.gains.hold]\nband = ["0 bar", "0.5 bar"]\n', [], "tune.gains.hold.band"),   # declared log
    ('[tune.gains.nobody]\nband = "0.1 bar"\n', [], "tune.gains.nobody"),
    ('[tune.weights]\ntracking = -1\n', [], "tune.weights.tracking"),
    ('[tune]\ntie = [["hold", "hold"]]\n', [], "tune.tie"),
    ("", ["--trials", "0"], "--trials"),
    ("", ["--workers", "0"], "--workers"),
    ("", ["--timeout", "-3"], "--timeout"),
])
def test_bad_input_exit_2_one_line_nothing_written(tmp_path, capsys, tune, argv, field):
    sc = write(tmp_path, HOLD + "\n" + tune)
    out = tmp_path / "out"
    code = main(["tune", str(sc), "--trials", "2", *argv, "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert len(err.splitlines()) == 1 and field in err and "Traceback" not in err, err
    assert not out.exists()


def test_a_scenario_without_controllers_is_refused(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["tune", "paper-cycle", "--trials", "2", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("frogsim: error: controllers") and "gains" in err, err
    assert not out.exists()


def test_a_patch_naming_another_controller_is_refused(tmp_path, capsys):
    sc = write(tmp_path, HOLD)
    patch = write(tmp_path, '[controllers.other]\nband = "0.2 bar"\n', "patch.toml")
    assert main(["simulate", str(sc), "--patch", str(patch), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert "controllers.other" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "o").exists()


# --- the search -----------------------------------------------------------------------------------
def test_a_second_run_continues_the_study(tmp_path):
    sc, out, s = tuned(tmp_path, HOLD, "--trials", "3")
    assert s["trials"] == 3 and s["trials_run_now"] == 3
    assert run([sc, "--trials", "5", "--out", out]) == 0
    s = summary(out)
    assert s["trials"] == 5 and s["trials_run_now"] == 2
    rows = list(csv.DictReader((out / "trials.csv").open()))
    assert [int(r["trial"]) for r in rows] == [0, 1, 2, 3, 4]
    # a study of another search space is not continued
    write(tmp_path, HOLD + '\n[tune.gains.hold]\nband = ["0.05 bar", "0.5 bar"]\n')
    assert run([sc, "--trials", "6", "--out", out]) == 2
    assert run([sc, "--trials", "2", "--out", out, "--overwrite"]) == 0
    assert summary(out)["trials"] == 2


def test_tied_gains_are_equal_in_every_trial(tmp_path, monkeypatch):
    """Each trial's settings as run: the tied controller's band is its leader's, and only the
    leader's band is a parameter of the study."""
    from frogsim.optimize import tune as T
    seen = []
    real = T.run

    def spy(tune, texts, report=None):
        seen.append(dict(texts))
        return real(tune, texts, report)
    monkeypatch.setattr(T, "run", spy)
    _, out, _ = tuned(tmp_path, PAIR + '\n[tune]\ntie = [["ca", "cb"]]\n', "--trials", "6", "--workers", "2")
    trials = [t for t in seen if t]             # the baseline runs the scenario as written
    assert len(trials) == 6
    for t in trials:
        assert t["controllers.ca.band"] == t["controllers.cb.band"]
    assert len({t["controllers.ca.band"] for t in trials}) == 6
    header = next(csv.reader((out / "trials.csv").open()))
    assert "ca.band [bar]" in header and not any(h.startswith("cb.band") for h in header)


def test_best_toml_through_simulate_reproduces_the_best_trial(tmp_path):
    sc, out, s = tuned(tmp_path, PAIR, "--trials", "8", "--workers", "2")
    table = assert_unit_headers(out / "trials.csv")
    assert len(table) == 8 and (out / "history.png").stat().st_size > 0
    assert s["trials_complete"] + s["trials_pruned"] + s["trials_failed"] == 8
    best = s["best"]["controllers"]
    sim = tmp_path / "sim"
    assert main(["simulate", str(sc), "--patch", str(out / "best.toml"), "--out", str(sim), "--quiet"]) == 0
    got = summary(sim)["control"]
    for c in ("ca", "cb"):
        assert got[c]["tracking_error_rms_bar"] == best[c]["tracking_rms"]
        assert got[c]["switchings_per_s"] == best[c]["switchings_per_s"]
        assert got[c]["air_used_L_std"] == best[c]["air_used_L_std"]
    # the objective it reports is its own definition: the mean of each RMS over the start's mean RMS
    start = s["start"]["controllers"]
    ref = (start["ca"]["tracking_rms"] + start["cb"]["tracking_rms"]) / 2
    mean = (got["ca"]["tracking_error_rms_bar"] + got["cb"]["tracking_error_rms_bar"]) / 2
    assert s["best"]["score"] == pytest.approx(mean / ref, rel=1e-12)
    assert s["start"]["score"] == pytest.approx(1.0, rel=1e-12)


def test_pareto_front_is_non_dominated(tmp_path):
    _, out, s = tuned(tmp_path, PAIR + '\n[tune]\npareto = ["tracking", "switchings"]\n', "--trials", "16",
                      "--workers", "2", "--pareto")
    assert (out / "pareto.png").stat().st_size > 0 and not (out / "history.png").exists()
    rows = [r for r in csv.DictReader((out / "trials.csv").open()) if r["state"] == "COMPLETE" and not r["failure"]]
    pts = {int(r["trial"]): (float(r["tracking [-]"]), float(r["switchings [-]"])) for r in rows}
    front = {f["trial"] for f in s["front"]}
    assert front and front <= set(pts)

    def dominates(a, b):
        return all(x <= y for x, y in zip(a, b)) and any(x < y for x, y in zip(a, b))
    for f in front:
        assert not any(dominates(pts[o], pts[f]) for o in pts if o != f), f
    for o in set(pts) - front:                     # every other trial is dominated by a member
        assert any(dominates(pts[f], pts[o]) or pts[f] == pts[o] for f in front), o


def test_the_tuned_band_of_a_bang_bang_hold_is_where_eq8_and_the_dead_time_put_it(tmp_path):
    """A hold at a constant 3 bar, valves shut between the band's edges, nothing leaking: the
    charge stops once the sensed pressure passes sp - band/2, and the valve shuts a dead time d
    after the sample that saw it (the crossing lies up to one period T before that sample), so
    the pressure settles at sp - band/2 + r (d + delta), delta in [0, T), r the charging rate
    there. Tracking alone is minimised (RMS = |r (d + delta) - band/2|) by a band in
    [2 r d, 2 r (d + T)]. The valve shuts on the sample grid (plus d), so the pressures it can
    stop at are r T apart: the best RMS is at most r T / 2. r from Eq. (8), subsonic at 3 bar from
    the full 6 bar source, adiabatic filling of the constant hip volume: r = k R T_ref C rho_ref
    p_s psi / V, psi = sqrt(1 - ((p/p_s - b)/(1 - b))^2): 60 bar/s, so the band lies in
    0.24..0.36 bar and the RMS is at most 0.03 bar; the search starts from 0.1 bar (which
    overshoots the band's top, vents and stops 0.038 bar low) over 0.01..1 bar on a log scale."""
    p = P_ATM + 3.0 * BAR
    ratio = p / P_SOURCE
    psi = math.sqrt(1.0 - ((ratio - B_MHJ9) / (1.0 - B_MHJ9)) ** 2)
    r = K_AIR * R_AIR * T_REF * C_MHJ9 * RHO_REF * P_SOURCE * psi / HIP_V
    low, high = 2 * r * DEAD, 2 * r * (DEAD + DT)
    _, _, s = tuned(tmp_path, HOLD, "--trials", "30")
    band = float(s["best_gains"]["controllers.hold.band"].split()[0]) * BAR
    # the source has given some air (it cools and its pressure falls a little): 5 % below low
    assert 0.95 * low <= band <= high, (band / BAR, low / BAR, high / BAR)
    assert s["best"]["controllers"]["hold"]["tracking_rms"] * BAR <= r * DT / 2
    assert s["start"]["controllers"]["hold"]["tracking_rms"] * BAR > r * DT / 2    # the start was not there yet


def test_a_bar_with_the_best_so_far_on_stderr_and_nothing_under_quiet(tmp_path, capsys):
    sc = write(tmp_path, HOLD)
    capsys.readouterr()
    assert main(["tune", str(sc), "--trials", "2", "--out", str(tmp_path / "loud")]) == 0
    err = capsys.readouterr().err
    assert "2/2 trials" in err and "best " in err and "(start 1)" in err, err[-1000:]
    assert main(["tune", str(sc), "--trials", "2", "--out", str(tmp_path / "quiet"), "--quiet"]) == 0
    assert capsys.readouterr().err == ""


def test_two_runs_sharing_a_storage_url_share_one_study(tmp_path):
    """--storage: the study lives at the URL (as for several machines), not in --out; a run from
    another folder continues its count."""
    sc = write(tmp_path, HOLD)
    url = f"sqlite:///{tmp_path / 'shared.db'}"
    assert run([sc, "--trials", "2", "--storage", url, "--out", tmp_path / "m1"]) == 0
    assert run([sc, "--trials", "4", "--storage", url, "--out", tmp_path / "m2"]) == 0
    s = summary(tmp_path / "m2")
    assert s["trials"] == 4 and s["trials_run_now"] == 2 and s["storage"] == url
    assert not (tmp_path / "m1" / "study.db").exists() and not (tmp_path / "m2" / "study.db").exists()


def test_optimize_gait_and_tune_share_one_optuna_plumbing():
    """The issue's rule "one module, no second copy": in frogsim.optimize, Optuna's studies,
    samplers, pruners and storages are made, and trials are run on threads, only in study.py,
    and both searches go through it."""
    import re
    from pathlib import Path

    import frogsim.optimize
    folder = Path(frogsim.optimize.__file__).parent
    makers = re.compile(r"\b(create_study|load_study|\w+Sampler|\w+Pruner|RDBStorage|JournalStorage|"
                        r"ThreadPoolExecutor|tqdm)\b")
    found = {p.name: sorted(set(makers.findall(p.read_text()))) for p in folder.glob("*.py") if p.name != "study.py"}
    assert {"gait.py", "tune.py"} <= set(found)
    assert not any(found.values()), found
    for name in ("gait.py", "tune.py"):
        assert "from frogsim.optimize import study as S" in (folder / name).read_text(), name
    assert makers.search((folder / "study.py").read_text())
