"""DVC stage ``train``: OFBENet per benchmark dataset, protocol and fold into models/cv/.

Reads ``train`` (OFBENet parameters), ``train_run`` (parallel fits, an optional
``scheduler``) and ``benchmark_run``
(which protocols run on which datasets) from params.yaml; all logic lives in
:mod:`ofbe_model.ofbenet.training`. Every dataset is trained under each benchmark protocol
it has (its ``fold_<protocol>`` columns, which ``dataset.protocols`` decides).
"""

from __future__ import annotations

import sys

from ofbe_data.io.pipeline_params import load_params, resolved_params_file, timed
from ofbe_model.cli.train import main as train_main


def main(params_file: str = "params.yaml") -> int:
    params = load_params(params_file)
    run = params["benchmark_run"]
    jobs = str(params.get("train_run", {}).get("jobs", 1))
    scheduler = str(params.get("train_run", {}).get("scheduler", "processes"))
    campaigns = list(dict.fromkeys(c for names in run["protocols"].values() for c in names))
    with resolved_params_file(params_file) as resolved:
        # one call: every dataset under each benchmark protocol it has, all fits in one pool
        return train_main([*(f"processed/datasets/{c}" for c in campaigns), "--protocol", *run["protocols"],
                           "--out", "models/cv", "--params", resolved, "--jobs", jobs,
                           "--scheduler", scheduler])


if __name__ == "__main__":
    with timed("train"):
        code = main()
    sys.exit(code)
