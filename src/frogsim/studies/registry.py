"""The study registry: name -> (compute data, draw figure, contribute to summary.json)."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import pandas as pd


@dataclass
class StudyData:
    """What a study computes: a tidy table (written as CSV by :func:`write_table`), summary entries,
    and extras for plots. Every column of the table is headed ``name [unit]``
    (:func:`frogsim.scenario.tables.header`) or is a label column of text or whole numbers
    (:data:`frogsim.scenario.tables.LABEL_COLUMNS`)."""
    table: pd.DataFrame
    summary: dict
    extras: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Study:
    name: str
    title: str
    compute: Callable[[], StudyData]
    draw: Callable[[StudyData, str], None]
    group: str = "paper"     # "paper": frogsim reproduce; "design": frogsim design
    cost: float = 1.0        # relative first-run cost (compilation included): costly ones start first


STUDIES: dict[str, Study] = {}


def register(name: str, title: str, group: str = "paper", cost: float = 1.0):
    """Decorator pairing a compute function with a draw function under a study name."""
    def deco(compute):
        def with_draw(draw):
            STUDIES[name] = Study(name, title, compute, draw, group, cost)
            return draw
        compute.draws = with_draw
        return compute
    return deco


def studies_in(group: str) -> list[str]:
    """Names of the registered studies of a group, in registration order."""
    return [n for n, s in STUDIES.items() if s.group == group]


def run_study(name: str) -> StudyData:
    """Compute a registered study's data."""
    if name not in STUDIES:
        raise KeyError(f"unknown study {name!r}; studies: {', '.join(STUDIES)}")
    return STUDIES[name].compute()


def write_table(name: str, data: StudyData, out) -> Path:
    """Write a study's table as ``<name>.csv`` in folder ``out`` (frogsim._files.write_csv); its path."""
    from frogsim._files import write_csv
    path = Path(out) / f"{name}.csv"
    write_csv(path, data.table)
    return path
