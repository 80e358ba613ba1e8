"""The pages say what the code does: the control studies the command runs and its --help lists,
the help written for users, the step APIs' blocks running as written (with the array the docs
give), the shipped scenarios' headers, a program's cycles within its run, the swim command's
output interval, and counts in messages in the right number."""
from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

import frogsim
from frogsim.cli import build_parser, main
from frogsim.errors import ScenarioError
from frogsim.scenario.load import SCENARIOS_DIR

ROOT = Path(__file__).resolve().parent.parent
CONTROL_MD = (ROOT / "docs" / "control.md").read_text()
README = (ROOT / "README.md").read_text()


def _help(argv, capsys) -> str:
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args(argv)
    assert exc.value.code == 0
    return capsys.readouterr().out


# --- the control command and the help -------------------------------------------------------------
@pytest.mark.parametrize("group", ["control", "design"])
def test_the_group_commands_help_lists_every_study_of_the_group(group, capsys):
    from frogsim.studies import studies_in
    text = " ".join(_help([group, "--help"], capsys).split())
    for name in studies_in(group):
        assert name in text, (name, text)
    if group == "control":
        top = " ".join(_help(["--help"], capsys).split())
        assert all(n in top for n in studies_in("control")), top


def test_control_without_studies_runs_every_control_study_as_the_pages_say(tmp_path, monkeypatch):
    from frogsim import cli
    from frogsim.studies import studies_in
    ran = []
    monkeypatch.setattr(cli, "_studies_into", lambda args, folder, out, names, summaries: ran.extend(names) or 0)
    assert main(["control", "--out", str(tmp_path / "c"), "--quiet"]) == 0
    assert ran == studies_in("control") and len(ran) == 5 and "heat" in ran
    # the pages say so: five studies, heat among them, and control-pressure alone by its name
    assert "`frogsim control --out DIR` runs it with the other\nfour control studies" in CONTROL_MD
    assert "runs the five control studies" in README


def test_the_top_help_is_written_for_users(capsys):
    text = _help(["--help"], capsys)
    assert "``" not in text and ":mod:" not in text and "thin layer" not in text, text
    first = text.split("\n\n")[1]
    assert first.startswith("frogsim simulates") and "COMMAND --help" in first, first
    assert max(len(line) for line in first.splitlines()) <= 100


# --- the step APIs -----------------------------------------------------------------------------------
def _python_block(md: str, needle: str) -> str:
    blocks = re.findall(r"^```python\n(.*?)^```$", md, flags=re.S | re.M)
    found = [b for b in blocks if needle in b]
    assert len(found) == 1, needle
    return found[0]


def test_the_pneumatic_plant_block_runs_as_written():
    code = _python_block(CONTROL_MD, "PneumaticPlant(")
    assert code.startswith("import frogsim\n")
    space: dict = {}
    exec(compile(code, "docs/control.md PneumaticPlant block", "exec"), space)
    assert space["obs"].shape == (space["plant"].n + 3,)


def test_the_coupled_stepper_block_runs_as_written_with_its_per_muscle_rows():
    code = _python_block(CONTROL_MD, "CoupledStepper(")
    assert "import frogsim\n" in code
    space: dict = {}
    exec(compile(code, "docs/control.md CoupledStepper block", "exec"), space)
    st, u = space["st"], space["u"]
    assert u.shape == (st.n, 2) == (6, 2)          # swim: six driving muscles, spring recovery
    # the documented (charge, discharge) rows and the flat array are one command
    st.reset()
    st.step(u, 1.0)
    rows = st.pressures().copy()
    st.reset()
    st.step(u.reshape(-1), 1.0)
    assert np.array_equal(rows, st.pressures())
    with pytest.raises(ValueError, match=r"\(6, 2\)"):
        st.step(np.zeros((2, 6)), 1.0)


# --- shipped scenarios and examples --------------------------------------------------------------
@pytest.mark.parametrize("path", sorted(SCENARIOS_DIR.glob("*.toml")), ids=lambda p: p.stem)
def test_a_shipped_scenarios_header_counts_its_muscles_right(path):
    head = " ".join(line[1:].strip() for line in path.read_text().splitlines() if line.startswith("#"))
    raw = tomllib.loads(path.read_text())
    if "gait" in raw:
        n = len(frogsim.load_robot_scenario(path.stem).muscles)
    else:
        n = len(frogsim.load_scenario(path.stem).muscles)
    words = {"six": 6, "twelve": 12}
    claims = [int(m) if m.isdigit() else words[m] for m in re.findall(r"\b(\d+|six|twelve) (?:driving )?muscles\b",
                                                                          head)]
    # the first count a header gives is of what the scenario runs (a variant may follow)
    if claims:
        assert claims[0] == n, (path.name, claims, n, head)


def test_the_swim_scenario_says_it_runs_six_muscles():
    text = (SCENARIOS_DIR / "swim.toml").read_text()
    assert 'recovery = "spring"' in text
    assert len(frogsim.load_robot_scenario("swim").muscles) == 6
    head = text.split("name =")[0]
    assert "six driving muscles" in head and "The full robot: two antagonistic" not in head


def _readme_toml(needle: str) -> str:
    found = [b for b in re.findall(r"^```toml\n(.*?)^```$", README, flags=re.S | re.M) if needle in b]
    assert len(found) == 1
    return found[0]


