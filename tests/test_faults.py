"""The fault catalogue: bad inputs and faults, each ending in one line and a documented exit code.

Every case asserts the exit code (0 success, 1 some case failed, 2 invalid input
with nothing run or written, 3 the run could not complete: docs/when-things-go-wrong.md),
exactly one line on stderr naming what is wrong, no "Traceback", and what is
left on disk.  The command runs in this process (``ncstab.cli.main``; signals are
sent to this process) except where the fault needs a process of its own (the
section "faults that need a process of their own": a process group's Ctrl-C, a
killed run, a real dask scheduler, another user, a tmpfs in a mount namespace).
The last section proves the machinery the catalogue relies on (checksums, size
estimates, locks) against independent computations.
"""

from __future__ import annotations

import errno
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import xarray as xr
from fault_helpers import (
    FOUR,
    TINY,
    assert_one_line,
    chunk_offset,
    contiguous_offset,
    copy_archive,
    edit_archive,
    flip_byte,
    run_cli,
    tree,
    write_study,
)

import ncstab.studies.chunked as chunked_module
from ncstab.studies import open_study, parse_study, run_study, write_dataset
from ncstab.studies import preflight as preflight_module
from ncstab.studies.errors import ArchiveError
from ncstab.studies.locks import OutputLock, lock_path


@pytest.fixture(autouse=True)
def _no_full_collection_per_chunk(monkeypatch):
    """A chunked run calls gc.collect() after each chunk to hold one chunk at a time (memory,
    tested in test_streaming.py); in a test process that holds sympy's objects each pass costs
    0.3 s and tests nothing here."""
    monkeypatch.setattr(chunked_module, "gc", type("NoCollector", (), {"collect": staticmethod(lambda: 0)}))

# --- bad study files: exit 2, the field named, nothing written ------------------------------------

#: (id, text replaced in TINY, its replacement, the field the one line names).
BAD_STUDIES = [
    ("toml-syntax", "max_step = 0.05", "max_step = = 0.05", r"toml: invalid TOML"),
    ("toml-huge-integer", "max_step = 0.05", "max_steps = " + "9" * 5000, r"toml: .*too long"),
    ("toml-deep-nesting", "max_step = 0.05", "max_step = " + "[" * 100_000, r"toml: .*nested too deeply"),
    ("study-missing", '[study]\nname = "tiny"\ndescription = "fault catalogue"\n', "", r"study\.name: missing"),
    ("study-name-slash", 'name = "tiny"', 'name = "a/b"', r"study\.name"),
    ("study-name-number", 'name = "tiny"', "name = 3", r"study\.name: expected a string"),
    ("study-description-number", 'description = "fault catalogue"', "description = 1", r"study\.description"),
    ("study-unknown-key", 'name = "tiny"', 'name = "tiny"\ntitle = "x"', r"study\.title: unknown key"),
    ("unknown-section", "[options]", "[optoins]", r"optoins: unknown section"),
    ("key-outside-sections", "[study]", "verbose = true\n[study]", r"verbose: key 'verbose' is outside"),
    ("system-unknown", 'alpha0 = "pi/4"', 'name = "hexagon"\nalpha0 = "pi/4"', r"system\.name: unknown system"),
    ("system-secondary-contacts", 'secondary_contacts = "ignore"', 'secondary_contacts = "maybe"',
     r"system\.secondary_contacts"),
    ("system-normal", 'secondary_contacts = "ignore"', 'secondary_contacts = "ignore"\nnormal = "stiff"',
     r"system\.normal"),
    ("system-alpha0-range", 'alpha0 = "pi/4"', 'alpha0 = "pi/2 + 1"', r"system\.alpha0"),
    ("system-alpha0-sweep", 'alpha0 = "pi/4"', "alpha0 = [0.6, 0.7]", r"system\.alpha0: a sweep"),
    ("system-law-parameter", 'alpha0 = "pi/4"', 'alpha0 = "pi/4"\ngamma = 1.0', r"system\.gamma: .*law parameter"),
    ("laws-missing", 'names = ["mcnamara"]', "", r"laws\.names: missing"),
    ("laws-not-a-list", 'names = ["mcnamara"]', 'names = "mcnamara"', r"laws\.names: expected an array"),
    ("laws-empty", 'names = ["mcnamara"]', "names = []", r"laws\.names: give at least one law"),
    ("laws-unknown", 'names = ["mcnamara"]', 'names = ["mcnamra"]', r"laws\.names: unknown law .*did you mean"),
    ("laws-listed-twice", 'names = ["mcnamara"]', 'names = ["mcnamara", "mcnamara"]', r"laws\.names: .*twice"),
    ("laws-modifier-twice", 'names = ["mcnamara"]', 'names = ["turco+no_tension+no_tension"]',
     r"laws\.names: modifier 'no_tension' is given twice"),
    ("laws-two-spellings", 'names = ["mcnamara"]', 'names = ["turco+no_tension", "turco + no_tension"]',
     r"laws\.names: .*(are the same law|is listed twice)"),
    ("laws-unknown-modifier", 'names = ["mcnamara"]', 'names = ["mcnamara+no_tensoin"]',
     r"laws\.names: unknown law modifier"),
    ("gamma-negative", "gamma = [0.5, 2.0]", "gamma = [-0.5, 2.0]", r"parameters\.gamma: .*>= 0"),
    ("gamma-empty-sweep", "gamma = [0.5, 2.0]", "gamma = []", r"parameters\.gamma: an empty sweep"),
    ("gamma-twice-in-sweep", "gamma = [0.5, 2.0]", "gamma = [0.5, 0.5]", r"parameters\.gamma: .*more than once"),
    ("gamma-division-by-zero", "gamma = [0.5, 2.0]", 'gamma = "1/0"', r"parameters\.gamma: .*division by zero"),
    ("gamma-infinite", "gamma = [0.5, 2.0]", "gamma = inf", r"parameters\.gamma: .*not finite"),
    ("gamma-huge-exponent", "gamma = [0.5, 2.0]", "gamma = 1e999", r"parameters\.gamma: .*not finite"),
    ("gamma-code-injection", "gamma = [0.5, 2.0]", "gamma = \"__import__('os').system('touch pwned')\"",
     r"parameters\.gamma"),
    ("gamma-nested-list", "gamma = [0.5, 2.0]", "gamma = [[0.5]]", r"parameters\.gamma: element 1 is an array"),
    ("gamma-date", "gamma = [0.5, 2.0]", "gamma = 1979-05-27", r"parameters\.gamma: expected a number"),
    ("gamma-missing", "gamma = [0.5, 2.0]", "", r"parameters\.gamma: missing"),
    ("parameter-reserved", "gamma = [0.5, 2.0]", 'gamma = [0.5, 2.0]\nstep = 0.1', r"parameters\.step: .*reserved"),
    ("parameter-unused", "gamma = [0.5, 2.0]", "gamma = [0.5, 2.0]\nspeed = 3.0", r"parameters\.speed: .*unused"),
    ("parameter-bad-name", "gamma = [0.5, 2.0]", 'gamma = [0.5, 2.0]\n"2x" = 1.0', r"parameters\.2x: parameter name"),
    ("kappa-negative", "gamma = [0.5, 2.0]", "gamma = [0.5, 2.0]\nkappa = -1.0", r"parameters\.kappa"),
    ("gamma-in-pure-shear", 'secondary_contacts = "ignore"', 'secondary_contacts = "ignore"\nnormal = "rigid"',
     r"parameters\.gamma: gamma has no meaning"),
    ("parameter-twice", "gamma = [0.5, 2.0]", "gamma = [0.5, 2.0]\nalpha0 = 0.7", r"parameters\.alpha0: .*also given"),
    ("loading-missing", "[[loading]]\nhold = { F2 = 0.0 }\ndrive = { D1 = 0.05 }\n", "", r"loading: missing"),
    ("loading-a-table", "[[loading]]", "[loading]", r"loading: expected \[\[loading\]\] stages"),
    ("stage-unknown-key", "drive = { D1 = 0.05 }", "drive = { D1 = 0.05 }\nhols = { F1 = 0.0 }",
     r"loading\[1\]\.hols: unknown key"),
    ("stage-drives-nothing", "drive = { D1 = 0.05 }", "", r"loading\[1\]\.drive: the stage drives nothing"),
    ("stage-drives-a-load-it-has-not", "drive = { D1 = 0.05 }", "drive = { D1 = 0.05, P = 1.0 }",
     r"loading\[1\]\.drive\.P: 'P' is a load parameter, and this system has none"),
    ("stage-controlled-twice", "hold = { F2 = 0.0 }", "hold = { F2 = 0.0, D2 = 0.0 }",
     r"loading\[1\]\..*controlled twice"),
    ("stage-not-controlled", "hold = { F2 = 0.0 }", "", r"loading\[1\]\.hold: dof D2/F2 is not controlled"),
    ("stage-unknown-quantity", "drive = { D1 = 0.05 }", "drive = { D3 = 0.05 }",
     r"loading\[1\]\.drive\.D3: unknown quantity"),
    ("stage-undefined-parameter", "drive = { D1 = 0.05 }", 'drive = { D1 = "D1_end" }',
     r"loading\[1\]\.drive\.D1: refers to undefined parameter 'D1_end'"),
    ("stage-drive-current", "drive = { D1 = 0.05 }", 'drive = { D1 = "current" }',
     r"loading\[1\]\.drive\.D1: a driven target cannot be 'current'"),
    ("stage-unknown-event", "drive = { D1 = 0.05 }", 'drive = { D1 = 0.05 }\nstop_at = ["hill"]',
     r"loading\[1\]\.stop_at: unknown event 'hill' \(did you mean 'hill_loss'\?\)"),
    ("stage-drive-to-rest", "drive = { D1 = 0.05 }", "drive = { D1 = 0.0 }",
     r"loading\[1\]\.drive\.D1: drives D1 to 0, the value it already has \(at rest\): the study would compute "
     "nothing"),
    ("stages-drive-to-where-they-are", "drive = { D1 = 0.05 }",
     "drive = { D1 = 0.0 }\n[[loading]]\nhold = { D1 = 0.0 }\ndrive = { F2 = 0.0 }",
     r"loading\[1\]\.drive\.D1: drives D1 to 0, .* \(at rest\) and so does every later stage"),
    ("stage-drive-swept-to-rest", "drive = { D1 = 0.05 }", 'drive = { F1 = "F_end" }',
     r"loading\[1\]\.drive\.F1: drives F1 to 0"),
    ("cycle-zero-radius", "hold = { F2 = 0.0 }\ndrive = { D1 = 0.05 }", "cycle = { center = [0.0, 0.0], turns = 1 }",
     r"loading\[1\]\.cycle\.center: .*\(\[0, 0\], at rest\): a circle of radius 0"),
    ("cycle-zero-radius-after-a-stage", "hold = { F2 = 0.0 }\ndrive = { D1 = 0.05 }",
     "hold = { D2 = 0.0 }\ndrive = { D1 = 0.02 }\n[[loading]]\ncycle = { center = [0.02, 0.0] }",
     r"loading\[2\]\.cycle\.center: .*\(\[0\.02, 0\], where stage 1 leaves it\): a circle of radius 0"),
    ("dynamic-without-duration", "drive = { D1 = 0.05 }",
     "drive = { D1 = 0.05 }\n[[loading]]\ndynamic = { perturbation = { D1 = 1e-6 } }",
     r"loading\[2\]\.dynamic\.duration: missing"),
    ("dynamic-unknown-dof", "drive = { D1 = 0.05 }",
     "drive = { D1 = 0.05 }\n[[loading]]\ndynamic = { duration = 1.0, perturbation = { D3 = 1e-6 } }",
     r"loading\[2\]\.dynamic\.perturbation\.D3: unknown dof 'D3'; dofs are: D1, D2"),
    ("dynamic-not-last", "drive = { D1 = 0.05 }",
     "drive = { D1 = 0.05 }\n[[loading]]\ndynamic = { duration = 1.0 }\n[[loading]]\nhold = { F2 = 0.0 }\ndrive = { D1 = 0.06 }",
     r"loading\[2\]\.dynamic: a dynamic stage is the programme's last"),
    ("cycle-zero-turns", "hold = { F2 = 0.0 }\ndrive = { D1 = 0.05 }", "cycle = { center = [0.01, 0.0], turns = 0 }",
     r"loading\[1\]\.cycle\.turns"),
    ("cycle-direction", "hold = { F2 = 0.0 }\ndrive = { D1 = 0.05 }",
     "cycle = { center = [0.01, 0.0], direction = 2 }", r"loading\[1\]\.cycle\.direction"),
    ("cycle-with-hold", "drive = { D1 = 0.05 }", "cycle = { center = [0.01, 0.0] }",
     r"loading\[1\]\.hold: a cycle stage drives both displacements"),
    ("options-unknown", "max_step = 0.05", "max_stpe = 0.05", r"options\.max_stpe: unknown key .*did you mean"),
    ("options-negative-rtol", "max_step = 0.05", "max_step = 0.05\nrtol = -1.0", r"options\.rtol"),
    ("options-max-steps-float", "max_step = 0.05", "max_step = 0.05\nmax_steps = 2.5",
     r"options\.max_steps: expected a whole number"),
    ("options-max-cases-zero", "max_step = 0.05", "max_step = 0.05\nmax_cases = 0", r"options\.max_cases"),
    ("options-max-cases-text", "max_step = 0.05", 'max_step = 0.05\nmax_cases = "many"', r"options\.max_cases"),
    ("options-min-above-max", "max_step = 0.05", "max_step = 0.05\nmin_step = 0.1", r"options\.min_step"),
    ("options-backend", "max_step = 0.05", 'max_step = 0.05\nbackend = "gpu"', r"options\.backend"),
    ("map-empty", "[output]", "[map]\n[output]", r"map: an empty \[map\] section"),
    ("map-directions-too-few", "[output]", "[map]\ndirections = 3\n[output]", r"map\.directions"),
    ("map-directions-too-many", "[output]", "[map]\ndirections = 100001\n[output]", r"map\.directions"),
    ("map-grid-bad", "[output]", "[map]\ngrid = { D1 = [0.0, 0.1, 5], D2 = [0.1, 0.0, 5] }\n[output]",
     r"map\.grid\.D2: expected min < max"),
    ("map-grid-too-fine", "[output]", "[map]\ngrid = { D1 = [0.0, 0.1, 5000], D2 = [0.0, 0.1, 5] }\n[output]",
     r"map\.grid\.D1: the number of grid points"),
    ("figures-unknown", "figures = []", 'figures = ["stabilty"]', r"output\.figures: unknown figure kind"),
    ("figures-twice", "figures = []", 'figures = ["stability", "stability"]', r"output\.figures: .*twice"),
    ("figures-cycle-without-cycle", "figures = []", 'figures = ["cycle_work"]',
     r"output\.figures: .*no cycle stage"),
    ("figures-diagram-one-sweep", "figures = []", 'figures = ["stability_diagram"]',
     r"output\.figures: .*two swept parameters"),
    ("figures-work-map-without-directions", "figures = []", 'figures = ["second_order_work_map"]',
     r"output\.figures: .*\[map\] directions"),
    ("figures-state-map-without-grid", "figures = []", 'figures = ["state_map"]',
     r"output\.figures: .*\[map\] grid"),
    ("figures-state-map-without-total-form", "figures = []",
     'figures = ["state_map"]\n[map]\ngrid = { D1 = [0.0, 0.1, 5], D2 = [0.0, 0.1, 5] }',
     r"output\.figures: .*total form"),
    ("output-file-directory", "figures = []", 'figures = []\nfile = "results/"', r"output\.file: .*directory"),
    ("output-file-empty", "figures = []", 'figures = []\nfile = ""', r"output\.file: expected a non-empty"),
    # issue 42: ranges and the symbolic work bounded before anything is computed
    ("options-newton-max-iter-huge", "max_step = 0.05", "max_step = 0.05\nnewton_max_iter = 100000000000000000000",
     r"options\.newton_max_iter: expected a whole number from 1 to 1,000, got 100,000,000,000,000,000,000"),
    ("options-max-steps-huge", "max_step = 0.05", "max_step = 0.05\nmax_steps = 9223372036854775807",
     r"options\.max_steps: expected a whole number from 1 to 1,000,000,000"),
    ("user-law-900-digit-constant", 'names = ["mcnamara"]',
     'names = ["w"]\n[laws.w]\nnormal = "-(l - 1)*1' + "0" * 899 + '"\ntangential = "gamma*sin(alpha - alpha0)"',
     r"laws\.w\.normal: the number 1000+\.\.\. is too large: numbers in a formula are at most 1e\+15"),
    ("user-law-computed-huge-constant", 'names = ["mcnamara"]',
     'names = ["w"]\n[laws.w]\nnormal = "-(l - 1)*(1 + 999999999999999**5*(l - 1)**2)"\n'
     'tangential = "gamma*sin(alpha - alpha0)"', r"laws\.w\.normal: .* makes the number 9+\d*\.\.\., whose numerator"),
    ("user-law-energy-of-a-hundredth-power", 'names = ["mcnamara"]',
     'names = ["w"]\n[laws.w]\nenergy = "(l + alpha + gamma + alpha0 + 1)**100*(l - 1)**2"',
     r"laws\.w\.energy: '\(l \+ alpha \+ gamma \+ alpha0 \+ 1\) \*\* 100' has more than 1,000 terms once expanded"),
    ("user-law-function-of-a-large-power", 'names = ["mcnamara"]',
     'names = ["w"]\n[laws.w]\nnormal = "-(l - 1)"\ntangential = "sin((l + alpha + gamma + 1)**20)"',
     r"laws\.w\.tangential: .* has more than 1,000 terms once expanded"),
]


