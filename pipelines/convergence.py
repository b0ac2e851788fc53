"""DVC stage ``convergence``: the convergence report of the campaigns in ``convergence_run``.

Reads ``label`` (labelling parameters, less ``min_samples``), ``convergence`` (the
recommendation rule) and ``convergence_run`` (campaigns, worker processes) from
params.yaml; all logic lives in :mod:`ofbe_model.convergence_report`.
"""

from __future__ import annotations

import sys

import yaml

from ofbe_model.convergence_report import main as convergence_main


def main(params_file: str = "params.yaml") -> int:
    with open(params_file, encoding="utf-8") as fh:
        run = yaml.safe_load(fh)["convergence_run"]
    return convergence_main([*(f"raw/{name}" for name in run["campaigns"]), "--out", "reports/convergence",
                             "--params", params_file, "--jobs", str(run["jobs"])])


if __name__ == "__main__":
    sys.exit(main())
