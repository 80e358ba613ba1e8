"""A plan that does not fit the board is refused before anything is written: `frogsim firmware`
knows the control interrupt's worst case and the serial log's share (a cycle estimate, or with
--build the built machine code timed on the emulated ATmega2560) and refuses a plan whose sum
exceeds the controller period, naming what would fit; --allow-overrun writes it and says so in
firmware.json.

Expected values: the datasheet's conversion arithmetic (13 ADC clocks of the prescaler's CPU
cycles, 25 for the first) as the floor of every estimate, and the emulated board's own timing
(simavr, not frogsim's arithmetic) as what the estimate must cover."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
from avr_tools import need_avr_tools

import frogsim
from frogsim.cli import main
from frogsim.control.firmware import firmware_plan
from frogsim.export import fit as fitting

HERE = Path(__file__).with_name("firmware")
SHIPPED = Path(frogsim.__file__).with_name("scenarios")


def _at(rate: str, tmp_path: Path) -> Path:
    """tests/firmware/every-kind.toml (five kinds, three channels) at another controller rate."""
    text = (HERE / "every-kind.toml").read_text().replace('rate = "1 kHz"', f'rate = "{rate}"')
    path = tmp_path / "fast.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("build", [False, True])
def test_a_plan_that_does_not_fit_is_refused_and_nothing_is_written(tmp_path, capsys, build):
    """Every kind at 3.2 kHz: a 5000-cycle period; the sliding mode's law alone takes a good part of
    it, the three conversions another (at least 3 x 13 x 32 cycles at the fastest clock the
    plan may take): refused, one line, exit 2, no folder."""
    if build:
        need_avr_tools()
    path = _at("3200 Hz", tmp_path)
    out = tmp_path / "fw"
    code = main(["firmware", str(path), "--out", str(out), "--quiet", *(["--build"] if build else [])])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert "controller.rate" in err[0] and "does not fit its 5000-cycle period" in err[0]
    assert "what would fit: a controller rate of at most" in err[0] and "--allow-overrun" in err[0]
    assert ("(emulated)" if build else "(estimate)") in err[0]
    assert not out.exists()


def test_allow_overrun_writes_it_and_firmware_json_says_so(tmp_path, capsys):
    path = _at("3200 Hz", tmp_path)
    out = tmp_path / "fw"
    assert main(["firmware", str(path), "--out", str(out), "--allow-overrun", "--quiet"]) == 0
    assert "written anyway (--allow-overrun)" in capsys.readouterr().err
    fit = json.loads((out / "firmware.json").read_text())["fit"]
    assert fit["fits"] is False and fit["allowed_overrun"] is True and fit["total_percent"] > 100


def test_the_suggested_rate_fits(tmp_path, capsys):
    """The rate the refusal names is exported without complaint (the same estimate)."""
    path = _at("3200 Hz", tmp_path)
    assert main(["firmware", str(path), "--out", str(tmp_path / "a"), "--quiet"]) == 2
    err = capsys.readouterr().err
    rate = err.split("a controller rate of at most ")[1].split(" Hz")[0]
    assert main(["firmware", str(_at(f"{rate} Hz", tmp_path)), "--out", str(tmp_path / "b"), "--quiet"]) == 0


@pytest.mark.parametrize("scenario", [SHIPPED / "hold-3bar.toml", HERE / "every-kind.toml"])
def test_the_estimate_covers_the_emulated_interrupt(tmp_path, scenario):
    """The cycle estimate (no build) is at least the emulated board's largest interrupt, and not
    more than twice it, and never below the conversions' datasheet cycles."""
    need_avr_tools()
    assert main(["firmware", str(scenario), "--out", str(tmp_path / "fw"), "--build", "--quiet"]) == 0
    rec = json.loads((tmp_path / "fw" / "firmware.json").read_text())
    plan = firmware_plan(frogsim.build_model(frogsim.load_scenario(scenario)))
    est = fitting.estimate(plan, 40)
    n = len(plan.channels)
    assert est["conversion_cycles"] == n * 13 * plan.adc.prescaler + (25 - 13) * plan.adc.prescaler
    measured = rec["fit"]["interrupt_max_cycles"]
    assert rec["fit"]["method"] == "emulated"
    assert measured <= est["interrupt_max_cycles"] <= 2 * measured, (measured, est)
