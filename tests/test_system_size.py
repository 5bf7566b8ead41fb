"""The size of a study's system before anything is built: its dofs from its settings, the
estimate said for a long run, the refusal (exit code 2, naming the setting) of a system the
memory cannot hold, and a count so large it would exhaust memory while being checked."""

from __future__ import annotations

import pytest

from ncstab.cli import main
from ncstab.studies import load_study
from ncstab.studies import system_size
from ncstab.systems.registry import MOST_DOFS, SYSTEMS, system_definition


@pytest.mark.parametrize(
    ("name", "settings"),
    [("diamond", {}), ("diamond", {"reduction": "axes"}), ("ring", {"grains": 6}), ("ring", {"grains": 40}),
     ("column", {"links": 5}), ("column", {"links": 30}), ("ziegler", {}), ("ziegler", {"load": "dead"})],
)
def test_dof_count_from_settings_equals_the_built_systems(name, settings):
    kind = SYSTEMS[name]
    built = system_definition(name, tuple(settings.items()))
    assert kind.dof_count(**kind.check_settings(settings)) == built.n_dof


def _ring_study(folder, grains: int, name: str = "ring_size"):
    holds = ", ".join(f"F{k} = 0.0" for k in range(2, grains + 1))
    path = folder / f"{name}.toml"
    path.write_text(
        f'[study]\nname = "{name}"\n[system]\nname = "ring"\ngrains = {grains}\nsecondary_contacts = "ignore"\n'
        f'[laws]\nnames = ["mcnamara"]\n[parameters]\ngamma = 0.5\n[[loading]]\nhold = {{ {holds} }}\n'
        f'drive = {{ D1 = 0.05 }}\n[output]\nfigures = []\n'
    )
    return path


def test_the_cost_grows_with_the_system_and_is_none_for_a_derived_one(tmp_path):
    assert system_size.system_cost(load_study(_ring_study(tmp_path, 6, "ring6"))) is None
    small = system_size.system_cost(load_study(_ring_study(tmp_path, 40, "ring40")))
    large = system_size.system_cost(load_study(_ring_study(tmp_path, 400, "ring400")))
    assert small.n == 40 and large.n == 400
    assert large.seconds > small.seconds > 0 and large.memory_bytes > small.memory_bytes > 0


def test_a_system_larger_than_the_memory_is_refused_naming_grains(tmp_path, monkeypatch, capsys):
    import ncstab.sizes

    study = _ring_study(tmp_path, 40)
    monkeypatch.setattr(ncstab.sizes, "available_memory", lambda: 100_000)
    output = tmp_path / "out.nc"
    assert main(["run", str(study), "-o", str(output), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "[system] grains" in err and "memory" in err and "40 dofs" in err
    assert not output.exists()


def test_a_long_run_says_its_estimate_before_it_starts(tmp_path, monkeypatch, capsys):
    study = load_study(_ring_study(tmp_path, 40))
    monkeypatch.setattr(system_size, "SECONDS_PER_STATE", (1000.0, 0.0, 0.0))
    cost = system_size.check_system_size(study)
    err = capsys.readouterr().err
    from ncstab.sizes import readable_duration

    assert cost.seconds == pytest.approx(1000.0 * cost.states)
    assert "40 dofs" in err and "(estimate)" in err and f"about {readable_duration(cost.seconds)}" in err


def test_a_count_that_would_exhaust_memory_while_checked_is_refused(tmp_path, capsys):
    path = tmp_path / "huge.toml"
    path.write_text(
        f'[study]\nname = "huge"\n[system]\nname = "ring"\ngrains = {MOST_DOFS + 1}\n[laws]\nnames = ["mcnamara"]\n'
        '[parameters]\ngamma = 0.5\n[[loading]]\ndrive = { D1 = 0.1 }\n'
    )
    assert main(["run", str(path), "-o", str(tmp_path / "huge.nc"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "grains" in err and "10,000,000" in err
