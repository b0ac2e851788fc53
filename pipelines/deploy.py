"""DVC stage ``deploy``: the deployable OFBENet and gravity-prior of every benchmark dataset,
fitted on all its windows, with model cards that quote the benchmark (models/<dataset>/).

Reads ``train`` (OFBENet parameters), ``train_run`` (fits at once, an optional
``scheduler``) and ``benchmark_run`` (which datasets) from params.yaml; all logic lives in
:mod:`ofbe_model.deploy.final`.
"""

from __future__ import annotations

import sys

from ofbe_data.io.pipeline_params import load_params, resolved_params_file, timed
from ofbe_model.deploy.final import train_finals
from ofbe_model.ofbenet.training import read_params


def main(params_file: str = "params.yaml") -> int:
    params_all = load_params(params_file)
    run = params_all["benchmark_run"]["protocols"]
    train_run = params_all.get("train_run", {})
    datasets = sorted({name for names in run.values() for name in names})
    reports = [f"reports/benchmark/{protocol}/benchmark.json" for protocol in run]
    with resolved_params_file(params_file) as resolved:
        params = read_params(resolved)
        folders = train_finals([f"processed/datasets/{name}" for name in datasets], "models", params, reports,
                               jobs=int(train_run.get("jobs", 1)),
                               scheduler=str(train_run.get("scheduler", "processes")))
    for folder in folders:
        print(f"deploy: {folder}/final.keras, gravity-prior.json, MODEL_CARD.md", file=sys.stderr)
    return 0


if __name__ == "__main__":
    with timed("deploy"):
        code = main()
    sys.exit(code)
