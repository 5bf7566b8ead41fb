"""Every example of README.md and docs/*.md runs (issue 19, "docs that run").

Each fenced code block of the pages is one test, ``page:index`` (the index counts
every fenced block of the page from 0, whatever its language), so a failure names
the page and the block.  What a block is, and what is done with it:

``python``
    Executed.  A page's Python blocks run in order in one namespace (a block may
    use what an earlier one made), in the page's working directory (below).
``console``, ``sh``, ``bash``, ``shell``, or no language
    Commands, with or without a ``$`` prompt, ``#`` comments, ``&&`` and ``;``
    chains, ``*`` globs.  Every ``ncstab`` command runs in this process through
    :func:`ncstab.cli.main` and must exit with 0 (or the code of an ``exit``
    annotation).  The programs of :data:`NOT_NCSTAB` (pip, NetCDF tools, the
    shell's ``echo``) are not ncstab's and are not run; any other program fails
    the test.  A chain with a pipe fails it too.
``toml``
    A complete study (one with a ``[study]`` table) is written to a file and read
    with :func:`ncstab.studies.load_study`: it must be valid, or, marked
    ``error-example``, it must be refused with a ``StudyFileError``.  A fragment
    (no ``[study]``) is skipped as such.
``text`` and any other language
    Output that a page shows, not a command: skipped (outputs that can be
    compared are, in :data:`CHECKS` or in the tests of :data:`COVERED`).

Annotations are HTML comments on the lines just above a block's opening fence
(invisible on the rendered page); any other comment there fails the test:

``<!-- no-run: REASON -->``
    The block is not run; the test is skipped with REASON.
``<!-- no-run "TEXT": REASON -->``
    The commands of a console block that contain TEXT are not run (REASON); the
    others are.  An annotation that matches no command fails the test.
``<!-- file: NAME -->``
    A block written into the working directory as NAME when the page reaches it,
    for the later blocks that use it (a study the page shows, then runs).
``<!-- exit: N -->``
    The ``ncstab`` commands of the block must exit with N.
``<!-- error-example -->``
    A TOML study that must be refused.
``<!-- main-command -->``, ``<!-- test-command -->`` (and their closing tags)
    The README blocks that ``.ci/run`` runs; they carry a ``no-run`` too.

Each page runs once per test process, in a fresh temporary working directory that
holds a copy of the repository's ``studies/`` and the stand-ins of
``tests/data/docs_examples/``: small studies under the placeholder names the
pages use for the reader's own files (``study.toml``, ``big.toml``,
``STUDY.toml``).  Nothing is written into the repository.  Blocks that another
test runs and checks already are listed in :data:`COVERED` and skipped here
(with the name of that test, whose existence is checked).
"""

from __future__ import annotations

import contextlib
import dataclasses
import glob
import io
import math
import re
import shlex
import shutil
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from ncstab.cli import build_parser, main
from ncstab.studies import StudyFileError, load_study

