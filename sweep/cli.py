"""Command-line interface: argument parsing and printing only.

Every command calls a function that a notebook can call too. Exit status: 0 on
success, 2 for bad input (config, result file, arguments, output path), 1 for other
failures and for an audit that found a disagreement.
"""

import argparse
import contextlib
import logging
import math
import shlex
import sys

from .errors import InputError, RunError

EXIT_BAD_INPUT = 2


def _integer(text):
    """``text`` as an integer, or the argparse error saying it is not one."""
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None


def _threads(text):
    import numba

    n = _integer(text)
    top = numba.config.NUMBA_NUM_THREADS
    if not 1 <= n <= top:
        raise argparse.ArgumentTypeError(f"must be in [1, {top}] on this machine, got {n}")
    return n


def _integer_at_least(low):
    """An argparse type: an integer ``>= low``."""

    def parse(text):
        n = _integer(text)
        if n < low:
            raise argparse.ArgumentTypeError(f"must be >= {low}, got {n}")
        return n

    return parse


def _integer_in(low, high):
    """An argparse type: an integer in [low, high]."""

    def parse(text):
        n = _integer(text)
        if not low <= n <= high:
            raise argparse.ArgumentTypeError(f"must be in [{low}, {high}], got {n}")
        return n

    return parse


def _finite_number(low_open):
    """An argparse type: a finite number in [0, inf), or (0, inf) with ``low_open``."""
    interval = "(0, inf)" if low_open else "[0, inf)"

    def parse(text):
        try:
            x = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a number, got {text!r}") from None
        if not (0 < x if low_open else 0 <= x) or x == float("inf"):
            raise argparse.ArgumentTypeError(f"must be in {interval}, got {text}")
        return x

    return parse


def _path(text):
    """An argparse type: a path that is not empty."""
    if not text.strip():
        raise argparse.ArgumentTypeError("must be a path, got an empty string")
    return text


_positive_int = _integer_at_least(1)
_count = _integer_at_least(0)
_seed = _integer_in(0, 2**31 - 1)  # as the configs' seeds
_trace_points = _integer_in(1, 10_000_000)
_fraction = _finite_number(low_open=False)
_positive_float = _finite_number(low_open=True)


