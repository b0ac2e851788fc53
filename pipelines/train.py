"""DVC stage ``train``: OFBENet per benchmark dataset, protocol and fold into models/.

Reads ``train`` (OFBENet parameters) and ``benchmark_run`` (which protocols run on which
datasets) from params.yaml; all logic lives in :mod:`ofbe_model.train_cli`.
"""

from __future__ import annotations

import sys

import yaml

from ofbe_model.train_cli import main as train_main


def main(params_file: str = "params.yaml") -> int:
    with open(params_file, encoding="utf-8") as fh:
        run = yaml.safe_load(fh)["benchmark_run"]
    for protocol, campaigns in run["protocols"].items():
        for name in campaigns:
            code = train_main([f"processed/datasets/{name}", "--protocol", protocol, "--out", "models",
                               "--params", params_file])
            if code:
                return code
    return 0


if __name__ == "__main__":
    sys.exit(main())
