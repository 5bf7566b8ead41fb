"""The ``ncstab`` command line: a thin layer, tested for what it prints."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

import ncstab
from ncstab.cli import main
from strategies import BASE_LAWS, EXPECTED_CLASS


@pytest.fixture(autouse=True)
def _cache_in_a_temporary_directory(tmp_path, monkeypatch):
    """``ncstab laws`` keeps the classes it derives in the cache directory: here a temporary one."""
    monkeypatch.setenv("NCSTAB_CACHE_DIR", str(tmp_path / "cache"))


def _table_rows(text: str) -> dict[str, list[str]]:
    """Rows of the law table by law name (columns are separated by 2+ spaces)."""
    rows = {}
    for line in text.splitlines():
        cells = re.split(r"\s{2,}", line.strip())
        if cells and (cells[0].split("+")[0] in EXPECTED_CLASS):
            rows[cells[0]] = cells
    return rows


def test_laws_prints_every_law_with_its_class(capsys):
    assert main(["laws"]) == 0
    out = capsys.readouterr().out
    rows = _table_rows(out)
    assert set(rows) == set(BASE_LAWS)
    for name, cells in rows.items():
        assert cells[1] == EXPECTED_CLASS[name], cells
    assert "Eq. (8)" in out and "fails" in out


def test_laws_all_adds_the_no_tension_variants(capsys):
    assert main(["laws", "--all"]) == 0
    rows = _table_rows(capsys.readouterr().out)
    assert len(rows) == 2 * len(BASE_LAWS)
    for name in BASE_LAWS:
        assert rows[f"{name}+no_tension"][1] == EXPECTED_CLASS[name]


def test_version(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"ncstab {ncstab.__version__}"


def test_no_command_prints_help(capsys):
    assert main([]) == 0
    assert "usage: ncstab" in capsys.readouterr().out


def test_unknown_command_exits_with_usage_error(capsys):
    with pytest.raises(SystemExit) as info:
        main(["lwas"])
    assert info.value.code == 2
    assert "invalid choice" in capsys.readouterr().err


def test_module_entry_point_runs_in_a_subprocess():
    completed = subprocess.run(
        [sys.executable, "-m", "ncstab", "laws"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert completed.returncode == 0, completed.stderr
    rows = _table_rows(completed.stdout)
    assert {name: cells[1] for name, cells in rows.items()} == EXPECTED_CLASS