@pytest.mark.parametrize("case_id, old, new, field", BAD_STUDIES, ids=[c[0] for c in BAD_STUDIES])
def test_a_bad_study_file_exits_2_naming_its_field_and_writes_nothing(
    case_id, old, new, field, tmp_path, capfd, monkeypatch
):
    assert old in TINY, case_id
    text = TINY.replace(old, new, 1)
    if case_id == "stage-drive-swept-to-rest":
        text = text.replace("gamma = [0.5, 2.0]", "gamma = [0.5, 2.0]\nF_end = [0.0]")  # a sweep of one value
    if case_id == "figures-state-map-without-total-form":
        text = text.replace('names = ["mcnamara"]', 'names = ["cundall_strack"]')
    monkeypatch.chdir(tmp_path)
    study = write_study(tmp_path, text)
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 2, err
    assert_one_line(err, rf"^{study}: {field}")
    assert tree(tmp_path) == {"study.toml"}, "nothing is run or written"


def test_a_study_file_that_is_not_utf8_exits_2(tmp_path, capfd):
    study = tmp_path / "study.toml"
    study.write_bytes(TINY.encode() + b"\n# \xff\xfe\n")
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 2
    assert_one_line(err, r"toml: the file is not UTF-8")
    assert tree(tmp_path) == {"study.toml"}


# --- bad command lines: exit 2, one line, nothing written ----------------------------------------

#: (id, arguments after "ncstab" -- "{study}" and "{out}" are filled in --, what the line says).
BAD_ARGUMENTS = [
    ("unknown-command", ["lwas"], r"invalid choice: 'lwas'"),
    ("run-without-study", ["run"], r"the following arguments are required: STUDY\.toml"),
    ("workers-not-a-number", ["run", "{study}", "--workers", "two"], r"--workers: invalid int value: 'two'"),
    ("workers-zero", ["run", "{study}", "-o", "{out}", "--workers", "0"], r"--workers must be at least 1"),
    ("chunk-cases-zero", ["run", "{study}", "-o", "{out}", "--chunk-cases", "0"], r"--chunk-cases must be at least 1"),
    ("max-cases-zero", ["run", "{study}", "-o", "{out}", "--max-cases", "0"], r"--max-cases must be at least 1"),
    ("scheduler-timeout-zero", ["run", "{study}", "-o", "{out}", "--scheduler-timeout", "0"],
     r"--scheduler-timeout must be a positive number"),
    ("workers-and-scheduler", ["run", "{study}", "--workers", "2", "--scheduler", "tcp://127.0.0.1:8786"],
     r"not allowed with argument"),
    ("resume-and-overwrite", ["run", "{study}", "--resume", "--overwrite"], r"not allowed with argument"),
    ("output-for-two-studies", ["run", "{study}", "{study}", "-o", "{out}"], r"-o/--output needs exactly one study"),
    ("scheduler-not-an-address", ["run", "{study}", "-o", "{out}", "--scheduler", "notanaddress"],
     r"--scheduler 'notanaddress' is not a dask scheduler address"),
    ("scheduler-port-out-of-range", ["run", "{study}", "-o", "{out}", "--scheduler", "tcp://127.0.0.1:99999"],
     r"is not a dask scheduler address"),
    ("scheduler-unknown-protocol", ["run", "{study}", "-o", "{out}", "--scheduler", "http://127.0.0.1:8786"],
     r"is not a dask scheduler address"),
    ("study-file-missing", ["run", "{missing}", "-o", "{out}"], r"cannot read the study file: No such file"),
    ("study-file-a-directory", ["run", "{directory}", "-o", "{out}"], r"cannot read the study file: Is a directory"),
    ("info-missing-archive", ["info", "{missing}"], r"no such archive"),
    ("plot-missing-archive", ["plot", "{missing}"], r"no such archive"),
    ("info-without-archive", ["info"], r"the following arguments are required: OUT\.nc"),
    ("plot-unknown-kind", ["plot", "{archive}", "--kinds", "stabilty"], r"unknown figure kind 'stabilty'"),
    ("plot-kind-that-does-not-fit", ["plot", "{archive}", "--kinds", "cycle_work"], r"cannot draw the figures: .*cycle"),
    ("plot-diagram-of-one-sweep", ["plot", "{archive}", "--kinds", "stability_diagram"],
     r"cannot draw the figures: .*two swept parameters"),
    ("unknown-option", ["run", "{study}", "--fast"], r"unrecognized arguments: --fast"),
    # issue 42: the output is absent, or an ncstab archive and --overwrite; nothing else is touched
    ("output-empty", ["run", "{study}", "-o", ""], r"^ncstab run: -o/--output '' is empty"),
    ("output-dotdot-after-a-missing-directory", ["run", "{study}", "-o", "nosuch/../out.nc"],
     r"output nosuch/\.\./out\.nc: nosuch does not exist, so nosuch/\.\. cannot be resolved"),
    ("output-directory-name-too-long", ["run", "{study}", "-o", "d" * 300 + "/out.nc"],
     r"^ncstab run: tiny: output path 'd{40}'\.\.\. is too long for the file system"),
    ("output-path-too-long", ["run", "{study}", "-o", "d/" * 2100 + "out.nc"],
     r"^ncstab run: tiny: output path '(d/){20}'\.\.\. is too long for the file system"),
    ("output-an-archive-without-overwrite", ["run", "{study}", "-o", "{archive}"],
     r"output .*archive\.nc is an ncstab archive already: pass --overwrite to replace it"),
    ("output-an-archive-of-another-study-with-resume", ["run", "{study}", "-o", "{archive}", "--resume"],
     r"archive\.nc is an ncstab archive of another study .*--resume does not replace it"),
    ("output-the-study-file", ["run", "{study}", "-o", "{study}", "--overwrite"],
     r"output .*study\.toml is the study file"),
    ("output-a-device", ["run", "{study}", "-o", "/dev/null", "--overwrite"],
     r"output /dev/null is a character device: ncstab writes only regular files"),
    ("output-a-directory-with-overwrite", ["run", "{study}", "-o", "{directory}", "--overwrite"],
     r"output .*folder is a directory"),
    ("output-twice-for-two-studies", ["run", "{study}", "{study}"],
     r"output results/tiny\.nc is also the output of study 'tiny'"),
]


#: Four cases of 20 states or more: ``u`` and ``stage`` have 64 values or more, so they are compressed
#: (Fletcher-32 checked by HDF5) while ``n_steps`` and the strings carry digests.
ARCHIVED = FOUR.replace("drive = { D1 = 0.05 }", "drive = { D1 = 0.4 }").replace("max_step = 0.05", "max_step = 0.02")


@pytest.fixture(scope="module")
def archive(tmp_path_factory) -> Path:
    """A good archive of a four-case study."""
    path = tmp_path_factory.mktemp("good") / "four.nc"
    write_dataset(run_study(parse_study(ARCHIVED)), path)
    with h5py.File(path, "r") as handle:  # the layout the cases below rely on
        assert handle["u"].fletcher32 and handle["stage"].fletcher32 and handle["n_steps"].chunks is None
    return path


