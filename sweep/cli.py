"""Command-line interface: argument parsing and printing only.

Every command calls a function that a notebook can call too. Exit status: 0 on
success, 2 for bad input (config, arguments, output path), 1 for other failures.
"""

import argparse
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
    return parser


def summary_lines(ds):
    """One line per regime (count and share of runs) for a result Dataset."""
    import numpy as np

    regime = ds["regime"].values.ravel()
    names = ds["regime"].attrs["flag_meanings"].split()
    lines = []
    for code, name in zip(ds["regime"].attrs["flag_values"], names):
        count = int(np.count_nonzero(regime == code))
        lines.append(f"{name:<11} {count:>8d} runs ({100.0 * count / regime.size:5.1f} %)")
    return lines


def cmd_run(args):
    from .config import load_config
    from .runner import run_sweep

    config = load_config(args.config)
    result = run_sweep(
        config,
        out=args.out,
        threads=args.threads,
        chunk_size=args.chunk_size,
        show_progress=not args.quiet,
    )
    for line in summary_lines(result.dataset):
        print(line)
    n = result.dataset["regime"].size
    print(f"wrote {result.path} ({n} runs in {result.elapsed:.1f} s)")
    return 0


COMMANDS = {"run": cmd_run}


def main(argv=None):
    args = build_parser().parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
