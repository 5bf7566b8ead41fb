"""Fast commands (issue 19): startup without sympy, the law-class cache, ``ncstab info``'s summary.

Every test that may write to the cache directory points ``NCSTAB_CACHE_DIR`` at a
temporary folder: nothing is written outside temporary directories.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

import ncstab
from ncstab.cache import cache_directory, read_entry, write_entry
from ncstab.cli import main
from ncstab.laws import law_definition, law_names
from ncstab.studies import open_study_lazily
from ncstab.studies.archive_contents import open_archive_contents
from ncstab.studies.summary import LINE_WIDTH, archive_summary, status_lines, swept_values
from ncstab.symbolic import class_cache
from ncstab.symbolic.class_cache import class_summary, definition_fingerprint, law_explanation
from ncstab.symbolic.explain import explain_law

#: Modules a quick command must not import (each costs a second or so).
HEAVY = ["sympy", "scipy", "xarray", "dask", "numba", "matplotlib"]


def _imported_after(argv: list[str], env: dict[str, str] | None = None) -> list[str]:
    """The heavy modules imported by ``ncstab ARGV`` run in a fresh interpreter."""
    script = textwrap.dedent(f"""
        import contextlib, io, json, sys
        from ncstab.cli import main
        with contextlib.redirect_stdout(io.StringIO()):
            try:
                main({argv!r})
            except SystemExit:
                pass
        print(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120,
                          env=env, check=False)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


# --- startup -----------------------------------------------------------------------------------


@pytest.mark.parametrize("argv", [["--version"], ["--help"], ["laws", "--help"], ["run", "--help"],
                                  ["info", "--help"], ["plot", "--help"], ["cache", "--help"]], ids=" ".join)
def test_version_and_help_import_neither_sympy_nor_the_engine(argv):
    assert _imported_after(argv) == []


def test_the_cache_command_imports_neither_sympy_nor_the_engine(tmp_path):
    env = dict(os.environ, NCSTAB_CACHE_DIR=str(tmp_path / "cache"))
    (tmp_path / "cache" / "law_classes").mkdir(parents=True)
    assert _imported_after(["cache"], env) == []
    assert _imported_after(["cache", "clear"], env) == []
    assert not (tmp_path / "cache" / "law_classes").exists()


def test_module_version_in_a_subprocess_prints_the_version():
    done = subprocess.run([sys.executable, "-m", "ncstab", "--version"], capture_output=True, text=True,
                          timeout=120, check=False)
    assert (done.returncode, done.stdout.strip()) == (0, f"ncstab {ncstab.__version__}")


def test_every_public_name_is_importable_as_before():
    import ncstab.operators
    import ncstab.paths
    import ncstab.studies
    import ncstab.systems
    from ncstab import DiamondChain, follow, make_law, open_study  # noqa: F401

    for package in (ncstab, ncstab.paths, ncstab.studies, ncstab.systems, ncstab.operators):
        for name in package.__all__:
            assert getattr(package, name) is not None, (package.__name__, name)
            assert name in dir(package)
    assert ncstab.follow is ncstab.paths.api.follow
    assert ncstab.open_study is ncstab.studies.archive.open_study
    assert ncstab.studies.chunked.run_study_chunked is ncstab.studies.run_study_chunked  # a submodule
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        ncstab.nothing  # noqa: B018
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        ncstab.studies.nothing  # noqa: B018


# --- the law-class cache -----------------------------------------------------------------------


@pytest.fixture
def cache(tmp_path, monkeypatch) -> Path:
    """An empty cache directory for the test."""
    folder = tmp_path / "cache"
    monkeypatch.setenv("NCSTAB_CACHE_DIR", str(folder))
    return folder


def test_the_cache_directory_honours_ncstab_cache_dir_then_xdg_cache_home(tmp_path, monkeypatch):
    monkeypatch.setenv("NCSTAB_CACHE_DIR", str(tmp_path / "mine"))
    assert cache_directory("law_classes") == tmp_path / "mine" / "law_classes"
    monkeypatch.setenv("NCSTAB_CACHE_DIR", "")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_directory("law_classes") == tmp_path / "xdg" / "ncstab" / "law_classes"
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert cache_directory("law_classes") == Path.home() / ".cache" / "ncstab" / "law_classes"


def _never(*args, **kwargs):
    raise AssertionError("derived again: the cache was not used")


def test_cached_laws_print_what_the_fresh_derivation_prints_for_every_catalogue_law(cache, capsys, monkeypatch):
    assert main(["laws", "--all"]) == 0  # an empty cache: every law classified afresh
    fresh = capsys.readouterr().out
    entries = sorted((cache / "law_classes").glob("*.json"))
    assert len(entries) == len(law_names(with_modifiers=True))
    monkeypatch.setattr(class_cache, "classify", _never)  # now every row comes from the cache
    assert main(["laws", "--all"]) == 0
    assert capsys.readouterr().out == fresh


