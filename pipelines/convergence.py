"""DVC stage ``convergence``: the convergence report of the campaigns in ``convergence_run``.

Reads ``label`` (labelling parameters, less ``min_samples``), ``convergence`` (the
recommendation rule) and ``convergence_run`` (campaigns, worker processes, an optional
``scheduler``) from
params.yaml; all logic lives in :mod:`ofbe_data.reports.convergence`.
"""

from __future__ import annotations

import sys

from ofbe_data.cli.convergence import main as convergence_main
from ofbe_data.io.pipeline_params import load_params, resolved_params_file, timed


def main(params_file: str = "params.yaml") -> int:
    run = load_params(params_file)["convergence_run"]
    with resolved_params_file(params_file) as resolved:
        return convergence_main([*(f"raw/{name}" for name in run["campaigns"]), "--out",
                                 "reports/convergence", "--params", resolved, "--jobs", str(run["jobs"]),
                                 "--scheduler", str(run.get("scheduler", "processes"))])


if __name__ == "__main__":
    with timed("convergence"):
        code = main()
    sys.exit(code)
