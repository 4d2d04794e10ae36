"""The ``taylorball`` command (``python -m taylorball`` is the same).

Subcommands: ``reproduce`` (the paper's figures, from :mod:`taylorball.figures`), ``verify``
(the paper's claims, :mod:`taylorball.verify`; ``--precision``: the precision study,
:mod:`taylorball.verify.precision`), ``demo``. Their ``--help`` texts come from
:data:`DESCRIPTION` and the parser built in :func:`main` (plain text, no markup).

Logging: the command shows the ``taylorball`` logger's INFO records on stderr (one line per
compiled object, :mod:`taylorball._cache`, and progress), ``-q`` only warnings, ``-v`` also
DEBUG (compile timings). Spawned worker processes get the same level explicitly.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import time
from typing import Optional, Sequence
from pathlib import Path

import numpy as np

__all__ = ["main", "DESCRIPTION"]

DESCRIPTION = """\
High-precision Taylor integration of the Chaplygin ball on a rotating plane: reproduce
and verify the paper (Bizyaev, Borisov & Mamaev).

  taylorball reproduce     regenerate the paper's figures (quick by default, --full for
                           publication density), N figures at a time in worker processes
  taylorball verify        check every checkable claim of the paper; a table of verdicts
                           (exit status 1 if a check fails), --json for machines
  taylorball verify --precision
                           precision study: digits of float64, long double, real128
                           against a 256-bit reference, drift and cost per number type
  taylorball demo          propagate the Fig. 5 ball and print its integrals and drift
  taylorball run STUDY.toml [--extend T] [--restart] [--workers N] [--force]
                           your own long runs: run, resume or extend a study file's orbits
  taylorball status STUDY.toml
                           per-orbit progress, integral drift and time left of a study
  taylorball docs [TOPIC]  the user guide's pages as installed with the package (study
                           files and long runs: taylorball docs longruns)
  taylorball explore [--port P] [--no-browser]
                           Poincare sections in the browser: click, watch orbits come in
  taylorball prove --check CERT [--state FILE] | --list
                           re-verify a certificate of a validated computation from scratch

