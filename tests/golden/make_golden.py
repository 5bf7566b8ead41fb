"""Write the golden archives of ``tests/golden/studies/*.toml`` (``tests/test_golden.py``).

Run once, from the main branch *before* a change that must not alter results
(issue 13: the general model), then never again unless a documented decision
changes the archives::

    python tests/golden/make_golden.py

Each archive is ``run_study`` + ``write_dataset`` of its study with default
engine options (the study's own ``[options]``), so a later run of the same
study must give a Dataset identical to it (``created`` aside).
"""

from __future__ import annotations

import sys
from pathlib import Path

from ncstab.studies import load_study, run_study, write_dataset

HERE = Path(__file__).resolve().parent


def main() -> int:
    for study_file in sorted((HERE / "studies").glob("*.toml")):
        study = load_study(study_file)
        write_dataset(run_study(study), HERE / f"{study.name}.nc")
        print(f"wrote {study.name}.nc")
    return 0


if __name__ == "__main__":
    sys.exit(main())