def test_a_corrupt_or_foreign_cache_entry_is_ignored_and_rewritten(cache, capsys):
    assert main(["laws"]) == 0
    expected = capsys.readouterr().out
    entries = sorted((cache / "law_classes").glob("*.json"))
    assert entries
    spoilt = ["{not json", "", json.dumps({"format": 1, "key": "0" * 64, "value": {"kind": "hyperelastic"}}),
              json.dumps({"format": 1, "key": entries[3].stem, "value": {"kind": 3}}), "\x00\xff garbage"]
    for entry, text in zip(entries, spoilt):
        entry.write_text(text, encoding="latin-1")
    assert main(["laws"]) == 0
    assert capsys.readouterr().out == expected
    for entry in entries:  # each rewritten whole
        assert read_entry("law_classes", entry.stem) is not None
    assert not list((cache / "law_classes").glob(".*.tmp")), "no temporary left"


def test_a_cache_directory_that_cannot_be_written_only_costs_the_derivation(tmp_path, monkeypatch, capsys):
    blocked = tmp_path / "a_file"
    blocked.write_text("in the way")
    monkeypatch.setenv("NCSTAB_CACHE_DIR", str(blocked / "cache"))
    assert main(["laws"]) == 0
    assert "mcnamara" in capsys.readouterr().out
    write_entry("law_classes", "ab" * 32, {"kind": "x"})  # no error either
    assert read_entry("law_classes", "ab" * 32) is None


def test_the_explanation_is_cached_and_equals_the_fresh_one(cache, monkeypatch):
    definition = law_definition("mcnamara")
    fresh = explain_law(definition)
    assert law_explanation(definition) == fresh  # derived, then written
    monkeypatch.setattr(class_cache, "explain_law", _never)
    assert law_explanation(definition) == fresh  # read back
    assert class_summary(definition) == class_summary(definition, use_cache=False)


def test_the_fingerprint_is_the_definition(cache):
    turco, again = law_definition("turco"), law_definition("turco")
    assert definition_fingerprint(turco) == definition_fingerprint(again)
    assert definition_fingerprint(turco) != definition_fingerprint(law_definition("turco+no_tension"))
    assert definition_fingerprint(turco) != definition_fingerprint(law_definition("mcnamara"))


# --- ncstab info -------------------------------------------------------------------------------

LONG_DESCRIPTION = ("A sweep of the stiffness ratio with nine values, one of them with more than six "
                    "significant digits, and a description long enough to be wrapped over two lines")

SWEPT_STUDY = f"""
[study]
name = "swept"
description = "{LONG_DESCRIPTION}"
[system]
alpha0 = "pi/4"
secondary_contacts = "ignore"
[laws]
names = ["mcnamara", "cundall_strack"]
[parameters]
gamma = [0.123456789, 0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0, 2.5]
F2_lateral = [0.0, 0.25]
[[loading]]
hold = {{ F1 = 0.0 }}
drive = {{ F2 = "F2_lateral" }}
[[loading]]
hold = {{ F2 = "current" }}
drive = {{ D1 = 0.05 }}
"""


@pytest.fixture(scope="module")
def swept_archive(tmp_path_factory) -> Path:
    """A 36-case archive (2 laws x 9 gamma x 2 F2*), written by ncstab run (with the
    session's cache: its compiled loops, and the study remembered valid there)."""
    folder = tmp_path_factory.mktemp("swept")
    study = folder / "swept.toml"
    study.write_text(SWEPT_STUDY)
    output = folder / "swept.nc"
    assert main(["run", str(study), "-o", str(output), "--quiet"]) in (0, 1)
    return output


@pytest.fixture
def info_text(swept_archive, cache, capsys) -> str:
    assert main(["info", str(swept_archive)]) == 0
    return capsys.readouterr().out


def test_plot_imports_neither_sympy_nor_the_engine(swept_archive, tmp_path):
    """``ncstab plot`` draws what the archive stores: the symbolic layer (sympy, a
    second of import) and the path engine (numba) stay out of its process."""
    # the cache ncstab run used (the session's): the run remembered its study as valid,
    # so the archive's check does not parse it again (which needs the law catalogue, sympy)
    env = dict(os.environ, MPLBACKEND="Agg")
    imported = _imported_after(["plot", str(swept_archive), "--directory", str(tmp_path)], env)
    assert {"xarray", "matplotlib"} <= set(imported)  # it did draw
    assert not {"sympy", "numba"} & set(imported)
    assert sorted(path.name for path in tmp_path.glob("*.png"))