Compiling a system takes seconds the first time; heyoka keeps the machine code on disk, so
later runs start faster. A line on stderr says what is being compiled (-q hides it).
"python -m taylorball" is the same command."""

# -v / -q: the level of the "taylorball" logger's handler on stderr
_LEVELS = {-1: logging.WARNING, 0: logging.INFO, 1: logging.DEBUG}


class _StderrHandler(logging.StreamHandler):
    """Writes to whatever ``sys.stderr`` is at the time (tests swap it); through
    ``tqdm.write`` when tqdm is loaded, so that a line does not land inside a progress bar."""

    def __init__(self):
        super().__init__(sys.stderr)

    @property
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, value):  # StreamHandler.__init__ assigns it; always sys.stderr
        pass

    def emit(self, record):
        tqdm = sys.modules.get("tqdm")
        if tqdm is None:
            return super().emit(record)
        try:
            tqdm.tqdm.write(self.format(record), file=sys.stderr)
        except Exception:  # logging's own policy for a failing handler
            self.handleError(record)


class _Formatter(logging.Formatter):
    def __init__(self, name: str):
        super().__init__()
        self.name = name

    def format(self, record):
        msg = record.getMessage()
        if record.levelno == logging.INFO:
            return f"{self.name}: {msg}"
        return f"{self.name}: {record.levelname.lower()}: {msg}"


def configure_logging(level: int, *, name: str = "taylorball") -> None:
    """Show the ``taylorball`` logger's records at ``level`` and above on stderr, each line
    starting with ``name`` (one handler, replaced on a second call). Only the command calls
    this: the library itself never configures logging."""
    logger = logging.getLogger("taylorball")
    for h in list(logger.handlers):
        if isinstance(h, _StderrHandler):
            logger.removeHandler(h)
    handler = _StderrHandler()
    handler.setFormatter(_Formatter(name))
    logger.addHandler(handler)
    logger.setLevel(level)


def _nearest_existing(p: Path) -> Path:
    """``p`` or its nearest ancestor that exists (``lexists``: no error for a long name)."""
    probe = p
    while not os.path.lexists(probe) and probe != probe.parent:
        probe = probe.parent
    return probe


def _check_writable(option: str, path: "str | os.PathLike[str]", *, folder: bool) -> None:
    """A path the command will write (a file, or a folder it creates if needed) is checked
    before any work, so that a typo or a read-only disk does not cost a long run: no NUL
    character, every name within the file system's length limit, no file where a folder
    must be, and the nearest existing folder takes a new file (a probe file is created and
    removed at once: this also finds a read-only file system, which ``os.access`` does not
    see for root). Raises :class:`~taylorball.errors.UsageError` naming ``option``, the path
    and the reason."""
    import errno
    import tempfile

    from .errors import UsageError

    text = os.fspath(path)
    if "\0" in text:
        raise UsageError(f"{option}: cannot write {text!r}: a path cannot contain a NUL character")
    p = Path(text).absolute()
    probe = _nearest_existing(p)
    try:
        name_max = os.pathconf(probe if probe.is_dir() else probe.parent, "PC_NAME_MAX")
    except (OSError, ValueError):
        name_max = 255
    for part in p.relative_to(probe).parts:
        if len(os.fsencode(part)) > name_max:
            raise UsageError(f"{option}: cannot write {text}: the name {part[:16]}... is {len(os.fsencode(part))} "
                             f"bytes long; the file system takes at most {name_max} "
                             f"({os.strerror(errno.ENAMETOOLONG)})")
    if p.is_dir() and not folder:
        raise UsageError(f"{option}: {text} is a folder; give a file name, e.g. {p / 'out'}")
    if os.path.lexists(p) and not p.is_dir() and folder:
        raise UsageError(f"{option}: cannot write into {text}: it is a file, not a folder")
    if not probe.is_dir():
        raise UsageError(f"{option}: cannot write {text}: {probe} is a file, not a folder")
    if not folder and probe != p and probe != p.parent:
        raise UsageError(f"{option}: cannot write {text}: folder {p.parent} does not exist")
    try:
        fd, tmp = tempfile.mkstemp(dir=probe, prefix=".taylorball-probe-", suffix=".tmp")
    except OSError as exc:
        raise UsageError(f"{option}: cannot write {text}: folder {probe} is not writable "
                         f"({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(tmp)


def _check_output_file(option: str, path: str) -> None:
    """A file argument is usable when its folder exists and takes a new file and it is not
    a folder itself (:func:`_check_writable`)."""
    _check_writable(option, path, folder=False)


def _check_output_dir(option: str, path: str) -> None:
    """An output folder is usable when it is a writable folder or can be created: its
    nearest existing ancestor is a folder that takes a new file (:func:`_check_writable`)."""
    _check_writable(option, path, folder=True)


def _os_error_line(exc: OSError) -> str:
    """One line for an OS error: the path and the system's reason; where a folder of the
    path is a file (``mkdir`` then says "File exists", ``open`` "Not a directory"), says so."""
    name = exc.filename if exc.filename is not None else ""
    reason = exc.strerror or str(exc)
    if name:
        p = Path(os.fsdecode(name))
        for parent in [p, *p.parents]:
            if os.path.lexists(parent) and not parent.is_dir() and parent != p:
                return f"cannot write {p}: {parent} is a file, not a folder"
        if exc.filename2 is not None:
            return f"{os.fsdecode(name)} -> {os.fsdecode(exc.filename2)}: {reason}"
        return f"cannot write {p}: {reason}" if exc.errno in _WRITE_ERRNOS else f"{p}: {reason}"
    return reason


def _write_errnos() -> frozenset:
    import errno

    names = ("ENOSPC", "EROFS", "EDQUOT", "EFBIG")  # errors only a write meets
    return frozenset(getattr(errno, n) for n in names if hasattr(errno, n))


_WRITE_ERRNOS = _write_errnos()


def cmd_demo(args) -> int:
    """Propagate the Fig. 5 ball and print its integrals and their drift."""
    import taylorball as tb
    from taylorball.paper import FIG5_BALL, demo_reduced_state

    from .numbers import times

    times("--t", args.t)  # checked before any work
    params = FIG5_BALL
    full0 = tb.reduced_to_full(params, demo_reduced_state())
    print(f"Fig. 5 ball: {params}")
    print(f"initial full state (omega, alpha, beta, gamma, x, y):\n  {np.array2string(full0, precision=6)}")
    i0 = tb.integrals("full", params, full0)
    scales = tb.integral_scales("full", params, full0)
    t_end = float(args.t)
    t0 = time.perf_counter()
    full1 = tb.propagate("full", params, full0, t_end)
    wall = time.perf_counter() - t0
    i1 = tb.integrals("full", params, full1, check=False)
    s1 = tb.integral_scales("full", params, full1, check=False)
    scales = {k: max(scales[k], s1[k]) for k in scales}  # the larger of the two ends
    geo = tb.geometric_integrals("full", params, full1)
    print(f"propagated to t = {t_end:g} in {wall:.2f} s (float64, tol = eps)")
    print(f"  {'integral':<12}{'t = 0':>24}{'t = end':>24}{'drift/scale':>14}")
    for k in i0:
        print(f"  {k:<12}{i0[k]:>24.16g}{i1[k]:>24.16g}{(i1[k] - i0[k]) / scales[k]:>14.2e}")
    worst = max(abs(geo[k] - (1.0 if k.endswith("2") else 0.0)) for k in geo)
    print(f"  frame orthonormality error at t = end: {worst:.2e}")
    print(f"  contact point at t = end: x = {full1[12]:.6f}, y = {full1[13]:.6f}")
    return 0


def cmd_reproduce(args) -> int:
    from .figures import runner

    names = runner.figure_studies()
    if args.full and not args.only:
        # the extra studies' FULL configurations take tens of minutes each (taylorball docs figures):
        # --full alone is the paper's figures; an extra study at full density is asked for by name
        names = list(runner.FIGURES)
        print(f"--full: the paper's figures; the studies {', '.join(runner.EXTRA_FIGURES)} at full density "
              "need --only NAME (tens of minutes each: taylorball docs figures)")
    if args.only:
        names = names + list(runner.ON_REQUEST)
        wanted = [w.strip() for w in args.only.split(",") if w.strip()]
        unknown = [w for w in wanted if not any(n == w or n.startswith(w + "_") for n in names)]
        if unknown:
            print(f"--only: unknown figure(s) {unknown}; available: {names}", file=sys.stderr)
            return 2
        names = [n for n in names if any(n == w or n.startswith(w + "_") for w in wanted)]
        if not names:
            print(f"--only: no figure named in {args.only!r}; available: {runner.figure_studies()}",
                  file=sys.stderr)
            return 2
    if args.jobs_old is not None:  # the old name, for one release
        if args.workers is not None:
            print("give --workers only (--jobs is its old name)", file=sys.stderr)
            return 2
        print("--jobs is deprecated: use --workers N (the same: figures computed at once)", file=sys.stderr)
        args.workers = args.jobs_old
    if args.workers is not None and args.workers < 1:
        print(f"--workers must be a positive integer (figures computed at once), got {args.workers!r}; "
              "leave it out for one per core", file=sys.stderr)
        return 2
    _check_output_dir("--out", args.out)
    out = Path(args.out)
    if args.plot_only:
        runner.check_plot_only(names, out, args.full)
    jobs = min(args.workers or os.cpu_count() or 1, len(names))
    print(f"regenerating {len(names)} figure(s) ({'full' if args.full else 'quick'}) into {out.resolve()}"
          + (f", {jobs} at a time" if jobs > 1 else ""))
    t0 = time.perf_counter()
    if jobs == 1:
        for name in names:
            runner.run(runner.load_study(name), full=args.full, outdir=out, plot_only=args.plot_only)
        print(f"done in {time.perf_counter() - t0:.1f} s")
        return 0
    # one process per figure at a time on the many-orbit engine (spawned: heyoka and threads
    # do not survive a fork; progress bars off in the workers, they would interleave), a line
    # per finished figure; a failed figure is reported and the others finish (exit 1); Ctrl-C
    # ends the workers, drops the queued figures (a figure's files are written atomically, so
    # the finished ones are complete and the others absent) and exits 130
    from .ensemble import MemberFailure, call, run_many

    if not args.full:
        names = runner.schedule(names, jobs)  # longest first: the workers end together
    failed, finished = [], []
    level = logging.getLogger("taylorball").getEffectiveLevel()

    os_errors = []

    def report(i, r):
        if isinstance(r, MemberFailure):
            failed.append(names[i])
            if isinstance(r.error, OSError):  # the disk, not the figure: one line, exit 2
                os_errors.append(names[i])
                print(f"{names[i]}: FAILED: {_os_error_line(r.error)}", file=sys.stderr, flush=True)
            else:
                print(f"{names[i]}: FAILED: {type(r.error).__name__}: {r.error}", file=sys.stderr, flush=True)
        else:
            finished.append(names[i])
            print(r, flush=True)

    try:
        run_many([call(_reproduce_one, name, args.full, str(out), args.plot_only, level) for name in names],
                 backend="processes", workers=jobs, on_error="keep", on_result=report)
    except KeyboardInterrupt:
        print(f"interrupted after {time.perf_counter() - t0:.1f} s; finished: {', '.join(finished) or 'none'}",
              file=sys.stderr, flush=True)
        return 130
    print(f"done in {time.perf_counter() - t0:.1f} s" + (f"; failed: {', '.join(failed)}" if failed else ""))
    return 2 if os_errors else 1 if failed else 0


_WORKER_LOGGING: list = []


def _worker_logging(log_level: int) -> None:
    """Logging of a spawned worker (which starts with a fresh ``logging``): the parent's
    level, lines labelled by worker; once per process."""
    if not _WORKER_LOGGING:
        configure_logging(log_level, name=f"taylorball (worker {os.getpid()})")
        _WORKER_LOGGING.append(log_level)


def _heyoka_without_sympy() -> None:
    """Import heyoka in a ``reproduce`` worker without its optional sympy interop: heyoka's
    import loads sympy when it is installed (for ``heyoka.from_sympy`` / ``to_sympy``),
    ~0.45 CPU s of each worker's start (measured 2026-11-29: ``import heyoka`` 0.63 CPU s
    with sympy, 0.18 s without), and the figure studies never convert sympy expressions. sympy
    itself stays importable in the worker afterwards; only heyoka's conversions are off
    there. Nothing happens if heyoka or sympy is already imported."""
    if "heyoka" in sys.modules or "sympy" in sys.modules:
        return
    sys.modules["sympy"] = None  # type: ignore[assignment]  # import sympy fails: heyoka skips its interop
    try:
        import heyoka  # noqa: F401
    finally:
        del sys.modules["sympy"]


def _reproduce_one(name, full, out, plot_only, log_level=logging.INFO):
    """One figure in a worker process (the parent's logging level: spawned workers start
    with a fresh ``logging``); returns its log line."""
    from .figures import runner

    _worker_logging(log_level)
    _heyoka_without_sympy()
    lines = []
    runner.run(runner.load_study(name), full=full, outdir=Path(out), plot_only=plot_only, log=lines.append)
    return "\n".join(lines)


def cmd_verify(args) -> int:
    for option, value in (("--json", args.json), ("--markdown", args.markdown)):
        if value is not None and value != "-":
            _check_output_file(option, value)
    if args.markdown == "-":
        return _usage("--markdown needs a file name (for the table on stdout, leave --markdown out)")
    only = [w.strip() for w in args.only.split(",") if w.strip()]
    if args.precision:
        if args.details:
            return _usage("--details applies to the claims table, not to --precision")
        from .verify.precision import run_precision

        return run_precision(args.full, only=only or None, t_end=args.t_end, json_out=args.json,
                             markdown_out=args.markdown)
    if args.t_end is not None:
        return _usage("--t-end applies to --precision only")
    from .verify import CHECK_MODULES, run_verify

    bad = [m for m in only if m not in CHECK_MODULES]
    if bad:
        return _usage(f"--only: unknown topic(s) {bad}; valid: {', '.join(CHECK_MODULES)}")
    return run_verify(args.full, only or CHECK_MODULES, details=args.details, json_out=args.json,
                      markdown_out=args.markdown)


def cmd_run(args) -> int:
    """Run, resume or extend a study (see taylorball.study)."""
    from .study import Terminated, load_study, run_study

    cfg = load_study(args.study)
    _check_output_dir("[output] store", str(cfg.store))  # a NUL, a long name, a file on the way, read-only
    try:
        status = run_study(cfg, extend=args.extend, restart=args.restart, workers=args.workers,
                           progress=args.verbosity >= 0, force=args.force)
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM: every committed chunk is kept, rerun to resume
        what = "terminated (SIGTERM)" if isinstance(exc, Terminated) else "interrupted"
        print(f"{what}; the committed chunks are kept: rerun the same command to resume", file=sys.stderr,
              flush=True)
        return 143 if isinstance(exc, Terminated) else 130
    except BrokenPipeError:
        raise
    except OSError as exc:  # zarr's write on a full disk names no file: name the store
        if exc.filename is None and exc.errno is not None:
            raise type(exc)(exc.errno, exc.strerror, str(cfg.store)) from exc
        raise
    print(status.table())
    return 0


def cmd_status(args) -> int:
    """Per-orbit progress of a study's store."""
    from .study import study_status

    print(study_status(args.study).table())
    return 0


