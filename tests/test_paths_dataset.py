"""The labelled Dataset of a path study (``Path.to_dataset``).

Checked against the Path it comes from and against identities of the seed:
K = K_sym + K_skew; K symmetric for the hyperelastic McNamara law (Eq. 41);
K21 - K12 = 2 T / l for Cundall--Strack (Eq. 38); indicators equal to numpy
linear algebra on K.
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from ncstab.paths import PathOptions, SystemSpec, follow

LAWS = ["mcnamara", "cundall_strack"]
GAMMAS = [0.5, 2.0]
ALPHA0S = [0.7, 0.8, 0.9]
F2_PRELOAD = 0.3
PROGRAMME = [
    {"hold": {"F1": 0.0}, "drive": {"F2": "F2l"}},
    {"hold": {"F2": "current"}, "drive": {"D1": 0.2}},
]
SWEEP_DIMS = ("law", "gamma", "alpha0")
STEP_DIMS = SWEEP_DIMS + ("step",)
#: Variables without units (strings).
UNITLESS = {"status", "message"}


@pytest.fixture(scope="module")
def path():
    """12 cases, two stages each, coarse steps (about 2 s)."""
    return follow(
        SystemSpec(secondary_contacts="ignore"),
        LAWS,
        PROGRAMME,
        {"gamma": GAMMAS, "alpha0": ALPHA0S, "F2l": F2_PRELOAD},
        PathOptions(max_step=0.05),
    )


@pytest.fixture(scope="module")
def dataset(path):
    return path.to_dataset()


def stored(dataset: xr.Dataset, name: str) -> np.ndarray:
    """Values of a step variable at the stored states only (padding dropped)."""
    values = dataset[name].values
    mask = np.arange(dataset.sizes["step"]) < dataset["n_steps"].values[..., None]
    return values[mask]


def test_dimensions_are_law_sweep_step_dof_i_j_in_order(dataset):
    assert tuple(dataset.dims) == SWEEP_DIMS + ("step", "dof", "i", "j")
    assert dataset["u"].dims == STEP_DIMS + ("dof",)
    assert dataset["F"].dims == STEP_DIMS + ("dof",)
    assert dataset["K"].dims == STEP_DIMS + ("i", "j")
    for name in (
        "alpha",
        "l",
        "N",
        "T",
        "s",
        "stage",
        "lam",
        "work",
        "det_K",
        "hill",
        "mixed_control",
    ):
        assert dataset[name].dims == STEP_DIMS, name
    for name in ("n_steps", "status", "message", "limit_point_s", "secondary_contact_stage"):
        assert dataset[name].dims == SWEEP_DIMS, name
    assert dataset["secondary_contact_u"].dims == SWEEP_DIMS + ("dof",)
    assert dataset["hill_loss_K"].dims == SWEEP_DIMS + ("i", "j")
    # Swept parameters are coordinates, in the given order; fixed ones are attributes.
    assert dataset["law"].values.tolist() == LAWS
    np.testing.assert_array_equal(dataset["gamma"].values, GAMMAS)
    np.testing.assert_array_equal(dataset["alpha0"].values, ALPHA0S)
    assert dataset.attrs["parameter_F2l"] == F2_PRELOAD
    assert dataset["law_class"].values.tolist() == ["hyperelastic", "strongly hypoelastic"]


def test_every_variable_is_described(dataset):
    for name, variable in dataset.data_vars.items():
        attrs = variable.attrs
        assert attrs.get("long_name"), name
        assert attrs.get("description"), name
        if name not in UNITLESS:
            assert "units" in attrs, name
    assert dataset["alpha"].attrs["units"] == "rad"
    for name in dataset.coords:
        assert dataset[name].attrs.get("long_name"), name


def test_dataset_equals_the_path_it_comes_from(path, dataset):
    for law_index, law in enumerate(LAWS):
        for gamma in GAMMAS:
            for alpha0 in ALPHA0S:
                result, k = path.case(law, gamma=gamma, alpha0=alpha0)
                where = {"law": law, "gamma": gamma, "alpha0": alpha0}
                case = dataset.sel(where)
                n = int(result.n_steps[k])
                assert int(case["n_steps"]) == n
                assert str(case["status"].values) == result.status[k] == "finished"
                assert str(case["message"].values) == result.message[k]
                for name in ("u", "F", "alpha", "l", "T", "s", "K"):
                    np.testing.assert_array_equal(case[name].values[:n], result.steps[name][k, :n])
                np.testing.assert_array_equal(
                    case["stage"].values[:n], result.steps["stage"][k, :n]
                )
                contact = result.events["secondary_contact"]
                assert bool(np.isfinite(case["secondary_contact_s"])) == bool(contact["found"][k])
                np.testing.assert_array_equal(case["secondary_contact_u"].values, contact["u"][k])
    assert path.status.shape == (len(LAWS), len(GAMMAS), len(ALPHA0S))


def test_n_steps_is_the_length_of_the_non_nan_prefix(dataset):
    n_steps = dataset["n_steps"].values
    s = dataset["s"].values
    filled = np.isfinite(s)
    assert np.all(filled.sum(axis=-1) == n_steps)
    assert np.all(filled == (np.arange(dataset.sizes["step"]) < n_steps[..., None]))
    assert dataset.sizes["step"] == n_steps.max()
    assert np.all(n_steps > 5)
    # Padding: NaN for numbers, -1 for the stage index.
    assert np.all(dataset["stage"].values[~filled] == -1)
    assert np.all(np.isnan(dataset["u"].values[~filled]))
    # Arclength increases within a stage; a stage starts where the previous one
    # ended (the boundary state is stored once per stage, at the same s).
    stage = dataset["stage"].values
    u = dataset["u"].values
    for index in np.ndindex(n_steps.shape):
        n = n_steps[index]
        ds, dstage = np.diff(s[index][:n]), np.diff(stage[index][:n])
        assert set(stage[index][:n]) == {0, 1} and np.all(dstage >= 0)
        assert np.all(ds[dstage == 0] > 0)
        boundary = np.flatnonzero(dstage)
        assert boundary.size == 1
        assert ds[boundary[0]] == 0
        np.testing.assert_array_equal(u[index][boundary[0]], u[index][boundary[0] + 1])


def test_k_is_the_sum_of_its_symmetric_and_skew_parts(dataset):
    # Two halvings and an addition: exact to a few ulps of O(1) entries.
    total = stored(dataset, "K_sym") + stored(dataset, "K_skew")
    np.testing.assert_allclose(total, stored(dataset, "K"), rtol=0, atol=1e-14)
    np.testing.assert_array_equal(
        stored(dataset, "K_sym"), np.swapaxes(stored(dataset, "K_sym"), -1, -2)
    )
    np.testing.assert_array_equal(
        stored(dataset, "K_skew"), -np.swapaxes(stored(dataset, "K_skew"), -1, -2)
    )


def test_mcnamara_is_symmetric_and_cundall_strack_skew_is_2t_over_l(dataset):
    mcnamara = dataset.sel(law="mcnamara")
    mask = np.arange(dataset.sizes["step"]) < mcnamara["n_steps"].values[..., None]
    # Seed Eq. (41): K12 = K21 on the equilibrium path.  Exact identity for the
    # total form (K is the Hessian of Eq. 19 plus the load terms): rounding only.
    np.testing.assert_allclose(mcnamara["K_skew"].values[mask], 0.0, rtol=0, atol=1e-12)
    cundall = dataset.sel(law="cundall_strack")
    mask = np.arange(dataset.sizes["step"]) < cundall["n_steps"].values[..., None]
    stiffness = cundall["K"].values[mask]
    # Seed Eq. (38): K21 - K12 = (F1 sin(a) - F2 cos(a)) / l = 2 T / l (Eq. 4).
    # T is integrated (rtol 1e-10) and F recomputed from it: the identity holds
    # to rounding; 1e-10 as in the issue.
    expected = 2 * cundall["T"].values[mask] / cundall["l"].values[mask]
    np.testing.assert_allclose(
        stiffness[:, 1, 0] - stiffness[:, 0, 1], expected, rtol=0, atol=1e-10
    )
    assert np.abs(expected).max() > 0.05  # the paths do shear the contacts


def test_indicators_agree_with_numpy_linear_algebra(dataset):
    stiffness = stored(dataset, "K")
    # det of a 2x2 and eigenvalues of a symmetric 2x2: a few ulps of |K|^2, |K|.
    np.testing.assert_allclose(
        stored(dataset, "det_K"), np.linalg.det(stiffness), rtol=0, atol=1e-13
    )
    smallest = np.linalg.eigvalsh(0.5 * (stiffness + np.swapaxes(stiffness, -1, -2)))[:, 0]
    np.testing.assert_allclose(stored(dataset, "hill"), smallest, rtol=0, atol=1e-13)
    # Growth rate max Re s of I s^2 + K (grains of equal mass): s = +-sqrt(-lambda(K)).
    # Compared squared: near a zero eigenvalue of K the root amplifies rounding.
    growth = np.abs(np.sqrt(-np.linalg.eigvals(stiffness).astype(complex)).real).max(axis=-1)
    np.testing.assert_allclose(stored(dataset, "flutter") ** 2, growth**2, rtol=1e-10, atol=1e-13)
    # Mixed control: F1 and F2 both prescribed in stage 1 (det K), F2 only in
    # stage 2 (K22, seed Eq. 35).
    stage = stored(dataset, "stage")
    expected = np.where(stage == 0, np.linalg.det(stiffness), stiffness[:, 1, 1])
    np.testing.assert_allclose(stored(dataset, "mixed_control"), expected, rtol=0, atol=1e-13)
    # Normalised second-order work along the path: a cosine.
    assert np.all(np.abs(stored(dataset, "d2W")) <= 1 + 1e-12)


def test_dataset_round_trips_through_netcdf(dataset, tmp_path):
    file = tmp_path / "path.nc"
    dataset.to_netcdf(file)
    with xr.open_dataset(file) as back:
        back.load()
    xr.testing.assert_identical(back, dataset)
