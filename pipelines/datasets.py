"""DVC stage ``datasets``: one windowed dataset per labelled campaign in processed/datasets.

Reads ``dataset`` (windowing, folds, protocols) and ``dataset_run`` (campaigns, worker
processes) from params.yaml; all logic lives in :mod:`ofbe_data.dataset_cli`.
"""

from __future__ import annotations

import sys

import yaml

from ofbe_data.dataset_cli import main as dataset_main


def main(params_file: str = "params.yaml") -> int:
    with open(params_file, encoding="utf-8") as fh:
        run = yaml.safe_load(fh)["dataset_run"]
    for name in run["campaigns"]:
        code = dataset_main(["build", f"processed/labels/{name}", "--raw", f"raw/{name}",
                             "--out", f"processed/datasets/{name}", "--params", params_file,
                             "--jobs", str(run["jobs"]), "--force"])
        if code:
            return code
    return 0


if __name__ == "__main__":
    sys.exit(main())
