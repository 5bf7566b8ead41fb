"""What the commands print fits a terminal and is never obeyed by it (issue 41).

* ``ncstab laws`` fits 100 columns, each law's first line still names it and
  its class;
* an estimate from a tiny ``sample_step`` is said by its order of magnitude,
  not by 300 digits;
* ``ncstab info`` writes a description's control characters as escapes
  (``\\x1b``, ``\\x00``), never raw.
"""

from __future__ import annotations

import re

import pytest

from fault_helpers import TINY, assert_one_line, run_cli, write_study
from ncstab.laws import law_names
from ncstab.sizes import readable_count
from ncstab.terminal_text import LINE_WIDTH, fitted_table, printable


@pytest.mark.parametrize("argv", [["laws"], ["laws", "--all"]], ids=["catalogue", "all"])
def test_the_law_table_fits_100_columns_and_names_every_law_on_its_first_line(argv, capfd):
    code, out, err = run_cli(argv, capfd)
    assert (code, err) == (0, "")
    lines = out.splitlines()
    assert max(len(line) for line in lines) <= LINE_WIDTH
    first_cells = [re.split(r"\s{2,}", line)[0] for line in lines if line and not line[0].isspace()]
    names = law_names(with_modifiers=argv == ["laws", "--all"])
    assert [cell for cell in first_cells if cell in names] == list(names)
    assert sum(line.startswith("    energy W(l, alpha): ") for line in lines) == len(names)
    assert sum(line.startswith("    decided by: ") for line in lines) == len(names)


def test_a_fitted_table_wraps_only_the_columns_after_the_fixed_ones():
    rows = [["a_name", "class", "word " * 40]]
    table = fitted_table(rows, ["law", "class", "text"], width=40, notes=[["note " * 20]])
    lines = table.splitlines()
    assert max(len(line) for line in lines) <= 40
    assert lines[2].startswith("a_name  class  word")
    body = [line for line in lines[3:] if "note" not in line]
    assert all(line.startswith(" " * len("a_name  class  ")) for line in body)  # continuations blank below
    assert " ".join(" ".join(line.split()) for line in lines[2:]).split().count("word") == 40
    assert " ".join(lines).split().count("note") == 20


@pytest.mark.parametrize("count, text", [(0, "0"), (999_999, "999,999"), (5e299, "~5e299"), (1.2e6, "~1e6")])
def test_a_count_is_its_digits_below_a_million_else_its_order(count, text):
    assert readable_count(count) == text


def test_a_tiny_sample_step_is_refused_in_one_short_line(tmp_path, capfd):
    study = write_study(tmp_path, TINY.replace("max_step = 0.05", "max_step = 0.05\nsample_step = 1e-300"))
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 2
    line = assert_one_line(err, r" ~5e298 states ")  # D1* = 0.05 driven in steps of 1e-300
    assert len(line) < 300
    assert not re.search(r"\d{16}", line)
    assert not (tmp_path / "out.nc").exists()


@pytest.mark.parametrize("raw, shown", [("\x1b[2J", r"\x1b[2J"), ("\x00", r"\x00"), ("\u202e", r"\u202e"),
                                        ("\r", r"\r"), ("\x7f", r"\x7f"), ("\u2028", r"\u2028")])
def test_printable_writes_control_characters_as_escapes(raw, shown):
    assert printable(f"a {raw} γ") == f"a {shown} γ"


def test_info_escapes_the_control_characters_of_a_description(tmp_path, capfd):
    text = TINY.replace('description = "fault catalogue"', r'description = "clear \u001b[2J, nul \u0000, bell \u0007"')
    study = write_study(tmp_path, text)
    archive = tmp_path / "out.nc"
    assert run_cli(["run", "-q", study, "-o", archive], capfd)[0] == 0
    code, out, err = run_cli(["info", archive], capfd)
    assert (code, err) == (0, "")
    assert r"clear \x1b[2J, nul \x00, bell \x07" in out
    assert all(character.isprintable() for character in out.replace("\n", ""))