_NOT_PAGES = ("index", "api")  # Sphinx scaffolding, not pages to read in a terminal (setup.py: the same)


def _doc_pages() -> dict:
    """The user guide's pages by topic: the copies a wheel installs (``taylorball/_pages``,
    put there by setup.py), else, in a checkout, ``docs/*.md`` themselves."""
    from importlib import resources

    pages: dict = {}
    installed = resources.files("taylorball").joinpath("_pages")
    if installed.is_dir():
        pages = {f.name[:-3]: f for f in installed.iterdir() if f.name.endswith(".md")}
    if not pages:
        docs = Path(__file__).resolve().parent.parent / "docs"
        pages = {f.stem: f for f in docs.glob("*.md") if f.stem not in _NOT_PAGES}
    return dict(sorted(pages.items()))


def cmd_docs(args) -> int:
    """Print a page of the user guide (markdown), or list the topics."""
    pages = _doc_pages()
    if not pages:
        return _usage("no pages of the user guide are installed with this copy of taylorball")
    if args.topic is None:
        print("topics (taylorball docs TOPIC prints the page; pipe it to a pager):")
        for name, page in pages.items():
            title = next((line.lstrip("# ").strip() for line in page.read_text(encoding="utf-8").splitlines()
                          if line.startswith("# ")), "")
            print(f"  {name:<18}{title}")
        return 0
    if args.topic not in pages:
        return _usage(f"docs: no page {args.topic!r}; topics: {', '.join(pages)}")
    sys.stdout.write(pages[args.topic].read_text(encoding="utf-8"))
    return 0
