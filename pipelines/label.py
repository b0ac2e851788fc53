"""DVC stage ``label``: label the simulated campaigns into processed/labels.

Reads ``label`` (labelling parameters) and ``label_run`` (campaigns, worker processes, an
optional ``scheduler`` (``processes``, ``dask`` or ``tcp://host:port``), and
the convergence report whose recommendation is ``label.min_samples`` unless ``label`` sets
it) from params.yaml; all logic lives in :mod:`ofbe_data.cli.label`.
"""

from __future__ import annotations

import sys
from pathlib import Path

from ofbe_data.cli.label import main as label_main
from ofbe_data.core.checksums import write_sha256_list
from ofbe_data.io.pipeline_params import load_params, resolved_params_file, timed

CHECKSUMS = Path("checksums") / "label.sha256"
"""Per-file SHA-256 list of processed/labels (committed beside dvc.lock)."""


def main(params_file: str = "params.yaml") -> int:
    run = load_params(params_file)["label_run"]
    extra = ["--min-samples-from", run["min_samples_from"]] if run.get("min_samples_from") else []
    with resolved_params_file(params_file) as resolved:
        code = label_main([*(f"raw/{name}" for name in run["campaigns"]), "--out", "processed/labels",
                           "--params", resolved, "--jobs", str(run["jobs"]),
                           "--scheduler", str(run.get("scheduler", "processes")), *extra])
    if code == 0:
        write_sha256_list(CHECKSUMS, ["processed/labels"])
    return code



if __name__ == "__main__":
    with timed("label"):
        code = main()
    sys.exit(code)