@pytest.mark.parametrize("case_id, argv, message", BAD_ARGUMENTS, ids=[c[0] for c in BAD_ARGUMENTS])
def test_a_bad_command_line_exits_2_in_one_line_and_writes_nothing(
    case_id, argv, message, archive, tmp_path, capfd, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    study = write_study(tmp_path, TINY)
    copy = copy_archive(archive, tmp_path)
    (tmp_path / "folder").mkdir()
    names = {"{study}": study, "{out}": tmp_path / "out.nc", "{missing}": tmp_path / "missing.toml",
             "{directory}": tmp_path / "folder", "{archive}": copy}
    before = tree(tmp_path)
    code, _, err = run_cli([names.get(a, a) for a in argv], capfd)
    assert code == 2, err
    assert_one_line(err, message)
    assert tree(tmp_path) == before, "nothing is run or written"


# --- archives that are not readable ncstab archives: info and plot exit 2 -------------------------


def _truncated(fraction: float):
    def make(path: Path) -> Path:
        data = path.read_bytes()
        path.write_bytes(data[: int(len(data) * fraction)])
        return path

    return make


def _zeroed_superblock(path: Path) -> Path:
    with open(path, "r+b") as handle:
        handle.write(bytes(48))
    return path


def _flipped_compressed(path: Path) -> Path:
    flip_byte(path, chunk_offset(path, "u"))  # inside deflated data: HDF5's Fletcher-32 fails
    return path


def _flipped_compressed_integers(path: Path) -> Path:
    flip_byte(path, chunk_offset(path, "stage"), 0x01)
    return path


def _flipped_uncompressed(path: Path) -> Path:
    flip_byte(path, contiguous_offset(path, "n_steps") + 1, 0x01)  # n_steps += 256: only the digest sees it
    return path


def _flipped_status_text(path: Path) -> Path:
    data = bytearray(path.read_bytes())
    at = data.index(b"finished")
    data[at] = ord("F")  # "Finished": the strings live in HDF5's heap, checked by the digest
    path.write_bytes(bytes(data))
    return path


def _netcdf3(path: Path) -> Path:
    xr.Dataset({"t": ("x", np.arange(3.0))}).to_netcdf(path, engine="scipy")
    return path


def _foreign_netcdf4(path: Path) -> Path:
    xr.Dataset({"t": ("x", np.arange(3.0))}, attrs={"title": "not ncstab"}).to_netcdf(path, engine="netcdf4")
    return path


def _plain_hdf5(path: Path) -> Path:
    with h5py.File(path, "w") as handle:
        handle["group/data"] = np.arange(10)
    return path


def _text_file(path: Path) -> Path:
    path.write_text("this is not an archive\n")
    return path


def _directory(path: Path) -> Path:
    path.unlink()
    path.mkdir()
    return path


def _without_status(path: Path) -> Path:
    # Rewritten by another program without the status variable (and without ncstab's digests).
    dataset = xr.open_dataset(path, engine="netcdf4").load()
    dataset.close()
    dataset.attrs.pop("ncstab_sha256")
    dataset.drop_vars("status").to_netcdf(path, engine="netcdf4")
    return path


def _bad_figures_attribute(path: Path) -> Path:
    edit_archive(path, attribute="figures", text="load_displacement,pie_chart")
    return path


def _first_value(path: Path, variable: str, value):
    values = xr.open_dataset(path, engine="netcdf4")[variable].load().values.astype(object)
    values.flat[0] = value
    return values


def _n_steps_beyond_the_steps(path: Path) -> Path:
    # As if written without digests (an archive from before them), so that only the invariant can see it.
    edit_archive(path, variable="n_steps", values=_first_value(path, "n_steps", 415))
    return path


def _unknown_status(path: Path) -> Path:
    edit_archive(path, variable="status", values=_first_value(path, "status", "done"))
    return path


def _study_text_invalid(path: Path) -> Path:
    edit_archive(path, attribute="study", text="[study]\nname = 3\n")
    return path


def _study_text_missing(path: Path) -> Path:
    edit_archive(path, attribute="study")
    return path


def _damaged_digests(path: Path) -> Path:
    edit_archive(path, attribute="ncstab_sha256", text="status 1234", drop_digests=False)
    return path


def _negative_n_steps(path: Path) -> Path:
    edit_archive(path, variable="n_steps", values=_first_value(path, "n_steps", -1))
    return path


def _flipped_attribute_name(path: Path) -> Path:
    # One bit of a global attribute's name in HDF5's metadata: netCDF lists the attributes,
    # then cannot open one ("Can't open HDF5 attribute"; issue 42: info exited 3).
    flip_byte(path, path.read_bytes().index(b"study_description"))
    return path


#: (id, how the archive is spoilt, what the line says after "is not a readable ncstab archive: ").
BAD_ARCHIVES = [
    ("empty", _truncated(0.0), r"the file is empty"),
    ("truncated-100-bytes", lambda p: _truncated(100 / p.stat().st_size)(p), r"netCDF cannot open it"),
    ("truncated-tenth", _truncated(0.1), r"netCDF cannot open it|cannot be read"),
    ("truncated-half", _truncated(0.5), r"netCDF cannot open it|cannot be read"),
    ("truncated-last-byte", _truncated(0.9999), r"netCDF cannot open it|cannot be read|checksum"),
    ("zeroed-superblock", _zeroed_superblock, r"netCDF cannot open it"),
    ("flipped-compressed-floats", _flipped_compressed, r"variable 'u' cannot be read"),
    ("flipped-compressed-integers", _flipped_compressed_integers, r"variable 'stage' cannot be read"),
    ("flipped-uncompressed", _flipped_uncompressed, r"variable 'n_steps' does not match its checksum"),
    ("flipped-string", _flipped_status_text, r"variable 'status' does not match its checksum"),
    ("netcdf3", _netcdf3, r"no 'status', 'message', 'n_steps', 'law' variable"),
    ("foreign-netcdf4", _foreign_netcdf4, r"no 'status', 'message', 'n_steps', 'law' variable"),
    ("plain-hdf5", _plain_hdf5, r"no 'status'|netCDF cannot open it"),
    ("text-file", _text_file, r"netCDF cannot open it"),
    ("directory", _directory, r"it is a directory"),
    ("without-status", _without_status, r"no 'status' variable"),
    ("bad-figures-attribute", _bad_figures_attribute, r"attribute 'figures' names 'pie_chart'"),
    ("n-steps-beyond-steps", _n_steps_beyond_the_steps,
     r"variable 'n_steps' has 415 stored states where the 'step' dimension has \d+"),
    ("n-steps-negative", _negative_n_steps, r"variable 'n_steps' has -1 stored states"),
    ("unknown-status", _unknown_status, r"variable 'status' holds 'done'"),
    ("study-text-invalid", _study_text_invalid, r"its 'study' attribute is not a valid study file \(study\.name"),
    ("study-text-missing", _study_text_missing, r"no 'study' attribute"),
    ("digests-damaged", _damaged_digests, r"attribute 'ncstab_sha256' is damaged"),
    ("flipped-attribute-name", _flipped_attribute_name,
     r"its metadata cannot be read \(damaged file\?\): NetCDF: Can't open HDF5 attribute|netCDF cannot open it"),
]


@pytest.mark.parametrize("command", ["info", "plot"])
@pytest.mark.parametrize("case_id, spoil, reason", BAD_ARCHIVES, ids=[c[0] for c in BAD_ARCHIVES])
def test_an_archive_that_is_not_readable_exits_2_saying_why(
    case_id, spoil, reason, command, archive, tmp_path, capfd
):
    path = spoil(copy_archive(archive, tmp_path))
    before = tree(tmp_path)
    # plot reads what its figures show (the archive's study draws none by default): u and stage
    kinds = ["--kinds", "load_displacement"] if command == "plot" else []
    code, out, err = run_cli([command, path, *kinds], capfd)
    assert code == 2, err
    assert_one_line(err, rf"^ncstab {command}: {path} is not a readable ncstab archive: ({reason})")
    assert out == "" and tree(tmp_path) == before, "no figure and no file is written"


def test_the_good_archive_passes_info_and_plot(archive, tmp_path, capfd):
    """The control of the table above: the unspoilt copy is read, summarised and drawn."""
    path = copy_archive(archive, tmp_path)
    code, out, err = run_cli(["info", path], capfd)
    assert (code, err) == (0, "") and "finished: 4" in out
    code, out, err = run_cli(["plot", path, "--kinds", "load_displacement"], capfd)
    assert (code, err) == (0, "") and tree(tmp_path) == {"archive.nc", "archive_load_displacement.png"}


def test_plot_reads_only_what_its_figures_show(archive, tmp_path, capfd):
    """``ncstab plot`` opens the archive lazily: a damaged chunk of a variable no figure
    shows (the work) does not stop the figures, and the full read still names it."""
    path = copy_archive(archive, tmp_path)
    flip_byte(path, chunk_offset(path, "work"))
    code, out, err = run_cli(["plot", path, "--kinds", "load_displacement"], capfd)
    assert (code, err) == (0, "") and (tmp_path / "archive_load_displacement.png").exists()
    with pytest.raises(ArchiveError, match="variable 'work' cannot be read"):
        open_study(path)


# --- outputs that cannot be written ---------------------------------------------------------------


def _enospc(*args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The archive of the four-case study run in process, as read back (for identical resumed runs)."""
    path = tmp_path_factory.mktemp("reference") / "out.nc"
    write_dataset(run_study(parse_study(FOUR)), path)
    return open_study(path)


def assert_same_archive(path: Path, reference: xr.Dataset) -> None:
    """Identical to the in-process archive but for the ``created`` time stamp."""
    archive = open_study(path)
    expected = reference.copy()
    archive.attrs.pop("created"), expected.attrs.pop("created")
    xr.testing.assert_identical(archive, expected)


def test_an_output_that_is_a_directory_exits_2(tmp_path, capfd):
    study = write_study(tmp_path, TINY)
    (tmp_path / "out.nc").mkdir()
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 2
    assert_one_line(err, r"output .*out\.nc is a directory")
    assert tree(tmp_path) == {"study.toml", "out.nc"}


def test_an_output_under_a_file_exits_2(tmp_path, capfd):
    study = write_study(tmp_path, TINY)
    (tmp_path / "plain").write_text("a file")
    code, _, err = run_cli(["run", study, "-o", tmp_path / "plain" / "sub" / "out.nc"], capfd)
    assert code == 2
    assert_one_line(err, r"plain is a file, not a directory")
    assert tree(tmp_path) == {"study.toml", "plain"}


def test_a_study_name_too_long_for_a_file_name_exits_2(tmp_path, capfd, monkeypatch):
    monkeypatch.chdir(tmp_path)
    study = write_study(tmp_path, TINY.replace('name = "tiny"', f'name = "{"n" * 240}"'))
    code, _, err = run_cli(["run", study], capfd)  # results/<name>.nc
    assert code == 2
    assert_one_line(err, r"output name .* is too long: 243 bytes, and the file system allows 255")
    assert tree(tmp_path) == {"study.toml"}


@pytest.mark.parametrize("where, message", [
    ("/sys/ncstab-faults/out.nc", r"cannot create the directory /sys/ncstab-faults: Operation not permitted"),
    ("/proc/ncstab-faults.nc", r"cannot write in /proc: "),
])
def test_an_output_root_cannot_create_exits_3_before_computing(where, message, tmp_path, capfd, monkeypatch):
    computed = []
    monkeypatch.setattr("ncstab.studies.run_study", lambda *a, **k: computed.append(1))
    study = write_study(tmp_path, TINY)
    code, _, err = run_cli(["run", study, "-o", where], capfd)
    assert code == 3
    assert_one_line(err, message)
    assert not computed and not Path(where).exists() and tree(tmp_path) == {"study.toml"}


@pytest.mark.parametrize("failure, message", [
    (OSError(errno.ENOSPC, "No space left on device"), r"disk full while writing .*out\.nc"),
    (RuntimeError("NetCDF: HDF error"), r"disk full while writing .*out\.nc \(NetCDF: HDF error\)"),
    (RuntimeError("NetCDF: HDF error"), r"could not write .*out\.nc: NetCDF: HDF error"),
])
def test_a_failed_archive_write_exits_3_leaving_nothing(failure, message, tmp_path, capfd, monkeypatch):
    def half_written(self, path, *args, **kwargs):
        Path(path).write_bytes(b"half an archive")
        raise failure

    monkeypatch.setattr(xr.Dataset, "to_netcdf", half_written)
    if "disk full" in message and isinstance(failure, RuntimeError):
        # netCDF says only "HDF error" for a full disk: the free space decides.
        monkeypatch.setattr("ncstab.studies.errors._free_bytes", lambda path: 1000)
    study = write_study(tmp_path, TINY)
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 3
    assert_one_line(err, r"^ncstab run: tiny: " + message, r"nothing was written to .*out\.nc$")
    assert tree(tmp_path) == {"study.toml"}, "no temporary, no lock"


def test_a_full_disk_while_drawing_keeps_the_archive_and_exits_3(tmp_path, capfd, monkeypatch):
    from matplotlib.figure import Figure

    monkeypatch.setattr(Figure, "savefig", _enospc)
    study = write_study(tmp_path, TINY.replace("figures = []", 'figures = ["load_displacement"]'))
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 3
    assert_one_line(err, r"disk full", r"the archive .*out\.nc was written, its figures were not all drawn")
    assert tree(tmp_path) == {"study.toml", "out.nc"}
    open_study(tmp_path / "out.nc")  # complete and verified


def test_a_full_disk_in_a_chunked_run_keeps_its_chunks_for_resume(reference, tmp_path, capfd, monkeypatch):
    import ncstab.studies.parts as parts_module

    real_savez, calls = np.savez, []

    def full_at_third(handle, **arrays):
        calls.append(1)
        if len(calls) == 3:
            raise OSError(errno.ENOSPC, "No space left on device")
        real_savez(handle, **arrays)

    monkeypatch.setattr(parts_module.np, "savez", full_at_third)
    study = write_study(tmp_path, FOUR)
    out = tmp_path / "out.nc"
    code, _, err = run_cli(["run", study, "-o", out, "--chunk-cases", "1"], capfd)
    assert code == 3
    assert_one_line(err, r"disk full while writing .*mcnamara_000002\.npz",
                    r"2 of 4 chunks kept in .*out\.nc\.parts: rerun with --resume")
    parts = {"out.nc.parts", "out.nc.parts/manifest.json", "out.nc.parts/mcnamara_000000.npz",
             "out.nc.parts/mcnamara_000001.npz"}
    assert tree(tmp_path) == {"study.toml"} | parts
    monkeypatch.setattr(parts_module.np, "savez", real_savez)
    code, _, err = run_cli(["run", study, "-o", out, "--resume"], capfd)
    assert (code, err) == (0, "")
    assert tree(tmp_path) == {"study.toml", "out.nc"}
    assert_same_archive(out, reference)


# --- limits: refused before computing, exit 2, naming the key and the estimate ---------------------


def test_more_cases_than_max_cases_option_exits_2(tmp_path, capfd):
    study = write_study(tmp_path, TINY)
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc", "--max-cases", "1"], capfd)
    assert code == 2
    assert_one_line(err, r"has 2 cases .*more than max_cases = 1 \(at least .* on disk\)")
    assert tree(tmp_path) == {"study.toml"}


def test_more_cases_than_the_study_max_cases_exits_2(tmp_path, capfd):
    study = write_study(tmp_path, TINY.replace("max_step = 0.05", "max_step = 0.05\nmax_cases = 1"))
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 2
    assert_one_line(err, r"more than max_cases = 1")
    assert tree(tmp_path) == {"study.toml"}


def test_a_sweep_of_a_million_cases_is_refused_by_default(tmp_path, capfd):
    gammas = ", ".join(f"{0.1 + 0.001 * k:.4f}" for k in range(1001))
    alphas = ", ".join(f"{0.5 + 0.0005 * k:.5f}" for k in range(1000))
    text = TINY.replace("gamma = [0.5, 2.0]", f"gamma = [{gammas}]\nalpha0 = [{alphas}]").replace('alpha0 = "pi/4"\n', "")
    study = write_study(tmp_path, text)
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 2
    assert_one_line(err, r"has 1,001,000 cases .*more than max_cases = 1,000,000 \(at least [\d.]+ GB on disk\)")
    assert tree(tmp_path) == {"study.toml"}


def test_an_archive_larger_than_the_free_disk_exits_2(tmp_path, capfd, monkeypatch):
    monkeypatch.setattr(preflight_module, "free_disk", lambda path: 10_000)
    study = write_study(tmp_path, TINY)
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 2
    assert_one_line(err, r"needs at least [\d.]+ kB on disk .* has 10 kB free; reduce the sweep \(\[parameters\]\)")
    assert tree(tmp_path) == {"study.toml"}


@pytest.mark.parametrize("section, message", [
    ("directions = 100000", r"\[map\] directions = 100000: the directional work .* needs at least [\d.]+ MB of memory"),
    ("grid = { D1 = [0.0, 0.1, 2000], D2 = [0.0, 0.1, 2000] }",
     r"\[map\] grid of 2000 x 2000 points: the 7 state maps of 2 cases need at least 448 MB of memory"),
])
def test_a_map_larger_than_the_memory_exits_2(section, message, tmp_path, capfd, monkeypatch):
    monkeypatch.setattr(preflight_module, "available_memory", lambda: 1_000_000)
    study = write_study(tmp_path, TINY.replace("[output]", f"[map]\n{section}\n[output]"))
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 2
    assert_one_line(err, message, r"more than the 1 MB available")
    assert tree(tmp_path) == {"study.toml"}


# --- two runs on one output: the lock -------------------------------------------------------------


def _hostname() -> str:
    import socket

    return socket.gethostname()


def test_an_output_locked_by_a_live_process_exits_3_naming_its_pid(tmp_path, capfd):
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        study = write_study(tmp_path, TINY)
        lock = lock_path(tmp_path / "out.nc")
        lock.write_text(f"pid {holder.pid}\nhost {_hostname()}\n")
        code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
        assert code == 3
        assert_one_line(err, rf"out\.nc is being written by process {holder.pid} \(lock .*out\.nc\.lock\)")
        assert tree(tmp_path) == {"study.toml", "out.nc.lock"} and str(holder.pid) in lock.read_text()
    finally:
        holder.kill()
        holder.wait()


def test_an_output_locked_by_another_run_in_this_process_exits_3(tmp_path, capfd):
    """The lock is a real flock: held by another thread (as by another run), it is refused."""
    held, done = threading.Event(), threading.Event()

    def other_run() -> None:
        with OutputLock(tmp_path / "out.nc"):
            held.set()
            done.wait(30)

    thread = threading.Thread(target=other_run)
    thread.start()
    try:
        assert held.wait(10)
        study = write_study(tmp_path, TINY)
        code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc", "--chunk-cases", "1"], capfd)
        assert code == 3
        assert_one_line(err, rf"is being written by this process \({os.getpid()}, another thread\)")
        assert tree(tmp_path) == {"study.toml", "out.nc.lock"}, "the other run's parts would be untouched"
    finally:
        done.set()
        thread.join()
    assert tree(tmp_path) == {"study.toml"}, "the holder removes its lock"


def test_a_stale_lock_is_taken_over_with_one_line(tmp_path, capfd):
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    pid = int(gone.stdout)
    study = write_study(tmp_path, TINY)
    lock_path(tmp_path / "out.nc").write_text(f"pid {pid}\nhost {_hostname()}\n")
    code, out, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 0 and "finished: 2" in out
    assert_one_line(err, rf"took over the lock .*out\.nc\.lock of process {pid}, which is no longer running")
    assert tree(tmp_path) == {"study.toml", "out.nc"}


def test_a_lock_file_without_a_holder_is_taken_silently(tmp_path, capfd):
    study = write_study(tmp_path, TINY)
    lock_path(tmp_path / "out.nc").write_text("")
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert (code, err) == (0, "")
    assert tree(tmp_path) == {"study.toml", "out.nc"}


# --- finished parts are never deleted without --resume or --overwrite -----------------------------


def _interrupted_after(monkeypatch, chunks: int, signal_number: int = signal.SIGINT):
    """Make the run of chunks send itself ``signal_number`` when chunk ``chunks + 1`` starts."""
    original, started = chunked_module.run_chunk, []

    def run_chunk(*args):
        started.append(args)
        if len(started) == chunks + 1:
            os.kill(os.getpid(), signal_number)  # a real signal: the handler raises at the next bytecode
            time.sleep(5)  # not reached: the run stops here
        return original(*args)

    monkeypatch.setattr(chunked_module, "run_chunk", run_chunk)
    return started


@pytest.fixture(scope="module")
def interrupted_once(tmp_path_factory):
    """A chunked run of the four-case study stopped by SIGINT after two chunks of one case
    (run once; each test gets a copy of what it left)."""
    from _pytest.monkeypatch import MonkeyPatch

    directory = tmp_path_factory.mktemp("interrupted")
    study = write_study(directory, FOUR)
    with MonkeyPatch.context() as patch:
        _interrupted_after(patch, 2)
        patch.setattr(chunked_module, "gc", type("NoCollector", (), {"collect": staticmethod(lambda: 0)}))
        from ncstab.cli import main

        code = main(["run", str(study), "-o", str(directory / "out.nc"), "--chunk-cases", "1"])
    assert code == 3
    return directory


@pytest.fixture
def interrupted(interrupted_once, tmp_path):
    """(study file, output) of a copy of the interrupted run's directory."""
    shutil.copytree(interrupted_once, tmp_path, dirs_exist_ok=True)
    return tmp_path / "study.toml", tmp_path / "out.nc", 3, ""


PARTS_OF_TWO = {"out.nc.parts", "out.nc.parts/manifest.json", "out.nc.parts/mcnamara_000000.npz",
                "out.nc.parts/mcnamara_000001.npz"}


@pytest.mark.parametrize("signal_number", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_an_interrupted_chunked_run_exits_3_keeping_its_chunks(signal_number, tmp_path, capfd, monkeypatch, reference):
    study = write_study(tmp_path, FOUR)
    out = tmp_path / "out.nc"
    _interrupted_after(monkeypatch, 2, signal_number)
    code, _, err = run_cli(["run", study, "-o", out, "--chunk-cases", "1"], capfd)
    assert code == 3
    name = signal.Signals(signal_number).name
    assert_one_line(err, rf"^ncstab run: tiny: interrupted by {name}; 2 of 4 chunks kept in .*out\.nc\.parts: "
                         "rerun with --resume")
    assert tree(tmp_path) == {"study.toml"} | PARTS_OF_TWO, "no lock, no temporary, no archive in progress"
    assert signal.getsignal(signal.SIGINT) is not None and signal.getsignal(signal.SIGTERM) == signal.SIG_DFL


def test_resume_after_an_interrupt_gives_the_identical_archive(interrupted, reference, capfd, monkeypatch):
    study, out, code, _ = interrupted
    assert code == 3
    computed = []
    original = chunked_module.run_chunk
    monkeypatch.setattr(chunked_module, "run_chunk", lambda *a: computed.append(a[2]) or original(*a))
    code, _, err = run_cli(["run", study, "-o", out, "--resume"], capfd)
    assert (code, err) == (0, "") and computed == [2, 3], "only the missing chunks are computed"
    assert tree(out.parent) == {"study.toml", "out.nc"}
    assert_same_archive(out, reference)


def test_a_run_without_resume_refuses_to_start_over_finished_chunks(interrupted, capfd):
    study, out, _, _ = interrupted
    before = {p: p.read_bytes() for p in out.parent.rglob("*.npz")}
    for extra in ([], ["--chunk-cases", "1"]):  # in process (a small study) or in chunks: the same refusal
        code, _, err = run_cli(["run", study, "-o", out, *extra], capfd)
        assert code == 2
        assert_one_line(err, r"out\.nc\.parts holds 2 finished chunk\(s\) of an earlier run of out\.nc: "
                             r"pass --resume to keep them .*or --overwrite to discard them")
        assert tree(out.parent) == {"study.toml"} | PARTS_OF_TWO
        assert {p: p.read_bytes() for p in out.parent.rglob("*.npz")} == before, "parts untouched"


def test_overwrite_discards_the_finished_chunks_and_starts_over(interrupted, reference, capfd):
    study, out, _, _ = interrupted
    code, _, err = run_cli(["run", study, "-o", out, "--overwrite"], capfd)
    assert (code, err) == (0, "")
    assert tree(out.parent) == {"study.toml", "out.nc"}
    assert_same_archive(out, reference)


def test_resume_refuses_the_chunks_of_another_study(interrupted, capfd):
    study, out, _, _ = interrupted
    study.write_text(FOUR.replace("drive = { D1 = 0.05 }", "drive = { D1 = 0.06 }"))
    code, _, err = run_cli(["run", study, "-o", out, "--resume"], capfd)
    assert code == 2
    assert_one_line(err, r"the parts belong to another version of study 'tiny'; run with --overwrite")
    assert tree(out.parent) == {"study.toml"} | PARTS_OF_TWO


def test_resume_refuses_another_chunk_size(interrupted, capfd):
    study, out, _, _ = interrupted
    code, _, err = run_cli(["run", study, "-o", out, "--resume", "--chunk-cases", "2"], capfd)
    assert code == 2
    assert_one_line(err, r"the parts were written with chunk_cases = 1, not 2")
    assert tree(out.parent) == {"study.toml"} | PARTS_OF_TWO


@pytest.mark.parametrize("damage", ["truncated", "flipped", "empty"])
def test_a_damaged_chunk_is_computed_again_on_resume(damage, interrupted, reference, capfd):
    study, out, _, _ = interrupted
    part = out.parent / "out.nc.parts" / "mcnamara_000001.npz"
    data = part.read_bytes()
    if damage == "truncated":
        part.write_bytes(data[: len(data) // 2])
    elif damage == "flipped":
        flip_byte(part, len(data) // 2)
    else:
        part.write_bytes(b"")
    code, _, err = run_cli(["run", study, "-o", out, "--resume"], capfd)
    assert code == 0
    assert_one_line(err, r"1 kept chunk\(s\) could not be read back \(mcnamara_000001\.npz\.\.\.\): computing them again")
    assert tree(out.parent) == {"study.toml", "out.nc"}
    assert_same_archive(out, reference)


def test_the_temporaries_of_a_killed_run_are_removed_by_the_next_run(interrupted, reference, capfd):
    """What a killed process leaves beside the archive and in its parts: removed, with one line."""
    study, out, _, _ = interrupted
    left = [out.parent / ".out.nc.0123abcd.tmp", out.parent / ".out_load_displacement.png.4242.0123456789ab.tmp",
            out.parent / "out.nc.parts" / ".mcnamara_000002.npz.89abcdef.part",
            out.parent / "out.nc.parts" / "archive.nc.tmp"]
    for path in left:
        path.write_bytes(b"half a file")
    keep = out.parent / ".other.nc.0123abcd.tmp"  # another output's temporary: not ours to remove
    keep.write_bytes(b"someone else's")
    code, _, err = run_cli(["run", study, "-o", out, "--resume"], capfd)
    assert code == 0
    assert_one_line(err, r"removed 4 temporary file\(s\) a killed run left")
    assert tree(out.parent) == {"study.toml", "out.nc", keep.name}
    assert_same_archive(out, reference)


# --- interrupts of a run in process ----------------------------------------------------------------


def test_an_interrupted_run_in_process_exits_3_writing_nothing(tmp_path, capfd, monkeypatch):
    import ncstab.studies as studies

    original = studies.run_study

    def interrupted(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(5)  # not reached
        return original(*args, **kwargs)

    monkeypatch.setattr(studies, "run_study", interrupted)
    study = write_study(tmp_path, TINY)
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 3
    assert_one_line(err, r"^ncstab run: tiny: interrupted by SIGINT; nothing was written to .*out\.nc$")
    assert tree(tmp_path) == {"study.toml"}


def test_an_interrupt_while_drawing_keeps_the_archive(tmp_path, capfd, monkeypatch):
    from matplotlib.figure import Figure

    def interrupted(self, *args, **kwargs):
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)  # not reached

    monkeypatch.setattr(Figure, "savefig", interrupted)
    study = write_study(tmp_path, TINY.replace("figures = []", 'figures = ["load_displacement"]'))
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 3
    assert_one_line(err, r"interrupted by SIGTERM; the archive .*out\.nc was written, its figures were not all drawn")
    assert tree(tmp_path) == {"study.toml", "out.nc"}, "no half PNG"


def test_a_second_study_failing_says_which_archives_were_written(tmp_path, capfd, monkeypatch):
    first = write_study(tmp_path, TINY, "first.toml")
    second = write_study(tmp_path, TINY.replace('name = "tiny"', 'name = "second"'), "second.toml")
    monkeypatch.chdir(tmp_path)
    original, calls = xr.Dataset.to_netcdf, []

    def full_second_time(self, *args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise OSError(errno.ENOSPC, "No space left on device")
        return original(self, *args, **kwargs)

    monkeypatch.setattr(xr.Dataset, "to_netcdf", full_second_time)
    code, _, err = run_cli(["run", first, second], capfd)
    assert code == 3
    assert_one_line(err, r"^ncstab run: second: disk full while writing results/second\.nc",
                    r"written before: results/tiny\.nc$")
    assert tree(tmp_path) == {"first.toml", "second.toml", "results", "results/tiny.nc"}


def test_an_unexpected_error_is_one_line_and_debug_shows_the_traceback(tmp_path, capfd, monkeypatch):
    import ncstab.studies as studies

    monkeypatch.setattr(studies, "run_study", lambda *a, **k: 1 / 0)
    study = write_study(tmp_path, TINY)
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 3
    assert_one_line(err, r"internal error: ZeroDivisionError: division by zero \(rerun with --debug")
    with pytest.raises(ZeroDivisionError):
        run_cli(["run", study, "-o", tmp_path / "out.nc", "--debug"], capfd)
    assert tree(tmp_path) == {"study.toml"}


# --- what is at the output's path: never a user's file (issue 42) --------------------------------


def _fifo(path: Path) -> Path:
    os.mkfifo(path)
    return path


def _study_file_itself(path: Path) -> Path:
    return path.parent / "study.toml"


def _symbolic_link(path: Path) -> Path:
    (path.parent / "target.txt").write_text("the link's target\n")
    path.symlink_to(path.parent / "target.txt")
    return path


#: (id, what is put at the output's path, what the line says).
NOT_OURS = [
    ("foreign-netcdf4", _foreign_netcdf4, r"exists and is not an ncstab archive: ncstab replaces only its own"),
    ("netcdf3", _netcdf3, r"exists and is not an ncstab archive"),
    ("plain-hdf5", _plain_hdf5, r"exists and is not an ncstab archive"),
    ("text-file", _text_file, r"exists and is not an ncstab archive"),
    ("the-study-file", _study_file_itself, r"is the study file .*study\.toml"),
    ("fifo", _fifo, r"is a fifo \(named pipe\): ncstab writes only regular files"),
    ("symbolic-link", _symbolic_link, r"is a symbolic link: ncstab writes only regular files"),
]


def _snapshot(directory: Path) -> dict[str, tuple]:
    """Every entry's kind, bytes (regular files) and inode: what 'nothing touched' compares."""
    snapshot = {}
    for path in sorted(directory.rglob("*")):
        status = os.lstat(path)
        content = path.read_bytes() if path.is_file() and not path.is_symlink() else None
        snapshot[str(path.relative_to(directory))] = (status.st_mode, status.st_ino, content)
    return snapshot


@pytest.mark.parametrize("overwrite", [[], ["--overwrite"]], ids=["plain", "overwrite"])
@pytest.mark.parametrize("case_id, make, message", NOT_OURS, ids=[c[0] for c in NOT_OURS])
def test_an_output_that_is_not_an_ncstab_archive_is_never_replaced(
    case_id, make, message, overwrite, tmp_path, capfd, monkeypatch
):
    computed = []
    monkeypatch.setattr("ncstab.studies.run_study", lambda *a, **k: computed.append(1))
    study = write_study(tmp_path, TINY)
    output = make(tmp_path / "out.nc")
    before = _snapshot(tmp_path)
    code, out, err = run_cli(["run", study, "-o", output, *overwrite], capfd)
    assert code == 2, err
    assert_one_line(err, rf"^ncstab run: tiny: output {output}", message)
    assert (out, computed) == ("", []), "nothing run"
    assert _snapshot(tmp_path) == before, "nothing touched"


def test_an_ncstab_archive_is_replaced_only_with_overwrite(tmp_path, capfd):
    study = write_study(tmp_path, TINY)
    out = tmp_path / "out.nc"
    assert run_cli(["run", study, "-o", out], capfd)[0] == 0
    before = _snapshot(tmp_path)
    code, _, err = run_cli(["run", study, "-o", out], capfd)
    assert code == 2
    assert_one_line(err, rf"^ncstab run: tiny: output {out} is an ncstab archive already: pass --overwrite to "
                         r"replace it, or give another output \(-o\)$")
    assert _snapshot(tmp_path) == before, "the archive is untouched"
    code, out_text, err = run_cli(["run", study, "-o", out, "--overwrite"], capfd)
    assert (code, err) == (0, "") and "finished: 2" in out_text
    assert os.stat(out).st_ino != before["out.nc"][1], "replaced by a new file"
    assert tree(tmp_path) == {"study.toml", "out.nc"}
    open_study(out)


def test_resume_keeps_the_complete_archive_of_its_study(tmp_path, capfd, monkeypatch):
    """--resume onto the finished archive of the same study: nothing to compute, nothing replaced."""
    study = write_study(tmp_path, TINY)
    out = tmp_path / "out.nc"
    assert run_cli(["run", study, "-o", out], capfd)[0] == 0
    before = _snapshot(tmp_path)
    monkeypatch.setattr(chunked_module, "run_chunk", lambda *a: pytest.fail("nothing is computed"))
    code, _, err = run_cli(["run", study, "-o", out, "--resume"], capfd)
    assert (code, err) == (0, "")
    assert _snapshot(tmp_path) == before


def test_an_archive_written_after_the_check_is_not_replaced(tmp_path, capfd, monkeypatch):
    """Another run may write the archive between the check and the run: checked again under the lock."""
    from ncstab import run_command
    from ncstab.studies.outputs import claim_output
    from ncstab.studies.errors import OutputPathError

    archive = tmp_path / "first.nc"
    assert run_cli(["run", write_study(tmp_path, TINY), "-o", archive], capfd)[0] == 0
    with pytest.raises(OutputPathError, match="is an ncstab archive already"):
        with claim_output(archive, protect_existing=True):
            pytest.fail("not reached")
    with claim_output(archive, overwrite=True, protect_existing=True):
        pass
    with claim_output(archive):  # the library's runs (run_study_chunked) are not the command
        pass

    out = tmp_path / "out.nc"
    original = run_command._preflight

    def preflight_then_another_run(study, output, args):
        original(study, output, args)
        shutil.copy(archive, output)  # as if another run finished first

    monkeypatch.setattr(run_command, "_preflight", preflight_then_another_run)
    code, _, err = run_cli(["run", tmp_path / "study.toml", "-o", out], capfd)
    assert code == 2
    assert_one_line(err, r"out\.nc is an ncstab archive already")
    assert out.read_bytes() == archive.read_bytes(), "the other run's archive is kept"
    assert not lock_path(out).exists()


@pytest.mark.parametrize("file, message", [
    ("../thesis.txt", r"\[output\] file = '\.\./thesis\.txt' of .*study\.toml leaves the directory ncstab run "
                      r"runs in \('\.\.'\)"),
    ("sub/../../thesis.txt", r"\[output\] file = 'sub/\.\./\.\./thesis\.txt' .* leaves the directory"),
    ("{absolute}", r"\[output\] file = '.*thesis\.txt' of .* is an absolute path"),
])
def test_a_study_file_cannot_write_outside_the_directory_it_runs_in(file, message, tmp_path, capfd, monkeypatch):
    """A shared study file's [output] file cannot reach the user's other files (-o can)."""
    work = tmp_path / "work"
    work.mkdir()
    thesis = tmp_path / "thesis.txt"
    thesis.write_text("three years of work\n")
    file = file.replace("{absolute}", str(thesis))
    study = write_study(work, TINY.replace("figures = []", f'figures = []\nfile = "{file}"'))
    monkeypatch.chdir(work)
    before = _snapshot(tmp_path)
    code, _, err = run_cli(["run", study], capfd)
    assert code == 2
    assert_one_line(err, r"^ncstab run: tiny: " + message, r"choose the path on the command line with -o")
    assert _snapshot(tmp_path) == before
    code, out, err = run_cli(["run", study, "-o", tmp_path / "elsewhere.nc"], capfd)  # the user's choice
    assert (code, err) == (0, "") and (tmp_path / "elsewhere.nc").exists()


def test_a_study_file_output_inside_keeps_its_meaning(tmp_path, capfd, monkeypatch):
    """A relative [output] file without '..' is relative to the directory ncstab run runs in, as before."""
    study = write_study(tmp_path, TINY.replace("figures = []", 'figures = []\nfile = "sub/./here.nc"'))
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli(["run", study], capfd)
    assert (code, err) == (0, "")
    assert tree(tmp_path) == {"study.toml", "sub", "sub/here.nc"}


def test_a_cycle_of_a_billion_turns_is_refused_before_running(tmp_path, capfd, monkeypatch):
    """The turn tables (33 bytes per case and turn) are estimated first: 66 GB here, exit 2 at once."""
    computed = []
    monkeypatch.setattr("ncstab.studies.run_study", lambda *a, **k: computed.append(1))
    monkeypatch.setattr("ncstab.studies.cycle_limits.available_memory", lambda: 8 * 2**30)
    study = write_study(tmp_path, TINY.replace("hold = { F2 = 0.0 }\ndrive = { D1 = 0.05 }",
                                               "cycle = { center = [0.01, 0.0], turns = 1000000000 }"))
    start = time.monotonic()
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 2 and time.monotonic() - start < 10
    assert_one_line(err, r"^ncstab run: tiny: loading\[1\]\.cycle\.turns = 1,000,000,000: the turn tables of 2 "
                         r"case\(s\) x 1,000,000,000 turns need at least 66 GB of memory, more than the 8\.59 GB")
    assert not computed and tree(tmp_path) == {"study.toml"}


def test_the_cycle_turn_estimate_is_what_the_stepper_allocates():
    """Four float64 and a flag per case and turn (ncstab.paths.compiled_stages' turn tables)."""
    from ncstab.studies.cycle_limits import TURN_BYTES, check_cycle_turns

    study = parse_study(TINY.replace("hold = { F2 = 0.0 }\ndrive = { D1 = 0.05 }",
                                     "cycle = { center = [0.01, 0.0], turns = 3 }"))
    closed, values = np.zeros((2, 3), dtype=bool), np.empty((2, 3, 4))
    assert check_cycle_turns(study, memory=10**9) == closed.nbytes + values.nbytes == 2 * 3 * TURN_BYTES
    assert check_cycle_turns(parse_study(TINY), memory=1) == 0.0


def test_a_hostile_archive_is_summarised_or_refused_at_once(archive, tmp_path, capfd):
    """An archive whose study holds a law that sympy would not finish with: info exits 2 in
    well under 15 s, naming the law's field (it hung for more than 90 s)."""
    hostile = TINY.replace('names = ["mcnamara"]', 'names = ["w"]\n[laws.w]\n'
                                                   'energy = "(l + alpha + gamma + alpha0 + 1)**100*(l - 1)**2"')
    path = copy_archive(archive, tmp_path)
    edit_archive(path, attribute="study", text=hostile)
    start = time.monotonic()
    code, out, err = run_cli(["info", path], capfd)
    assert code == 2 and time.monotonic() - start < 15
    assert_one_line(err, r"its 'study' attribute is not a valid study file \(laws\.w\.energy: .*more than 1,000 terms")


def test_info_does_not_classify_the_laws_of_an_archive(monkeypatch):
    """The archive stores the classes: reading its study builds the user laws, classifies none."""
    import ncstab.symbolic.classification as classification
    from ncstab.studies.verification import check_study_text

    monkeypatch.setattr(classification, "classify", lambda definition: pytest.fail("classified"))
    text = TINY.replace('names = ["mcnamara"]', 'names = ["w"]\n[laws.w]\nenergy = "(l - 1)**2/2 + gamma*(alpha - alpha0)**2/2 + l/7"')
    check_study_text(f"{text}\n# {os.urandom(8).hex()}: a text not seen before\n", "archive.nc")


def test_the_symbolic_work_on_a_law_is_stopped_after_its_time_limit(tmp_path, capfd, monkeypatch):
    """Within the formulas' limits, a law that still takes too long is stopped (SIGALRM), exit 2."""
    import ncstab.studies.user_laws as user_laws

    monkeypatch.setattr(user_laws, "SYMBOLIC_SECONDS", 0.2)
    study = write_study(tmp_path, TINY.replace(
        'names = ["mcnamara"]', 'names = ["w"]\n[laws.w]\nenergy = "(l + alpha + gamma + alpha0 + 1)**6*(l - 1)**2"'))
    start = time.monotonic()
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 2 and time.monotonic() - start < 10
    assert_one_line(err, r"laws\.w\.energy: the symbolic work on the law \(energy\) took more than 0\.2 s")
    assert signal.getsignal(signal.SIGALRM) == signal.SIG_DFL and signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)
    assert tree(tmp_path) == {"study.toml"}


def test_running_out_of_memory_is_said_so(tmp_path, capfd, monkeypatch):
    """llvmlite under ``ulimit -v``: "could not load libllvmlite.so", raised from "failed to map
    segment": one line saying it is memory, exit 3 (it said "please report it")."""
    def no_memory(*args, **kwargs):
        try:
            raise OSError("/site-packages/llvmlite/binding/libllvmlite.so: failed to map segment from shared object")
        except OSError:  # what llvmlite raises while handling it
            raise OSError("Could not find/load shared object file 'libllvmlite.so' from resource location")

    monkeypatch.setattr("ncstab.studies.run_study", no_memory)
    study = write_study(tmp_path, TINY)
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert code == 3
    assert_one_line(err, r"^ncstab run: tiny: out of memory \(OSError: .*failed to map segment from shared object\); "
                         r"nothing more was written")
    assert "report" not in err and tree(tmp_path) == {"study.toml"}


def test_sighup_stops_a_run_as_sigint_does(tmp_path, capfd, monkeypatch):
    """The terminal closed: one line, exit 3, the finished chunks kept, no lock left (it exited 129)."""
    study = write_study(tmp_path, FOUR)
    _interrupted_after(monkeypatch, 2, signal.SIGHUP)
    code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc", "--chunk-cases", "1"], capfd)
    assert code == 3
    assert_one_line(err, r"^ncstab run: tiny: interrupted by SIGHUP; 2 of 4 chunks kept in .*out\.nc\.parts: "
                         "rerun with --resume")
    assert tree(tmp_path) == {"study.toml"} | PARTS_OF_TWO, "no lock left"
    assert signal.getsignal(signal.SIGHUP) == signal.SIG_DFL


# --- faults that need a process of their own -------------------------------------------------------


def _wait_for(condition, timeout: float = 60.0, what: str = "") -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.02)


def _python(code: str, *args, **kwargs) -> subprocess.Popen:
    """A child Python running ``code`` (its stderr captured), in a session of its own."""
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    return subprocess.Popen([sys.executable, "-c", code, *map(str, args)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env, start_new_session=True, **kwargs)


#: ``ncstab run`` in a child whose chunks each take 0.3 s more (so that a signal lands mid-run).
SLOW_RUN = """
import sys, time
import ncstab.studies.chunked as chunked
original = chunked.run_chunk
def run_chunk(*args):
    time.sleep(0.3)
    return original(*args)
chunked.run_chunk = run_chunk
from ncstab.cli import main
sys.exit(main(sys.argv[1:]))
"""

#: SLOW_RUN at 1 s a chunk: a window of seconds between the chunks a test waits for and
#: the end of the run, for a signal sent then (at 0.3 s a chunk, a loaded machine once let
#: the whole run end before the signal arrived: exit 0).
SLOWER_RUN = SLOW_RUN.replace("time.sleep(0.3)", "time.sleep(1.0)")


def test_a_killed_run_is_resumed_identical_taking_over_its_lock(tmp_path, reference, capfd):
    """kill -9 after two chunks: the lock, the archive in progress and the finished parts stay;
    --resume takes the stale lock over, removes the temporaries, computes the rest."""
    study = write_study(tmp_path, FOUR)
    out = tmp_path / "out.nc"
    child = _python(SLOWER_RUN, "run", study, "-o", out, "--chunk-cases", "1")
    parts = tmp_path / "out.nc.parts"
    _wait_for(lambda: len(list(parts.glob("*.npz"))) >= 2 or child.poll() is not None, what="two chunks")
    os.kill(child.pid, signal.SIGKILL)
    child.communicate()
    left = tree(tmp_path)
    assert {"out.nc.lock", "out.nc.parts/manifest.json", "out.nc.parts/archive.nc.tmp"} <= left and "out.nc" not in left
    code, _, err = run_cli(["run", study, "-o", out, "--resume"], capfd)
    assert code == 0
    assert_one_line(err, rf"took over the lock .*out\.nc\.lock of process {child.pid}, which is no longer running; "
                         r"removed \d+ temporary file\(s\)")
    assert tree(tmp_path) == {"study.toml", "out.nc"}
    assert_same_archive(out, reference)


def test_ctrl_c_on_a_local_cluster_stops_every_process_in_one_line(tmp_path, reference, capfd):
    """SIGINT to the whole process group, as a terminal's Ctrl-C: the workers ignore it, the run
    closes them, keeps its finished chunks and says so in one line; --resume completes it."""
    pytest.importorskip("dask.distributed")
    study = write_study(tmp_path, FOUR)
    out = tmp_path / "out.nc"
    child = _python(SLOW_RUN, "run", study, "-o", out, "--chunk-cases", "1", "--workers", "2")
    manifest = tmp_path / "out.nc.parts" / "manifest.json"
    _wait_for(lambda: manifest.exists() or child.poll() is not None, timeout=90, what="the cluster")
    os.killpg(child.pid, signal.SIGINT)
    _, err = child.communicate(timeout=90)
    assert child.returncode == 3, err
    assert_one_line(err, r"^ncstab run: tiny: interrupted by SIGINT; (no chunk was finished|\d of 4 chunks kept)")
    _wait_for(lambda: _group_is_empty(child.pid), timeout=30, what="the workers to exit")
    left = tree(tmp_path)
    assert not {"out.nc", "out.nc.lock", "out.nc.parts/archive.nc.tmp"} & left
    assert not [name for name in left if name.rsplit("/", 1)[-1].startswith(".")], "no temporary"
    code, _, err = run_cli(["run", study, "-o", out, "--resume"], capfd)
    assert (code, err) == (0, "")
    assert_same_archive(out, reference)


def test_a_stopped_run_removes_the_part_temporaries_its_workers_left_and_keeps_its_parts(tmp_path):
    """A worker of a local cluster closed while it wrote its part leaves the part's temporary
    (``.<part>.<hex>.part``): the run that stops removes it on the way out, keeps its finished
    parts for --resume and its lock is released. (Ctrl-C on a cluster run left one at times.)"""
    from ncstab.studies.outputs import claim_output, parts_directory

    out = tmp_path / "out.nc"
    parts = parts_directory(out)
    with pytest.raises(KeyboardInterrupt):
        with claim_output(out):
            parts.mkdir()
            (parts / "mcnamara_000000.npz").write_bytes(b"a finished part")
            (parts / ".mcnamara_000001.npz.6c77d7a8.part").write_bytes(b"half a part")
            raise KeyboardInterrupt
    assert sorted(p.name for p in parts.iterdir()) == ["mcnamara_000000.npz"]
    assert not lock_path(out).exists()


def _group_is_empty(group: int) -> bool:
    try:
        os.killpg(group, 0)
    except ProcessLookupError:
        return True
    return False


@pytest.fixture
def dask_cluster(tmp_path):
    """A real dask scheduler and one worker on 127.0.0.1, each in a process of its own.
    Yields (scheduler address, scheduler process); both are stopped at the end."""
    pytest.importorskip("dask.distributed")
    dask = Path(sys.executable).with_name("dask")
    file = tmp_path / "scheduler.json"
    logs = [open(tmp_path / name, "w") for name in ("scheduler.log", "worker.log")]
    scheduler = subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                  "--scheduler-file", file], stdout=logs[0], stderr=logs[0], start_new_session=True)
    processes = [scheduler]
    try:
        _wait_for(lambda: file.exists() and file.stat().st_size > 0, what="the scheduler")
        import json

        address = json.loads(file.read_text())["address"]
        worker = subprocess.Popen([dask, "worker", address, "--nthreads", "1", "--no-dashboard",
                                   "--local-directory", tmp_path / "worker"], stdout=logs[1], stderr=logs[1],
                                  start_new_session=True, cwd=tmp_path)
        processes.append(worker)
        _wait_for(lambda: "Registered to" in (tmp_path / "worker.log").read_text(), what="the worker")
        yield address, scheduler
    finally:
        for process in processes:
            process.kill()
            process.wait()
        for log in logs:
            log.close()


#: Four cases of about 60 steps each: a chunk of one case keeps a worker busy long enough for the
#: scheduler to be killed while chunks are still to come.
LONGER = FOUR.replace("drive = { D1 = 0.05 }", "drive = { D1 = 0.5 }").replace("max_step = 0.05", "max_step = 0.01")


def test_a_lost_scheduler_exits_3_keeping_chunks_then_an_unreachable_one_writes_nothing(
    dask_cluster, tmp_path, capfd
):
    address, scheduler = dask_cluster
    run = tmp_path / "run"
    run.mkdir()
    study = write_study(run, LONGER)
    out = run / "out.nc"
    child = _python("import sys\nfrom ncstab.cli import main\nsys.exit(main(sys.argv[1:]))",
                    "run", study, "-o", out, "--chunk-cases", "1", "--scheduler", address, "--scheduler-timeout", "5")
    _wait_for(lambda: any((run / "out.nc.parts").glob("*.npz")) or child.poll() is not None, timeout=90,
              what="a first chunk")
    scheduler.kill()
    _, err = child.communicate(timeout=120)
    assert child.returncode == 3, err
    assert_one_line(err, r"^ncstab run: tiny: lost the dask cluster while running chunk .*\.npz",
                    r"[1-3] of 4 chunks kept in .*out\.nc\.parts: rerun with --resume")
    assert {"out.nc.parts/manifest.json"} <= tree(run)
    assert not {"out.nc", "out.nc.lock", "out.nc.parts/archive.nc.tmp"} & tree(run)
    code, _, err = run_cli(["run", study, "-o", out, "--resume"], capfd)  # in this process: the same archive
    assert (code, err) == (0, "")
    expected = tmp_path / "expected.nc"
    write_dataset(run_study(parse_study(LONGER)), expected)
    assert_same_archive(out, open_study(expected))

    scheduler.wait()
    elsewhere = tmp_path / "unreachable"
    elsewhere.mkdir()
    study = write_study(elsewhere, FOUR)
    code, _, err = run_cli(["run", study, "-o", elsewhere / "out.nc", "--scheduler", address,
                            "--scheduler-timeout", "1"], capfd)
    assert code == 3
    assert_one_line(err, rf"cannot reach the dask scheduler at {address} within 1 s", r"no chunk was finished$")
    assert tree(elsewhere) == {"study.toml"}, "nothing is written when the cluster cannot be reached"


def test_a_scheduler_that_does_not_answer_exits_3_within_its_timeout(tmp_path, capfd):
    pytest.importorskip("dask.distributed")
    import socket

    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen(4)  # accepts connections, never speaks
        address = f"tcp://127.0.0.1:{silent.getsockname()[1]}"
        study = write_study(tmp_path, FOUR)
        started = time.monotonic()
        code, _, err = run_cli(["run", study, "-o", tmp_path / "out.nc", "--scheduler", address,
                                "--scheduler-timeout", "1"], capfd)
        assert time.monotonic() - started < 30
    assert code == 3
    assert_one_line(err, rf"cannot reach the dask scheduler at {address} within 1 s: it does not answer")
    assert tree(tmp_path) == {"study.toml"}


def test_a_directory_another_user_cannot_write_exits_3(tmp_path, capfd):
    """As a user without write permission: this user if it is not root, else a child that has
    imported ncstab as root and switched to 'nobody' (who may not even reach the directory)."""
    study = write_study(tmp_path, TINY)
    locked = tmp_path / "locked"
    locked.mkdir()
    if os.geteuid() != 0:
        locked.chmod(0o555)
        code, _, err = run_cli(["run", study, "-o", locked / "out.nc"], capfd)
    else:
        import pwd

        nobody = pwd.getpwnam("nobody")
        study.chmod(0o644)  # readable by anyone through the descriptor the child opens as root
        code_text = (
            "import os, sys\n"
            # (the standard library of this interpreter may be readable by root only: import first,
            # the package's public names too: they are imported on first use)
            "import encodings.ascii, ncstab.cli, ncstab.studies.preflight, ncstab.studies.outputs\n"
            "import ncstab.studies.run, ncstab.studies.study, ncstab.studies.chunked, ncstab.paths.api\n"
            "study = os.open(sys.argv[1], os.O_RDONLY)\n"
            f"os.setgroups([]); os.setgid({nobody.pw_gid}); os.setuid({nobody.pw_uid})\n"
            "sys.exit(ncstab.cli.main(['run', f'/dev/fd/{study}', '-o', sys.argv[2]]))\n"
        )
        child = _python(code_text, study, locked / "out.nc")
        _, err = child.communicate(timeout=120)
        code = child.returncode
    assert code == 3, err
    assert_one_line(err, rf"cannot (write in|reach) {locked}: Permission denied")
    assert tree(locked) == set()


def test_a_full_file_system_stops_the_write_in_one_line(tmp_path, capfd, monkeypatch):
    """A real full disk (a 96 kB tmpfs in a mount namespace of its own, where the machine allows one):
    the preflight lets the study through (its estimate is a lower bound), netCDF fails with
    "HDF error", the run says "disk full" and leaves nothing.  Else the same with a write raising ENOSPC."""
    study = write_study(tmp_path, TINY)
    mount = tmp_path / "small"
    mount.mkdir()
    script = (f"mount -t tmpfs -o size=96k tmpfs {mount} || exit 99; "
              f"{sys.executable} -m ncstab run {study} -o {mount / 'out.nc'} 2> {tmp_path / 'err.txt'}; "
              f"echo $? > {tmp_path / 'code.txt'}; ls -A {mount} > {tmp_path / 'left.txt'}")
    shell = shutil.which("unshare") and subprocess.run(
        ["unshare", "--mount", "--propagation", "private", "sh", "-c", script], capture_output=True, timeout=120,
        env={**os.environ, "PYTHONWARNINGS": "ignore"})
    if shell and shell.returncode == 0 and (tmp_path / "code.txt").exists():
        code, err = int((tmp_path / "code.txt").read_text()), (tmp_path / "err.txt").read_text()
        left = set((tmp_path / "left.txt").read_text().split())
    else:  # no mount namespace here: the write itself reports the full disk
        monkeypatch.setattr(xr.Dataset, "to_netcdf", _enospc)
        code, _, err = run_cli(["run", study, "-o", mount / "out.nc"], capfd)
        left = {p.name for p in mount.iterdir()}
    assert code == 3, err
    assert_one_line(err, r"disk full while writing .*small/out\.nc", r"nothing was written")
    assert left == set()


@pytest.mark.parametrize("argv", [["laws", "--all"], ["info", "{archive}"]], ids=["laws", "info"])
def test_a_reader_that_goes_away_ends_the_command_quietly(argv, archive, tmp_path):
    """``ncstab laws --all | head -c 5``: the pipe's reader is gone before the output is written
    (its end is closed before the child starts writing): exit 0, nothing on stderr, five times
    out of five (it exited 3, "BrokenPipeError", at times)."""
    argv = [str(archive) if a == "{archive}" else a for a in argv]
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    for _ in range(5):
        reader, writer = os.pipe()
        os.close(reader)  # "head -c 5" that has read its 5 bytes, at the worst moment: before any
        try:
            done = subprocess.run([sys.executable, "-m", "ncstab", *argv], stdout=writer, stderr=subprocess.PIPE,
                                  text=True, timeout=120, env=env, cwd=tmp_path)
        finally:
            os.close(writer)
        assert (done.returncode, done.stderr) == (0, "")


@pytest.mark.parametrize("name", ["SIGTERM", "SIGHUP"])
def test_a_signal_as_the_command_starts_is_one_line_and_exit_3(name):
    """Before the command's own handlers (the run's cleanup) are set, a signal is one line and
    exit code 3 too, not a silent death (143, 129)."""
    code = ("import os, signal, time\n"
            "import ncstab.cli as cli\n"
            "def build_parser():\n"
            f"    os.kill(os.getpid(), signal.{name})\n"
            "    time.sleep(10)\n"
            "cli.build_parser = build_parser\n"
            "cli.main()\n")
    child = _python(code)
    _, err = child.communicate(timeout=60)
    assert child.returncode == 3, err
    assert_one_line(err, rf"^ncstab: interrupted by {name}; stopped at once \(archives and figures are written "
                         r"whole or not at all\)$")


def test_the_command_ends_as_soon_as_its_work_is_done():
    """No interpreter finalization after the work (Python puts the default signal handlers back
    there, and tearing numba down took seconds: a SIGTERM then exited 143, silently): an atexit
    handler of 30 s is not waited for; the output is complete."""
    code = ("import atexit, sys, time\n"
            "atexit.register(time.sleep, 30)\n"
            "sys.argv = ['ncstab', 'laws']\n"
            "from ncstab.cli import main\n"
            "main()\n"
            "raise SystemExit(99)  # not reached\n")
    start = time.monotonic()
    child = _python(code)
    out, err = child.communicate(timeout=60)
    assert (child.returncode, err) == (0, "")
    assert time.monotonic() - start < 25
    assert out.rstrip().endswith("gamma = k_t/k_n."), "flushed before the process ended"


def test_sighup_to_a_running_command_keeps_its_chunks_and_removes_its_lock(tmp_path, reference, capfd):
    """The terminal of a run closes: SIGHUP stops it as Ctrl-C does (it exited 129 leaving out.nc.lock)."""
    study = write_study(tmp_path, FOUR)
    out = tmp_path / "out.nc"
    child = _python(SLOWER_RUN, "run", study, "-o", out, "--chunk-cases", "1")
    parts = tmp_path / "out.nc.parts"
    _wait_for(lambda: len(list(parts.glob("*.npz"))) >= 1 or child.poll() is not None, what="a chunk")
    os.kill(child.pid, signal.SIGHUP)
    _, err = child.communicate(timeout=60)
    assert child.returncode == 3, err
    assert_one_line(err, r"^ncstab run: tiny: interrupted by SIGHUP; \d of 4 chunks kept in .*out\.nc\.parts")
    left = tree(tmp_path)
    assert "out.nc.lock" not in left and "out.nc" not in left
    assert run_cli(["run", study, "-o", out, "--resume"], capfd)[0] == 0
    assert_same_archive(out, reference)


def test_a_damaged_numba_cache_is_compiled_again(tmp_path):
    """numba's index (.nbi) and data (.nbc) files garbled: the function is compiled again, its
    entry rewritten, the result right (it exited 3, "UnpicklingError")."""
    code = ("import sys\n"
            "from ncstab.generated_modules import compiled_module\n"
            "def triple(x):\n"
            "    return 3.0 * x\n"
            "module = compiled_module('ncstab_fault_catalogue', triple)\n"
            "print(module.triple(2.5))\n")
    env = {**os.environ, "PYTHONWARNINGS": "ignore", "NCSTAB_CACHE_DIR": str(tmp_path / "cache")}
    script = tmp_path / "triple.py"
    script.write_text(code)
    first = subprocess.run([sys.executable, script], capture_output=True, text=True, timeout=120, env=env)
    assert (first.returncode, first.stdout.strip()) == (0, "7.5"), first.stderr
    entries = sorted((tmp_path / "cache").rglob("*.nb[ic]"))
    assert {p.suffix for p in entries} == {".nbi", ".nbc"}
    for entry in entries:
        entry.write_bytes(b"garbage, not a pickle")
    second = subprocess.run([sys.executable, script], capture_output=True, text=True, timeout=120, env=env)
    assert (second.returncode, second.stdout.strip(), second.stderr) == (0, "7.5", "")
    assert all(entry.read_bytes() != b"garbage, not a pickle" for entry in entries), "rewritten"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS as ulimit -v on Linux")
def test_a_run_without_memory_for_the_compiler_says_so(tmp_path):
    """``ulimit -v 300000``: libllvmlite.so cannot be mapped; one line saying it is memory, exit 3."""
    import resource

    study = write_study(tmp_path, TINY)

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (300_000 * 1024, 300_000 * 1024))

    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    done = subprocess.run([sys.executable, "-m", "ncstab", "run", study, "-o", tmp_path / "out.nc"],
                          capture_output=True, text=True, timeout=120, env=env, preexec_fn=limit)
    if done.returncode == 0:
        pytest.skip("300 MB of address space were enough for llvmlite here")
    assert done.returncode == 3, done.stderr
    assert_one_line(done.stderr, r"^ncstab run: (tiny: )?out of memory \(.*\); nothing more was written")
    assert tree(tmp_path) == {"study.toml"}


# --- the machinery, proven against independent computations -----------------------------------------


def _fletcher32_as_hdf5_writes_it(data: bytes) -> int:
    """H5_checksum_fletcher32 (HDF5's H5checksum.c), transcribed loop for loop: 16-bit big-endian
    words summed in blocks of 360 with the sums folded after each block, an odd last byte as a
    high byte -- the reference for the vectorised form."""
    length, position, sum1, sum2 = len(data) // 2, 0, 0, 0
    while length:
        block = min(length, 360)
        length -= block
        for _ in range(block):
            sum1 = (sum1 + ((data[position] << 8) | data[position + 1])) & 0xFFFFFFFF
            sum2 = (sum2 + sum1) & 0xFFFFFFFF
            position += 2
        sum1 = (sum1 & 0xFFFF) + (sum1 >> 16)
        sum2 = (sum2 & 0xFFFF) + (sum2 >> 16)
    if len(data) % 2:
        sum1 += data[position] << 8
        sum2 += sum1
        sum1 = (sum1 & 0xFFFF) + (sum1 >> 16)
        sum2 = (sum2 & 0xFFFF) + (sum2 >> 16)
    sum1 = (sum1 & 0xFFFF) + (sum1 >> 16)
    sum2 = (sum2 & 0xFFFF) + (sum2 >> 16)
    return (sum2 << 16) | sum1


def test_fletcher32_is_hdf5s_checksum_on_every_kind_of_input(rng):
    """Exact equality (integers): random bytes of odd and even lengths across the 360-word blocks,
    all zeros (the sums stay 0) and all 0xff (every sum a multiple of 65535: 65535, not 0)."""
    from ncstab.studies.checksums import fletcher32

    inputs = [bytes(), b"\x01", bytes(720), b"\xff" * 721, b"\xff" * 1440, b"\x00\x01" * 999]
    inputs += [rng.integers(0, 256, int(n), dtype=np.uint8).tobytes() for n in rng.integers(0, 5000, 60)]
    for data in inputs:
        assert fletcher32(data) == _fletcher32_as_hdf5_writes_it(data), len(data)


def test_fletcher32_of_a_chunk_larger_than_a_block_is_what_hdf5_stores(tmp_path, rng):
    """9.6 MB (more than the 2^22 words summed at once): the checksum HDF5 appended to the chunk."""
    from ncstab.studies.checksums import fletcher32

    values = rng.normal(size=1_200_001)
    with h5py.File(tmp_path / "big.h5", "w") as handle:
        handle.create_dataset("x", data=values, chunks=values.shape, fletcher32=True)
        _, stored = handle["x"].id.read_direct_chunk((0,))
    assert stored[:-4] == values.tobytes()
    assert fletcher32(values.tobytes()) == int.from_bytes(stored[-4:], "little")


@pytest.mark.parametrize("block", [1, 2, 7, 360])
def test_fletcher32_summed_in_many_blocks_is_hdf5s_checksum(block, rng, monkeypatch):
    """The blocks' sums combined (checksums._BLOCK words at a time, here a few words): the
    transcribed HDF5 loop's value, for lengths that end inside a block and on its edge."""
    from ncstab.studies import checksums

    monkeypatch.setattr(checksums, "_BLOCK", block)
    for size in (1, 2, 3, 14, 15, 719, 720, 721, 4001):
        data = rng.integers(0, 256, size, dtype=np.uint8).tobytes()
        assert checksums.fletcher32(data) == _fletcher32_as_hdf5_writes_it(data), (block, size)
    assert checksums.fletcher32(b"\xff" * 1441) == _fletcher32_as_hdf5_writes_it(b"\xff" * 1441)


@pytest.mark.parametrize("dtype", ["<f8", "<i4"])
def test_chunks_encoded_by_ncstab_are_read_back_by_hdf5(dtype, tmp_path, rng):
    """The bytes a chunked run writes directly (checksum, shuffle, deflate) decode in netCDF to the
    values, exactly; HDF5's own checksum of a chunk it wrote is ours; a flipped byte is refused."""
    import netCDF4

    from ncstab.studies.checksums import fletcher32, hdf5_chunk

    values = rng.normal(size=(3, 50)) if dtype == "<f8" else rng.integers(-5, 5, (3, 50))
    values = values.astype(dtype)
    path = tmp_path / "chunks.nc"
    with netCDF4.Dataset(path, "w") as handle:
        handle.createDimension("a", 3), handle.createDimension("b", 50)
        for name in ("direct", "plain"):
            handle.createVariable(name, dtype, ("a", "b"), zlib=True, complevel=1, shuffle=True, fletcher32=True,
                                  chunksizes=(1, 50))
        handle["plain"][:] = values
    with h5py.File(path, "r+") as handle:
        for row in range(3):
            handle["direct"].id.write_direct_chunk((row, 0), hdf5_chunk(values[row:row + 1], 1))
        _, stored = handle["plain"].id.read_direct_chunk((1, 0))
    import zlib

    raw = zlib.decompress(stored)
    itemsize = np.dtype(dtype).itemsize
    unshuffled = np.frombuffer(raw[: 50 * itemsize], np.uint8).reshape(itemsize, 50).T.tobytes() if itemsize == 8 \
        else np.frombuffer(raw, np.uint8).reshape(itemsize, 51).T.tobytes()
    assert unshuffled[: 50 * itemsize] == values[1].tobytes()
    assert int.from_bytes(unshuffled[50 * itemsize:][:4] if itemsize == 4 else raw[-4:], "little") == \
        fletcher32(values[1].tobytes())
    with netCDF4.Dataset(path) as handle:
        np.testing.assert_array_equal(handle["direct"][:], values)
    flip_byte(path, chunk_offset(path, "direct"))
    with netCDF4.Dataset(path) as handle, pytest.raises(RuntimeError, match="HDF error"):
        handle["direct"][:]


def test_the_digest_is_what_a_reader_sees_and_nothing_else():
    """Equal for values read back alike (any NaN, any string width), different for a change of
    one value, of the shape or of the type."""
    from ncstab.studies.checksums import variable_digest

    base = np.array([1.0, np.nan, -0.0])
    other_nan = base.copy()
    other_nan.view(np.uint64)[1] |= np.uint64(1 << 63)  # a NaN with its sign bit set (0/0 on x86 gives one)
    assert variable_digest(base) == variable_digest(other_nan)
    assert variable_digest(np.array(["a", "bc"], dtype="<U9")) == variable_digest(np.array(["a", "bc"]))
    assert variable_digest(base) != variable_digest(np.array([1.0, np.nan, 0.0]))
    assert variable_digest(np.arange(6.0)) != variable_digest(np.arange(6.0).reshape(2, 3))
    assert variable_digest(np.arange(3, dtype="<i8")) != variable_digest(np.arange(3, dtype="<f8"))
    assert variable_digest(np.array(["ab", "c"])) != variable_digest(np.array(["a", "bc"]))


def _text(attribute) -> str:
    """An HDF5 string attribute as h5py gives it (str, or bytes for a fixed-length one)."""
    return attribute.decode() if isinstance(attribute, bytes) else str(attribute)


def test_every_variable_of_an_archive_is_checked_and_open_study_returns_what_was_written(archive, tmp_path):
    """Fletcher-32 on the compressed variables, a digest for each of the others: together all of them;
    what open_study gives is the Dataset written (no checksum attribute in it)."""
    from ncstab.studies.checksums import DIGEST_ATTRIBUTE, parse_digests

    with h5py.File(archive, "r") as handle:
        names = [name for name in handle if isinstance(handle[name], h5py.Dataset) and "_Netcdf4" not in name]
        filtered = {name for name in names if handle[name].fletcher32}
        digested = set(parse_digests(_text(handle.attrs[DIGEST_ATTRIBUTE])))
    assert filtered and digested and not filtered & digested
    assert filtered | digested == set(names)
    dataset = open_study(archive)
    assert DIGEST_ATTRIBUTE not in dataset.attrs
    written = run_study(parse_study(ARCHIVED))
    written.attrs.pop("created"), dataset.attrs.pop("created")
    xr.testing.assert_identical(dataset, written)


def test_chunked_archives_are_checked_like_the_others(interrupted, capfd):
    """The archive a chunked run writes: Fletcher-32 on every variable with cases, digests on the rest."""
    from ncstab.studies.checksums import DIGEST_ATTRIBUTE, parse_digests

    study, out, _, _ = interrupted
    assert run_cli(["run", study, "-o", out, "--resume"], capfd)[0] == 0
    with h5py.File(out, "r") as handle:
        names = {name for name in handle if isinstance(handle[name], h5py.Dataset) and "_Netcdf4" not in name}
        filtered = {name for name in names if handle[name].fletcher32}
        digested = set(parse_digests(_text(handle.attrs[DIGEST_ATTRIBUTE])))
    assert {"u", "F", "stage", "n_steps", "K"} <= filtered and {"status", "message", "law"} <= digested
    assert filtered | digested == names
    flip_byte(out, chunk_offset(out, "F"))
    code, _, err = run_cli(["info", out], capfd)
    assert code == 2
    assert_one_line(err, r"variable 'F' cannot be read")


GOLDEN = Path(__file__).parent / "golden"


@pytest.mark.parametrize("study_file", sorted((GOLDEN / "studies").glob("*.toml")), ids=lambda p: p.stem)
def test_the_size_estimates_are_below_what_a_run_stores(study_file):
    """Against the golden archives: each case stores at least the estimated states (a stored state
    per max_step of driven length, at most: every case of these studies runs to its end), and the
    archive is larger than the estimate -- by less than 10x (measured: 1.8x to 5.8x)."""
    from ncstab.studies import load_study
    from ncstab.studies.preflight import size_estimate

    study = load_study(study_file)
    estimate = size_estimate(study)
    dataset = open_study(GOLDEN / f"{study.name}.nc")
    n_steps = dataset["n_steps"].values
    assert estimate.cases == n_steps.size
    assert estimate.mean_states <= n_steps.mean() and estimate.longest_states <= n_steps.max()
    size = (GOLDEN / f"{study.name}.nc").stat().st_size
    assert size / 10 < estimate.disk_bytes <= size
    per_state = sum(v.dtype.itemsize * int(np.prod([n for d, n in v.sizes.items() if d not in n_steps_dims(dataset)
                                                    and d != "step"]))
                    for v in dataset.data_vars.values() if "step" in v.dims and v.dtype.kind in "biuf")
    assert estimate.bytes_per_state == per_state, "the bytes of a state are those of the variables"


def n_steps_dims(dataset) -> tuple[str, ...]:
    return dataset["n_steps"].dims


def test_the_memory_of_the_maps_is_that_of_their_arrays(tmp_path):
    """The grid's estimate is exactly the state maps' bytes; the directions' is at most d2W_dir's."""
    from ncstab.studies.preflight import map_memory, size_estimate

    text = TINY.replace("[output]", "[map]\ndirections = 36\ngrid = { D1 = [0.0, 0.05, 6], D2 = [-0.01, 0.01, 5] }\n"
                                    "[output]")
    study = parse_study(text)
    dataset = run_study(study)
    needs = map_memory(study, size_estimate(study), study.n_cases)
    assert needs["grid"] == sum(dataset[name].nbytes for name in dataset.data_vars if name.startswith("map_")
                                and name not in ("map_D1", "map_D2"))
    assert 0 < needs["directions"] <= dataset["d2W_dir"].nbytes


def test_what_a_study_file_says_about_its_stages():
    """Known starts and driven lengths, exactly: from rest, then where each stage leaves its quantities."""
    from ncstab.studies.stage_extent import stage_extents

    study = parse_study((ROOT_STUDIES / "seed" / "fig09_11_lateral_load.toml").read_text())
    preload, vertical = stage_extents(study.programme.stages, study.parameters)
    assert preload.start == {"F1": 0.0, "F2": 0.0} and preload.driven == "F2"
    np.testing.assert_array_equal(preload.length, [0.0, 0.75])
    assert not preload.does_nothing  # the case F2_lateral = 0.75 does something
    assert vertical.start == {}, "D1 moved with the preload; F2 ends at 0 or 0.75: known in no case"
    assert np.isnan(vertical.length).all() and vertical.measured_from_rest.tolist() == [0.6]
    green = parse_study((ROOT_STUDIES / "green_paradox.toml").read_text())
    first, back = stage_extents(green.programme.stages, green.parameters)
    radius = np.array(green.parameters["radius"])
    np.testing.assert_allclose(first.length, 2 * np.pi * 3 * radius, rtol=1e-15)  # 3 turns about (r, 0) from rest
    assert back.start == {"D1": 0.0, "D2": 0.0}, "whole turns come back to where they started"


ROOT_STUDIES = Path(__file__).resolve().parents[1] / "studies"


@pytest.mark.parametrize("address, expected", [
    ("127.0.0.1:8786", "tcp://127.0.0.1:8786"),
    ("tcp://head:8786", "tcp://head:8786"),
    ("tls://head.example.org:1/", "tls://head.example.org:1"),
    ("tcp://[::1]:8786", "tcp://[::1]:8786"),
    (" tcp://node-7:65535 ", "tcp://node-7:65535"),
])
def test_scheduler_addresses(address, expected):
    from ncstab.studies.cluster import scheduler_address

    assert scheduler_address(address) == expected


def test_the_lock_is_reentrant_in_its_thread_and_removed_by_the_outermost_holder(tmp_path):
    with OutputLock(tmp_path / "out.nc") as outer:
        with OutputLock(tmp_path / "out.nc") as inner:
            assert inner.stale_pid is None and outer.path.exists()
        assert outer.path.exists(), "still held by the outer run"
        assert outer.path.read_text() == f"pid {os.getpid()}\nhost {_hostname()}\n"
    assert not outer.path.exists()


def test_a_second_signal_during_the_cleanup_stops_at_once_with_one_line():
    """The first SIGINT raises (the cleanup runs); a second one during that cleanup exits 3 at once."""
    code = (
        "import os, signal, time\n"
        "from ncstab.studies.errors import RunInterrupted\n"
        "from ncstab.studies.interrupts import stop_on_signals\n"
        "with stop_on_signals('ncstab run'):\n"
        "    try:\n"
        "        os.kill(os.getpid(), signal.SIGINT)\n"
        "        time.sleep(10)\n"
        "    except RunInterrupted:\n"
        "        os.kill(os.getpid(), signal.SIGTERM)  # a slow cleanup, interrupted again\n"
        "        time.sleep(10)\n"
        "raise SystemExit(0)\n"
    )
    child = _python(code)
    _, err = child.communicate(timeout=60)
    assert child.returncode == 3
    assert_one_line(err, r"^ncstab run: SIGTERM again: stopped at once \(temporary files are removed by the next run")


def test_a_stage_that_moves_nothing_among_stages_that_do_is_accepted(tmp_path, capfd):
    """A preload of 0 before a driven stage is skipped by the engine: the study does what it says."""
    study = write_study(tmp_path, TINY.replace("hold = { F2 = 0.0 }\ndrive = { D1 = 0.05 }",
                                               "hold = { F1 = 0.0 }\ndrive = { F2 = 0.0 }\n[[loading]]\n"
                                               'hold = { F2 = "current" }\ndrive = { D1 = 0.05 }'))
    code, out, err = run_cli(["run", study, "-o", tmp_path / "out.nc"], capfd)
    assert (code, err) == (0, "") and "finished: 2" in out
    assert int(open_study(tmp_path / "out.nc")["n_steps"].min()) > 1


def test_an_archive_of_a_path_followed_from_python_is_readable(tmp_path):
    """No study file behind it (its 'study' attribute is empty): still a readable archive."""
    import ncstab

    path = ncstab.follow(ncstab.SystemSpec(secondary_contacts="ignore"), "mcnamara",
                         [{"hold": {"F2": 0.0}, "drive": {"D1": 0.05}}], {"gamma": 0.5, "alpha0": np.pi / 4},
                         ncstab.PathOptions(max_step=0.05))
    dataset = path.to_dataset()
    assert dataset.attrs["study"] == ""
    write_dataset(dataset, tmp_path / "path.nc")
    from ncstab.studies.archive import normalise_dataset

    xr.testing.assert_identical(open_study(tmp_path / "path.nc"), normalise_dataset(dataset))
