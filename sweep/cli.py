"""Command-line interface: argument parsing and printing only.

Every command calls a function that a notebook can call too. Exit status: 0 on
success, 2 for bad input (config, arguments, output path), 1 for other failures.
"""

import argparse
import logging
import shlex
import sys

from .config import ConfigError

EXIT_BAD_INPUT = 2


def _threads(text):
    import numba

    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
    top = numba.config.NUMBA_NUM_THREADS
    if not 1 <= n <= top:
        raise argparse.ArgumentTypeError(f"must be in [1, {top}] on this machine, got {n}")
    return n


def _positive_int(text):
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {n}")
    return n


def _shard(text):
    try:
        i, n = (int(v) for v in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be I/N (integers), got {text!r}") from None
    if not 0 <= i < n:
        raise argparse.ArgumentTypeError(f"needs 0 <= I < N, got {text!r}")
    return i, n


def build_parser():
    parser = argparse.ArgumentParser(
        prog="python -m sweep",
        description="Parameter sweeps of the Rice-Ruina spring-block model.",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a sweep config and write its NetCDF result")
    run.add_argument("config", help="YAML config file")
    run.add_argument("--out", help="output NetCDF path (default: the config's output)")
    run.add_argument("--threads", type=_threads, help="numba threads (default: all cores)")
    run.add_argument("--chunk-size", type=_positive_int, help="systems per chunk")
    run.add_argument("--quiet", action="store_true", help="no progress output")
    run.add_argument("--resume", action="store_true", help="reuse finished chunks of this config")
    where = run.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDRESS", help="run on this Dask scheduler")
    where.add_argument(
        "--dask-local", type=_positive_int, metavar="N", help="run on N local Dask worker processes"
    )
    run.add_argument(
        "--shard",
        type=_shard,
        metavar="I/N",
        help="compute share I of N (0 <= I < N) of the chunks",
    )
    merge = sub.add_parser("merge", help="assemble a NetCDF result from the parts of shards")
    merge.add_argument("parts", nargs="+", metavar="PARTS", help="part files or folders of parts")
    merge.add_argument("--out", required=True, help="output NetCDF path")
    return parser


def summary_lines(ds):
    """One line per regime (count and share of runs) for a result Dataset."""
    import numpy as np

    regime = ds["regime"].values.ravel()
    names = ds["regime"].attrs["flag_meanings"].split()
    lines = []
    for code, name in zip(ds["regime"].attrs["flag_values"], names, strict=True):
        count = int(np.count_nonzero(regime == code))
        lines.append(f"{name:<11} {count:>8d} runs ({100.0 * count / regime.size:5.1f} %)")
    return lines


def cmd_run(args):
    from .config import load_config
    from .runner import Interrupted, run_sweep, stop_on_signals

    config = load_config(args.config)
    if args.threads and (args.scheduler or args.dask_local):
        print("error: --threads is for numba threads; Dask workers own theirs", file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        with stop_on_signals() as stop:
            result = run_sweep(
                config,
                out=args.out,
                threads=args.threads,
                chunk_size=args.chunk_size,
                show_progress=not args.quiet,
                resume=args.resume,
                scheduler=args.scheduler,
                dask_local=args.dask_local,
                shard=args.shard,
                stop=stop,
            )
    except Interrupted as exc:
        again = [a for a in args.argv if a != "--resume"] + ["--resume"]
        print(f"{exc}:\n  python -m sweep {shlex.join(again)}", file=sys.stderr)
        return 128 + exc.signum
    if args.shard:
        i, n = args.shard
        print(f"shard {i}/{n}: {result.computed} runs computed, parts in {result.path}")
        out = args.out or config.output
        print(f"when all shards are done: python -m sweep merge {result.path} --out {out}")
        return 0
    for line in summary_lines(result.dataset):
        print(line)
    n = result.dataset["regime"].size
    print(f"wrote {result.path} ({n} runs in {result.elapsed:.1f} s)")
    return 0


def cmd_merge(args):
    from .runner import merge_parts

    ds = merge_parts(args.parts, args.out)
    for line in summary_lines(ds):
        print(line)
    print(f"wrote {args.out} ({ds['regime'].size} runs)")
    return 0


COMMANDS = {"run": cmd_run, "merge": cmd_merge}


def _log_to_stderr(quiet):
    """The package's log messages (resume, parts, cluster) as plain lines on stderr."""
    logger = logging.getLogger("sweep")
    for handler in [h for h in logger.handlers if getattr(h, "sweep_cli", False)]:
        logger.removeHandler(handler)
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(message)s"))
    handler.sweep_cli = True
    logger.addHandler(handler)
    logger.setLevel(logging.WARNING if quiet else logging.INFO)


def main(argv=None):
    from .runner import RunError

    args = build_parser().parse_args(argv)
    args.argv = sys.argv[1:] if argv is None else list(argv)
    _log_to_stderr(quiet=getattr(args, "quiet", False))
    try:
        return COMMANDS[args.command](args)
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except RunError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
