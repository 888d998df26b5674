"""ISO 2859-1 Table 1 (sample size code letters) and Tables 2-A, 2-B and 2-C (single sampling: normal, tightened, reduced).

Transcribed from two public copies of the tables, which agree with each other (ISO 2859-1 is
MIL-STD-105E and ANSI/ASQ Z1.4 on these tables):

- Table 1: "ANSI/ASQC Z1.4/MIL-STD-105E/BS 6001/DIN 40080/ISO 2859 Table I, Sample Size Code
  Letters" (https://pdfcoffee.com/aql-sampling-chart-pdf-free.html), cross-checked row by row
  against GOST R ISO 2859-1's Table A.1 (https://base.garant.ru/71446952/), which states that its
  code letters are ISO 2859-1's (it merges the A rows into B; every other row is the same).
- Table 2-A: the same chart's "Table II Single Sampling Plans For Normal Inspection", cross-checked
  cell by cell for level II, AQL 0.65 to 15, against "TABLE 1-A, developed from MIL-STD-105E
  TABLE I and TABLE II-A" (http://www.nibs.org/FMOC/DPW_AC/AC-TABLE.ASC), and for levels S-3 and
  S-4 against the plans ISO 2859-1:1999 gives for lots of 35,001 to 500,000 quoted in
  https://plos.figshare.com/articles/figure/22583454 (tests/test_lot.py checks each of those).

In Table 2-A, ``v`` is the standard's downward arrow ("use the first sampling plan below the
arrow": a larger sample) and ``^`` its upward arrow ("the first sampling plan above the arrow");
a plan is "Ac Re". The sample size is the one of the row where the arrow ends.
"""

# ruff: noqa: E501 (a row of Table 2-A is one line, as the standard prints it)

from __future__ import annotations

LEVELS = ("S-1", "S-2", "S-3", "S-4", "I", "II", "III")

# Table 1: (largest lot size of the row, code letters for S-1, S-2, S-3, S-4, I, II, III)
CODE_LETTERS = (
    (8, "A A A A A A B"),
    (15, "A A A A A B C"),
    (25, "A A B B B C D"),
    (50, "A B B C C D E"),
    (90, "B B C C C E F"),
    (150, "B B C D D F G"),
    (280, "B C D E E G H"),
    (500, "B C D E F H J"),
    (1200, "C C E F G J K"),
    (3200, "C D E G H K L"),
    (10000, "C D F G J L M"),
    (35000, "C D F H K M N"),
    (150000, "D E G J L N P"),
    (500000, "D E G J M P Q"),
    (None, "D E H K N Q R"),  # 500,001 and over
)

SAMPLE_SIZES = {
    "A": 2, "B": 3, "C": 5, "D": 8, "E": 13, "F": 20, "G": 32, "H": 50,
    "J": 80, "K": 125, "L": 200, "M": 315, "N": 500, "P": 800, "Q": 1250, "R": 2000,
}  # fmt: skip

# the AQLs of Table 2-A's columns, as the standard prints them (percent nonconforming up to 10,
# nonconformities per 100 items above)
AQLS = (
    "0.010", "0.015", "0.025", "0.040", "0.065", "0.10", "0.15", "0.25", "0.40", "0.65", "1.0", "1.5", "2.5",
    "4.0", "6.5", "10", "15", "25", "40", "65", "100", "150", "250", "400", "650", "1000",
)  # fmt: skip

