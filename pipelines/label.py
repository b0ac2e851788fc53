"""DVC stage ``label``: label the simulated campaigns into processed/labels.

Reads ``label`` (labelling parameters) and ``label_run`` (campaigns, worker processes) from
params.yaml; all logic lives in :mod:`ofbe_data.label_cli`.
"""

from __future__ import annotations

import sys

import yaml

from ofbe_data.label_cli import main as label_main


def main(params_file: str = "params.yaml") -> int:
    with open(params_file, encoding="utf-8") as fh:
        run = yaml.safe_load(fh)["label_run"]
    return label_main([*(f"raw/{name}" for name in run["campaigns"]), "--out", "processed/labels",
                       "--params", params_file, "--jobs", str(run["jobs"])])


if __name__ == "__main__":
    sys.exit(main())
