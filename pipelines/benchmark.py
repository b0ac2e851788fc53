"""DVC stage ``benchmark``: every estimator on every fold of each protocol, one report each.

Reads ``benchmark`` (methods, baselines, estimator parameters) and ``benchmark_run``
(protocol → datasets, optional ``jobs`` and ``scheduler``) from params.yaml; all logic lives
in :mod:`ofbe_model.benchmark.runner`.
"""

from __future__ import annotations

import sys

from ofbe_data.io.pipeline_params import load_params, resolved_params_file, timed
from ofbe_model.cli.benchmark import main as benchmark_main


def main(params_file: str = "params.yaml") -> int:
    run = load_params(params_file)["benchmark_run"]
    with resolved_params_file(params_file) as resolved:
        for protocol, campaigns in run["protocols"].items():
            args = [*(f"processed/datasets/{c}" for c in campaigns), "--protocol", protocol,
                    "--out", f"reports/benchmark/{protocol}", "--params", resolved, "--models", "models/cv",
                    "--scheduler", str(run.get("scheduler", "processes"))]
            if "jobs" in run:
                args += ["--jobs", str(run["jobs"])]
            for c in campaigns:
                args += ["--truth", f"raw/{c}/_truth"]
            code = benchmark_main(args)
            if code:
                return code
    return 0


if __name__ == "__main__":
    with timed("benchmark"):
        code = main()
    sys.exit(code)
