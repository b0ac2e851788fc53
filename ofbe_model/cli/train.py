"""``ofbe-train``: OFBENet on every fold (and seed) of windowed datasets under their protocols
(ofbe_model.ofbenet.training).

Several datasets and protocols may be named at once: each dataset is trained under each named
protocol it has, and all the fits share one pool of workers.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from ofbe_data.core.cli import (
    add_jobs,
    add_params,
    add_scheduler,
    add_verbose,
    command,
    fail,
    quiet_libraries,
    with_examples,
)
from ofbe_data.core.errors import ConfigError, OfbeError

PROG = "ofbe-train"


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=PROG,
                                description="Train OFBENet on every fold of windowed datasets under their "
                                            "protocols; write models, histories, curves and a summary.")
    p.add_argument("dataset", nargs="+", help="dataset folder(s) (processed/datasets/<name>)")
    p.add_argument("--protocol", required=True, nargs="+",
                   help="protocol(s): fold_<protocol> columns; each dataset is trained under each "
                        "of these it has, all fits in one pool")
    p.add_argument("--out", default="models", help="models folder (default: models)")
    p.add_argument("--folds", type=int, nargs="+", metavar="K", help="train only these folds (default: all)")
    p.add_argument("--max-epochs", type=int, help="override train.max_epochs")
    p.add_argument("--seeds", type=int, metavar="N",
                   help="train every fold with N seeds (train.seed … train.seed + N − 1; "
                        "overrides train.seeds)")
    add_params(p, "train", "the OFBENet parameters and the number of seeds")
    add_jobs(p, "fits trained at once, each in a single-threaded worker (the models do not depend on it)")
    add_scheduler(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar and no summary line")
    add_verbose(p)
    return with_examples(
        p, "ofbe-train processed/datasets/rotated --protocol grouped --out mine/models --jobs 2",
        "ofbe-train processed/datasets/rotated --protocol grouped --folds 0 --seeds 1 --out mine/models")


@command(PROG)
def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ofbe-train``.

    Returns
    -------
    int
        0 on success, 1 on bad data or a failed fit, 2 on a usage or parameter error.
    """
    return _run(_parser().parse_args(argv))


def _run(args: argparse.Namespace) -> int:
    """``ofbe-train`` on its parsed arguments; the dataset and training modules (TensorFlow) are
    imported here, after parsing and after its start-up lines are quietened
    (docs/architecture.md, "Command lines")."""
    quiet_libraries(args.verbose)
    from ofbe_data.dataset.store import fold_column
    from ofbe_model.ofbenet.training import TrainingUsageError, read_params, read_seed_count, train_many

    try:
        params = read_params(args.params, args.max_epochs)
        seeds = read_seed_count(args.params, args.seeds)
        if args.jobs < 1:
            raise ConfigError("command line", "--jobs", "an integer >= 1", str(args.jobs))
        for protocol in args.protocol:
            fold_column(protocol)
    except OfbeError as exc:
        return fail(PROG, str(exc), 2)
    datasets = [Path(d) for d in args.dataset]
    for dataset in datasets:
        if not dataset.is_dir():
            return fail(PROG, f"{dataset}: expected a dataset folder, found no such folder", 2)
    t0 = time.perf_counter()
    try:
        written = train_many(datasets, args.protocol, args.out, params, args.folds, progress=not args.quiet,
                             seeds=seeds, jobs=args.jobs, scheduler=args.scheduler)
    except TrainingUsageError as exc:
        return fail(PROG, str(exc), 2)
    except (OfbeError, OSError) as exc:
        return fail(PROG, str(exc), 1)
    if not args.quiet:
        print(f"{PROG}: trained {', '.join(args.protocol)} on {', '.join(map(str, datasets))} in "
              f"{time.perf_counter() - t0:.0f} s; summaries: "
              f"{', '.join(map(str, written))}", file=sys.stderr)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
