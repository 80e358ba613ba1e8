"""The robot's studies and outputs: the in-air leg experiment (paper Figs. 12-13) and swim runs.

``leg-in-air`` (registered study): the paper's Sec. 4.1-4.2 setting, body fixed on a base in air,
1 s pressurise / 1 s release from 6 bar with spring recovery. Joint angles with the delay between
the valve command and the joint's motion (Fig. 12's kind), and the hip muscle pressure with the
muscle volume taken from the simulated joint angles (Fig. 13's kind), next to the prescribed-motion
model of ``paper-cycle``.

:func:`write_outputs` writes a robot run's files (``frogsim swim``): timeseries.csv, a figure,
summary.json, the MJCF model and the animation.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from frogsim._plotting import figure, legend_in, save
from frogsim._words import count
from frogsim.scenario.tables import header
from frogsim.studies.registry import StudyData, register

BAR = 1e5
NOTE = "frogsim, parameter set fan2017 with the robot sections; pressures gauge"
JOINT_COLORS = {"hip": "tab:blue", "knee": "tab:orange", "ankle": "tab:green"}
# leg-in-air's CSV columns, in the one header convention (frogsim.scenario.tables)
TIME = header("time", "s")
HIP_PRESSURE = header("hip pressure", "bar gauge")
HIP_PRESSURE_PRESCRIBED = header("hip pressure prescribed motion", "bar gauge")
HIP_VOLUME = header("hip volume", "cm^3")


def _angle(joint: str) -> str:
    return header(f"{joint} angle", "deg")


def _gauge(result, p):
    return (np.asarray(p) - result.atmospheric_pressure) / BAR


# --- leg in air -------------------------------------------------------------------------------------
@register("leg-in-air", "Leg in air, body fixed: joint angles and delay, hip pressure from the joints "
                        "(paper Figs. 12-13)", group="robot", cost=8.0)   # compiles the coupled MuJoCo engine (~10 s)
def leg_in_air() -> StudyData:
    from frogsim.circuit import layout as CL
    from frogsim.engine.pneumatic import simulate
    from frogsim.engine.swim import swim
    from frogsim.circuit import actuators
    r = swim("leg-in-air")
    t = r.t
    i = r.muscle_names.index("hip_left")
    mp = r.model.pneumatic.mp
    V = np.array([actuators.volume(mp, i, L) for L in r.lengths[:, i]]) + mp[i, CL.M_DEAD]
    prescribed = simulate("paper-cycle")
    table = pd.DataFrame({TIME: t})
    for j in ("hip", "knee", "ankle"):
        table[_angle(j)] = np.degrees(r.joint_angles[:, r.joint_names.index(f"{j}_left")])
    table[HIP_PRESSURE] = _gauge(r, r.pressures[:, i])
    table[HIP_VOLUME] = V * 1e6
    table[header("hip contraction", "%")] = 100 * r.contraction()[:, i]
    table[HIP_PRESSURE_PRESCRIBED] = np.interp(
        t, prescribed.t, _gauge(prescribed, prescribed.muscle_pressure("hip_left")))
    table[header("source pressure", "bar gauge")] = _gauge(r, r.source_pressure)
    s = r.summary()
    left = [f"{j}_left" for j in ("hip", "knee", "ankle")]
    summary = {"leg_in_air": {
        "joint_delay_s": {n: s["joint_delay_s"][n] for n in left},
        "joint_delay_mean_s": float(np.mean([s["joint_delay_s"][n] for n in left])),
        "joint_range_deg": {n: s["joints"][n]["max_deg"] - s["joints"][n]["min_deg"] for n in left},
        "max_contraction_percent": {n: s["max_contraction_percent"][n] for n in left},
        "hip_aeration_volume_L": s["aeration_volume_L_std"]["hip_left"],
        "hip_pressure_end_of_pressurise_bar_gauge": float(np.interp(1.0, t, table[HIP_PRESSURE])),
    }}
    return StudyData(table, summary, {"delays": summary["leg_in_air"]["joint_delay_s"],
                                      "command_s": 0.0, "release_s": 1.0})


@leg_in_air.draws
def _draw_leg(data: StudyData, path: str) -> None:
    d = data.table
    fig, ax = figure(2, 1, width=10.0, height=6.4, sharex=True)
    a, b = ax[0, 0], ax[1, 0]
    for j in ("hip", "knee", "ankle"):
        delay = data.extras["delays"][f"{j}_left"]
        a.plot(d[TIME], d[_angle(j)], color=JOINT_COLORS[j], lw=2,
               label=f"{j}: delay {delay * 1e3:.0f} ms")
    # the valve commands named on a top axis of their own: written inside, their text met the curves
    commands = {data.extras["command_s"]: "charge command", data.extras["release_s"]: "vent command"}
    for x in commands:
        a.axvline(x, color="0.4", ls=":", lw=1)
    top = a.secondary_xaxis("top")
    top.set_xticks(list(commands), list(commands.values()), fontsize=8, color="0.3")
    top.tick_params(length=3, color="0.4")
    a.set_ylabel("joint angle from flexed stop [deg]")
    a.set_title("Leg in air, body fixed: joint angles (cf. paper Fig. 12)")
    a.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)     # outside: hides no curve
    b.plot(d[TIME], d[HIP_PRESSURE], lw=2, label="hip muscle, volume from the joint angles")
    b.plot(d[TIME], d[HIP_PRESSURE_PRESCRIBED], lw=1, ls="--", color="0.35",
           label="paper-cycle: prescribed muscle motion")
    b.set_ylabel("pressure [bar gauge]")
    b.set_xlabel("time [s]")
    b.set_title("Hip muscle pressure (cf. paper Fig. 13)")
    b2 = b.twinx()
    b2.plot(d[TIME], d[HIP_VOLUME], color="tab:purple", lw=1, alpha=0.7, label="hip muscle volume (right axis)")
    b2.set_ylabel("hip muscle volume [cm$^3$]", color="tab:purple")
    lines = b.get_legend_handles_labels()
    more = b2.get_legend_handles_labels()
    b.legend(lines[0] + more[0], lines[1] + more[1], loc="upper left", bbox_to_anchor=(1.1, 1.0),
             fontsize=8)
    save(fig, path, NOTE)


# --- swim outputs -----------------------------------------------------------------------------------
MAX_CONTROL_PANELS = 4      # closed-loop controllers drawn, one panel each (all are in summary.json)


def plot_swim(result, path: str, summary: dict | None = None) -> None:
    """Panels against time: forward motion (not for a fixed base: nothing moves), the medium's
    forces (water or air), joint angles (the palms' opening on a 0-1 axis of its own), pressures
    (driving muscles solid, recovery muscles dashed), then one panel per closed-loop controller
    (:func:`_draw_controller`). Each panel's legend stands in a column of its own at the right, clear
    of the curves and of the right-hand axes' labels."""
    s = summary or result.summary()
    t = result.t
    fixed = result.rs.options.base == "fixed"
    medium = result.rs.options.environment
    controllers = [(n, c) for n, c in result.rs.pneumatic.controllers.items() if c.kind != "program"]
    shown = controllers[:MAX_CONTROL_PANELS]
    rows = (3 if fixed else 4) + len(shown)
    fig, grid = figure(rows, 2, width=12.5, height=2.6 * rows + 0.3 * (not fixed), sharex=True,
                       gridspec_kw={"width_ratios": [1, 0.2]})
    ax, lax = grid[:, 0], grid[:, 1]
    for x0, x1 in result.extension_windows():
        for axis in ax:
            axis.axvspan(x0, x1, color="tab:orange", alpha=0.07, lw=0)
    air = f"{s['air_used_per_cycle_L_std']:.2f} L of air per cycle (shaded: extension)"
    if fixed:
        b, c, e = ax[:3]
        lb, lc, le = lax[:3]
        b.set_title(f"{s['scenario']}: base fixed in {medium}, no swimming; {air}", fontsize=9)
    else:
        a, b, c, e = ax[:4]
        la, lb, lc, le = lax[:4]
        la.axis("off")
        a.plot(t, result.forward, color="k", lw=2, label="forward distance")
        a.set_ylabel("distance [m]")
        a2 = a.twinx()
        a2.plot(t, result.forward_velocity, color="tab:blue", lw=1, label="forward velocity")
        a2.set_ylabel("velocity [m/s]", color="tab:blue")
        a.set_title(f"{s['scenario']}: {s['mean_speed_m_per_s']:.2f} m/s ({s['mean_speed_body_lengths_per_s']:.2f} "
                    f"body lengths/s), {s['distance_per_cycle_m']:.2f} m and {air}", fontsize=9)
    b.plot(t, result.thrust, lw=1.2, label="legs (thrust)")
    b.plot(t, result.hull_force, lw=1.2, label="hull")
    b.axhline(0, color="0.5", lw=0.6)
    b.set_ylabel(f"{medium} force along heading [N]")
    legend_in(lb, b, fontsize=8)
    for j in ("hip", "knee", "ankle"):
        c.plot(t, np.degrees(result.joint_angles[:, result.joint_names.index(f"{j}_left")]),
               color=JOINT_COLORS[j], label=j)
    c.set_ylabel("left leg joint angle [deg]")
    c2 = c.twinx()
    c2.plot(t, result.palm_opening[:, 0], color="0.45", ls=":", lw=1.2, label="left palm opening (right axis)")
    c2.set_ylim(-0.05, 1.6)
    c2.set_yticks([0, 1], ["fold", "open"])
    c2.set_ylabel("palm", color="0.45")
    legend_in(lc, c, c2, fontsize=8)
    e.plot(t, _gauge(result, result.source_pressure), "k", lw=2, label="source")
    e.plot(t, _gauge(result, result.exhaust_pressure), "k--", lw=1, label="exhaust")
    for j in ("hip", "knee", "ankle"):
        i = result.muscle_names.index(f"{j}_left")
        e.plot(t, _gauge(result, result.pressures[:, i]), color=JOINT_COLORS[j], lw=1, label=f"{j} driving")
        if f"{j}_left_recovery" in result.muscle_names:
            k = result.muscle_names.index(f"{j}_left_recovery")
            e.plot(t, _gauge(result, result.pressures[:, k]), color=JOINT_COLORS[j], lw=1, ls="--",
                   label=f"{j} recovery")
    e.set_ylabel("left leg, pressure [bar gauge]")
    legend_in(le, e, fontsize=8)
    first = rows - len(shown)
    for k, (name, ctl) in enumerate(shown):
        _draw_controller(ax[first + k], lax[first + k], result, name, ctl, s.get("control", {}).get(name, {}))
    ax[-1].set_xlabel("time [s]")
    note = NOTE
    if len(controllers) > len(shown):
        note += f"; {len(controllers) - len(shown)} more closed-loop controller(s) in summary.json"
    save(fig, path, note)


def _draw_controller(a, lax, result, name: str, ctl, m: dict) -> None:
    """One closed-loop controller: its setpoint and the tracked signal on one axis (a joint angle
    [deg] or a muscle pressure [bar gauge]), a joint-angle controller's muscle and antagonist
    pressures on the right axis, the time before ``settle`` hatched (not in the metrics) and the
    tracking numbers of summary.json written in the panel; its legend in ``lax``."""
    t = result.t
    settle = m.get("settle_s", ctl.settle_time(result.rs.duration))
    a.axvspan(t[0], settle, facecolor="none", edgecolor="0.75", hatch="//", lw=0)
    if ctl.kind == "joint-angle":
        j = result.joint_names.index(ctl.joint)
        a.plot(t, np.degrees(result.setpoint(name)), "k--", lw=1.5, label=f"{ctl.joint} setpoint")
        a.plot(t, np.degrees(result.joint_angles[:, j]), color="tab:purple", lw=1.5, label=f"{ctl.joint} angle")
        a.set_ylabel(f"{name}: angle [deg]")
        a2 = a.twinx()
        for mu, ls in ((ctl.muscle, "-"), (ctl.antagonist, ":")):
            i = result.muscle_names.index(mu)
            role = "muscle" if mu == ctl.muscle else "antagonist"
            a2.plot(t, _gauge(result, result.pressures[:, i]), color="tab:red", ls=ls, lw=1,
                    label=f"{mu} ({role}) pressure, right axis")
        a2.set_ylabel("pressure [bar gauge]", color="tab:red")
        legend_in(lax, a, a2, fontsize=8)
        unit, rms, mx = "deg", m.get("tracking_error_rms_deg"), m.get("tracking_error_max_deg")
        extra = f", pressure target clipped at {count(m.get('samples_pressure_target_clipped', 0), 'sample')}"
    else:
        i = result.muscle_names.index(ctl.muscle)
        a.plot(t, _gauge(result, result.setpoint(name)), "k--", lw=1.5, label=f"{ctl.muscle} setpoint")
        a.plot(t, _gauge(result, result.pressures[:, i]), color="tab:red", lw=1.5, label=f"{ctl.muscle} pressure")
        a.set_ylabel(f"{name}: pressure [bar gauge]")
        legend_in(lax, a, fontsize=8)
        unit, rms, mx = "bar", m.get("tracking_error_rms_bar"), m.get("tracking_error_max_bar")
        extra = ""

    def num(x):
        return "n/a" if x is None else f"{x:.3g}"
    a.set_title(f"{name}: {ctl.kind} control; tracking error from {settle:g} s on (earlier: hatched, "
                f"not counted) RMS {num(rms)} {unit}, max {num(mx)} {unit}\n"
                f"{num(m.get('switchings_per_s'))} valve switchings/s, {num(m.get('air_used_L_std'))} L "
                f"(standard) of air{extra}", fontsize=8.5)


def write_outputs(result, out, animation: bool = True, progress=None, extra: dict | None = None) -> dict:
    """Write timeseries.csv, swim.png, summary.json, frog.xml and animation.gif into ``out``
    (``extra``: more sections of summary.json, e.g. software in the loop's "sil").

    Every file is written atomically (a reader never sees half a file). If no OpenGL backend can
    draw offscreen, the animation is skipped and the reason kept in the summary under
    "animation_skipped". Returns ({file kind: path}, summary).
    """
    from frogsim._files import atomic_write, write_csv, write_figure, write_json
    out = Path(out)
    files = {}
    from frogsim.scenario.tables import unit_headers
    write_csv(out / "timeseries.csv", unit_headers(result.to_dataframe(units="display")))
    files["timeseries"] = out / "timeseries.csv"
    summary = {**result.summary(), **(extra or {})}
    write_figure(out / "swim.png", lambda p: plot_swim(result, p, summary))
    files["figure"] = out / "swim.png"
    atomic_write(out / "frog.xml", lambda tmp: Path(tmp).write_text(result.model.xml))
    files["mjcf"] = out / "frog.xml"
    if animation:
        from frogsim.robot.render import RenderUnavailable, render_animation
        if progress:
            progress("rendering the animation offscreen ...")
        try:
            files["animation"] = render_animation(result, out / "animation.gif", fps=12)
        except RenderUnavailable as exc:
            summary["animation_skipped"] = str(exc)
    write_json(out / "summary.json", summary)
    files["summary"] = out / "summary.json"
    return files, summary