ROOT = Path(__file__).resolve().parent.parent
STAND_INS = Path(__file__).parent / "data" / "docs_examples"
PAGES = ["README.md", *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md"))]

CONSOLE = {"", "console", "sh", "bash", "shell"}
#: Programs that docs' console blocks name and this test does not run, and why.
NOT_NCSTAB = {
    "pip": "installs packages (the environment is already installed)",
    "ncdump": "a netCDF-C tool, not an ncstab command",
    "ncinfo": "a netCDF4-python tool, not an ncstab command",
    "echo": "the shell printing the exit code, which the test checks itself",
}
#: Annotations of .ci/run that may stand above a block.
CI_MARKERS = re.compile(r"^<!-- /?(main-command|test-command) -->$")
ANNOTATION = re.compile(r'^<!-- (no-run(?: "(?P<pattern>[^"]+)")?: (?P<reason>.+?)|file: (?P<file>\S+)|exit: (?P<exit>\d+)|error-example) -->$')
FENCE = re.compile(r"^```(?P<language>[\w+-]*)[^\n]*\n(?P<text>.*?)^```[ \t]*$", re.MULTILINE | re.DOTALL)


@dataclasses.dataclass(frozen=True)
class Block:
    """One fenced code block of a page.

    Attributes
    ----------
    page : str
        The page, relative to the repository (``docs/archive.md``).
    index : int
        Its position among the page's fenced blocks, from 0.
    line : int
        The line of its opening fence (1-based).
    language : str
        The fence's language tag (``""`` if none).
    text : str
        Its content.
    notes : tuple of str
        The HTML comments on the lines just above the fence, top to bottom.
    """

    page: str
    index: int
    line: int
    language: str
    text: str
    notes: tuple[str, ...]

    @property
    def where(self) -> str:
        return f"{self.page}, block {self.index} ({self.language or 'no language'}, line {self.line})"

    def annotations(self) -> list[re.Match[str]]:
        """The block's run annotations; a comment that is neither one nor a CI marker raises."""
        found = []
        for note in self.notes:
            match = ANNOTATION.match(note)
            if match:
                found.append(match)
            elif not CI_MARKERS.match(note):
                raise AssertionError(f"{self.where}: unknown annotation {note!r} (see tests/test_docs_examples.py)")
        return found

    def annotation(self, kind: str) -> re.Match[str] | None:
        return next((a for a in self.annotations() if a.group(0).startswith(f"<!-- {kind}")), None)


def page_blocks(page: str) -> list[Block]:
    """The fenced blocks of ``page``, with the comments just above each."""
    text = (ROOT / page).read_text(encoding="utf-8")
    blocks = []
    for index, match in enumerate(FENCE.finditer(text)):
        line = text.count("\n", 0, match.start()) + 1
        above = text[: match.start()].splitlines()
        notes: list[str] = []
        while above and above[-1].startswith("<!--"):
            notes.insert(0, above.pop().strip())
        blocks.append(Block(page, index, line, match["language"], match["text"], tuple(notes)))
    return blocks


BLOCKS = [block for page in PAGES for block in page_blocks(page)]

#: Blocks run and checked by another test: (page, text the block holds) -> that test.
COVERED = {
    ("docs/models.md", "SpringLaw(\"softening\""):
        "tests/test_models.py::test_the_python_example_of_the_models_page_runs",
    ("docs/dynamic-stability.md", "flutter_indicator(M, C(0.1, 0.1)"):
        "tests/test_dynamics.py::test_the_documented_example_runs_and_prints_what_the_page_shows",
    ("docs/dynamic-stability.md", "growth rate: [-0.005651"):  # the output of the block above
        "tests/test_dynamics.py::test_the_documented_example_runs_and_prints_what_the_page_shows",
    ("docs/study-files.md", 'name = "fig06_hyper_vs_hypo"'):
        "tests/test_studies.py::test_the_guide_example_study_is_valid",
    ("docs/study-files.md", "[outputs]"):
        "tests/test_studies.py::test_the_guide_error_report_is_what_load_study_says",
    ("docs/user-laws.md", "[laws.sine_shear]"):
        "tests/test_user_laws.py::test_the_guide_study_and_its_explanation_are_what_ncstab_says",
    ("docs/user-laws.md", 'print(classify(sine_shear).kind)'):
        "tests/test_user_laws.py::test_the_guide_python_example_runs_and_prints_what_it_says",
}


def covering_test(block: Block) -> str | None:
    """The test that covers ``block`` (from :data:`COVERED`), or None."""
    names = [test for (page, snippet), test in COVERED.items() if page == block.page and snippet in block.text]
    assert len(names) <= 1, f"{block.where}: covered twice in COVERED"
    return names[0] if names else None


# --- what a block printed or made, where the page says what it is ----------------------------


def _readme_python(ns: dict[str, Any], out: str) -> None:
    # ``ziegler.to_dataset()["flutter_onset_load"].item()   # 2.0857864376... = 7/2 - sqrt 2``;
    # the engine locates the onset to event_tol (1e-10), the page shows 10 digits.
    onset = ns["ziegler"].to_dataset()["flutter_onset_load"].item()
    assert abs(onset - (3.5 - math.sqrt(2))) < 1e-9, onset
    assert ns["ds"]["limit_point_F"].sel(dof="D1").dims == ("law", "gamma")


def _readme_console(ns: dict[str, Any], out: str) -> None:
    # ncstab laws STUDY.toml --explain my_law: which condition decides its class
    assert "class: weakly hypoelastic -- decided by Eq. (17) hyperelasticity" in out
    assert Path("results/ziegler_follower.nc").exists()  # ncstab run studies/ziegler_follower.toml


def _archive_python(ns: dict[str, Any], out: str) -> None:
    assert out == ns["ds"].attrs["study"] + "\n"  # print(ds.attrs["study"]): the study file
    assert ns["ds"].attrs["study"] == Path("studies/seed/fig09_11_lateral_load.toml").read_text()


def _figures_python(ns: dict[str, Any], out: str) -> None:
    lines = out.splitlines()
    assert lines[0] == "curves"  # print(sweep_shape(ds).layout)  # curves (2 cases)
    # draw_figures(ds, "figures", kinds="load_rotation,stability", progress=...): one line a figure
    assert [line.split()[0] for line in lines[1:]] == ["1/2", "2/2"], lines
    assert lines[1].endswith("load_rotation.png") and lines[2].endswith("stability.png"), lines
    assert Path(lines[2].split()[1]).stat().st_size > 0 and Path("load_rotation.png").stat().st_size > 0


def _green_python(ns: dict[str, Any], out: str) -> None:
    assert ns["ds"]["cycle_work"].dims == ("law", "cycle") == ns["ds"]["cycle_T_drift"].dims


def _study_files_console(ns: dict[str, Any], out: str) -> None:
    # writes results/fig06_hyper_vs_hypo_gamma2.nc and its figures
    assert Path("results/fig06_hyper_vs_hypo_gamma2.nc").exists()
    assert Path("results/fig06_hyper_vs_hypo_gamma2_load_rotation.png").exists()


def _nothing_printed(ns: dict[str, Any], out: str) -> None:
    assert out == "", out  # the archive opened: no ArchiveError reason printed


def _scale_python(ns: dict[str, Any], out: str) -> None:
    assert Path(ns["archive"]).samefile("results/big.nc")  # the archive's path


def _packings_console(ns: dict[str, Any], out: str) -> None:
    # the lines that the page shows after ncstab analyse ... --directions directions.csv --cone-plane push,shear
    assert "4 directions: d2W from 0.688871 to 4.408, 0 negative" in out, out
    assert "unstable cone in the plane of directions push,shear: none" in out, out


def _packings_cone(ns: dict[str, Any], out: str) -> None:
    assert out.splitlines() == ["hill = -0.000422412, unstable cone from 2.895114 to 3.388071 rad",
                                "[2.63  3.07  0.668 4.224] 0.0"], out


#: Checks of what a block printed (``out``) or left in its namespace or working
#: directory: (page, text the block holds) -> check(namespace, printed).
CHECKS: dict[tuple[str, str], Callable[[dict[str, Any], str], None]] = {
    ("README.md", "flutter_onset_load"): _readme_python,
    ("README.md", "ncstab laws STUDY.toml --explain my_law"): _readme_console,
    ("docs/archive.md", 'print(ds.attrs["study"])'): _archive_python,
    ("docs/figures.md", "sweep_shape(ds).layout"): _figures_python,
    ("docs/green-paradox.md", 'ds["cycle_T_drift"]'): _green_python,
    ("docs/study-files.md", "-o out.nc"): _study_files_console,
    ("docs/when-things-go-wrong.md", "except ArchiveError"): _nothing_printed,
    ("docs/scale.md", "run_study_chunked(load_study"): _scale_python,
    ("docs/packings.md", "--cone-plane push,shear -o"): _packings_console,
    ("docs/packings.md", "heavier = packing.with_forces"): _packings_cone,
}


# --- running a page ---------------------------------------------------------------------------


@dataclasses.dataclass
class Outcome:
    """What happened to one block: ``skipped`` with a reason, or ``error`` (None: it ran)."""

    skipped: str | None = None
    error: str | None = None


def commands(block: Block) -> list[list[str]]:
    """The commands of a console block, each a list of words (prompts, comments and
    chains taken apart; ``$`` lines are commands when the block uses prompts)."""
    lines = block.text.splitlines()
    prompted = any(line.startswith("$ ") for line in lines)
    found: list[list[str]] = []
    for line in lines:
        if prompted:
            if not line.startswith("$ "):
                raise AssertionError(f"{block.where}: output line {line!r} in a console block; show output in a text block")
            line = line[2:]
        lexer = shlex.shlex(line, posix=True, punctuation_chars=";&|")
        lexer.whitespace_split = True
        lexer.commenters = "#"
        words: list[str] = []
        for word in [*lexer, ";"]:
            if word in (";", "&&"):
                if words:
                    found.append(words)
                words = []
            elif set(word) <= set(";&|"):
                raise AssertionError(f"{block.where}: {word!r} in {line!r}: pipes and background jobs are not run")
            else:
                words.append(word)
    return found


def ncstab_arguments(words: list[str]) -> list[str]:
    """The arguments of ``ncstab ...`` (after ``ncstab``), globs expanded as a shell would."""
    arguments = []
    for word in words[1:]:
        expanded = sorted(glob.glob(word)) if any(c in word for c in "*?[") else [word]
        arguments += expanded or [word]
    return arguments


def run_ncstab(words: list[str]) -> tuple[int, str, str]:
    """``ncstab ARGS`` in this process: exit code, standard output, standard error."""
    arguments = ncstab_arguments(words)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(arguments)
        except SystemExit as exit_:  # argparse: --help, usage errors
            code = exit_.code if isinstance(exit_.code, int) else 1
    return code, out.getvalue(), err.getvalue()


def check_without_running(words: list[str], where: str) -> None:
    """What a command that is not run can still be checked for: its options are
    ``ncstab``'s (the command's parser accepts them) and the study files it
    names exist and are valid."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            args = build_parser().parse_args(ncstab_arguments(words))
        except SystemExit:
            raise AssertionError(f"{where}: {' '.join(words)!r}: {err.getvalue().strip()}") from None
    for study in [*getattr(args, "studies", []), getattr(args, "study", None)]:
        if study is not None:
            load_study(study)


def ncstab_commands(block: Block) -> list[list[str]]:
    """The ``ncstab`` commands of a console block, as ``["ncstab", ARGS...]``."""
    return [["ncstab", *words[3:]] if words[0] != "ncstab" else words
            for words in commands(block) if program(words) == "ncstab"]


def program(words: list[str]) -> str:
    """The program a command runs (``python -m pip`` is pip, ``python -m ncstab`` ncstab)."""
    if words[0].startswith("python") and words[1:2] == ["-m"] and len(words) > 2:
        return words[2]
    return words[0]


def run_console(block: Block) -> str:
    """Run the ncstab commands of a console block; what they printed (stdout)."""
    skips = [a for a in block.annotations() if a["pattern"]]
    exit_ = block.annotation("exit")
    expected = int(exit_["exit"]) if exit_ else 0
    unused = {a["pattern"] for a in skips}
    printed, ran = [], 0
    for words in commands(block):
        line = " ".join(words)
        matching = [a["pattern"] for a in skips if a["pattern"] in line]
        unused -= set(matching)
        name = program(words)
        if words[0] != "ncstab" and name == "ncstab":
            words = ["ncstab", *words[3:]]
        if matching and name == "ncstab":
            check_without_running(words, block.where)
        if matching or name in NOT_NCSTAB:
            continue
        if name != "ncstab":
            raise AssertionError(f"{block.where}: {line!r}: not an ncstab command, and not in NOT_NCSTAB")
        code, out, err = run_ncstab(words)
        assert code == expected, f"{block.where}: {line!r} exited with {code}, not {expected}: {err.strip()}"
        printed.append(out)
        ran += 1
    assert not unused, f"{block.where}: no-run annotations that match no command: {sorted(unused)}"
    if not ran:
        raise _Skip(f"no ncstab command to run ({'; '.join(NOT_NCSTAB[program(w)] for w in commands(block) if program(w) in NOT_NCSTAB) or 'all marked no-run'})")
    return "".join(printed)


class _Skip(Exception):
    """A block with nothing of ncstab's to run."""


def run_toml(block: Block) -> None:
    """Validate a complete study (or check that an error example is refused)."""
    name = block.annotation("file")
    path = Path(name["file"] if name else f"docs_block_{block.index}.toml")
    path.write_text(block.text, encoding="utf-8")
    if not re.search(r"^\[study\]", block.text, re.MULTILINE):
        raise _Skip("a fragment of a study file (no [study] table), not a complete study")
    if block.annotation("error-example"):
        with pytest.raises(StudyFileError):
            load_study(path)
    else:
        load_study(path)


def run_page(page: str, directory: Path) -> dict[int, Outcome]:
    """Run the blocks of ``page`` in order in ``directory``; the outcome of each."""
    shutil.copytree(ROOT / "studies", directory / "studies")
    for stand_in in STAND_INS.iterdir():
        shutil.copy(stand_in, directory / stand_in.name)
    namespace: dict[str, Any] = {"__name__": "__docs_example__"}
    outcomes: dict[int, Outcome] = {}
    with contextlib.chdir(directory):
        for block in page_blocks(page):
            outcomes[block.index] = run_block(block, namespace)
    return outcomes


def run_block(block: Block, namespace: dict[str, Any]) -> Outcome:
    """Run one block (in the current directory); its outcome."""
    try:
        no_run = next((a for a in block.annotations() if a.group(0).startswith("<!-- no-run:")), None)
        name = block.annotation("file")
        if name:
            Path(name["file"]).write_text(block.text, encoding="utf-8")
        if no_run:
            checked = ""
            if block.language in CONSOLE and ncstab_commands(block):
                for words in ncstab_commands(block):
                    check_without_running(words, block.where)
                checked = " (its ncstab commands checked: options parsed, study files loaded)"
            return Outcome(skipped=f"no-run: {no_run['reason']}{checked}")
        covered = covering_test(block)
        if covered:
            return Outcome(skipped=f"run and checked by {covered}")
        out = ""
        if block.language == "python":
            printed = io.StringIO()
            with contextlib.redirect_stdout(printed), contextlib.redirect_stderr(io.StringIO()):
                exec(compile(block.text, block.where, "exec"), namespace)  # noqa: S102 -- the docs' own example
            out = printed.getvalue()
        elif block.language in CONSOLE:
            out = run_console(block)
        elif block.language == "toml":
            run_toml(block)
        else:
            return Outcome(skipped=f"a {block.language} block: output shown by the page, not a command")
        for (page, snippet), check in CHECKS.items():
            if page == block.page and snippet in block.text:
                check(namespace, out)
    except _Skip as skip:
        return Outcome(skipped=str(skip))
    except Exception:  # noqa: BLE001 -- reported by the block's test, with its traceback
        return Outcome(error=traceback.format_exc())
    return Outcome()


@pytest.fixture(scope="session")
def docs_outcomes(tmp_path_factory: pytest.TempPathFactory) -> Callable[[str], dict[int, Outcome]]:
    """The outcomes of a page's blocks, run once per test process."""
    cache: dict[str, dict[int, Outcome]] = {}

    def outcomes(page: str) -> dict[int, Outcome]:
        if page not in cache:
            directory = tmp_path_factory.mktemp(re.sub(r"\W", "_", page))
            cache[page] = run_page(page, directory)
        return cache[page]

    return outcomes


@pytest.mark.parametrize("block", BLOCKS, ids=[f"{b.page}:{b.index}" for b in BLOCKS])
def test_the_example_runs(block: Block, docs_outcomes: Callable[[str], dict[int, Outcome]]) -> None:
    """The block runs as its page says (or is skipped by an explicit rule)."""
    outcome = docs_outcomes(block.page)[block.index]
    if outcome.error:
        pytest.fail(f"{block.where}:\n{block.text}\n{outcome.error}", pytrace=False)
    if outcome.skipped:
        pytest.skip(f"{block.where}: {outcome.skipped}")


def test_every_covered_block_and_check_names_a_block_and_a_test() -> None:
    """COVERED and CHECKS name blocks that exist, and COVERED tests that exist."""
    for (page, snippet), test in COVERED.items():
        assert [b for b in page_blocks(page) if snippet in b.text], (page, snippet)
        path, name = test.split("::")
        source = (ROOT / path).read_text(encoding="utf-8")
        assert f"def {name}(" in source and Path(page).name in source, test
    for page, snippet in CHECKS:
        assert len([b for b in page_blocks(page) if snippet in b.text]) == 1, (page, snippet)


def test_the_block_reader_sees_languages_annotations_and_commands() -> None:
    """The rules above, on a page made up for the purpose."""
    block = Block("made-up.md", 0, 1, "console",
                  "$ ncstab run a.toml -o x.nc  # a comment\n$ ncstab run b.toml; echo $?\n",
                  ("<!-- main-command -->", '<!-- no-run "b.toml": a reason -->', "<!-- exit: 1 -->"))
    assert commands(block) == [["ncstab", "run", "a.toml", "-o", "x.nc"], ["ncstab", "run", "b.toml"], ["echo", "$?"]]
    assert block.annotation("exit")["exit"] == "1"
    assert block.annotation('no-run "')["reason"] == "a reason"
    assert program(["python", "-m", "pip", "install", "."]) == "pip"
    with pytest.raises(AssertionError, match="unknown annotation"):
        dataclasses.replace(block, notes=("<!-- norun: typo -->",)).annotations()
    with pytest.raises(AssertionError, match="pipes"):
        commands(dataclasses.replace(block, text="ncstab info x.nc | head\n"))
    with pytest.raises(AssertionError, match="output line"):
        commands(dataclasses.replace(block, text="$ ncstab info x.nc\nstudy: x\n"))
    failing = dataclasses.replace(block, text="ncstab laws --explain no_such_law\n", notes=())
    assert "exited with 2, not 0" in run_block(failing, {}).error
    assert "not an ncstab command" in run_block(dataclasses.replace(failing, text="rm -rf results\n"), {}).error
    # A command that is not run is still checked: its options, its study files.
    unread = dataclasses.replace(failing, text="ncstab run studies/no_such_study.toml\n",
                                 notes=('<!-- no-run "no_such": a reason -->',))
    assert "No such file" in run_block(unread, {}).error
    misspelt = dataclasses.replace(unread, text="ncstab run studies/no_such.toml --wrokers 2\n")
    assert "unrecognized arguments: --wrokers" in run_block(misspelt, {}).error
    stale = dataclasses.replace(unread, text="ncstab laws --explain mcnamara\n", notes=('<!-- no-run "elsewhere": a reason -->',))
    assert "match no command" in run_block(stale, {}).error