def cmd_prove(args) -> int:
    """``taylorball prove --check CERT`` / ``--list``: re-verify a certificate of
    :mod:`taylorball.rigorous` from scratch (exit 0 only if it checks), or list them."""
    from .errors import UsageError

    try:
        from .rigorous import certificates as certs
        from .rigorous._balls import require_flint

        require_flint()
    except ImportError as exc:
        raise UsageError(str(exc)) from None
    if args.list is not None or not args.check:
        rows = certs.list_certificates(args.list or None)
        for name, claim, title in rows:
            print(f"{name}: {claim}: {title}")
        if not rows:
            print("no certificates found")
        return 0
    if not 1 <= args.workers <= 64:
        raise UsageError(f"--workers must be an integer in [1, 64], got {args.workers}")
    if args.state is not None:
        if len(args.check) != 1:
            raise UsageError(f"--state keeps the check of one certificate, got {len(args.check)} certificates")
        if Path(args.state).resolve() == Path(args.check[0]).resolve():
            raise UsageError(f"--state must be a file of the check's own, not the certificate itself ({args.state!r})")
    status = 0
    for path in args.check:
        cert = certs.load_certificate(path)
        if args.state is not None:
            from .rigorous.periodic_orbit_run import check_periodic_orbit

            res = check_periodic_orbit(cert, args.state, workers=args.workers)
        else:
            res = certs.check_certificate(cert, workers=args.workers)
        print(f"{path}: {res.message} [{res.cpu_seconds:.1f} CPU s]")
        status = status if res.ok else 1
    return status


