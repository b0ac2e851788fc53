"""``ofbe-benchmark``: every estimator on every fold of a protocol, and the report (ofbe_model.benchmark)."""

from __future__ import annotations

import argparse
import inspect
import sys
from collections.abc import Callable, Sequence
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

PROG = "ofbe-benchmark"


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="ofbe-benchmark",
        description="Run every estimator on every fold of a protocol and write benchmark.json, benchmark.md "
                    "(the paper's Table 3), per-signal errors, t-tests and figures.")
    p.add_argument("datasets", nargs="+", help="dataset folders (processed/datasets/<campaign>)")
    p.add_argument("--protocol", required=True, help="paper-gravity, paper-rotated or grouped")
    p.add_argument("--out", help="report folder (default: reports/benchmark/<protocol>)")
    add_params(p, "benchmark", "methods, baselines and estimator parameters")
    p.add_argument("--methods", nargs="+", help="override benchmark.methods")
    p.add_argument("--models", help="ofbe-train's output folder (OFBENet is trained here when not given)")
    p.add_argument("--truth", action="append", default=[],
                   help="the simulator's truth folder of a dataset's campaign, for the oracle (repeat per "
                        "dataset, in the same order)")
    add_jobs(p, "worker processes")
    add_scheduler(p)
    p.add_argument("--quiet", action="store_true", help="no progress, no summary")
    add_verbose(p)
    return with_examples(
        p, "ofbe-benchmark processed/datasets/rotated --protocol grouped --out mine/benchmark "
           "--models mine/models --truth raw/rotated/_truth",
        "ofbe-benchmark processed/datasets/rotated --protocol grouped --out mine/benchmark "
        "--methods level-mean gravity-prior")


def _run_options(args: argparse.Namespace, run_protocol: Callable[..., object]) -> dict[str, object]:
    """``jobs`` and ``scheduler`` for ``run_protocol``
    (:func:`ofbe_model.benchmark.runner.run_protocol`), as far as it takes them.

    Raises
    ------
    ConfigError
        ``--jobs`` below 1, or a value other than the default for an option the runner does
        not take.
    """
    if args.jobs < 1:
        raise ConfigError("command line", "--jobs", "an integer ≥ 1", str(args.jobs))
    takes = inspect.signature(run_protocol).parameters
    options: dict[str, object] = {}
    for key, default in (("jobs", 1), ("scheduler", "processes")):
        value = getattr(args, key)
        if key in takes:
            options[key] = value
        elif value != default:
            raise ConfigError("command line", f"--{key}", f"{default} (this benchmark runner runs here only)",
                              str(value))
    return options


@command(PROG)
def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ofbe-benchmark``: 0 written, 1 bad data, 2 usage."""
    return _run(_parser().parse_args(argv))


def _run(args: argparse.Namespace) -> int:
    """``ofbe-benchmark`` on its parsed arguments; pandas and the benchmark's modules are imported
    here, after parsing and after the libraries' start-up lines are quietened
    (docs/architecture.md, "Command lines")."""
    quiet_libraries(args.verbose)
    import pandas as pd

    from ofbe_data.io.typedconfig import read_section
    from ofbe_model.benchmark.report import summarise, write_report
    from ofbe_model.benchmark.runner import benchmark_params_from, run_protocol
    try:
        data = dict(read_section(args.params, "benchmark")) if args.params else {}
        if args.methods:
            data["methods"] = list(args.methods)
        params = benchmark_params_from(data, args.params or "command line")
        options = _run_options(args, run_protocol)
        if args.truth and len(args.truth) != len(args.datasets):
            raise ConfigError("command line", "--truth", f"one per dataset ({len(args.datasets)})",
                              str(len(args.truth)))
    except OfbeError as exc:
        return fail(PROG, str(exc), 2)
    out = Path(args.out) if args.out else Path("reports/benchmark") / args.protocol
    frames = []
    timing: dict[str, float] = {}
    try:
        for i, ds in enumerate(args.datasets):
            truth = args.truth[i] if args.truth else None
            pred, seconds = run_protocol(ds, args.protocol, params, models_dir=args.models, truth_dir=truth,
                                         progress=not args.quiet, **options)
            frames.append(pred)
            for k, v in seconds.items():
                timing[k] = timing.get(k, 0.0) + v
        pred = pd.concat(frames, ignore_index=True)
        summary = summarise(pred, baselines=params.baselines)
        write_report(out, pred, summary, title=f"Benchmark, protocol {args.protocol}")
    except OfbeError as exc:
        return fail(PROG, str(exc), 1)
    if not args.quiet:
        for name, info in summary["datasets"].items():
            best = min(info["methods"].items(), key=lambda kv: kv[1]["rmse_mean"])
            print(f"ofbe-benchmark: {name}: best {best[0]} RMSE {best[1]['rmse_mean']:.4g} m/s²",
                  file=sys.stderr)
        print("ofbe-benchmark: seconds per method: "
              + ", ".join(f"{k} {v:.1f}" for k, v in timing.items()) + f" -> {out}", file=sys.stderr)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
