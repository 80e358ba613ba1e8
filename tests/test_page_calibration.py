"""docs/calibration.md reads as the code computes: the braid angle from the force it names, the dead
volume's tube from its bore, the calibrated contractions as the calibration prints them (the printed
block itself is compared with a run of its command in tests/test_doc_blocks.py), the values the
parameter set keeps, and the aeration volumes those give."""
from __future__ import annotations

import math
import re

from scipy.optimize import brentq

import frogsim
from page_numbers import NUM, check, page, section, table_rows

DOC = page("calibration.md")
ROWS = table_rows(DOC, "| value | how it was set | result |")
PRINTED = re.search(r"<!-- test: output of the block above -->\n```text\n(.*?)```", DOC, re.S).group(1)
TYPES = frogsim.load_scenario("paper-cycle").muscle_types


def printed(mtype: str) -> str:
    return re.search(rf"^{mtype}: stroke_contraction = {NUM} % -> target [\d.]+ L$", PRINTED, re.M).group(1)


def test_the_braid_angle_is_the_one_that_gives_the_force_the_page_names():
    cell = ROWS["braid angle θ0"]
    m = re.search(r"DMSP-20's (\d+) N at (\d+) bar and 0 % contraction with D0 = (\d+) mm", cell[1])
    force, p, d0 = float(m.group(1)), float(m.group(2)) * 1e5, float(m.group(3)) * 1e-3
    theta = brentq(lambda th: math.pi * d0 ** 2 * p / 4 * (3 * math.cos(th) ** 2 - 1) / math.sin(th) ** 2 - force,
                   0.2, 0.9)
    check(cell[2], [("^" + NUM + "°$", math.degrees(theta)),
                    ("^" + NUM + "°$", math.degrees(TYPES["hip"].braid_angle))])


def test_the_dead_volume_and_its_tube():
    cell = ROWS["dead volume"]
    m = re.search(r"(\d+(?:\.\d+)?) m of the (\d+(?:\.\d+)?) mm bore branch tube \((\d+) cm³\)", cell[1])
    length, bore = float(m.group(1)), float(m.group(2)) * 1e-3
    assert float(m.group(3)) == round(math.pi * bore ** 2 / 4 * length * 1e6)
    check(cell[2], [("^" + NUM + " cm³$", TYPES["hip"].dead_volume * 1e6)])


def test_the_table_gives_the_printed_calibration_and_the_kept_values():
    for label, types in (("stroke contraction, hip", ("hip",)),
                         ("stroke contraction, knee and ankle", ("knee", "ankle"))):
        cell = ROWS[label][2]
        for t in types:
            check(cell, [("^" + NUM + " %;", float(printed(t))),
                         ("keeps " + NUM + " %$", 100 * TYPES[t].stroke_contraction)])


def test_the_kept_values_and_their_aeration_volumes(study):
    text = " ".join(section(DOC, "The parameter set keeps").split())
    check(text, [(r"keeps " + NUM + " % and", 100 * TYPES["hip"].stroke_contraction),
                 (r"% and " + NUM + r" %, an earlier", 100 * TYPES["knee"].stroke_contraction),
                 (NUM + " points above these",
                  100 * TYPES["hip"].stroke_contraction - float(printed("hip"))),
                 (NUM + " points above these",
                  100 * TYPES["knee"].stroke_contraction - float(printed("knee")))])
    aer = study("aeration").summary["aeration_volume_L"]
    check(text, [("volumes are " + NUM + r" L \(hip\)", aer["hip"]), ("and " + NUM + r" L \(knee", aer["knee"]),
                 ("and " + NUM + r" L \(knee", aer["ankle"])])
