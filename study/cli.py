"""Command line: ``study run | plan | report | bench | examples`` (also ``python -m study``).

The synopsis (:data:`SYNOPSIS`, also printed by ``study --help``; a test checks
that it lists every option of every command)::

    study run STUDY.toml [-o OUT.nc] [--workers N] [--scheduler ADDRESS | --scheduler-file FILE]
              [--fidelity NAME] [--retries N] [--worker-timeout SECONDS]
              [--scheduler-timeout SECONDS] [--overwrite] [--quiet]
    study plan STUDY.toml [--fidelity NAME] [--workers N] [--calibrate]
    study report RESULT.nc -o DIR [--overwrite]
    study bench -o DIR [--quick]
    study examples [NAME [-o FILE]]

Exit codes: 0 success, 1 a chunk failed or the cluster stopped answering
(``--worker-timeout``, ``--scheduler-timeout``), 2 bad input (one line on
stderr, nothing written), 130 interrupted by Ctrl-C (SIGINT) and 143 stopped by
SIGTERM (e.g. a batch job's time limit): finished chunks are kept, rerun to
resume. Timeouts and limits: ``docs/limits.md``.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shlex
import signal
import sys
from pathlib import Path

from study.connect import DEFAULT_SCHEDULER_TIMEOUT
from study.errors import StudyError, StudyFailed, StudyInterrupted
from study.watchdog import DEFAULT_WORKER_TIMEOUT

#: Every command and option, as ``study --help`` prints it.
SYNOPSIS = "\n".join(
    line[4:] for line in __doc__.split("::\n\n", 1)[1].split("\n\n", 1)[0].splitlines()
)

EXIT_FAILED = 1
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130
EXIT_TERMINATED = 143


class _Terminated:
    """SIGTERM handler: stop like Ctrl-C (KeyboardInterrupt), remember the signal."""

    received = False

    def __call__(self, signum, frame) -> None:
        type(self).received = True
        raise KeyboardInterrupt


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error message (exit code 2)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message}\n")


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {value}")
    return value


def _study_options(parser: argparse.ArgumentParser, workers_help: str) -> None:
    """``--workers N`` and ``--fidelity NAME`` (``run`` and ``plan``)."""
    parser.add_argument("--workers", type=_positive_int, metavar="N", help=workers_help)
    parser.add_argument("--fidelity", metavar="NAME", help="override the study's fidelity preset")


def build_parser() -> argparse.ArgumentParser:
    from frictionregimes import __version__

    parser = _Parser(
        prog="study",
        description="Classify the regimes of friction-damped chains: studies on Dask.",
        epilog="synopsis:\n"
        + "\n".join("  " + ln for ln in SYNOPSIS.splitlines())
        + "\n\nexit codes: 0 done, 1 failed (work kept), 2 bad input, 130/143 interrupted",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--version", action="version", version=f"study (frictionregimes) {__version__}"
    )
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    run = sub.add_parser("run", help="compute a study and write one netCDF file")
    run.add_argument("study", type=Path, help="study file (TOML)")
    run.add_argument(
        "-o", "--output", type=Path, metavar="OUT.nc", help="result file (default: NAME.nc)"
    )
    where = run.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDRESS", help="address of a running scheduler")
    where.add_argument("--scheduler-file", metavar="FILE", help="scheduler file of a running one")
    _study_options(
        run, "local worker processes (default: one per core); with --scheduler: wait for N workers"
    )
    run.add_argument(
        "--retries", type=int, default=3, metavar="N", help="retries of a failing task (0-100)"
    )
    run.add_argument(
        "--worker-timeout",
        type=float,
        default=DEFAULT_WORKER_TIMEOUT,
        metavar="SECONDS",
        help="stop (exit 1, work kept) after this long without any live worker: none "
        f"connected, or all stopped answering (default: {DEFAULT_WORKER_TIMEOUT:g})",
    )
    run.add_argument(
        "--scheduler-timeout",
        type=float,
        default=DEFAULT_SCHEDULER_TIMEOUT,
        metavar="SECONDS",
        help="longest wait for the scheduler to answer: connecting (exit 2) and during the "
        f"run (exit 1, work kept) (default: {DEFAULT_SCHEDULER_TIMEOUT:g})",
    )
    run.add_argument("--quiet", action="store_true", help="no progress display")
    run.add_argument(
        "--overwrite", action="store_true", help="compute again even if the output is complete"
    )

    pl = sub.add_parser("plan", help="points, tasks and estimated time, without running")
    pl.add_argument("study", type=Path, help="study file (TOML)")
    _study_options(pl, "workers the wall time is estimated for (default: one per core)")
    pl.add_argument(
        "--calibrate",
        action="store_true",
        help="time tasks.classify on a sample of each scene on this machine",
    )

    rep = sub.add_parser("report", help="write the analysis report of a result file")
    rep.add_argument("result", type=Path, help="result file of study run (netCDF)")
    rep.add_argument(
        "-o",
        "--output",
        type=Path,
        required=True,
        metavar="DIR",
        help="folder for report.md and its figures (created; an earlier report in it is replaced)",
    )
    rep.add_argument(
        "--overwrite", action="store_true", help="replace a file (not a folder) found at DIR"
    )

    bench = sub.add_parser(
        "bench",
        help="time and accuracy of every fidelity preset and of the paper's method "
        "(bench.md, pareto.png)",
    )
    bench.add_argument(
        "-o", "--output", type=Path, required=True, metavar="DIR", help="folder for the tables"
    )
    bench.add_argument("--quick", action="store_true", help="a smaller point set (~15 s)")

    ex = sub.add_parser(
        "examples", help="list the example studies (the paper's figures, HPC recipe) or write one"
    )
    ex.add_argument("name", nargs="?", help="an example to write out (e.g. quickstart)")
    ex.add_argument("-o", "--output", type=Path, help="file to write (default: stdout)")
    return parser


def _load(args) -> object:
    from study.definition import Study

    study = Study.from_toml(args.study)
    if args.fidelity:
        study = study.with_fidelity(args.fidelity)
    return study


def cmd_run(args) -> int:
    from study.run import run_study

    study = _load(args)
    output = args.output or Path(f"{study.name}.nc")
    command = "study " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    run_study(
        study,
        output,
        scheduler=args.scheduler,
        scheduler_file=args.scheduler_file,
        workers=args.workers,
        retries=args.retries,
        worker_timeout=args.worker_timeout,
        scheduler_timeout=args.scheduler_timeout,
        progress=not args.quiet,
        command=command,
        overwrite=args.overwrite,
    )
    return 0


def cmd_plan(args) -> int:
    from study.chunks import plan
    from study.cost import calibrate
    from study.run import default_workers

    study = _load(args)
    workers = args.workers or default_workers()
    plans = plan(study)
    if args.calibrate:
        from study.firstrun import compile_once, kernels_for

        calibrated = [p for p in plans if p.kind == "grid"]
        compile_once(sys.stderr, kernels_for(calibrated))  # kept out of the measured times
    print(f"study {study.name}: fidelity {study.fidelity}, {study.n_points:,} points")
    print(
        f"{'scene':<24}{'kind':>7}{'points':>12}{'tasks':>9}{'pts/task':>10}"
        f"{'est. s/task':>12}{'est. CPU s':>12}"
    )
    total_s = 0.0
    n_tasks = 0
    for p in plans:
        n = p.spec.n_points
        est = p.est_seconds
        if args.calibrate and p.kind == "grid":
            per = calibrate(
                p.spec.base_scene,
                study.settings,
                p.spec.r.values_array(),
                p.spec.beta.values_array(),
            )
            est = per * n
        total_s += est
        n_tasks += p.n_chunks
        print(
            f"{p.spec.name:<24}{p.kind:>7}{n:>12,}{p.n_chunks:>9,}"
            f"{n / p.n_chunks:>10.0f}{est / p.n_chunks:>12.2f}{est:>12.1f}"
        )
    from study.cost import wall_seconds
    from study.drive import local_threads
    from study.memory import MemoryWork

    # where `study run` would compute it (without --workers: threads of its own
    # process for a short study, study.drive.local_threads; else a local cluster)
    threads = 0
    if not args.workers:
        work = MemoryWork()
        for p in plans:
            p.verbose = False
            p.prepare(work)
        threads = local_threads(plans, work, workers)
    wall = wall_seconds(total_s, threads or workers, in_process=bool(threads))
    where = (
        f"in {threads} thread{'s' if threads > 1 else ''} of the run's process (a small study)"
        if threads
        else f"on {workers} workers"
    )
    print(
        f"total: {n_tasks:,} tasks, about {total_s:,.0f} CPU s; about {wall:,.0f} s {where}"
        + ("" if args.calibrate else " (cost model; --calibrate to measure)")
    )
    return 0


#: First bytes of a netCDF file: HDF5 (netCDF4) or classic netCDF.
_NETCDF_MAGIC = (b"\x89HDF\r\n\x1a\n", b"CDF\x01", b"CDF\x02", b"CDF\x05")


def _check_result_file(path: Path) -> None:
    """A regular, readable netCDF file (looked at before anything is created)."""
    if not path.exists():
        raise StudyError("result", f"no such file: {path}")
    if not path.is_file():
        raise StudyError("result", f"not a regular file: {path}")
    try:
        with path.open("rb") as f:
            head = f.read(8)
    except OSError as exc:
        raise StudyError("result", f"cannot read {path}: {exc.strerror}") from None
    if not head.startswith(_NETCDF_MAGIC):
        hint = f" (a study file: run it first, study run {path})" if path.suffix == ".toml" else ""
        raise StudyError("result", f"{path} is not a result file of study run (netCDF){hint}")


def cmd_report(args) -> int:
    """``study report RESULT -o DIR``: check both, then write; say what was written."""
    import shutil
    import time

    _check_result_file(args.result)
    out: Path = args.output
    if out.exists() and not out.is_dir():
        if not args.overwrite:
            raise StudyError("-o", f"{out} exists and is not a folder; --overwrite replaces it")
        out.unlink()
    if not out.parent.is_dir():
        raise StudyError("-o", f"parent folder does not exist: {out.parent}")
    from analysis.report import write_report

    created = not out.exists()
    t0 = time.time()
    try:
        path = write_report(args.result, out)
    except (OSError, ValueError, KeyError, TypeError, IndexError) as exc:
        if created:
            shutil.rmtree(out, ignore_errors=True)
        text = " ".join(str(exc).split())[:200]
        raise StudyError(
            "result", f"cannot report on {args.result}: {type(exc).__name__}: {text}"
        ) from None
    figures = [p for p in out.glob("*.png") if p.stat().st_mtime >= t0 - 1]
    print(f"study: wrote {path} and {len(figures)} figures in {out}", file=sys.stderr)
    return 0


def cmd_bench(args) -> int:
    if args.output.exists() and not args.output.is_dir():
        raise StudyError("-o", f"output is not a directory: {args.output}")
    from study.bench import main_bench

    args.output.mkdir(parents=True, exist_ok=True)
    path = main_bench(args.output, quick=args.quick, log=lambda line: print(line, file=sys.stderr))
    print(f"study: wrote {path} and {path.with_name('pareto.png')}", file=sys.stderr)
    return 0


def cmd_examples(args) -> int:
    from study.examples import list_examples, write_example

    if args.name is None:
        if args.output is not None:
            raise StudyError("-o", "name the example to write: study examples NAME -o FILE")
        try:
            print(list_examples())
        except BrokenPipeError:  # study examples | head: no flush into the closed pipe
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    else:
        write_example(args.name, args.output)
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run one command; ``argv`` None: the command line of this process (the ``study``
    command, ``python -m study``), which then ends at once (:func:`_end_process`)."""
    code = _command(argv)
    if argv is None:
        _end_process(code)
    return code