# Table 2-A, one row per code letter, one cell per AQL of AQLS
NORMAL = {
    "A": "v | v | v | v | v | v | v | v | v | v | v | v | v | v | 0 1 | ^ | v | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | 30 31",
    "B": "v | v | v | v | v | v | v | v | v | v | v | v | v | 0 1 | ^ | v | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | 30 31 | 44 45",
    "C": "v | v | v | v | v | v | v | v | v | v | v | v | 0 1 | ^ | v | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | 30 31 | 44 45 | ^",
    "D": "v | v | v | v | v | v | v | v | v | v | v | 0 1 | ^ | v | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | 30 31 | 44 45 | ^ | ^",
    "E": "v | v | v | v | v | v | v | v | v | v | 0 1 | ^ | v | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | 30 31 | 44 45 | ^ | ^ | ^",
    "F": "v | v | v | v | v | v | v | v | v | 0 1 | ^ | v | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^",
    "G": "v | v | v | v | v | v | v | v | 0 1 | ^ | v | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "H": "v | v | v | v | v | v | v | 0 1 | ^ | v | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "J": "v | v | v | v | v | v | 0 1 | ^ | v | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "K": "v | v | v | v | v | 0 1 | ^ | v | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "L": "v | v | v | v | 0 1 | ^ | v | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "M": "v | v | v | 0 1 | ^ | v | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "N": "v | v | 0 1 | ^ | v | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "P": "v | 0 1 | ^ | v | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "Q": "0 1 | ^ | v | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "R": "^ | ^ | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
}  # fmt: skip

# Table 2-B (single sampling, tightened inspection): the sample sizes of Table 2-A, and S (3150),
# which only the arrow of AQL 0.025 under R reaches; R at 0.015, with no plan below it, points back
# up to Q's 0/1 (as Table 2-A's R does at 0.010 and 0.015). Its plans are 0/1, then (two arrow
# cells further) 1/2, 2/3, 3/4, 5/6, 8/9, 12/13, 18/19, and for the five smallest samples 27/28 and
# 41/42; each row one AQL column to the right of the row below, as in Table 2-A (whose rows A to Q
# follow the same construction exactly, with ^ v after 0/1). Rows B to L at AQL 0.65 to 15 are
# checked against MIL-STD-105E's Table II-B as www.nibs.org/FMOC/DPW_AC/AC-TABLE.ASC quotes it
# (its Table 1-B), cell by cell (tests/test_lot.py). Row S: "-" is a cell no arrow reaches.
TIGHTENED_SAMPLE_SIZES = {**SAMPLE_SIZES, "S": 3150}

TIGHTENED = {
    "A": "v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | 0 1 | v | v | 1 2 | 2 3 | 3 4 | 5 6 | 8 9 | 12 13 | 18 19 | 27 28",
    "B": "v | v | v | v | v | v | v | v | v | v | v | v | v | v | 0 1 | v | v | 1 2 | 2 3 | 3 4 | 5 6 | 8 9 | 12 13 | 18 19 | 27 28 | 41 42",
    "C": "v | v | v | v | v | v | v | v | v | v | v | v | v | 0 1 | v | v | 1 2 | 2 3 | 3 4 | 5 6 | 8 9 | 12 13 | 18 19 | 27 28 | 41 42 | ^",
    "D": "v | v | v | v | v | v | v | v | v | v | v | v | 0 1 | v | v | 1 2 | 2 3 | 3 4 | 5 6 | 8 9 | 12 13 | 18 19 | 27 28 | 41 42 | ^ | ^",
    "E": "v | v | v | v | v | v | v | v | v | v | v | 0 1 | v | v | 1 2 | 2 3 | 3 4 | 5 6 | 8 9 | 12 13 | 18 19 | 27 28 | 41 42 | ^ | ^ | ^",
    "F": "v | v | v | v | v | v | v | v | v | v | 0 1 | v | v | 1 2 | 2 3 | 3 4 | 5 6 | 8 9 | 12 13 | 18 19 | ^ | ^ | ^ | ^ | ^ | ^",
    "G": "v | v | v | v | v | v | v | v | v | 0 1 | v | v | 1 2 | 2 3 | 3 4 | 5 6 | 8 9 | 12 13 | 18 19 | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "H": "v | v | v | v | v | v | v | v | 0 1 | v | v | 1 2 | 2 3 | 3 4 | 5 6 | 8 9 | 12 13 | 18 19 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "J": "v | v | v | v | v | v | v | 0 1 | v | v | 1 2 | 2 3 | 3 4 | 5 6 | 8 9 | 12 13 | 18 19 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "K": "v | v | v | v | v | v | 0 1 | v | v | 1 2 | 2 3 | 3 4 | 5 6 | 8 9 | 12 13 | 18 19 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "L": "v | v | v | v | v | 0 1 | v | v | 1 2 | 2 3 | 3 4 | 5 6 | 8 9 | 12 13 | 18 19 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "M": "v | v | v | v | 0 1 | v | v | 1 2 | 2 3 | 3 4 | 5 6 | 8 9 | 12 13 | 18 19 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "N": "v | v | v | 0 1 | v | v | 1 2 | 2 3 | 3 4 | 5 6 | 8 9 | 12 13 | 18 19 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "P": "v | v | 0 1 | v | v | 1 2 | 2 3 | 3 4 | 5 6 | 8 9 | 12 13 | 18 19 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "Q": "v | 0 1 | v | v | 1 2 | 2 3 | 3 4 | 5 6 | 8 9 | 12 13 | 18 19 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "R": "0 1 | ^ | v | 1 2 | 2 3 | 3 4 | 5 6 | 8 9 | 12 13 | 18 19 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "S": "- | - | 1 2 | - | - | - | - | - | - | - | - | - | - | - | - | - | - | - | - | - | - | - | - | - | - | -",
}  # fmt: skip

