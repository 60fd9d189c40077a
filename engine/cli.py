"""The `plugsim` command line: run, keys, check, export, animate, bench."""

from __future__ import annotations

import argparse
import os
import shlex
import signal
import sys

from . import __version__
from .case import KEYS, Case, CaseError, keys_markdown, overlay_overrides
from .parser import OneLineParser


def _keys(args: argparse.Namespace) -> int:
    if args.markdown:
        sys.stdout.write(keys_markdown())
        return 0
    for key in KEYS.values():
        print(f"{key.name:32s} {key.default!r:>10}  [{key.unit or '-'}]  {key.allowed()}")
        print(f"{'':32s} {key.doc}")
    return 0


def _case(args: argparse.Namespace) -> Case:
    """The case YAML with the overlays' `all_cases`, then the --set overrides (later wins)."""
    pairs = [pair for path in args.overlay for pair in overlay_overrides(path)]
    return Case.from_yaml(args.case).with_overrides([*pairs, *args.set])


def _case_options(p: argparse.ArgumentParser) -> None:
    """--set and --overlay, the options that change a case YAML's keys (run, check)."""
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a key, e.g. --set particles.friction=0.1 (repeatable)")
    p.add_argument("--overlay", action="append", default=[], metavar="FILE.yaml",
                   help="apply the `all_cases` keys of a workflow config overlay, e.g. the fitted "
                        "values of a calibration (results/calibration/<name>/fitted.yaml), before "
                        "--set (repeatable)")


def _check(args: argparse.Namespace) -> int:
    """Validate a case and print what it implies (time step, contact time, feed)."""
    from .contact import DASHPOT_RESOLVED_RATIO, DASHPOT_WARNING, ContactModel
    from .feed import Feed

    case = _case(args)
    model = ContactModel.from_case(case)
    feed = Feed(case, model.mass, case["run.seed"])
    print(f"case {args.case}: valid")
    print(f"  contact time        {model.contact_time:.4g} s")
    print(f"  time step           {model.time_step:.4g} s (stable limit {model.stable_time_step:.4g} s)")
    if model.dashpot_step_ratio <= DASHPOT_RESOLVED_RATIO:
        verdict = ""
    elif model.implicit_spin:
        verdict = f", above {DASHPOT_RESOLVED_RATIO}, resolved by the implicit spin kick (numerics.implicit_spin)"
    else:
        verdict = f", above {DASHPOT_RESOLVED_RATIO}: {DASHPOT_WARNING}"
    print(f"  tangential dashpot  gamma_t dt/(m/7) = {model.dashpot_step_ratio:.2f}{verdict}")
    if feed.enabled:
        print(f"  feed                {len(feed.template)} grains per layer, layers {feed.spacing * 1e3:.3f} mm "
              f"apart, solid fraction {feed.solid_fraction:.3f}")
    return 0


def _run(args: argparse.Namespace) -> int:
    """Run one case to a case file; numerical failures exit 1 with a one-line reason."""
    import logging

    from .run import (InitialStateError, NoSpaceError, OutputExistsError, OutputPathError, RunError,
                      RunInterrupted, run_case)
    from .simulation import check_threads

    logging.basicConfig(level=logging.WARNING if args.quiet else logging.INFO,
                        format="plugsim: %(message)s")
    case = _case(args)
    try:
        check_threads(args.threads)
    except ValueError as err:
        print(f"plugsim: error: --threads: {err}", file=sys.stderr)
        return 2
    try:
        run_case(case, args.out, quiet=args.quiet, initial_state=args.initial_state, threads=args.threads,
                 early_exit=lambda err: _exit_interrupted(err, args.argv), overwrite=args.overwrite)
    except (InitialStateError, OutputPathError, OutputExistsError) as err:  # refused before any step
        print(f"plugsim: error: {err}", file=sys.stderr)
        return 2
    except RunError as err:
        print(f"plugsim: run failed: {err}", file=sys.stderr)
        return 1
    except NoSpaceError as err:
        print(f"plugsim: error: {err}", file=sys.stderr)
        return 1
    except RunInterrupted as err:
        print(f"plugsim: {_interrupted(err, args.argv)}", file=sys.stderr)
        return 128 + err.signum
    return 0


def _export(args: argparse.Namespace) -> int:
    """ParaView files of a case file; bad input exits 2 with one line, a full disk 1."""
    from .export import ExportError, export_case
    from .output import DiskFullError
    try:
        done = export_case(args.case_file, args.out)
    except ExportError as err:
        print(f"plugsim: error: {err}", file=sys.stderr)
        return 2
    except DiskFullError as err:
        print(f"plugsim: error: {err}", file=sys.stderr)
        return 1
    empty = f"; {done.empty_snapshots} without grains, not written" if done.empty_snapshots else ""
    print(f"wrote {done.folder}/: grains.pvd ({done.grain_files} snapshots{empty}), slices.pvd "
          f"({done.slice_files} frames), {done.size / 1e6:.1f} MB")
    return 0


def _animate(args: argparse.Namespace) -> int:
    """An animation of a case file; bad input exits 2 with one line, a full disk 1."""
    from .animate import animate_case
    from .export import ExportError
    from .output import DiskFullError
    try:
        done = animate_case(args.case_file, args.out, fps=args.fps)
    except ExportError as err:
        print(f"plugsim: error: {err}", file=sys.stderr)
        return 2
    except DiskFullError as err:
        print(f"plugsim: error: {err}", file=sys.stderr)
        return 1
    print(f"wrote {done.path}: {done.frames} frames, {done.size / 1e6:.1f} MB")
    return 0


