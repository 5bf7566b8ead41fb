"""The ``ncstab run / plot / info`` commands, and every shipped study run end to end."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest

from ncstab.cli import main
from ncstab.paths.programme import EVENTS
from ncstab.studies import load_study, open_study

ROOT = Path(__file__).resolve().parents[1]
SEED_STUDIES = sorted((ROOT / "studies" / "seed").glob("*.toml"))
# stability_diagram.toml (16,384 cases, about a minute) runs on a reduced grid in test_stability_diagram.py.
ALL_STUDIES = SEED_STUDIES + sorted(p for p in (ROOT / "studies").glob("*.toml") if p.stem != "stability_diagram")
BAD_STUDIES = sorted((ROOT / "tests" / "data" / "bad_studies").glob("*.toml"))
CONTRACT = ["u", "F", "s", "stage", "K", "K_sym", "K_skew", "det_K",
            "hill", "d2W", "flutter", "status", "n_steps"]
#: The interaction variables of a granular system, of a system of springs.
GRANULAR, SPRINGS = ["alpha", "l", "N", "T"], ["theta", "moment"]

TINY_STUDY = """
[study]
name = "tiny"
description = "two laws, two gammas, one short stage"
[system]
alpha0 = "pi/4"
secondary_contacts = "ignore"
[laws]
names = ["mcnamara", "cundall_strack"]
[parameters]
gamma = [0.5, 2.0]
[[loading]]
hold = { F2 = 0.0 }
drive = { D1 = 0.05 }
"""


def test_seed_studies_cover_figures_3_to_15():
    """One study per figure: names fig<first>[_<last>]_..., e.g. fig03_05_... covers 3-5."""
    numbers = set()
    for path in SEED_STUDIES:
        parts = path.stem.split("_")
        first = int(parts[0].removeprefix("fig"))
        last = int(parts[1]) if parts[1].isdigit() else first
        numbers.update(range(first, last + 1))
    assert numbers == set(range(3, 16))


@pytest.mark.slow
@pytest.mark.parametrize("study_path", ALL_STUDIES, ids=lambda p: p.stem)
def test_every_shipped_study_runs_and_draws(study_path, tmp_path, capsys):
    """Each study runs through the command line, its archive holds the contract
    variables, and every figure it asks for is a non-trivial PNG."""
    output = tmp_path / f"{study_path.stem}.nc"
    assert main(["run", str(study_path), "-o", str(output), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert f"wrote {output}" in printed and "FAILED" not in printed
    ds = open_study(output)
    interactions = SPRINGS if "moment" in ds else GRANULAR
    # a [boundary] study traces curves, not paths (docs/boundaries.md): its own contract
    contract = (CONTRACT + interactions + (["load"] if "load_parameter" in ds.attrs else [])
                if "boundary_event" not in ds.attrs else
                [f"boundary_{ds.attrs['boundary_parameter']}", "boundary_u", "boundary_F", "boundary_note", "n_steps"])
    for name in contract:
        assert name in ds, name
        if name not in ("status",):
            assert {"long_name", "description"} <= set(ds[name].attrs), name
    for event in EVENTS if "boundary_event" not in ds.attrs else ():
        assert f"{event}_u" in ds and f"{event}_F" in ds and f"{event}_{interactions[0]}" in ds
        assert (f"{event}_load" in ds) == ("load_parameter" in ds.attrs)
    assert ds.attrs["study"] == study_path.read_text()
    assert ds.attrs["law_class"] and ds.attrs["ncstab_version"]
    statuses = set(np.unique(ds["status"].values.astype(str)))
    assert all(s == "finished" or s.startswith("stopped:") for s in statuses), statuses  # none failed
    study = load_study(study_path)
    for kind in study.figures:
        png = tmp_path / f"{output.stem}_{kind}.png"
        assert png.exists(), png
        image = mpimg.imread(png)
        assert image.shape[0] >= 600 and image.shape[1] >= 800
        rgb = image[..., :3].reshape(-1, 3)
        # Content, not a blank canvas: ink covers a few percent, in several colours.
        assert (rgb.sum(axis=1) < 2.5).mean() > 0.02
        assert len(np.unique((rgb * 255).astype(np.uint8), axis=0)) > 50


def test_run_plot_info_round_trip(tmp_path, capsys):
    study = tmp_path / "tiny.toml"
    study.write_text(TINY_STUDY)
    output = tmp_path / "out" / "tiny.nc"
    assert main(["run", str(study), "-o", str(output), "--quiet"]) == 0
    first = open_study(output)
    for png in output.parent.glob("*.png"):
        png.unlink()
    assert main(["plot", str(output)]) == 0
    assert sorted(p.name for p in output.parent.glob("*.png")) == [
        "tiny_load_displacement.png", "tiny_load_rotation.png"]
    capsys.readouterr()
    assert main(["info", str(output)]) == 0
    info = capsys.readouterr().out
    assert "study: tiny" in info and "sweep gamma: [0.5, 2]" in info
    assert "mcnamara (hyperelastic)" in info and "cundall_strack (strongly hypoelastic)" in info
    assert "finished: 4" in info
    # The same study run twice gives identical data variables.
    again = tmp_path / "again.nc"
    assert main(["run", str(study), "-o", str(again), "--quiet"]) == 0
    second = open_study(again)
    for name in first.data_vars:
        np.testing.assert_array_equal(first[name].values, second[name].values, err_msg=name)


def test_run_exits_1_when_a_case_fails_and_keeps_the_others(tmp_path, capsys):
    study = tmp_path / "partly.toml"
    # alpha0 = 0.4 with active secondary contacts: the side grains overlap at rest,
    # so holding F2 = 0 fails for that case only.
    study.write_text(TINY_STUDY.replace('alpha0 = "pi/4"\nsecondary_contacts = "ignore"', "").replace(
        "gamma = [0.5, 2.0]", "gamma = 0.5\nalpha0 = [0.4, 0.785]"))
    output = tmp_path / "partly.nc"
    assert main(["run", str(study), "-o", str(output), "--quiet"]) == 1
    printed = capsys.readouterr().out
    assert "FAILED (bad_stage_start)" in printed
    ds = open_study(output)
    status = ds["status"].astype(str).values
    assert (status[:, 0] == "failed:bad_stage_start").all() and (status[:, 1] == "finished").all()
    assert "overlap at rest" in str(ds["message"].values[0, 0])


@pytest.mark.parametrize("bad", BAD_STUDIES[:24], ids=lambda p: p.stem)
def test_bad_study_exits_2_names_the_field_and_writes_nothing(bad, tmp_path, capsys, monkeypatch):
    expected = [line.split(":", 1)[1].strip() for line in bad.read_text().splitlines() if line.startswith("# expect:")]
    monkeypatch.chdir(tmp_path)
    copy = tmp_path / bad.name
    shutil.copy(bad, copy)
    assert main(["run", str(copy), "-o", str(tmp_path / "never.nc")]) == 2
    err = capsys.readouterr().err
    for field in expected:
        assert field in err
    assert sorted(p.name for p in tmp_path.iterdir()) == [bad.name]  # nothing written, no temporaries


def test_bad_study_among_good_ones_runs_nothing(tmp_path, capsys):
    good = tmp_path / "tiny.toml"
    good.write_text(TINY_STUDY)
    bad = tmp_path / "bad.toml"
    bad.write_text(TINY_STUDY.replace('names = ["mcnamara", "cundall_strack"]', 'names = ["mcnamra"]'))
    assert main(["run", str(good), str(bad)]) == 2
    assert "did you mean 'mcnamara'" in capsys.readouterr().err
    assert not (tmp_path / "results").exists() and not Path("results/tiny.nc").exists()


def test_plot_and_info_refuse_a_missing_archive(tmp_path, capsys):
    assert main(["info", str(tmp_path / "none.nc")]) == 2
    assert main(["plot", str(tmp_path / "none.nc")]) == 2
    assert "no such archive" in capsys.readouterr().err


def test_console_script_runs_a_study(tmp_path):
    study = tmp_path / "tiny.toml"
    study.write_text(TINY_STUDY)
    output = tmp_path / "tiny.nc"
    done = subprocess.run([sys.executable, "-m", "ncstab", "run", str(study), "-o", str(output)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert output.exists() and "finished: 4" in done.stdout
    assert "\r" not in done.stderr  # no progress bar when not on a terminal


def test_on_a_terminal_the_run_says_when_it_writes_the_archive(tmp_path, capsys, monkeypatch):
    """No silent pause between the run's bar and the figures' bar: writing the archive
    is announced before it starts, then timed; with --quiet (or off a terminal) not."""
    from ncstab import run_command

    study = tmp_path / "tiny.toml"
    study.write_text(TINY_STUDY)
    output = tmp_path / "tiny.nc"
    monkeypatch.setattr(run_command, "_wants_progress", lambda args: not args.quiet)
    assert main(["run", str(study), "-o", str(output)]) == 0
    lines = capsys.readouterr().err.splitlines()
    writing = [line for line in lines if "writing" in line]
    assert writing[0] == f"ncstab run: tiny: writing {output} ..."
    assert writing[1].startswith(f"ncstab run: tiny: writing {output}: done in ") and writing[1].endswith(" s")
    assert main(["run", str(study), "-o", str(output), "--quiet", "--overwrite"]) == 0
    assert "writing" not in capsys.readouterr().err
