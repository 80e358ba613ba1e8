"""The firmware path end to end on the scenarios' own plans (frogsim.control.firmware): export ->
build (avr-gcc, the Arduino core) -> software in the loop (simavr) on the pneumatics alone and on
the robot. The firmware's machine code must command the same valves at the same samples as the
model's compiled law (mismatched_samples == 0) and the run's metrics must equal the compiled run's
(`simulate`, `swim`: the engines stop at other points, so to the solver's tolerance).

Independent checks: `avr-objdump -f` run here, the datasheet's conversion arithmetic for the CPU
load, the ADC's inputs A8..A15 reaching the firmware, the firmware's log read back by `frogsim
fit`, which recovers the valve constants the run was made with (C = 0.4 L/(s bar), b = 0.38)."""
from __future__ import annotations

import dataclasses
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from avr_tools import need_avr_tools

import frogsim
from frogsim.cli import main
from frogsim.export import sil, sketch

HERE = Path(__file__).with_name("firmware")
SHIPPED = Path(frogsim.__file__).with_name("scenarios")


def _cli(*argv) -> int:
    return main([*map(str, argv), "--quiet"])


def _export_and_sil(scenario, tmp: Path, *extra, timing: str = "grid", allow_overrun: bool = False) -> tuple[dict, dict]:
    """Export, build and run SIL; ``timing`` "grid" (each sample's decision at its own time, as the
    compiled model has it: the runs must then agree) or "cycle" (the board's own timing)."""
    fw, out = tmp / "fw", tmp / f"sil-{timing}"
    if not (fw / "firmware.json").exists():
        assert _cli("firmware", scenario, *extra, *(["--allow-overrun"] if allow_overrun else []), "--out", fw,
                    "--build") == 0
    assert _cli("sil", scenario, *extra, "--firmware", fw, "--timing", timing, "--out", out, *(
        ["--no-animation"] if "swim" in str(scenario) or "hip-angle" in str(scenario) or "robot" in str(scenario)
        else [])) == 0
    return json.loads((fw / "firmware.json").read_text()), json.loads((out / "summary.json").read_text())


@pytest.fixture(scope="module")
def hold(tmp_path_factory):
    need_avr_tools()
    tmp = tmp_path_factory.mktemp("hold")
    rec, summary = _export_and_sil("hold-3bar", tmp)
    assert _cli("simulate", "hold-3bar", "--out", tmp / "sim") == 0
    return tmp, rec, summary, json.loads((tmp / "sim" / "summary.json").read_text())


def test_hold_3bar_exports_an_avr6_elf_that_fits(hold):
    tmp, rec, _, _ = hold
    elf = tmp / "fw" / "build" / f"{rec['name']}.elf"
    info = subprocess.run(["avr-objdump", "-f", str(elf)], capture_output=True, text=True, check=True).stdout
    assert "architecture: avr:6" in info
    assert 0 < rec["flash_bytes"] < (256 - 8) * 1024 and 0 < rec["ram_bytes"] < 8 * 1024
    assert (tmp / "fw" / rec["name"] / f"{rec['name']}.ino").is_file()


