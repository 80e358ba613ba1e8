"""Write FESTO's DMSP-20 force-contraction data (frogsim.components.dmsp20.REFERENCE, cited there) as
a force table for ``frogsim fit``: one row per point, 0 to 6 bar gauge, contraction in %, force in N.

Run:  python examples/fit/force/make_table.py      (writes dmsp20-festo.csv here)

The rows are FESTO's as tabulated, negative forces included (the push needed to hold the muscle
shorter than it contracts on its own): the fit leaves those out and says so.
"""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from frogsim.components.dmsp20 import REFERENCE

HERE = Path(__file__).resolve().parent


def main() -> None:
    rows = [(p / 1e5, e * 100, f) for p, (eps, forces) in sorted(REFERENCE.items()) for e, f in zip(eps, forces)]
    df = pd.DataFrame(rows, columns=["pressure [bar gauge]", "contraction [%]", "force [N]"])
    df.to_csv(HERE / "dmsp20-festo.csv", index=False, float_format="%.6g")
    print(f"wrote {HERE / 'dmsp20-festo.csv'} ({len(df)} rows)")


if __name__ == "__main__":
    main()