def _usage(message: str) -> int:
    print(f"taylorball: error: {message}", file=sys.stderr)
    return 2


def _add_verbosity(parser, default) -> None:
    """-v / -q, on the top-level parser (default 0) and on each subcommand (default
    SUPPRESS, so that "taylorball -v reproduce" is not reset by the subcommand)."""
    g = parser.add_mutually_exclusive_group()
    g.add_argument("-v", "--verbose", dest="verbosity", action="store_const", const=1, default=default,
                   help="also show debug messages (what is compiled and how long it takes)")
    g.add_argument("-q", "--quiet", dest="verbosity", action="store_const", const=-1, default=default,
                   help="show warnings only (no compile notices, no progress lines)")


def cmd_explore(args) -> int:
    """``taylorball explore``: serve the section explorer until Ctrl-C."""
    from .explore import serve

    serve(args.port, open_browser=not args.no_browser)
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the ``taylorball`` command with ``argv`` (default: ``sys.argv[1:]``); returns the
    exit status: 0 success, 1 a failed check or figure, 2 a usage error or an error of the
    operating system (a full disk, a read-only file system, a name too long: one line on
    stderr naming the path and the reason), 130 interrupted, 143 terminated (SIGTERM,
    ``run``), 141 when the reader of stdout went away (``taylorball verify --json | head -1``).

    A closed stdout ends the command quietly, as it ends a Unix tool (which SIGPIPE kills:
    the shell reports 128 + 13 = 141, so ``set -o pipefail`` still sees that the output was
    cut): the recipe of the Python documentation (``signal`` module, "Note on SIGPIPE"),
    stdout pointed at ``os.devnull`` so that the interpreter's final flush finds no pipe."""
    try:
        status = _main(argv)
        sys.stdout.flush()  # inside the try: the last buffered lines may meet the closed pipe
        return status
    except BrokenPipeError:
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):  # a stdout without a file descriptor (tests)
            pass
        return 141


