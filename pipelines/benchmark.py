"""DVC stage ``benchmark``: every estimator on every fold of each protocol, one report each.

Reads ``benchmark`` (methods, baselines, estimator parameters) and ``benchmark_run``
(protocol → datasets) from params.yaml; all logic lives in :mod:`ofbe_model.benchmark`.
"""

from __future__ import annotations

import sys

import yaml

from ofbe_model.benchmark import main as benchmark_main


def main(params_file: str = "params.yaml") -> int:
    with open(params_file, encoding="utf-8") as fh:
        run = yaml.safe_load(fh)["benchmark_run"]
    for protocol, campaigns in run["protocols"].items():
        args = [*(f"processed/datasets/{c}" for c in campaigns), "--protocol", protocol,
                "--out", f"reports/benchmark/{protocol}", "--params", params_file, "--models", "models"]
        for c in campaigns:
            args += ["--truth", f"raw/{c}/_truth"]
        code = benchmark_main(args)
        if code:
            return code
    return 0


if __name__ == "__main__":
    sys.exit(main())
