"""DVC stage ``deploy``: the deployable OFBENet and gravity-prior of every benchmark dataset,
fitted on all its windows, with model cards that quote the benchmark (models/<dataset>/).

Reads ``train`` (OFBENet parameters), ``train_run`` (fits at once, an optional
``scheduler``), ``benchmark_run`` (which datasets) and ``deploy`` (``max_in_sample_ratio``: the
stage fails when a deployed model's in-sample RMSE on some device exceeds this multiple of the
cross-validated RMSE its card quotes) from params.yaml; all logic lives in
:mod:`ofbe_model.deploy.final`.
"""

from __future__ import annotations

import sys
from pathlib import Path

from ofbe_data.io.pipeline_params import load_params, resolved_params_file, timed
from ofbe_model.deploy.final import MAX_IN_SAMPLE_RATIO, SET_NAME, DeployError, train_finals
from ofbe_model.ofbenet.training import read_params


def main(params_file: str = "params.yaml") -> int:
    params_all = load_params(params_file)
    run = params_all["benchmark_run"]["protocols"]
    train_run = params_all.get("train_run", {})
    datasets = sorted({name for names in run.values() for name in names})
    reports = [f"reports/benchmark/{protocol}/benchmark.json" for protocol in run]
    ratio = float(params_all.get("deploy", {}).get("max_in_sample_ratio", MAX_IN_SAMPLE_RATIO))
    with resolved_params_file(params_file) as resolved:
        params = read_params(resolved)
        try:
            folders = train_finals([f"processed/datasets/{name}" for name in datasets], "models", params,
                                   reports, jobs=int(train_run.get("jobs", 1)),
                                   scheduler=str(train_run.get("scheduler", "processes")),
                                   max_in_sample_ratio=ratio)
        except DeployError as exc:
            print(f"deploy: error: {exc}", file=sys.stderr)
            return 1
    for folder in folders:
        print(f"deploy: {folder}/final.keras, gravity-prior.json, MODEL_CARD.md", file=sys.stderr)
    for name in datasets:
        if (Path("models") / name / SET_NAME).is_file():
            print(f"deploy: models/{name}/{SET_NAME}: one model per device (ofbe-predict models/{name} "
                  "picks each recording's)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    with timed("deploy"):
        code = main()
    sys.exit(code)