def test_settle_freezes_only_inside_a_command_and_the_command_unfreezes_at_its_end():
    """``ncstab.heap``: outside a command (ncstab as a library) the collector is left
    alone; inside, what settle() froze goes back to the collector when the command ends."""
    import gc

    from ncstab.heap import settle, settled_heap

    assert gc.get_freeze_count() == 0
    settle()
    assert gc.get_freeze_count() == 0
    with settled_heap():
        with settled_heap():  # nested: only the outermost end unfreezes
            settle()
            assert gc.get_freeze_count() > 0
        assert gc.get_freeze_count() > 0
    assert gc.get_freeze_count() == 0


def test_plot_freezes_the_imports_while_drawing_and_leaves_nothing_frozen(swept_archive, tmp_path, monkeypatch):
    """``ncstab plot`` settles the heap after its imports (ncstab.heap), before drawing,
    and leaves the collector as it found it."""
    import gc

    from ncstab.plotting import draw as draw_module

    frozen_while_drawing = []
    original = draw_module.draw_figures

    def drawing(*args, **kwargs):
        frozen_while_drawing.append(gc.get_freeze_count())
        return original(*args, **kwargs)

    monkeypatch.setattr(draw_module, "draw_figures", drawing)
    monkeypatch.setattr("ncstab.plotting.draw_figures", drawing)
    assert main(["plot", str(swept_archive), "--directory", str(tmp_path)]) == 0
    assert frozen_while_drawing and frozen_while_drawing[0] > 10_000  # the imports' objects
    assert gc.get_freeze_count() == 0