def _exit_interrupted(err, argv: list[str]) -> None:
    """End the process at once with the interruption's one line (nothing to save yet)."""
    print(f"plugsim: {_interrupted(err, argv)}", file=sys.stderr, flush=True)
    os._exit(128 + err.signum)


def _interrupted(err, argv: list[str]) -> str:
    """One line: where a run was stopped and how to resume it."""
    command = shlex.join(["plugsim", *argv])
    where = f" at t = {err.time:.3f} s" if err.time is not None else ""
    if err.checkpoint is None:
        return f"interrupted by {err} before any new frame, nothing saved; start again with: {command}"
    return f"interrupted by {err}{where}, checkpoint {err.checkpoint}; resume with the same command: {command}"


def _bench(args: argparse.Namespace, rest: list[str]) -> int:
    from . import bench
    return bench.main(rest)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        return _main(argv)
    except KeyboardInterrupt:
        print("plugsim: interrupted", file=sys.stderr)
        return 128 + signal.SIGINT
    except BrokenPipeError:  # e.g. `plugsim keys | head`: the reader has gone, stop quietly
        # stdout is still open: point it at /dev/null so that its flush at exit does not fail again
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 128 + signal.SIGPIPE


def _main(argv: list[str]) -> int:
    parser = OneLineParser(prog="plugsim", description="Dense-phase pneumatic conveying simulator")
    parser.add_argument("--version", action="version", version=f"plugsim {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("keys", help="list every case key with unit, default and allowed range")
    p.add_argument("--markdown", action="store_true", help="print the docs/case-keys.md table")
    p.set_defaults(func=_keys)
    p = sub.add_parser("check", help="validate a case file (with overrides) and print derived numbers")
    p.add_argument("case", help="case YAML, e.g. config/cases/horizontal.yaml")
    _case_options(p)
    p.set_defaults(func=_check)
    p = sub.add_parser(
        "run", help="run one case and write its NetCDF case file (from an empty tube, a checkpoint, "
                    "the end of a finished OUT, or --initial-state)",
        description="Run one case and write its NetCDF case file. It starts from an empty tube, or with "
                    "--initial-state FROM.nc from the grains at the end of another case file (a warm "
                    "start). Run again with the same arguments, "
                    "it resumes from its checkpoint (OUT.ckpt) or, when OUT is finished, says so and "
                    "does nothing; with a longer run.duration it continues OUT from its end. A shorter "
                    "run.duration or other keys would replace OUT with another result: refused (exit 2, "
                    "naming each key that differs) unless --overwrite. A full disk exits 1 and keeps "
                    "the last checkpoint, from which the same command resumes once space is freed.")
    p.add_argument("case", help="case YAML, e.g. config/cases/horizontal.yaml")
    p.add_argument("--out", required=True, help="case file to write (NetCDF), e.g. results/h.nc")
    p.add_argument("--overwrite", action="store_true",
                   help="replace a finished case file at OUT that holds another result (other keys, a "
                        "shorter run.duration), running the case again from the start (or its checkpoint)")
    _case_options(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar, warnings only (workflow mode)")
    p.add_argument("--initial-state", metavar="FROM.nc", default=None,
                   help="warm start: begin with the grains at the end of another case file "
                        "(same grains and tube diameter; another tube length or inclination needs "
                        "--set run.warm_start_any=true) instead of an empty tube")
    p.add_argument("--threads", type=int, default=1,
                   help="threads for the contact forces (default 1; 2 split the single loop, which "
                        "runs a horizontal case no faster than one thread's contact passes, for twice "
                        "the CPU, docs/performance.md; results differ from 1 thread by rounding only)")
    p.set_defaults(func=_run)
    p = sub.add_parser("export", help="ParaView files of a case file's whole-tube grain snapshots "
                                      "(output.tube_snapshot_interval) and slice fields")
    p.add_argument("case_file", help="case file written by `plugsim run`, e.g. results/h.nc")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="folder to write (default: next to the case file, CASE_vtk)")
    p.set_defaults(func=_export)
    p = sub.add_parser("animate", help="GIF (or MP4 with ffmpeg) of the slice porosity over x and t "
                                       "and of the grains moving through the tube")
    p.add_argument("case_file", help="case file with whole-tube snapshots, e.g. results/h.nc")
    p.add_argument("--out", default=None, metavar="FILE",
                   help="FILE.gif, FILE.mp4 (needs ffmpeg) or FILE.png (the last frame); "
                        "default: next to the case file, CASE.gif")
    p.add_argument("--fps", type=float, default=10.0, help="frames (snapshots) per second (default 10)")
    p.set_defaults(func=_animate)
    p = sub.add_parser("bench", help="grain-engine benchmark on the standard dense case", add_help=False)
    p.set_defaults(func=_bench)
    # `bench` options belong to engine.bench's own parser (REMAINDER would drop leading options)
    args, rest = parser.parse_known_args(argv)
    if args.command == "bench":
        return _bench(args, rest)
    if rest:
        parser.error(f"unrecognized arguments: {' '.join(rest)}")
    args.argv = argv
    try:
        return args.func(args)
    except CaseError as err:
        print(f"plugsim: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