def test_on_the_boards_own_timing_each_write_comes_after_its_conversion(hold):
    """`sil` on the board's timing (the default): the firmware decides as the model at every
    sample (the same counts, the same commands), but each valve write reaches the plant when the
    firmware made it: after the sample's conversion, at least 13 ADC clocks of 128 CPU cycles
    (25 for the very first conversion, the one that opens the charge valve; datasheet Table
    26-1), and before the period ends. The tracking then differs from the compiled run's a
    little, and the summary says by how much."""
    tmp, _, _, _ = hold
    _, s = _export_and_sil("hold-3bar", tmp, timing="cycle")
    sil_ = s["sil"]
    assert sil_["timing"] == "cycle"
    assert sil_["mismatched_samples"] == 0 and sil_["samples_off_the_on_time_model"] == 0
    assert sil_["samples"] == sil_["firmware_samples"] == 2001 and sil_["samples_late"] == 0
    assert sil_["effective_rate_hz"] == pytest.approx(1000.0, rel=1e-12)
    lat = sil_["valve_write_latency_us"]
    assert lat["samples_with_a_valve_change"] == 2           # the charge valve opens, then closes
    assert lat["max"] >= 25 * 128 / 16 and 13 * 128 / 16 <= lat["mean"] < 1000
    assert sil_["response_us"]["max"] < 1000
    # awake while the interrupt runs but for its conversion (13 ADC clocks of 128 CPU cycles, 10.4 %
    # of the 16000-cycle period: the law waits for it asleep, in idle mode), asleep the rest but for
    # the log's formatting: awake less than the interrupt is busy, and not by more than the conversion
    conversion = 100.0 * 13 * 128 / 16000
    load = sil_["cpu_load_percent"]["mean"]
    assert load - conversion <= sil_["awake_percent"] < load
    assert sil_["log_records"] == {"made": 201, "received": 201, "dropped": 0, "unsent": 0, "lines_unreadable": 0,
                                   "faults": {}}
    assert sil_["warnings"] == []
    cmp = sil_["compiled"]["controllers"]["hold"]["tracking_error_rms_bar"]
    assert cmp["sil"] == pytest.approx(s["control"]["hold"]["tracking_error_rms_bar"], rel=1e-12)
    assert cmp["sil_over_compiled"] == pytest.approx(cmp["sil"] / cmp["compiled"], rel=1e-12)
    # the valve is open shorter by the first write's latency less the closing one's: less air
    air = sil_["compiled"]["controllers"]["hold"]["air_used_L_std"]
    assert air["sil"] < air["compiled"] and air["sil_over_compiled"] > 0.99


def test_the_build_times_the_interrupt_within_the_period(hold):
    """`firmware --build` times the interrupt on the emulated board: at least one 10-bit
    conversion (13 ADC clocks at prescaler 128, the datasheet's; 25 for the very first), and
    for one bang-bang law well inside the 1 ms period."""
    _, rec, _, _ = hold
    t = rec["interrupt"]
    assert t["period_cycles"] == 16000 and t["samples_over_period"] == 0 and t["overruns"] == 0
    assert 100 * 13 * 128 / 16000 < t["mean_percent"] < t["max_percent"] < 100


def test_hold_3bar_sil_matches_the_compiled_run(hold):
    _, rec, s, sim = hold
    assert s["sil"]["mismatched_samples"] == 0
    assert s["sil"]["samples"] == 2001 and s["sil"]["overruns"] == 0
    assert s["sil"]["adc_read_differs_samples"] == 0
    # one 10-bit conversion at prescaler 128 (13 ADC clocks, the first ever 25) is the least the
    # interrupt can take; a bang-bang law adds little
    assert 100 * 13 * 128 / 16000 < s["sil"]["cpu_load_percent"]["mean"] < 40
    assert s["sil"]["cpu_load_percent"]["max"] >= 100 * 25 * 128 / 16000
    assert s["sil"]["flash_bytes"] == rec["flash_bytes"]
    a, b = s["control"]["hold"], sim["control"]["hold"]
    for key in ("tracking_error_rms_bar", "tracking_error_max_bar", "air_used_L_std"):
        assert a[key] == pytest.approx(b[key], rel=1e-6), key
    assert a["switchings"] == b["switchings"] and a["switchings"]["hip"]["charge"] > 0
    assert a["kind"] == "bang-bang"


def test_every_pneumatic_kind_commands_the_same_valves(tmp_path):
    """Bang-bang, PWM (closed and open loop), sliding mode and a program on one board."""
    need_avr_tools()
    scenario = HERE / "every-kind.toml"
    rec, s = _export_and_sil(scenario, tmp_path)
    assert s["sil"]["mismatched_samples"] == 0 and s["sil"]["overruns"] == 0
    assert s["sil"]["samples"] == 1001
    assert len(rec["muscles"]) == 5 and len(rec["channels"]) == 3     # PWM open loop and the program sense nothing
    assert _cli("simulate", scenario, "--out", tmp_path / "sim") == 0
    sim = json.loads((tmp_path / "sim" / "summary.json").read_text())
    for name, entry in sim["control"].items():
        assert s["control"][name]["switchings"] == entry["switchings"], name
        if "tracking_error_rms_bar" in entry:
            assert s["control"][name]["tracking_error_rms_bar"] == pytest.approx(entry["tracking_error_rms_bar"],
                                                                                 rel=1e-6)
    # the program's valves were the firmware's too: its muscle ends where the compiled run's does
    # (to the solvers' tolerance: 1 Pa, the run's atol being far below it)
    assert s["muscles"]["hip_e"]["final_pressure_bar_gauge"] == pytest.approx(
        sim["muscles"]["hip_e"]["final_pressure_bar_gauge"], abs=1e-5)