# Table 2-C (single sampling, reduced inspection; ISO 2859-1:1999, where every plan's rejection number
# is its acceptance number + 1): each code letter takes the sample of the letter two rows above it
# in Table 2-A (A, B and C all 2), and that letter's plans, with the two arrow cells after its 0/1
# (^ v in Table 2-A) made 0/1 and 1/2. A and B point down to C (the same sample of 2); R's AQL
# 0.010, below which no plan lies, is read as R's 0/1. Not checked cell by cell against a copy of
# the 1999 table (none was at hand): built by this construction, which gives code letter J at AQL
# 1.0 the plan quoted for the 1999 edition (sample 32, Ac 1, Re 2).
REDUCED_SAMPLE_SIZES = {
    "A": 2, "B": 2, "C": 2, "D": 3, "E": 5, "F": 8, "G": 13, "H": 20,
    "J": 32, "K": 50, "L": 80, "M": 125, "N": 200, "P": 315, "Q": 500, "R": 800,
}  # fmt: skip

REDUCED = {
    "A": "v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v",
    "B": "v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v | v",
    "C": "v | v | v | v | v | v | v | v | v | v | v | v | v | v | 0 1 | 0 1 | 1 2 | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | 30 31",
    "D": "v | v | v | v | v | v | v | v | v | v | v | v | v | 0 1 | 0 1 | 1 2 | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | 30 31 | 44 45",
    "E": "v | v | v | v | v | v | v | v | v | v | v | v | 0 1 | 0 1 | 1 2 | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | 30 31 | 44 45 | ^",
    "F": "v | v | v | v | v | v | v | v | v | v | v | 0 1 | 0 1 | 1 2 | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | 30 31 | 44 45 | ^ | ^",
    "G": "v | v | v | v | v | v | v | v | v | v | 0 1 | 0 1 | 1 2 | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | 30 31 | 44 45 | ^ | ^ | ^",
    "H": "v | v | v | v | v | v | v | v | v | 0 1 | 0 1 | 1 2 | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^",
    "J": "v | v | v | v | v | v | v | v | 0 1 | 0 1 | 1 2 | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "K": "v | v | v | v | v | v | v | 0 1 | 0 1 | 1 2 | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "L": "v | v | v | v | v | v | 0 1 | 0 1 | 1 2 | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "M": "v | v | v | v | v | 0 1 | 0 1 | 1 2 | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "N": "v | v | v | v | 0 1 | 0 1 | 1 2 | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "P": "v | v | v | 0 1 | 0 1 | 1 2 | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "Q": "v | v | 0 1 | 0 1 | 1 2 | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
    "R": "0 1 | 0 1 | 0 1 | 1 2 | 1 2 | 2 3 | 3 4 | 5 6 | 7 8 | 10 11 | 14 15 | 21 22 | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^ | ^",
}  # fmt: skip