def _shard(text):
    try:
        i, n = (int(v) for v in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be I/N (integers), got {text!r}") from None
    if not 0 <= i < n:
        raise argparse.ArgumentTypeError(f"needs 0 <= I < N, got {text!r}")
    return i, n


def build_parser():
    from ._version import __version__

    parser = argparse.ArgumentParser(
        prog="python -m sweep",
        description="Parameter sweeps of the Rice-Ruina spring-block model.",
    )
    parser.add_argument("--version", action="version", version=f"rsf-sweep {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("examples", help="list the example configs that ship with the package")
    run = sub.add_parser("run", help="run a sweep config and write its NetCDF (or Zarr) result")
    run.add_argument(
        "config", help="YAML config file, or the name of a packaged example (rsf-sweep examples)"
    )
    run.add_argument(
        "--out",
        type=_path,
        help="output path (default: the config's output): .nc for NetCDF, or .zarr for a Zarr "
        "store written chunk by chunk, readable while the sweep runs (needs rsf-sweep[zarr])",
    )
    run.add_argument("--threads", type=_threads, help="threads (default: all cores)")
    run.add_argument("--chunk-size", type=_positive_int, help="systems per chunk")
    run.add_argument("--quiet", action="store_true", help="no progress output")
    run.add_argument(
        "--resume",
        action="store_true",
        help="reuse finished chunks of this config (parts, or the rows of a .zarr store)",
    )
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
    run.add_argument(
        "--refine",
        type=_count,
        metavar="LEVELS",
        help="refine where the labels change, LEVELS levels (the config's refine section "
        "otherwise, or its defaults)",
    )
    run.add_argument(
        "--max-runs",
        type=_positive_int,
        metavar="N",
        help="with --refine or a refine section: run at most N runs in all",
    )
    merge = sub.add_parser("merge", help="assemble a NetCDF result from the parts of shards")
    merge.add_argument("parts", nargs="+", metavar="PARTS", help="part files or folders of parts")
    merge.add_argument("--out", type=_path, required=True, help="output NetCDF path")
    add_check_commands(sub)
    add_figure_commands(sub)
    return parser


def add_check_commands(sub):
    """Subcommands extend and audit (``sweep/commands/extend.py``, ``sweep/commands/audit.py``)."""
    ext = sub.add_parser(
        "extend",
        help="continue the undecided runs of a result to a later end time",
        description="Continue each undecided run of RESULT from its final state up to the "
        "end time T and replace its statistics; other runs are left as they are. Exit "
        "status 0 (also when no run is undecided), 2 for bad input, 1 if the file cannot "
        "be written.",
    )
    ext.add_argument("result", help="result NetCDF file of python -m sweep run")
    ext.add_argument(
        "--t-end", type=_positive_float, metavar="T",
        help="new end time, in the config's t_unit (default: 4x the time undecided runs reached)",
    )  # fmt: skip
    ext.add_argument("--out", type=_path, help="output NetCDF (default: replace RESULT)")
    ext.add_argument("--threads", type=_threads, help="threads (default: all cores)")
    ext.add_argument("--quiet", action="store_true", help="no progress output")
    aud = sub.add_parser(
        "audit",
        help="rerun a sample of a result's points for longer and with tighter tolerances, "
        "and compare the regimes",
        description="Rerun a seeded random sample of RESULT's grid points, plus every point "
        "near Kc, from the initial state with early exit off and a later end time, and again "
        "with the file's settings but rtol and atol divided by a factor, and compare the "
        "regimes. Exit status 0 when all agree, 1 when some disagree, 2 for bad input.",
    )
    aud.add_argument("result", help="result NetCDF file of python -m sweep run")
    aud.add_argument(
        "--sample", type=_count, default=20, metavar="N",
        help="grid points drawn at random (default 20)",
    )  # fmt: skip
    aud.add_argument(
        "--near-kc", type=_fraction, default=0.01, metavar="FRACTION",
        help="also audit every point with |K/Kc - 1| <= FRACTION (default 0.01)",
    )  # fmt: skip
    aud.add_argument(
        "--t-end", type=_positive_float, metavar="T",
        help="end time of the reruns, in the config's t_unit (default: 10x the file's)",
    )  # fmt: skip
    aud.add_argument(
        "--tighten", type=_positive_float, default=100.0, metavar="FACTOR",
        help="the second rerun divides rtol and atol by FACTOR, above 1 (default 100)",
    )  # fmt: skip
    aud.add_argument("--seed", type=_seed, default=0,
                     help="seed of the random sample, in [0, 2147483647] (default 0)")  # fmt: skip
    aud.add_argument("--threads", type=_threads, help="threads (default: all cores)")
    aud.add_argument("--quiet", action="store_true", help="no progress output")


def _assignment(text):
    """``NAME=VALUE`` (a model parameter in physical units, finite) → (name, float)."""
    name, sep, value = text.partition("=")
    try:
        number = float(value)
    except ValueError:
        number = None
    if not sep or not name or number is None or not math.isfinite(number):
        raise argparse.ArgumentTypeError(
            f"must be NAME=VALUE with a finite number, e.g. K_W=0.046; got {text!r}"
        )
    return name.strip(), number


def _once(source, option, pairs):
    """Raise :class:`InputError` if ``pairs`` (NAME=VALUE of ``option``) name an axis twice."""
    names = [name for name, _ in pairs]
    twice = sorted({name for name in names if names.count(name) > 1})
    if twice:
        raise InputError(source, [f"{option} gives {', '.join(twice)} more than once"])


_dpi = _integer_in(10, 2000)


def _add_dpi(parser):
    from .plot.common import DPI

    parser.add_argument(
        "--dpi", type=_dpi, default=DPI, help=f"resolution of PNG output (default {DPI})"
    )


def add_figure_commands(sub):
    """Subcommands plot, trace, bifurcation and figures (``sweep/plot/``,
    ``sweep/commands/trace.py``)."""
    plot = sub.add_parser("plot", help="phase diagram, or a map of one variable, of a result")
    plot.add_argument("result", help="result NetCDF file of python -m sweep run")
    plot.add_argument(
        "--var",
        metavar="NAME",
        help="map this variable (e.g. period, v_max, friction_drop, convergence) "
        "instead of the phase diagram",
    )
    plot.add_argument(
        "--orbit",
        nargs="?",
        const="",
        metavar="AXIS",
        help="orbit diagram instead: the last events' maxima of ln v and the Lyapunov "
        "exponent along AXIS (default: the first sweep axis)",
    )
    plot.add_argument(
        "--catalogue",
        type=_assignment,
        nargs="*",
        metavar="AXIS=VALUE",
        help="one run's slip events in space and time and their size-frequency plot instead "
        "(a result with catalogue.capacity > 0): the run nearest these sweep-axis values "
        "(member=INDEX for an ensemble; axes not given at their first value)",
    )
    plot.add_argument(
        "--out", type=_path, help="output .png, .pdf or .svg (default: the result's path with .png)"
    )
    _add_dpi(plot)
    trace = sub.add_parser("trace", help="time series of one system of a config (NetCDF + figure)")
    trace.add_argument("config", help="YAML config file or packaged example name")
    trace.add_argument(
        "--at",
        type=_assignment,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="value of a sweep axis (every axis needs one) or of a fixed parameter, in "
        "physical units; repeat for several",
    )
    trace.add_argument("--t-end", type=float, help="end time, in the config's t_unit")
    trace.add_argument(
        "--points",
        type=_trace_points,
        default=4000,
        help="time bins of the series, in [1, 10000000] (default 4000)",
    )
    trace.add_argument(
        "--out", type=_path, help="output NetCDF (default results/<name>_trace_<at>.nc)"
    )
    trace.add_argument(
        "--png", type=_path, help="output .png, .pdf or .svg (default: the NetCDF path with .png)"
    )
    _add_dpi(trace)
    kick = sub.add_parser(
        "kick",
        help="critical kick at every point of a config sweeping a start axis (bisection; "
        "NetCDF + figure; resumes from its file)",
    )
    kick.add_argument("config", help="YAML config file or packaged example name")
    kick.add_argument(
        "--rtol",
        type=float,
        default=0.01,
        help="relative width of the brackets, in (0, 1) (default 0.01)",
    )
    kick.add_argument("--out", type=_path, help="output NetCDF (default results/<name>_kick.nc)")
    kick.add_argument(
        "--png", type=_path, help="output .png, .pdf or .svg (default: the NetCDF path with .png)"
    )
    kick.add_argument("--threads", type=_threads, help="threads (default: all cores)")
    kick.add_argument("--quiet", action="store_true", help="no progress")
    _add_dpi(kick)
    bas = sub.add_parser(
        "basins",
        help="basin fractions of an ensemble's result (NetCDF + figure of one attractor's)",
    )
    bas.add_argument("result", help="a result NetCDF with initial.ensemble members")
    bas.add_argument(
        "--attractor", default="cycle_1ev", help="the attractor drawn (default cycle_1ev)"
    )
    bas.add_argument(
        "--width",
        type=float,
        help="also say how many members each point needs for every 95 %% interval to be at "
        "most this wide, in (0, 1)",
    )
    bas.add_argument("--out", type=_path, help="output NetCDF (default <result>_basins.nc)")
    bas.add_argument(
        "--png", type=_path, help="output .png, .pdf or .svg (default: the NetCDF path with .png)"
    )
    _add_dpi(bas)
    bif = sub.add_parser("bifurcation", help="amplitude against K/Kc of 1-D sweeps")
    bif.add_argument("results", nargs="+", help="result NetCDF files, one curve per model")
    bif.add_argument(
        "--out",
        type=_path,
        help="output .png, .pdf or .svg (default: <first result>_bifurcation.png)",
    )
    _add_dpi(bif)
    comp = sub.add_parser(
        "compile",
        help="compile the kernels of configs into numba's cache, side by side (before job arrays)",
    )
    comp.add_argument(
        "configs", nargs="+", metavar="CONFIG", help="YAML config files or packaged example names"
    )
    comp.add_argument(
        "--processes",
        type=_positive_int,
        help="processes that compile side by side (default: one per core)",
    )
    figs = sub.add_parser("figures", help="regenerate the paper's figures (in ./results)")
    figs.add_argument(
        "--config", default="paper", help="the paper config (default: the packaged example paper)"
    )
    figs.add_argument("--out-dir", type=_path, default="results", help="folder for the figures")
    figs.add_argument(
        "--format", choices=("png", "pdf", "svg"), default="png", help="file type (default png)"
    )
    _add_dpi(figs)
    figs.add_argument("--threads", type=_threads, help="threads (default: all cores)")


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
    from .engine.backends import Resources
    from .engine.run_control import stop_on_signals
    from .engine.runner import run_sweep
    from .errors import Interrupted

    config = refine_options(load_config(args.config), args.refine, args.max_runs)
    if args.threads and (args.scheduler or args.dask_local):
        print("error: --threads is for local threads; Dask workers own theirs", file=sys.stderr)
        return EXIT_BAD_INPUT
    try:
        with stop_on_signals() as stop:
            result = run_sweep(
                config,
                out=args.out,
                resources=Resources(args.threads, args.scheduler, args.dask_local),
                chunk_size=args.chunk_size,
                resume=args.resume,
                shard=args.shard,
                show_progress=not args.quiet,
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
    if "refine_runs" in result.dataset.attrs:
        runs = result.dataset.attrs["refine_runs"]
        per_level = ", ".join(f"{r}" for r in runs)
        print(f"refined {len(runs) - 1} levels ({result.dataset.attrs['refine_stopped']}): "
              f"runs per level {per_level}")  # fmt: skip
    print(f"wrote {result.path} ({n} runs in {result.elapsed:.1f} s)")
    return 0


def refine_options(config, levels, max_runs):
    """``config`` with ``--refine LEVELS`` and ``--max-runs N`` applied (validated)."""
    from .api import with_refine

    if max_runs is not None and levels is None and config.refine is None:
        raise InputError(config.source, ["--max-runs needs --refine or a refine section"])
    section = {} if levels is None else {"levels": levels}
    if max_runs is not None:
        section["max_runs"] = max_runs
    return with_refine(config, section) if section else config


def cmd_extend(args):
    from .commands.extend import extend_file

    ds, n_continued = extend_file(
        args.result, args.t_end, args.out, args.threads, show_progress=not args.quiet
    )
    if not n_continued:
        print(f"no undecided runs in {args.result}; nothing to do, the file is unchanged")
        return 0
    for line in summary_lines(ds):
        print(line)
    end = f"{ds.attrs['integrator_t_end']:g} {ds.attrs['integrator_t_unit']}"
    print(f"wrote {args.out or args.result} ({n_continued} undecided runs continued to {end})")
    return 0


#: The audit's reruns: (regime variable, agreement variable, label, what agreement means).
AUDIT_RERUNS = (
    ("regime_audit", "agree", "long run", "regime"),
    ("regime_tight", "agree_tight", "tighter tolerance", "regime, attractor and events per cycle"),
)


def agreement_lines(audit):
    """The agreement tables of an audit Dataset, one per rerun: regime in the file (rows)
    against the rerun's regime (columns), then the share of points that agree."""
    import numpy as np

    names = audit["regime_file"].attrs["flag_meanings"].split()
    reruns = [r for r in AUDIT_RERUNS if r[0] in audit]
    width = max(len(n) for n in names) + 2
    corners = ["file \\ " + label for _, _, label, _ in reruns]
    left = max(len(c) for c in corners) + 2
    in_file, lines = audit["regime_file"].values, []
    for (regime, agree, _, compared), corner in zip(reruns, corners, strict=True):
        in_rerun = audit[regime].values
        lines.append(f"{corner:<{left}}" + "".join(f"{n:>{width}}" for n in names))
        for code, name in enumerate(names):
            counts = [
                np.count_nonzero((in_file == code) & (in_rerun == c)) for c in range(len(names))
            ]
            lines.append(f"{name:<{left}}" + "".join(f"{c:>{width}d}" for c in counts))
        n, same = in_file.size, int(audit[agree].sum())
        share = 100.0 * same / n if n else 100.0
        lines.append(f"agreement: {same} of {n} {_audited(audit)} ({share:.1f} %; {compared})")
    return lines


def _label(audit, point, regime):
    """A run's label in an audit line: the regime in variable ``regime``, and for
    stick-slip its attractor (and events per cycle) where the audit has them beside it
    (``regime_file`` and ``regime_tight``)."""
    name = audit[regime].attrs["flag_meanings"].split()[int(point[regime])]
    source = regime.removeprefix("regime_")
    if name != "stick_slip" or f"attractor_{source}" not in audit:
        return name
    kind = audit["attractor_file"].attrs["flag_meanings"].split()
    attractor = kind[int(point[f"attractor_{source}"])]
    events = int(point[f"cycle_events_{source}"])
    if attractor == "periodic":
        attractor += f", {events} event" + ("s" if events != 1 else "")
    return f"{name} ({attractor})"


def disagreement_lines(audit):
    """One line per audited run where a rerun disagrees with the file: where it is and
    every label."""
    import numpy as np

    reruns = [r for r in AUDIT_RERUNS if r[0] in audit]
    differ = np.zeros(audit.sizes["point"], bool)
    for _, agree, _, _ in reruns:
        differ |= audit[agree].values == 0
    lines = []
    for i in differ.nonzero()[0]:
        point = audit.isel(point=i)
        labels = [f"file: {_label(audit, point, 'regime_file')}"]
        labels += [f"{label}: {_label(audit, point, regime)}" for regime, _, label, _ in reruns]
        lines.append(f"  {_where(audit, point)}  " + "  ".join(labels))
    return lines


def merged_lines(audit):
    """One line per audited stick-slip run (in the file) whose blocks round-off merged:
    where it is and how many blocks."""
    if "merged_blocks" not in audit:
        return []
    names = audit["regime_file"].attrs["flag_meanings"].split()
    stick_slip = audit["regime_file"].values == names.index("stick_slip")
    lines = []
    for i in (stick_slip & (audit["merged_blocks"].values > 0)).nonzero()[0]:
        point = audit.isel(point=i)
        blocks = int(point["merged_blocks"])
        lines.append(f"  {_where(audit, point)}  {blocks} blocks equal bit for bit")
    return lines


def _where(audit, point):
    """An audited run in a line: its sweep axes (and ensemble member) and K/Kc."""
    at = " ".join(f"{a}={point[a].item():g}" for a in audit.attrs["sweep_axes"].split())
    if "member" in audit.coords:
        at += f" member={point['member'].item()}"
    return f"{at}  K/Kc={point['K_over_Kc'].item():.4g}"


def _audited(audit):
    """What an audit's rows are: grid points, or runs of an initial-condition ensemble."""
    return "runs" if "member" in audit.coords else "points"


def cmd_audit(args):
    from .commands.audit import audit_result

    audit = audit_result(
        args.result, args.sample, args.near_kc, args.t_end, args.seed, args.threads,
        tighten=args.tighten, show_progress=not args.quiet,
    )  # fmt: skip
    near, unit = int(audit["near_kc"].sum()), audit.attrs["audit_t_unit"]
    print(
        f"audited {audit.sizes['point']} {_audited(audit)} of {args.result} ({near} within "
        f"{audit.attrs['audit_near_kc']:g} of Kc): runs to {audit.attrs['audit_t_end']:g} "
        f"{unit} without early exit, and to {audit.attrs['file_t_end']:g} {unit} with rtol "
        f"and atol / {audit.attrs['audit_tighten']:g}"
    )
    for line in agreement_lines(audit):
        print(line)
    merged = merged_lines(audit)
    if merged:
        print(
            f"stick-slip {_audited(audit)} whose blocks ended equal bit for bit though they "
            "started apart (merged by round-off: their label may be of a symmetric orbit they "
            "would leave):"
        )
        for line in merged:
            print(line)
    wrong = disagreement_lines(audit)
    if wrong:
        print(f"{_audited(audit)} where a rerun disagrees:")
        for line in wrong:
            print(line)
        return 1
    return 0


def cmd_merge(args):
    from .engine.runner import merge_parts

    ds = merge_parts(args.parts, args.out)
    for line in summary_lines(ds):
        print(line)
    print(f"wrote {args.out} ({ds['regime'].size} runs)")
    return 0


def _plotted(source, draw, out, dpi):
    """Save the figure ``draw()`` to ``out`` after checking ``out``; a result it cannot
    draw is bad input."""
    from .io.files import check_writable
    from .plot import save_figure
    from .plot.common import FORMATS

    check_writable(out, source, "--out", tuple(FORMATS))
    try:
        fig = draw()
    except ValueError as exc:
        raise InputError(source, [f"cannot plot: {exc}"]) from None
    return save_figure(fig, out, dpi)


def cmd_examples(args):
    from . import examples

    for name in examples.names():
        print(f"{name:<16} {examples.describe(name)}")
    print(f"(in {examples.folder()}; run one with: rsf-sweep run NAME)")
    return 0


def cmd_plot(args):
    import functools
    from pathlib import Path

    from .io.netcdf import read_result
    from .plot import plot_orbit_diagram, plot_result, plot_variable

    ds = read_result(args.result)
    if sum((bool(args.var), args.orbit is not None, args.catalogue is not None)) > 1:
        raise InputError(args.result, ["give one of --var, --orbit and --catalogue"])
    if args.catalogue is not None:
        from .plot import plot_catalogue

        _once(args.result, "--catalogue", args.catalogue)
        suffix, draw = "_catalogue.png", functools.partial(plot_catalogue, ds, dict(args.catalogue))
    elif args.orbit is not None:
        suffix, draw = "_orbit.png", functools.partial(plot_orbit_diagram, ds, args.orbit or None)
    elif args.var is not None:
        suffix, draw = f"_{args.var}.png", functools.partial(plot_variable, ds, args.var)
    else:
        suffix, draw = ".png", functools.partial(plot_result, ds)
    out = args.out or Path(args.result).with_name(Path(args.result).stem + suffix)
    print(f"wrote {_plotted(args.result, draw, out, args.dpi)}")
    return 0


def cmd_trace(args):
    """Pin the config at ``--at``, integrate, write the trace's NetCDF and its figure
    (both paths checked before the run)."""
    from pathlib import Path

    from .commands.trace import compute_trace, pin_config
    from .config import load_config
    from .io.files import check_writable
    from .io.netcdf import write_netcdf
    from .plot import plot_trace, save_figure
    from .plot.common import FORMATS

    config = load_config(args.config)
    _once(args.config, "--at", args.at)
    at = dict(args.at)
    pinned = pin_config(config, at, args.t_end)
    stem = "_".join(f"{name}={value:g}" for name, value in at.items())
    nc = Path(args.out) if args.out else Path("results") / f"{config.name}_trace_{stem}.nc"
    png = Path(args.png) if args.png else nc.with_suffix(".png")
    check_writable(nc, config.source, "--out")
    check_writable(png, config.source, "--png", tuple(FORMATS))
    ds = compute_trace(pinned, args.points)
    write_netcdf(ds, nc)
    save_figure(plot_trace(ds), png, args.dpi)
    end = f", t_runaway = {ds.attrs['t_runaway']:.6g} s" if ds.attrs["regime"] == "runaway" else ""
    print(f"{ds.attrs['regime']} (t_final = {ds.attrs['t_final']:.6g} s{end})")
    print(f"wrote {nc} ({ds.sizes['time']} time points) and {png}")
    return 0


def cmd_kick(args):
    """Bisect the critical kick of every point, write its NetCDF (after every round) and
    its figure, and say how many points have each status."""
    from pathlib import Path

    from .config import load_config
    from .engine.kicks import bisect_critical_kick
    from .io.files import check_writable
    from .plot import plot_critical_kick, save_figure
    from .plot.common import FORMATS
    from .results.kicks import KICK_STATUSES

    config = load_config(args.config)
    nc = Path(args.out) if args.out else Path("results") / f"{config.name}_kick.nc"
    png = Path(args.png) if args.png else nc.with_suffix(".png")
    check_writable(png, config.source, "--png", tuple(FORMATS))
    ds = bisect_critical_kick(
        config, args.rtol, out=nc, threads=args.threads, progress=not args.quiet
    )
    status = ds["critical_kick_status"].values.ravel()
    if ds["critical_kick"].ndim:
        save_figure(plot_critical_kick(ds), png, args.dpi)
        wrote = f"{nc} and {png}"
    else:  # one point: its bracket, no figure
        low, high = float(ds["critical_kick_low"]), float(ds["critical_kick"])
        print(f"critical kick between {low:.6g} and {high:.6g}")
        wrote = f"{nc} (one point: no figure)"
    for code, name in enumerate(KICK_STATUSES):
        print(f"{name:<15} {int((status == code).sum()):>6d} points")
    runs = int(ds["kick_runs"].sum())
    print(f"{runs} runs in {int(ds.attrs['kick_rounds'])} rounds; wrote {wrote}")
    return 0


def cmd_basins(args):
    """Match an ensemble's members into attractors, write the fractions' NetCDF and the
    figure of one attractor's fraction, and print the fractions over the grid."""
    from pathlib import Path

    from .errors import InputError
    from .io.files import check_writable
    from .io.netcdf import read_result, write_netcdf
    from .plot import plot_basin_fractions, save_figure
    from .plot.common import FORMATS
    from .results.basins import basin_fractions, members_needed

    source = Path(args.result)
    nc = Path(args.out) if args.out else source.with_name(f"{source.stem}_basins.nc")
    png = Path(args.png) if args.png else nc.with_suffix(".png")
    check_writable(nc, args.result, "--out")
    check_writable(png, args.result, "--png", tuple(FORMATS))
    if args.width is not None and not 0.0 < args.width < 1.0:
        raise InputError("--width", [f"must be in (0, 1), got {args.width:g}"])
    ds = read_result(source)
    if "member" not in ds.dims:
        raise InputError(args.result, ["no member dimension: run it with initial.ensemble > 0"])
    basins = basin_fractions(ds)
    names = [str(a) for a in basins["attractor"].values]
    if args.attractor not in names:
        raise InputError(
            "--attractor", [f"{args.attractor!r} is not reached; attractors: {', '.join(names)}"]
        )
    if args.width is not None:
        basins["members_needed"] = members_needed(basins, args.width)
    write_netcdf(basins, nc)
    save_figure(plot_basin_fractions(basins, args.attractor), png, args.dpi)
    fraction = basins["basin_fraction"]
    for name in names:
        values = fraction.sel(attractor=name).values
        print(f"{name:<16} fraction {values.min():.3g} to {values.max():.3g} over the grid")
    members = int(basins["members"].max())
    print(f"unresolved       up to {float(basins['unresolved_fraction'].max()):.3g}; "
          f"{members} members per point")  # fmt: skip
    if args.width is not None:
        need = int(basins["members_needed"].max())
        print(f"members for every interval at most {args.width:g} wide: up to {need} "
              "(initial.ensemble; the same seed repeats the first members)")  # fmt: skip
    print(f"wrote {nc} and {png}")
    return 0


def cmd_bifurcation(args):
    from pathlib import Path

    from .io.netcdf import read_result
    from .plot import plot_bifurcation

    first = Path(args.results[0])
    out = args.out or first.with_name(first.stem + "_bifurcation.png")
    datasets = [read_result(p) for p in args.results]
    source = ", ".join(args.results)
    print(f"wrote {_plotted(source, lambda: plot_bifurcation(datasets), out, args.dpi)}")
    return 0


def cmd_compile(args):
    from .accelerate import CACHE
    from .api import compile_kernels

    compile_kernels(*args.configs, processes=args.processes)
    if CACHE:
        print(f"the kernels of {len(args.configs)} config(s) are in numba's cache")
    else:
        print("compiled; SWEEP_NUMBA_CACHE=0, so nothing was kept for later runs")
    return 0


def cmd_figures(args):
    from .commands.figures import make_figures

    paths = make_figures(
        paper=args.config,
        out_dir=args.out_dir,
        threads=args.threads,
        suffix=f".{args.format}",
        dpi=args.dpi,
    )
    for path in paths:
        print(f"wrote {path}")
    return 0


COMMANDS = {
    "examples": cmd_examples,
    "run": cmd_run,
    "merge": cmd_merge,
    "extend": cmd_extend,
    "audit": cmd_audit,
    "plot": cmd_plot,
    "trace": cmd_trace,
    "kick": cmd_kick,
    "basins": cmd_basins,
    "bifurcation": cmd_bifurcation,
    "figures": cmd_figures,
    "compile": cmd_compile,
}


@contextlib.contextmanager
def _log_to_stderr(quiet):
    """The package's log messages (resume, parts, cluster) as plain lines on stderr while
    a command runs; the ``sweep`` logger's handlers and level are restored after it, so
    that a notebook or test calling :func:`main` keeps no handler of it."""
    logger = logging.getLogger("sweep")
    level = logger.level
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(message)s"))
    logger.addHandler(handler)
    logger.setLevel(logging.WARNING if quiet else logging.INFO)
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)


def main(argv=None):
    args = build_parser().parse_args(argv)
    args.argv = sys.argv[1:] if argv is None else list(argv)
    with _log_to_stderr(quiet=getattr(args, "quiet", False)):
        return _run_command(args)


def _run_command(args):
    """Run the parsed command; errors the user can act on become a message and an exit
    status."""
    try:
        return COMMANDS[args.command](args)
    except InputError as exc:  # ConfigError included
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except RunError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except MemoryError as exc:
        detail = f": {exc}" if str(exc) else ""
        print(f"error: not enough memory{detail}; a sweep's arrays are held in memory: make "
              "the grid smaller or split it into several configs", file=sys.stderr)  # fmt: skip
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # python -m sweep.cli, as python -m sweep
    sys.exit(main())