def test_a_plan_forced_past_its_period_overruns_and_still_agrees(tmp_path):
    """hold-3bar at 10 kHz: the export plans a 52 us conversion (prescaler 64) for the 100 us
    period; forced to prescaler 128 (13 x 128 = 1664 cycles > the period's 1600), the firmware
    overruns at every sample and counts it, and still decides as the model (the same counts,
    later)."""
    need_avr_tools()
    from frogsim.circuit.model import build_model
    from frogsim.control.firmware import adc_counts, firmware_plan
    text = (SHIPPED / "hold-3bar.toml").read_text().replace('rate = "1 kHz"', 'rate = "10 kHz"').replace(
        'duration = "2 s"', 'duration = "0.05 s"').replace('settle = "0.5 s"', 'settle = "0.01 s"')
    path = tmp_path / "fast.toml"
    path.write_text(text)
    model = build_model(frogsim.load_scenario(path))
    plan = firmware_plan(model)
    assert plan.adc.prescaler == 64
    assert 13 * 128 > plan.period_cycles
    forced = dataclasses.replace(plan, adc=dataclasses.replace(plan.adc, prescaler=128))
    sketch.write_sketch(forced, tmp_path / "fw", "fast")
    built = sketch.build_sketch(tmp_path / "fw", forced.name)
    run = sil.run_pneumatic(model, sketch.read_plan_record(tmp_path / "fw"), built.elf, forced, adc_counts,
                            compare=False)
    assert run.sil["overruns"] >= run.sil["firmware_samples"] - 1
    # on the board's timing the samples come late: a conversion alone takes 13 x 128 cycles, so
    # the board takes at most 16 MHz / 1664 = 9615 samples a second, not 10000 (datasheet)
    assert run.sil["effective_rate_hz"] <= 16e6 / (13 * 128)
    assert run.sil["samples_late"] >= run.sil["firmware_samples"] - 2
    assert run.sil["samples_skipped"] >= 0.038 * run.sil["samples"] - 2
    assert any("overran" in w for w in run.sil["warnings"]) and any("Hz, not" in w for w in run.sil["warnings"])
    # the build's own timing of the interrupt (random counts, no plant) sees the same: every
    # sample's conversion alone (1664 cycles) is longer than the period (1600)
    timing = sil.interrupt_timing(sketch.read_plan_record(tmp_path / "fw"), built.elf, samples=20)
    assert timing["samples_over_period"] == 20 and timing["samples_late"] >= timing["executions"] - 1
    assert timing["overruns"] >= 1
    assert run.sil["cpu_load_percent"]["mean"] > 100
    assert run.sil["mismatched_samples"] == 0


def test_all_sixteen_analog_inputs_reach_the_firmware(tmp_path):
    """Each input A0..A15 fed its own count is read as that count by the firmware's conversion
    (A8..A15 need MUX5 in ADCSRB; the emulation keeps them apart)."""
    need_avr_tools()
    from fw_stub import bang_bang_plan
    plan = bang_bang_plan(channels=16, rate=100.0)
    sketch.write_sketch(plan, tmp_path, "x")
    built = sketch.build_sketch(tmp_path, plan.name)
    rec = sketch.read_plan_record(tmp_path)
    b = sil.BoardRun(rec, built.elf)
    counts = np.array([40 + 61 * i for i in range(16)], np.int64)
    for k in range(3):
        b.frame(np.roll(counts, k))
    assert len(b.counts_read) == 3
    for k in range(3):
        assert b.counts_read[k].tolist() == np.roll(counts, k).tolist()
    b.finish()


