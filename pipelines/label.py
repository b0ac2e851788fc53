"""DVC stage ``label``: label the simulated campaigns into processed/labels.

Reads ``label`` (labelling parameters) and ``label_run`` (campaigns, worker processes, and
the convergence report whose recommendation is ``label.min_samples`` unless ``label`` sets
it) from params.yaml; all logic lives in :mod:`ofbe_data.label_cli`.
"""

from __future__ import annotations

import sys

import yaml

from ofbe_data.label_cli import main as label_main


def main(params_file: str = "params.yaml") -> int:
    with open(params_file, encoding="utf-8") as fh:
        run = yaml.safe_load(fh)["label_run"]
    extra = ["--min-samples-from", run["min_samples_from"]] if run.get("min_samples_from") else []
    return label_main([*(f"raw/{name}" for name in run["campaigns"]), "--out", "processed/labels",
                       "--params", params_file, "--jobs", str(run["jobs"]), *extra])


if __name__ == "__main__":
    sys.exit(main())
