"""DVC stage ``datasets``: one windowed dataset per labelled campaign in processed/datasets.

Reads ``dataset`` (windowing, folds, protocols) and ``dataset_run`` (campaigns, worker
processes, an optional ``scheduler``) from params.yaml; all logic lives in :mod:`ofbe_data.cli.dataset`.
"""

from __future__ import annotations

import sys
from pathlib import Path

from ofbe_data.cli.dataset import main as dataset_main
from ofbe_data.core.checksums import write_sha256_list
from ofbe_data.io.pipeline_params import load_params, resolved_params_file, timed

CHECKSUMS = Path("checksums") / "datasets.sha256"
"""Per-file SHA-256 list of processed/datasets (committed beside dvc.lock)."""


def main(params_file: str = "params.yaml") -> int:
    run = load_params(params_file)["dataset_run"]
    with resolved_params_file(params_file) as resolved:
        for name in run["campaigns"]:
            code = dataset_main(["build", f"processed/labels/{name}", "--raw", f"raw/{name}",
                                 "--out", f"processed/datasets/{name}", "--params", resolved,
                                 "--jobs", str(run["jobs"]), "--scheduler",
                                 str(run.get("scheduler", "processes")), "--force"])
            if code:
                return code
    write_sha256_list(CHECKSUMS, [f"processed/datasets/{name}" for name in run["campaigns"]])
    return 0



if __name__ == "__main__":
    with timed("datasets"):
        code = main()
    sys.exit(code)