def test_sil_refuses_a_firmware_of_another_scenario(hold, tmp_path, capsys):
    tmp, _, _, _ = hold
    code = main(["sil", str(HERE / "every-kind.toml"), "--firmware", str(tmp / "fw"), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and "another scenario" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("section, field", [
    ("valve_pins = { hip = [22, 70] }", "firmware.valve_pins.hip"),         # D70: the Mega has D0..D69
    ("valve_pins = { hip = [22, 22] }", "firmware.valve_pins.hip"),         # one pin twice
    ("valve_pins = { hip = [1, 23] }", "firmware.valve_pins.hip"),          # the serial port's TX
    ("pressure_inputs = { hip = 16 }", "firmware.pressure_inputs.hip"),     # A16: the Mega has A0..A15
    ('log_rate = "1 kHz"\nbaud = 9600', "firmware.log_rate"),              # 1000 lines/s at 960 bytes/s
])
def test_firmware_refuses_bad_wiring_in_one_line_and_writes_nothing(tmp_path, capsys, section, field):
    text = (SHIPPED / "hold-3bar.toml").read_text()
    head = text.split("\n[firmware]")[0] + "\n"
    path = tmp_path / "bad.toml"
    path.write_text(head + "[firmware]\n" + section + "\n")
    code = main(["firmware", str(path), "--out", str(tmp_path / "fw")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and field in err, err
    assert not (tmp_path / "fw").exists()


def test_every_kind_on_the_robot_commands_the_same_valves(tmp_path):
    """Joint-angle, bang-bang, sliding mode and PWM (closed and open loop) on the robot's board at
    once, 0.6 s of the fixed-base robot in air: the firmware decides as the model's compiled
    laws at every sample, and every controller's metrics equal the compiled `swim` run's."""
    need_avr_tools()
    from frogsim.scenario.load import with_firmware
    scenario = HERE / "robot-every-kind.toml"
    # at the edge of the board: its worst interrupt on random counts (95 %) and its log (7 %) do not
    # fit the period, so the export refuses it; written anyway, SIL measures it on the run
    rec, s = _export_and_sil(scenario, tmp_path, allow_overrun=True)
    assert s["sil"]["mismatched_samples"] == 0 and s["sil"]["samples"] == 601
    assert s["sil"]["adc_read_differs_samples"] == 0
    kinds = {entry["kind"] for name, entry in s["control"].items() if isinstance(entry, dict) and "kind" in entry}
    assert kinds == {"joint-angle", "bang-bang", "sliding-mode", "pwm"}
    compiled = frogsim.swim(frogsim.load_robot_scenario(with_firmware(scenario))).control_metrics()
    for name, entry in compiled.items():
        for key, value in entry.items():
            if isinstance(value, float):
                assert s["control"][name][key] == pytest.approx(value, rel=1e-6, abs=1e-12), (name, key)
            elif isinstance(value, (int, dict)):
                assert s["control"][name][key] == value, (name, key)


@pytest.mark.slow
def test_robot_hip_angle_in_air_commands_the_same_valves(tmp_path):
    """The joint-angle controller on the robot's firmware: 3 s of the fixed-base robot."""
    need_avr_tools()
    from frogsim.scenario.load import with_firmware
    _, s = _export_and_sil("hip-angle-in-air", tmp_path)      # no [firmware] in it: the board's defaults
    assert s["sil"]["mismatched_samples"] == 0 and s["sil"]["overruns"] == 0
    compiled = frogsim.swim(frogsim.load_robot_scenario(with_firmware("hip-angle-in-air"))).control_metrics()["hip"]
    for key in ("tracking_error_rms_deg", "tracking_error_max_deg"):
        assert s["control"]["hip"][key] == pytest.approx(compiled[key], rel=1e-6)
    assert s["control"]["hip"]["switchings"] == compiled["switchings"]
    assert s["control"]["hip"]["samples_pressure_target_clipped"] == compiled["samples_pressure_target_clipped"]


@pytest.mark.slow
def test_robot_swimming_gait_runs_from_the_firmware(tmp_path):
    """The gait (programs as tables) on the firmware, the robot free in water, one 2 s cycle."""
    need_avr_tools()
    scenario = SHIPPED / "swim.toml"            # the shipped gait carries its [firmware] section
    rec, s = _export_and_sil(scenario, tmp_path, "--cycles", "1")
    assert rec["channels"] == [] and len(rec["muscles"]) == 6
    assert s["sil"]["mismatched_samples"] == 0 and s["sil"]["samples"] == 2001
    compiled = frogsim.swim(frogsim.load_robot_scenario(scenario, cycles=1)).summary()
    for key in ("distance_per_cycle_m", "air_used_per_cycle_L_std"):
        assert s[key] == pytest.approx(compiled[key], rel=1e-6), key


@pytest.mark.slow
def test_the_sil_log_of_a_pressure_controlled_run_fits_back_to_the_valve(tmp_path):
    """Design, flash, log, fit: the SIL serial.csv of a bang-bang run (tests/firmware/rig-steps.toml:
    the paper's charge valve, C = 0.4 L/(s bar) and b = 0.38, Sec. 3.3) is a trace `frogsim fit`
    reads as it is; with C and b free, started far from them, the fit's 95 % intervals hold them.

    The trace's only error is the ADC's rounding: steps of 10 bar / (0.8 x 1024) = 12.2 mbar, an
    rms error of 12.2 / sqrt(12) = 3.5 mbar, the stated noise. The bang-bang law makes the model
    step-wise in C and b (a rise ends one sample earlier or later): the finite-difference step
    is 1 % of each range, so that the Jacobian sees the slope through those steps."""
    need_avr_tools()
    scenario = HERE / "rig-steps.toml"
    _, s = _export_and_sil(scenario, tmp_path)
    assert s["sil"]["mismatched_samples"] == 0
    trace = tmp_path / "sil-grid" / "serial.csv"
    spec = tmp_path / "FIT.toml"
    spec.write_text(f'''scenario = "{scenario}"
starts = 1
diff_step = 0.01
noise = "0.0035 bar"

[[experiments]]
name = "sil"
trace = "{trace}"

[parameters]
"valves.charge.sonic_conductance" = {{ min = "0.1 L/(s*bar)", max = "1 L/(s*bar)", start = "0.7 L/(s*bar)" }}
"valves.charge.critical_ratio" = {{ min = "0.1", max = "0.6", start = "0.2" }}
''')
    assert _cli("fit", spec, "--out", tmp_path / "fit") == 0
    fitted = json.loads((tmp_path / "fit" / "summary.json").read_text())["parameters"]
    c, b = fitted["valves.charge.sonic_conductance"], fitted["valves.charge.critical_ratio"]
    assert c["ci_low_si"] <= 0.4e-3 / 1e5 <= c["ci_high_si"], c
    assert b["ci_low_si"] <= 0.38 <= b["ci_high_si"], b


def test_the_checks_see_a_firmware_that_is_not_the_twins(hold):
    """The checks can fail: the firmware built for a 3 bar setpoint, run against the twin of a
    plan for 2.5 bar, decides otherwise wherever the pressure lies between the two bands (the
    twin vents or holds where the firmware still charges): mismatched samples, the first one
    named with both decisions. The shadow, the compiled law of the 3 bar scenario the plant runs,
    agrees with the firmware at every sample: no sample off the on-time model."""
    from frogsim.circuit.model import build_model
    from frogsim.control import firmware as fw
    tmp, rec, _, _ = hold
    elf = tmp / "fw" / "build" / f"{rec['name']}.elf"
    sc = frogsim.load_scenario("hold-3bar")
    model = build_model(sc)
    other = fw.firmware_plan(build_model(sc.replace({"controllers.hold.setpoint.value": 2.5e5})))
    record = sketch.read_plan_record(tmp / "fw")
    s = sil.run_pneumatic(model, record, elf, other, fw.adc_counts, compare=False, timing="grid").sil
    assert s["mismatched_samples"] > 0
    first = s["first_mismatch"]
    assert first["firmware"] != first["twin"]
    assert s["samples_off_the_on_time_model"] == 0 and "first_off_the_on_time_model" not in s
    assert any("differ from the integer twin" in w for w in s["warnings"])
