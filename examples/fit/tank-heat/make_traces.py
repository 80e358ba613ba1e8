"""Write the traces of this example from the measured points, copied verbatim.

Source: measured air traces shipped in HydDown (github.com/andr1976/HydDown, MIT licence, commit
1040d758b819533451086baa5cf2a47b4292a22f), files validation/Air_790kPa_21mm.yml (discharge) and
validation/Air_3-7kPa_271mm.yml (filling), keys validation.temperature and validation.pressure;
probably from Thorncroft, Patton & Gordon (2007), "Modeling compressible air flow in a charging or
discharging vessel and assessment of polytropic exponent", ASEE Annual Conference, AC 2007-2695,
doi:10.18260/1-2--2911 -- HydDown does not say so. Time in s, temperature in K, pressure in bar abs.

Two changes, both said in the files' names and in docs/fitting.md:
* a trace must start at 0 s, and no point was measured there: each trace's first row is the
  initial state the data set states (``initial`` in the same YAML: 790 kPa and 298 K for the
  discharge, 3.7 kPa and 295 K for the filling), not a measurement;
* the filling temperature's time list holds 0.473 before 0.308 (the digitising order): the
  (time, temperature) pairs are sorted by time.
The recovery traces hold the temperatures measured once the flow has (almost) stopped, from the
discharge's 42.5 s and the filling's 21.8 s on, their time counted from there: they start at a
measured point. The vessel's pressure at that moment (interpolated between the two pressure points
around it) is printed for FIT-*-recovery.toml.

The filling pressure stops at 25.705 s: its next points lie 15 s apart (41.1, 56.1, 69.7, 77.2 s,
all within 2 mbar of 1.006 bar), a gap frogsim refuses to interpolate over.

    python make_traces.py        # rewrites the four CSV files next to this script
"""
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent

DISCHARGE_T = ([3.58, 7.65, 11.4, 15.2, 19.2, 23.2, 26.8, 30.8, 34.7, 38.6, 42.5, 46.2, 50.1, 54],
               [285.9, 275.3, 265.8, 261.1, 257.8, 256.4, 256.7, 257.8, 260.4, 264.2, 268.6, 272.6, 276, 278.9])
DISCHARGE_P = ([0.226, 4.14, 8.06, 12, 15.7, 19.6, 23.6, 27.6, 31.5, 35.2, 39.2, 43.2, 47.1, 50.8, 54.8],
               [7.6883, 5.6748, 4.2327, 3.2582, 2.6213, 2.0884, 1.7112, 1.412, 1.2037, 1.0863, 1.0209, 1.0074,
                1.0069, 1.0064, 1.0059])
FILLING_T = ([0.0383, 0.473, 0.308, 1.12, 2.73, 6.91, 12.5, 17, 21.8, 27.3, 29.1, 31.6, 35.4, 46.3, 55.2, 64.2, 77.8],
             [295.8, 301.5, 306.6, 309.9, 312.1, 314.1, 313.7, 312.3, 311.4, 310, 308.2, 304.8, 306, 303.3, 301.5,
              300.2, 298.8])
FILLING_P = ([0.3882, 2.3087, 5.0182, 6.9438, 9.4554, 12.369, 13.319, 16.254, 19.198, 25.705, 41.089, 56.079,
              69.689, 77.184],
             [0.019082, 0.17692, 0.33477, 0.477, 0.63658, 0.77362, 0.88289, 0.95577, 1.0009, 1.0062, 1.0082,
              1.0068, 1.0053, 1.0054])
#: the stated initial state (YAML ``initial``): (pressure [bar abs], temperature [K])
DISCHARGE_START = (7.90, 298.0)
FILLING_START = (0.037, 295.0)
FILLING_P_END = 25.705          # s: the last filling pressure point before the 15 s gap
#: where the recovery traces start [s]: a temperature point at which the flow has (almost) stopped
DISCHARGE_RECOVERY, FILLING_RECOVERY = 42.5, 21.8


def write(name: str, header: str, t0_value: float, times, values, t_end: float = np.inf) -> None:
    order = np.argsort(times, kind="stable")
    t = np.asarray(times, float)[order]
    v = np.asarray(values, float)[order]
    keep = t <= t_end
    rows = [f"0,{t0_value:g}"] + [f"{a:g},{b:g}" for a, b in zip(t[keep], v[keep])]
    (HERE / name).write_text(f"time [s],{header}\n" + "\n".join(rows) + "\n")


if __name__ == "__main__":
    write("discharge-pressure.csv", "source pressure [bar abs]", DISCHARGE_START[0], *DISCHARGE_P)
    write("discharge-temperature.csv", "source temperature [K]", DISCHARGE_START[1], *DISCHARGE_T)
    write("filling-pressure.csv", "source pressure [bar abs]", FILLING_START[0], *FILLING_P, t_end=FILLING_P_END)
    write("filling-temperature.csv", "source temperature [K]", FILLING_START[1], *FILLING_T)
    for name, t0, (tt, TT), (tp, pp) in (("discharge", DISCHARGE_RECOVERY, DISCHARGE_T, DISCHARGE_P),
                                        ("filling", FILLING_RECOVERY, FILLING_T, FILLING_P)):
        order = np.argsort(tt, kind="stable")
        t, T = np.asarray(tt, float)[order], np.asarray(TT, float)[order]
        keep = t >= t0
        rows = [f"{a - t0:.4g},{b:g}" for a, b in zip(t[keep], T[keep])]
        (HERE / f"{name}-recovery-temperature.csv").write_text("time [s],source temperature [K]\n"
                                                               + "\n".join(rows) + "\n")
        print(f"{name} recovery from {t0:g} s: {T[keep][0]:g} K, pressure {np.interp(t0, tp, pp):.5f} bar abs")