def _end_process(code: int) -> None:
    """End the process with ``code`` without the interpreter's teardown of the libraries
    it imported (numba, xarray, dask: 0.3-0.6 s after the command is done).

    Only when Dask's ``distributed`` was not imported (its clusters clean up at exit):
    every file is closed, every result saved (:mod:`study.saving`), the threads of a
    small study idle or, after Ctrl-C, stopped with the process.
    """
    if "distributed" in sys.modules:
        return
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # a closed pipe, a closed stream
            stream.flush()
    os._exit(code)


def _command(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    handler = {
        "run": cmd_run,
        "plan": cmd_plan,
        "report": cmd_report,
        "bench": cmd_bench,
        "examples": cmd_examples,
    }[args.command]
    previous = None
    if args.command == "run":
        previous = signal.signal(signal.SIGTERM, _Terminated())
    try:
        return handler(args)
    except StudyError as exc:
        print(f"study: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except StudyInterrupted as exc:
        print(f"study: {exc}", file=sys.stderr)
        return EXIT_TERMINATED if _Terminated.received else EXIT_INTERRUPTED
    except StudyFailed as exc:
        print(f"study: error: {exc}", file=sys.stderr)
        return EXIT_FAILED
    except KeyboardInterrupt:
        print("study: interrupted", file=sys.stderr)
        return EXIT_TERMINATED if _Terminated.received else EXIT_INTERRUPTED
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