def test_a_program_whose_cycles_outrun_the_run_is_refused(tmp_path, capsys):
    raw = tomllib.loads(_readme_toml('name = "one-hip"'))
    assert raw["duration"] == "2 s" and raw["programs"]["stroke"]["cycles"] == 1     # the README's is consistent
    raw["programs"]["stroke"]["cycles"] = 3                                            # 3 x 2 s in a 2 s run
    with pytest.raises(ScenarioError) as exc:
        frogsim.load_scenario(raw)
    msg = str(exc.value)
    # the third cycle would begin at 4 s, after the 2 s run, which begins one of them
    assert msg.startswith("programs.stroke.cycles = 3: 3 cycles of 2 s from 0 s: the last would begin at 4 s") \
        and "\n" not in msg
    assert "begins 1 of them" in msg and "duration over 4 s" in msg, msg
    raw["duration"] = "6 s"
    assert len(frogsim.load_scenario(raw).muscles["hip"].program.steps) == 6
    raw["duration"] = "4.5 s"                    # the third begins at 4 s and is cut: it runs in part
    assert frogsim.load_scenario(raw).duration == 4.5
    raw["duration"] = "4 s"                      # the third would begin as the run ends
    with pytest.raises(ScenarioError, match=r"begins 2 of them: allowed 1 to 2"):
        frogsim.load_scenario(raw)
    # the same through a variant and in a muscle's own program
    sc = frogsim.load_scenario(dict(raw, duration="6 s"))
    with pytest.raises(ScenarioError, match=r"^programs\.stroke\.cycles = 3"):
        sc.replace({"duration": 4.0})
    own = dict(raw, duration="2 s", programs={})
    own["muscles"] = {"hip": dict(raw["muscles"]["hip"], program={"pressurise": "1 s", "release": "1 s",
                                                                   "cycles": 2})}
    with pytest.raises(ScenarioError, match=r"^muscles\.hip\.program\.cycles = 2"):
        frogsim.load_scenario(own)
    # one cycle may outlast the run (a part of a stroke), as before
    own["muscles"]["hip"]["program"] = {"pressurise": "1 s", "release": "2 s"}
    frogsim.load_scenario(own)
    # the command line: exit 2, one line, nothing written
    path = tmp_path / "s.toml"
    path.write_text(_readme_toml('name = "one-hip"').replace("cycles = 1 ", "cycles = 3 "))
    out = tmp_path / "out"
    assert main(["simulate", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("frogsim: error: programs.stroke.cycles = 3:") and "\n" not in err and not out.exists()


# --- swim --output-interval ----------------------------------------------------------------------------
@pytest.mark.parametrize("value, expect", [
    ("nan", "finite time > 0"), ("inf", "finite time > 0"), ("0", "finite time > 0"), ("-1", "finite time > 0"),
    ("0 ms", "finite time > 0"), ("3 bar", "expected a time"), ("1.5 ms", "whole number of robot.timestep steps"),
    ("10 s", "must not exceed the duration"),
])
def test_a_bad_swim_output_interval_is_refused(tmp_path, capsys, value, expect):
    out = tmp_path / "out"
    assert main(["swim", "leg-in-air", f"--output-interval={value}", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"frogsim: error: --output-interval = {value!r}: ") and expect in err, err
    assert "\n" not in err and not out.exists()


def test_the_swim_output_interval_and_counts_in_the_singular(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["swim", "leg-in-air", "--cycles", "1", "--output-interval", "5 ms", "--no-animation",
                 "--out", str(out)]) == 0
    err = capsys.readouterr().err
    t = np.loadtxt(out / "timeseries.csv", delimiter=",", skiprows=1, usecols=0)
    assert t.size == 401 and np.allclose(np.diff(t), 5e-3)        # 2 s every 5 ms
    assert "6 muscles in air, 1 cycle of 2 s" in err and "after 1 cycle\n" in err, err
    assert "1 cycles" not in err


# --- counts in messages --------------------------------------------------------------------------------
def test_count_words():
    from frogsim._words import count
    assert [count(n, "muscle") for n in (0, 1, 2)] == ["0 muscles", "1 muscle", "2 muscles"]
    assert count(1, "force table") == "1 force table" and count(3, "axis", "axes") == "3 axes"


ONE_MUSCLE = """name = "one"
duration = "10 ms"
[programs.stroke]
pressurise = "5 ms"
release = "5 ms"
[muscles.hip]
type = "hip"
program = "stroke"
motion = { kind = "constant" }
"""


def test_one_muscle_one_parameter_one_trace_in_the_singular(tmp_path, capsys, monkeypatch):
    import json

    import frogsim.fit as F
    from fit_helpers import write_rig
    path = tmp_path / "one.toml"
    path.write_text(ONE_MUSCLE)
    assert main(["simulate", str(path), "--out", str(tmp_path / "sim")]) == 0
    err = capsys.readouterr().err
    assert ": 1 muscle, 0.01 s" in err and "1 muscles" not in err, err
    # the fit's first line, before any model run
    write_rig(tmp_path)
    (tmp_path / "t.csv").write_text("time [s],hip pressure [bar gauge]\n0,0\n0.1,1\n0.2,1\n0.5,1\n")
    (tmp_path / "FIT.toml").write_text('scenario = "rig.toml"\nnoise = "0.02 bar"\nstarts = 1\n'
                                       '[[experiments]]\ntrace = "t.csv"\n[parameters]\n'
                                       '"valves.charge.sonic_conductance" = { min = "0.1 L/(s*bar)", '
                                       'max = "1 L/(s*bar)" }\n')

    def stop(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(F, "fit", stop)
    assert main(["fit", str(tmp_path / "FIT.toml"), "--out", str(tmp_path / "fit")]) == 130
    err = capsys.readouterr().err
    assert "fitting 1 parameter to 1 trace, 1 start ..." in err, err
    assert json.loads((tmp_path / "fit" / "manifest.json").read_text())["status"] == "interrupted"