def _main(argv: Optional[Sequence[str]]) -> int:
    from ._version import __version__
    from .errors import StoreError, TaylorballError, UsageError

    parser = argparse.ArgumentParser(prog="taylorball", description=DESCRIPTION,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"taylorball {__version__}")
    _add_verbosity(parser, 0)
    sub = parser.add_subparsers(dest="cmd", required=True, metavar="{reproduce,verify,demo,run,status,docs,explore,prove}")
    p = sub.add_parser("reproduce", help="regenerate the paper's figures (quick by default)",
                       description="Regenerate the paper's figures: data files with JSON sidecars in "
                                   "OUT/data, figures in OUT/figures (PNG; with --full also PDF).")
    p.add_argument("--full", action="store_true", help="publication density (slow)")
    p.add_argument("--only", default="", help="comma-separated figures, e.g. fig2,fig4")
    p.add_argument("--out", default="output", help="output folder (default ./output)")
    p.add_argument("--plot-only", action="store_true", help="re-plot saved data without computing")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="figures computed at once, each in its own process (default: the number of cores)")
    p.add_argument("--jobs", dest="jobs_old", type=int, default=None, help=argparse.SUPPRESS)  # old name of --workers
    _add_verbosity(p, argparse.SUPPRESS)
    p.set_defaults(func=cmd_reproduce)
    p = sub.add_parser(
        "verify", help="check the paper's claims; table of verdicts",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Check every checkable claim of the paper: one row per claim with its paper\n"
                    "reference, verdict (verified, erratum corrected, failed), residual and tolerance.\n"
                    "Exit status 1 if a check fails, 2 for a usage error.\n\n"
                    "With --precision: the precision study across number types (float64, long double,\n"
                    "real128 against a 256-bit reference); exit status 1 if the reference is not\n"
                    "clearly more accurate than every compared type.")
    p.add_argument("--full", action="store_true", help="more samples, longer runs")
    p.add_argument("--precision", action="store_true", help="run the precision study instead of the claims")
    p.add_argument("--only", default="", metavar="NAMES",
                   help="comma-separated topics (formulas, closed_forms, measures, charts, sections, chaos); "
                        "with --precision: orbit names (reduced-fig4a, mparallel-ball)")
    p.add_argument("--details", action="store_true", help="print how each residual was measured")
    p.add_argument("--json", nargs="?", const="-", default=None, metavar="FILE",
                   help="the results as JSON: into FILE (written atomically; the table is still printed), "
                        "or without FILE on stdout instead of the table (progress stays on stderr)")
    p.add_argument("--markdown", default=None, metavar="FILE",
                   help="also write the results as markdown tables to FILE")
    p.add_argument("--t-end", type=float, default=None, metavar="T",
                   help="with --precision: override every orbit's final time (short runs)")
    _add_verbosity(p, argparse.SUPPRESS)
    p.set_defaults(func=cmd_verify)
    p = sub.add_parser("demo", help="propagate the Fig. 5 ball and print its integrals and drift",
                       description="Propagate the Fig. 5 ball in float64 and print its first integrals at "
                                   "both ends and their drift.")
    p.add_argument("--t", default=1000.0, type=float, help="final time (default 1000)")
    _add_verbosity(p, argparse.SUPPRESS)
    p.set_defaults(func=cmd_demo)
    p = sub.add_parser("run", help="run, resume or extend a study file's long runs",
                       description="Run every orbit of a study file (TOML; its keys: taylorball docs longruns) into its store; "
                                   "rerunning resumes, --extend T continues every orbit to T (bit-identical to a "
                                   "direct run). Exit status 2 for a bad study file or store, 130 interrupted "
                                   "(Ctrl-C), 143 terminated (SIGTERM); both keep every committed chunk.")
    p.add_argument("study", help="the study file (TOML)")
    p.add_argument("--extend", type=float, default=None, metavar="T",
                   help="run every orbit to the end time T (a multiple of checkpoint_every)")
    p.add_argument("--restart", action="store_true", help="replace the store by a new one (atomically)")
    p.add_argument("--workers", type=int, default=None, metavar="N", help="threads or processes")
    p.add_argument("--force", action="store_true",
                   help="resume or extend a store written with another heyoka version, CPU or SIMD width "
                        "(recorded in the store)")
    _add_verbosity(p, argparse.SUPPRESS)
    p.set_defaults(func=cmd_run)
    p = sub.add_parser("status", help="per-orbit progress of a study",
                       description="Per orbit: time done, chunks, steps, largest relative integral drift so far, "
                                   "wall time per chunk and the estimated time left (one worker).")
    p.add_argument("study", help="the study file (TOML)")
    _add_verbosity(p, argparse.SUPPRESS)
    p.set_defaults(func=cmd_status)
    p = sub.add_parser("docs", help="print a page of the user guide (installed with the package)",
                       description="Print a page of the user guide (markdown) as installed with the package; "
                                   "without TOPIC, list the topics. E.g. taylorball docs longruns (study files, "
                                   "long runs) | less")
    p.add_argument("topic", nargs="?", default=None, help="the page, e.g. longruns, getting-started, transport")
    _add_verbosity(p, argparse.SUPPRESS)
    p.set_defaults(func=cmd_docs)
    p = sub.add_parser("explore", help="Poincare sections in the browser (needs the 'explore' extra)",
                       description="Serve an interactive section explorer at http://127.0.0.1:PORT/ (a local Bokeh "
                                   "server): click on the section, orbits are integrated in the background. "
                                   "Ctrl-C stops it. Needs pip install \"taylorball[explore]\".")
    p.add_argument("--port", type=int, default=5006, help="TCP port on 127.0.0.1 (default 5006; 0: a free one)")
    p.add_argument("--no-browser", action="store_true", help="do not open a browser")
    _add_verbosity(p, argparse.SUPPRESS)
    p.set_defaults(func=cmd_explore)
    p = sub.add_parser("prove", help="check or list the certificates of validated computations",
                       description="Re-verify certificates of taylorball.rigorous from scratch in this process "
                                   "(exit status 0 only if every one checks, 1 if one does not), or list the "
                                   "certificates shipped with the package. Needs the extra 'rigorous'.")
    p.add_argument("--check", nargs="+", default=None, metavar="CERT", help="certificate JSON file(s) to check")
    p.add_argument("--list", nargs="?", const="", default=None, metavar="DIR",
                   help="list the certificates (*cert*.json) in DIR (default: the package's)")
    p.add_argument("--workers", type=int, default=1, metavar="N",
                   help="processes for the independent covering relations of a covering-relations certificate "
                        "and for the segments of a periodic-orbit (multiple-shooting) one (default 1)")
    p.add_argument("--state", default=None, metavar="FILE",
                   help="periodic-orbit certificates: keep each finished section-map enclosure of the check in FILE "
                        "(made on first use), so that a long check stopped part-way goes on where it was when run "
                        "again with the same FILE")
    _add_verbosity(p, argparse.SUPPRESS)
    p.set_defaults(func=cmd_prove)
    args = parser.parse_args(argv)
    configure_logging(_LEVELS[args.verbosity])
    try:
        return args.func(args)
    except UsageError as exc:
        if args.verbosity > 0:
            raise
        return _usage(str(exc))
    except TaylorballError as exc:  # a bad study file or store (run, status): one line, exit 2
        if (args.verbosity > 0 or args.func not in (cmd_run, cmd_status)
                or not isinstance(exc, (ValueError, StoreError))):
            raise
        return _usage(str(exc))
    except BrokenPipeError:
        raise  # main's: the reader went away
    except OSError as exc:  # the system refused: a full disk, a read-only file system, ...
        if args.verbosity > 0:
            raise
        return _usage(_os_error_line(exc))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