def test_plot_does_not_import_dask_array_where_dask_is_installed(swept_archive, tmp_path):
    """ncstab.dask_probe: xarray's probe for dask arrays is answered without importing
    dask.array (0.8 s), and the figures are drawn."""
    pytest.importorskip("dask")
    script = textwrap.dedent(f"""
        import contextlib, io, sys
        from ncstab.cli import main
        with contextlib.redirect_stdout(io.StringIO()):
            code = main(["plot", {str(swept_archive)!r}, "--directory", {str(tmp_path)!r}])
        print(code, "dask.array" in sys.modules, "xarray" in sys.modules)
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, MPLBACKEND="Agg"), check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["0", "False", "True"]
    assert len(list(tmp_path.glob("*.png"))) >= 2


def test_xarray_still_tells_dask_arrays_after_the_probe_is_deferred():
    """After defer_dask_array_import, xarray's answers are the ones it gives without it: a
    numpy array is not a dask array (and dask.array is not imported to say so); once dask.array
    is imported, its arrays stay lazy in xarray, masked ones are filled, and the probe's class
    is dask's for isinstance and issubclass."""
    pytest.importorskip("dask")
    script = textwrap.dedent("""
        import sys
        import numpy as np
        import xarray as xr
        from xarray.namedarray import pycompat
        from ncstab.dask_probe import DeferredDaskArray, defer_dask_array_import
        assert defer_dask_array_import()
        assert not defer_dask_array_import()  # once
        plain = xr.Variable(("x",), np.arange(3.0))
        assert "dask.array" not in sys.modules and not isinstance(plain.data, DeferredDaskArray)
        import dask.array as da
        assert pycompat.array_type("dask") == (DeferredDaskArray,)
        lazy = xr.DataArray(da.arange(4.0, chunks=2), dims="x")
        assert lazy.chunks == ((2, 2),) and isinstance(lazy.data, DeferredDaskArray)
        assert issubclass(da.Array, DeferredDaskArray) and not issubclass(np.ndarray, DeferredDaskArray)
        masked = da.ma.masked_array(np.arange(4.0), mask=[0, 1, 0, 0], chunks=2)
        filled = xr.Variable(("x",), masked).compute().values
        assert np.isnan(filled[1]) and filled[2] == 2.0, filled
        assert str(pycompat.mod_version("dask")) == __import__("dask").__version__
        print("ok")
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"


def test_info_lines_fit_in_100_characters(info_text):
    lines = info_text.splitlines()
    assert max(len(line) for line in lines) <= LINE_WIDTH
    assert any(line.startswith("    ") and "wrapped" in line for line in lines), "the description is wrapped"


def test_info_summarises_long_sweeps_and_lists_short_ones(info_text):
    assert "  sweep gamma: 9 values from 0.123457 to 2.5\n" in info_text
    assert "  sweep F2_lateral: [0, 0.25]\n" in info_text


def test_info_prints_numbers_to_6_significant_digits(info_text):
    assert "alpha0 = 0.785398" in info_text and "0.123457" in info_text
    assert "0.123456789" not in info_text.replace(LONG_DESCRIPTION, "")


def test_info_summarises_each_law(info_text, swept_archive):
    lines = info_text.splitlines()
    assert "  cases: 36" in lines
    for name, law_class in [("mcnamara", "hyperelastic"), ("cundall_strack", "strongly hypoelastic")]:
        at = lines.index(f"  law {name} ({law_class}):")
        assert lines[at + 1] == "    cases: 18"
        assert lines[at + 2].startswith("    finished: ")
    with open_study_lazily(swept_archive) as dataset:
        statuses = np.asarray(dataset["status"].values)
        per_law = [int(np.sum(statuses[k] == "finished")) for k in range(2)]
    finished = [line for line in lines if line.startswith("    finished: ")]
    assert finished == [f"    finished: {count}" for count in per_law]


def test_info_reads_without_xarray_what_xarray_reads(swept_archive, cache):
    with open_archive_contents(swept_archive) as contents:
        quick = archive_summary(contents, swept_archive)
    with open_study_lazily(swept_archive) as dataset:
        assert archive_summary(dataset, swept_archive) == quick


def test_info_imports_neither_xarray_nor_sympy_once_the_study_is_known(swept_archive, cache):
    env = dict(os.environ, NCSTAB_CACHE_DIR=str(cache))
    first = _imported_after(["info", str(swept_archive)], env)  # parses the study once: sympy
    assert "xarray" not in first and "scipy" not in first
    assert _imported_after(["info", str(swept_archive)], env) == []


def test_info_cuts_a_long_failure_message_to_the_line_width():
    message = "Newton did not converge: " + "residual too large " * 10
    dataset = xr.Dataset({"status": ("law", ["failed:newton", "finished"]), "message": ("law", [message, ""])})
    lines = status_lines(dataset)
    assert lines[:2] == ["  cases: 2", "  finished: 1"]
    assert lines[2].startswith("  FAILED (newton): 1 -- e.g. Newton did not converge") and lines[2].endswith("...")
    assert max(len(line) for line in lines) == LINE_WIDTH


def test_swept_values_list_up_to_eight_values_then_summarise():
    assert swept_values(np.array([0.5, 2.0])) == "[0.5, 2]"
    assert swept_values(np.linspace(0.1, 2.0, 8)) == "[0.1, 0.371429, 0.642857, 0.914286, 1.18571, 1.45714, 1.72857, 2]"
    assert swept_values(np.linspace(0.1, 2.0, 64)) == "64 values from 0.1 to 2"
    assert swept_values(np.array(["a", "b"])) == "[a, b]"


def test_a_parsed_study_is_remembered_valid_and_a_rejected_one_is_not(cache):
    """parse_study remembers every text it validates (so archives of it are checked without
    parsing it again); a text it rejects is never remembered, and an archive carrying it is
    refused as before."""
    from ncstab.studies import StudyFileError, parse_study
    from ncstab.studies.errors import ArchiveError
    from ncstab.studies.verification import VALID_STUDIES_KIND, _study_key, check_study_text

    from ncstab.cache import read_entry

    parse_study(SWEPT_STUDY)
    assert read_entry(VALID_STUDIES_KIND, _study_key(SWEPT_STUDY)) == {"valid": True}
    bad = SWEPT_STUDY.replace('names = ["mcnamara", "cundall_strack"]', 'names = ["no_such_law"]')
    with pytest.raises(StudyFileError):
        parse_study(bad)
    assert read_entry(VALID_STUDIES_KIND, _study_key(bad)) is None
    with pytest.raises(ArchiveError, match="not a valid study file"):
        check_study_text(bad, "archive.nc")
    assert read_entry(VALID_STUDIES_KIND, _study_key(bad)) is None


@pytest.mark.parametrize(("environment", "advised"), [(None, False), ("1", True), ("0", False)])
def test_commands_switch_numpys_huge_page_advice_off_unless_the_environment_sets_it(
    swept_archive, environment, advised
):
    """ncstab.cli.advise_numpy_memory: a command run in a fresh process imports numpy with
    its transparent-huge-page advice off (its first touches of memory stalled for seconds
    on a virtual machine), unless NUMPY_MADVISE_HUGEPAGE says otherwise."""
    script = textwrap.dedent(f"""
        import contextlib, io
        from ncstab.cli import main
        with contextlib.redirect_stdout(io.StringIO()):
            code = main(["info", {str(swept_archive)!r}])
        import numpy
        core = getattr(numpy, "_core", None) or numpy.core  # numpy 2, numpy 1.26
        print(code, core.multiarray._get_madvise_hugepage())
    """)
    env = {key: value for key, value in os.environ.items() if key != "NUMPY_MADVISE_HUGEPAGE"}
    if environment is not None:
        env["NUMPY_MADVISE_HUGEPAGE"] = environment
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120,
                          env=env, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["0", str(advised)]
