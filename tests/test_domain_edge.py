"""A step that leaves the admissible domain is completed up to its last admissible state
(ncstab.paths.domain_edge): the events inside it are located, then the case fails.

The case: McNamara, gamma = 2, alpha0 = 1, F2* = 0.509 applied then held, D1* driven. The path
runs into alpha = pi/2 (left_domain) at s = 5.664, and loses Hill's condition and meets a
limit point at s = 5.6586, 6e-3 before. With steps of 0.01 to 0.05, that point fell in the
piece whose end left the domain, and the piece was dropped with its crossings: no limit point
and no loss of Hill's condition (with steps of 0.005 and 0.1 it lay in an earlier piece and
was found, at the same s).
"""

from __future__ import annotations

import numpy as np
import pytest

from ncstab.studies import parse_study, run_study

STUDY = """
[study]
name = "domain_edge"
[system]
secondary_contacts = "activate"
[laws]
names = ["mcnamara"]
[parameters]
gamma = 2.0
F2_lateral = 0.509090909090909
alpha0 = 1.0
[[loading]]
hold = {{ F1 = 0.0 }}
drive = {{ F2 = "F2_lateral" }}
[[loading]]
hold = {{ F2 = "current" }}
drive = {{ D1 = 0.6 }}
[options]
max_step = {max_step}
"""
#: Where the tight reference (max_step 0.005, rtol 1e-12) locates both events.
EVENT_S = 5.65863959


def _run(max_step: float):
    return run_study(parse_study(STUDY.format(max_step=max_step)))


@pytest.mark.parametrize("max_step", [0.01, 0.02, 0.05])
def test_events_in_the_step_that_leaves_the_domain_are_located(max_step):
    """The limit point and the loss of Hill's condition are found (they were not, before),
    where the reference finds them: 1e-8 in s (event_tol 1e-10, and the integration error of
    a path 5.66 long at rtol 1e-6 and steps up to 0.05)."""
    dataset = _run(max_step)
    assert dataset["status"].values.ravel().tolist() == ["failed:left_domain"]
    for event in ("limit_point", "hill_loss"):
        s = float(dataset[f"{event}_s"].values.ravel()[0])
        assert abs(s - EVENT_S) < 1e-8, (event, s)


def test_the_path_is_stored_up_to_the_edge_of_the_domain_and_no_further():
    """Every stored state is admissible (|alpha| < pi/2, l* > 0); the last lies within
    2 event_tol of the edge in arclength, so within 1e-8 of alpha = pi/2 (d alpha / ds is of
    order 1 there)."""
    dataset = _run(0.02)
    n = int(dataset["n_steps"].values.ravel()[0])
    alpha = dataset["alpha"].values.ravel()[:n]
    assert (np.abs(alpha) < np.pi / 2).all() and (dataset["l"].values.ravel()[:n] > 0).all()
    assert np.pi / 2 - alpha[-1] < 1e-8, np.pi / 2 - alpha[-1]

