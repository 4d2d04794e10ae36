"""The ``taylorball`` command line: the verify table (100 columns, each claim once), its
JSON and markdown outputs, ``verify --precision --json/--markdown FILE``, output paths
checked before any work, the compile notice through ``logging`` with ``-v``/``-q`` (also
in spawned workers), the library silent by default, ``--help`` without markup."""

import json
import logging
import os
import re
import shutil
import subprocess
import sys

import pytest

from taylorball import _cache, cli
from taylorball.verify import VERDICTS, CheckResult, format_table
from taylorball.verify import charts as charts_checks
from taylorball.verify import precision as precision_mod

RECORD_KEYS = {"topic", "name", "claim", "reference", "verdict", "residual", "tolerance", "detail"}
FAST_TOPIC = "measures"  # the quickest verify topic (~1.5 s)


@pytest.fixture(autouse=True)
def _restore_logging():
    """cli.main configures the "taylorball" logger; leave it as the library has it."""
    logger = logging.getLogger("taylorball")
    handlers, level = list(logger.handlers), logger.level
    yield
    logger.handlers[:] = handlers
    logger.setLevel(level)


def _run(args, env_extra=None, **kw):
    env = dict(os.environ, **(env_extra or {}))
    env.pop("TQDM_DISABLE", None)
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, env=env, timeout=600, **kw)


def _table_claims(out: str):
    """The claims of a verify table, read back from its claim column (continuation lines
    of a claim start with two spaces, topic lines are ``[topic]``)."""
    lines = out.splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("claim "))
    width = lines[head].index("paper")
    claims = []
    for line in lines[head + 2:-1]:  # after the rule, before the summary
        if re.fullmatch(r"\[\w+\]", line) or line.startswith("    "):  # topic line, details
            continue
        cell = line[:width].rstrip()
        if cell.startswith("  "):
            claims[-1] += " " + cell.strip()
        elif cell:
            claims.append(cell)
    return claims


# --- the verify table and its machine-readable forms ----------------------------------
def test_verify_table_json_and_markdown(capsys, tmp_path):
    """One quick topic: ``--json`` alone puts only JSON on stdout (a list of records);
    the table lists each claim exactly once in lines of at most 100 columns, and the same
    run can write the JSON and markdown files; progress on stderr does not repeat claims."""
    assert cli.main(["verify", "--only", FAST_TOPIC, "--json"]) == 0
    cap = capsys.readouterr()
    recs = json.loads(cap.out)  # the whole of stdout is the JSON document
    assert isinstance(recs, list) and recs
    for r in recs:
        assert set(r) == RECORD_KEYS
        assert r["topic"] == FAST_TOPIC and r["name"].startswith("check") and r["verdict"] in VERDICTS
        assert r["residual"] is None or isinstance(r["residual"], float)
    claims = [r["claim"] for r in recs]

    jpath, mpath = tmp_path / "v.json", tmp_path / "v.md"
    assert cli.main(["verify", "--only", FAST_TOPIC, "--json", str(jpath), "--markdown", str(mpath)]) == 0
    cap = capsys.readouterr()
    assert all(len(line) <= 100 for line in cap.out.splitlines()), max(cap.out.splitlines(), key=len)
    lines = cap.out.splitlines()
    assert lines[0].startswith("taylorball verify (quick)") and lines[1] == "" and lines[2].startswith("claim ")
    assert _table_claims(cap.out) == claims  # with the above: each claim once on stdout, in order
    assert not any(c in cap.err for c in claims)  # progress names checks, not claims
    assert cap.out.splitlines()[-1].endswith("0 failed")
    assert [r["claim"] for r in json.loads(jpath.read_text())] == claims
    md = mpath.read_text()
    assert md.startswith("| topic | claim |")
    assert all("| " + c.replace("|", "\\|") + " |" in md for c in claims)  # markdown escapes |
    assert not list(tmp_path.glob(".*.tmp"))  # atomic writes leave no temporary files


def test_table_wraps_long_claims_and_references():
    """A long claim, a long paper reference and long details wrap within 100 columns;
    verdict, residual and tolerance stay on the row's first line."""
    claim = "a claim " * 40
    res = [CheckResult(claim.strip(), "sec. 5, eqs. (19)-(21) [sved], (22) [Mpn2], and more", "verified",
                       1.5e-16, 2e-15, "detail " * 50, topic="charts", name="check_long"),
           CheckResult("short", "eq. (1) [eq1]", "erratum corrected", topic="charts", name="check_short"),
           CheckResult("failing one", "-", "failed", float("inf"), 1.0, topic="sections", name="check_f")]
    for details in (False, True):
        text = format_table(res, details=details)
        lines = text.splitlines()
        assert all(len(line) <= 100 for line in lines)
        assert _table_claims(text) == [r.claim for r in res]
        first = next(line for line in lines if line.startswith("a claim"))
        assert "verified" in first and "1.50e-16" in first and "2.00e-15" in first and "sec. 5" in first
        assert lines[-1] == "3 checks: 1 verified, 1 errata corrected, 1 failed"
        assert ("    detail detail" in text) == details


def test_table_keeps_a_printed_number_with_its_label():
    """A wrapped paper reference breaks between citations, not inside "(2) [eq4]" (the form of
    docs/equations.md); a range too long for the column may break before its label."""
    ref = "eqs. (1) [eq1], (2) [eq4], (6) [eq2], (8)-(10) [eq6]"
    text = format_table([CheckResult("a claim", ref, "verified", 0.0, 0.0, topic="formulas", name="check_x")])
    head = text.splitlines()[0]
    cells = [line[head.index("paper"):head.index("verdict")].strip() for line in text.splitlines()[3:-1]]
    assert cells == ["eqs.", "(1) [eq1],", "(2) [eq4],", "(6) [eq2],", "(8)-(10)", "[eq6]"], cells
    assert "\u00a0" not in text


def test_failed_check_json_and_exit_status(monkeypatch, capsys):
    """A failing check: exit status 1, JSON still valid with the failed record; NaN and
    infinite residuals become null (strict JSON)."""
    monkeypatch.setattr(charts_checks, "CHECKS", [
        lambda full: CheckResult("fails", "-", "failed", 1.0, 0.5),
        lambda full: [CheckResult("n/a", "-", "verified"), CheckResult("inf", "-", "failed", float("inf"))]])
    assert cli.main(["verify", "--only", "charts", "--json"]) == 1
    recs = json.loads(capsys.readouterr().out, parse_constant=lambda c: pytest.fail(f"non-JSON {c}"))
    assert [(r["claim"], r["verdict"], r["residual"]) for r in recs] == [
        ("fails", "failed", 1.0), ("n/a", "verified", None), ("inf", "failed", None)]


# --- output paths are checked before any work -----------------------------------------
def _no_study(*a, **k):
    raise AssertionError("the study ran before the output path was checked")


@pytest.mark.parametrize("argv_tail", [
    ["--precision", "--json", "{missing}/out.json"],
    ["--precision", "--markdown", "{missing}/out.md"],
    ["--precision", "--json", "{tmp}"],  # a folder, not a file
    ["--json", "{missing}/out.json"],
    ["--markdown", "{missing}/out.md"],
])
def test_bad_output_path_fails_fast(argv_tail, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(precision_mod, "precision_study", _no_study)
    monkeypatch.setattr(charts_checks, "CHECKS", [_no_study])
    subs = {"missing": str(tmp_path / "no" / "such"), "tmp": str(tmp_path)}
    tail = [a.format(**subs) for a in argv_tail]
    argv = ["verify", *tail] if "--precision" in tail else ["verify", "--only", "charts", *tail]
    assert cli.main(argv) == 2
    cap = capsys.readouterr()
    err = cap.err.strip().splitlines()
    assert len(err) == 1 and argv[-1] in err[0] and cap.out == "", cap
    assert not (tmp_path / "no").exists()


def test_reproduce_out_under_a_file_fails_fast(tmp_path, capsys):
    (tmp_path / "f").write_text("")
    assert cli.main(["reproduce", "--only", "fig2", "--out", str(tmp_path / "f" / "out")]) == 2
    assert "--out" in capsys.readouterr().err


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root may write anywhere")
def test_unwritable_folder_fails_fast(tmp_path, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        assert cli.main(["verify", "--precision", "--json", str(ro / "x.json")]) == 2
        assert "not writable" in capsys.readouterr().err
    finally:
        ro.chmod(0o700)


def test_usage_errors_of_verify(capsys):
    assert cli.main(["verify", "--only", "nope"]) == 2
    assert "unknown topic" in capsys.readouterr().err
    assert cli.main(["verify", "--t-end", "2"]) == 2
    assert "--precision" in capsys.readouterr().err


# --- verify --precision writes its results --------------------------------------------
def test_precision_json_and_markdown_files(tmp_path, capsys):
    """A short precision run (one orbit to t = 2, ~1 s) writes strict JSON and markdown
    atomically; with ``--json`` alone the JSON is all of stdout."""
    jpath, mpath = tmp_path / "p.json", tmp_path / "p.md"
    base = ["verify", "--precision", "--only", "mparallel-ball", "--t-end", "2"]
    assert cli.main(base + ["--json", str(jpath), "--markdown", str(mpath)]) == 0
    out = capsys.readouterr().out
    assert "correct digits" in out
    strict = {"parse_constant": lambda c: pytest.fail(f"non-JSON constant {c}")}
    rep = json.loads(jpath.read_text(), **strict)
    assert rep["mode"] == "quick" and [r["orbit"]["name"] for r in rep["results"]] == ["mparallel-ball"]
    assert rep["results"][0]["times"][-1] == 2.0
    assert "### mparallel-ball" in mpath.read_text()
    assert cli.main(base + ["--json"]) == 0
    cap = capsys.readouterr()
    assert json.loads(cap.out, **strict)["results"][0]["orbit"]["name"] == "mparallel-ball"
    assert "correct digits" in cap.err  # the tables moved to stderr


# --- logging: the compile notice, -v / -q ---------------------------------------------
def test_compile_notice_once_per_key(caplog):
    """In-process: one INFO line for a new key, none when it is asked for again."""
    caplog.set_level(logging.INFO, logger="taylorball")
    key = ("test-notice", os.getpid(), id(caplog))
    assert _cache.compiled(key, lambda: 41) == 41
    assert _cache.compiled(key, lambda: 42) == 41
    notes = [r for r in caplog.records if r.name == "taylorball.compile" and "test-notice" in r.getMessage()]
    assert len(notes) == 1 and notes[0].levelno == logging.INFO
    assert notes[0].getMessage().startswith("compiling test-notice ")


def test_slow_build_is_announced_while_it_runs(caplog, monkeypatch):
    """A build still running after SLOW_BUILD_NOTICE_S is announced at that moment, once
    (no second line after it); the disk-cache test calls a build "loaded" only when heyoka's
    in-memory cache grew while its disk cache did not."""
    import time as _time

    caplog.set_level(logging.INFO, logger="taylorball")
    monkeypatch.setattr(_cache, "SLOW_BUILD_NOTICE_S", 0.05)
    key = ("test-slow", os.getpid(), id(caplog))
    assert _cache.compiled(key, lambda: _time.sleep(0.5) or 7) == 7
    notes = [r.getMessage() for r in caplog.records if r.name == "taylorball.compile" and "test-slow" in r.getMessage()]
    assert len(notes) == 1 and notes[0].startswith("compiling test-slow ") and "not in heyoka's disk cache" in notes[0]
    assert _cache._served_by_disk_cache((0, 100), (5, 100))
    assert not _cache._served_by_disk_cache((0, 100), (5, 120))  # compiled and stored
    assert not _cache._served_by_disk_cache((5, 100), (5, 100))  # nothing new (in-memory)
    assert not _cache._served_by_disk_cache(None, (5, 100))


def test_compile_notice_on_stderr_and_quiet(tmp_path):
    """A new process (fresh heyoka disk cache via XDG_CACHE_HOME): the demo's integrator
    compile is announced once on stderr, the first notice naming the disk cache folder;
    -q (before or after the subcommand) hides it; a warm run says the disk cache served it;
    -v adds the DEBUG build timings; the library alone says nothing."""
    env = {"XDG_CACHE_HOME": str(tmp_path / "cache")}
    demo = ["-m", "taylorball", "demo", "--t", "0.1"]
    r = _run(demo, env)
    assert r.returncode == 0, r.stderr
    notes = [line for line in r.stderr.splitlines() if "compiling" in line]
    assert sum("compiling integrator full" in line for line in notes) == 1, r.stderr
    assert len(notes) == len(set(notes))  # one line per distinct build
    assert notes[0].startswith("taylorball: compiling ") and str(tmp_path / "cache" / "heyoka") in notes[0]
    assert "compiling" not in r.stdout
    for argv in (["-m", "taylorball", "-q", *demo[2:]], [*demo, "-q"]):
        r = _run(argv, env)
        assert r.returncode == 0 and "compiling" not in r.stderr, r.stderr
    r = _run(["-m", "taylorball", "demo", "-v", "--t", "0.1"], env)
    # warm now: heyoka's disk cache serves the machine code, and the notice says so
    assert "loaded integrator full momentum float from heyoka's disk cache" in r.stderr, r.stderr
    assert "compiling integrator full" not in r.stderr and "debug: built integrator full" in r.stderr
    r = _run(["-c", "import taylorball as tb, logging; from taylorball.paper import FIG5_BALL as b, "
                    "demo_reduced_state as s; tb.propagate('full', b, tb.reduced_to_full(b, s()), 0.1); "
                    "logging.getLogger('taylorball.x').warning('not shown')"], env)
    assert r.returncode == 0 and r.stderr == "", r.stderr


def test_verbosity_flags_set_the_level():
    logger = logging.getLogger("taylorball")
    for argv, level in ((["verify"], logging.INFO), (["-v", "verify"], logging.DEBUG),
                        (["-q", "verify"], logging.WARNING), (["verify", "-q"], logging.WARNING),
                        (["verify", "--verbose"], logging.DEBUG), (["-v", "verify", "-q"], logging.WARNING)):
        assert cli.main(argv + ["--only", "nope"]) == 2
        assert logger.level == level, argv
        assert sum(isinstance(h, cli._StderrHandler) for h in logger.handlers) == 1


def _level_in_worker(level):
    cli._worker_logging(level)
    return logging.getLogger("taylorball").getEffectiveLevel()


def test_spawned_worker_gets_the_level():
    """A ``reproduce --workers`` worker (a spawned process of the engine) installs the parent's level."""
    from taylorball.ensemble import call, run_many

    assert run_many([call(_level_in_worker, logging.DEBUG)], backend="processes", workers=1) == [logging.DEBUG]


@pytest.mark.slow
def test_reproduce_workers_log_at_the_commands_level(tmp_path):
    """``taylorball -v reproduce --workers 2``: the workers' compile notices and their DEBUG
    build lines reach stderr, labelled by worker (5 s warm on a quiet machine, 18 s
    measured under load: slow-marked; the initializer is tested above)."""
    r = _run(["-m", "taylorball", "-v", "reproduce", "--only", "fig2,fig5", "--workers", "2",
              "--out", str(tmp_path)])
    assert r.returncode == 0, r.stderr
    assert re.search(r"^taylorball \(worker \d+\): (compiling|loaded) ", r.stderr, re.M), r.stderr
    assert re.search(r"^taylorball \(worker \d+\): debug: built ", r.stderr, re.M), r.stderr


# --- help texts -----------------------------------------------------------------------
@pytest.mark.parametrize("sub", [[], ["reproduce"], ["verify"], ["demo"]])
def test_help_has_no_markup(sub, capsys):
    with pytest.raises(SystemExit) as e:
        cli.main([*sub, "--help"])
    assert e.value.code == 0
    text = capsys.readouterr().out
    assert text.startswith("usage: taylorball")
    assert "``" not in text and not re.search(r":(func|mod|class|data|meth|attr):", text), text


# --- bad command lines end in one clear line and status 2, before any work -------------
@pytest.mark.parametrize("argv, fragment", [
    (["reproduce", "--only", ","], "--only: no figure named"),
    (["reproduce", "--only", "fig9"], "--only: unknown figure"),
    (["reproduce", "--workers", "0"], "--workers must be a positive integer"),
    (["reproduce", "--workers", "-1"], "--workers must be a positive integer"),
    (["demo", "--t", "nan"], "--t must be finite"),
    (["demo", "--t", "inf"], "--t must be finite"),
])
def test_bad_command_lines(argv, fragment, capsys, tmp_path):
    assert cli.main(["-q", *argv, *(["--out", str(tmp_path / "o")] if argv[0] == "reproduce" else [])]) == 2
    err = capsys.readouterr().err
    assert fragment in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()  # nothing was computed or written


def test_plot_only_without_data_says_so_before_any_work(capsys, tmp_path):
    assert cli.main(["-q", "reproduce", "--plot-only", "--only", "fig2", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "--plot-only re-plots saved data" in err and "fig2_homogeneous.npz" in err


def test_full_alone_is_the_papers_figures(capsys, tmp_path):
    # --full without --only: Figs. 1-5 only (the extra studies' FULL configs take tens of
    # minutes); seen through --plot-only, which names every study it would run before any work
    from taylorball.figures import runner

    assert cli.main(["-q", "reproduce", "--full", "--plot-only", "--out", str(tmp_path)]) == 2
    out, err = capsys.readouterr()
    assert all(f"{name}_full.npz" in err for name in runner.FIGURES)
    assert not any(name in err for name in runner.EXTRA_FIGURES)
    assert "need --only NAME" in out
    # named, an extra study runs at full density
    assert cli.main(["-q", "reproduce", "--full", "--plot-only", "--only", "megno_map", "--out", str(tmp_path)]) == 2
    assert "megno_map_full.npz" in capsys.readouterr().err


# --- errors of the operating system and a closed stdout: one line, no traceback ----------
def _ok_check(full):
    return CheckResult("a quick claim", "-", "verified", 0.0, 1.0)


_STUDY = """\
[ball]
inertia = [2.0, 3.0, 4.0]
mass = 1.0
radius = 5.0
plane_rate = 2.0
[level]
G = 10.0
H = 2.0
h = 5.0
[orbits]
n = 1
[run]
t_end = 20.0
checkpoint_every = 10.0
backend = "serial"
[output]
store = "{store}"
"""


def _files(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


@pytest.mark.parametrize("case", ["nul", "long name", "parent is a file"])
@pytest.mark.parametrize("cmd", ["run", "reproduce --out", "verify --json", "verify --markdown"])
def test_bad_paths_end_in_one_line_before_any_work(cmd, case, tmp_path, monkeypatch, capsys):
    """A NUL, a 300-character name or a file where a folder must be: one line naming the
    option, the path and the reason, exit status 2, before any work, nothing written (these
    ended in a ValueError / OSError / FileExistsError traceback with exit status 1)."""
    monkeypatch.setattr(charts_checks, "CHECKS", [_no_study])
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("")
    path = {"nul": "a\0b", "long name": "x" * 300, "parent is a file": "afile/inner"}[case]
    if cmd == "run":
        if case == "nul":
            path = "a\\u0000b"  # TOML's escape: the store's name holds a NUL
        (tmp_path / "s.toml").write_text(_STUDY.format(store=path))
        argv = ["run", "s.toml"]
    elif cmd == "reproduce --out":
        argv = ["reproduce", "--only", "fig2", "--out", path]
    else:
        argv = ["verify", "--only", "charts", cmd.split()[1], path]
    before = _files(tmp_path)
    assert cli.main(argv) == 2
    cap = capsys.readouterr()
    err = cap.err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in cap.err, cap.err
    reason = {"nul": "NUL character", "long name": "File name too long", "parent is a file": "afile is a file"}
    assert reason[case] in err[0], err[0]
    assert _files(tmp_path) == before  # no store, no output folder, no probe left behind


@pytest.mark.parametrize("err", [(28, "No space left on device"), (30, "Read-only file system")])
def test_write_error_names_the_file_and_leaves_nothing(err, tmp_path, monkeypatch, capsys):
    """The disk fills up (or turns read-only) while the results are written: one line naming
    the file and the system's reason, exit status 2, the table already printed, no partial
    or temporary file left (this ended in a traceback with exit status 1)."""
    import taylorball.io as tio

    monkeypatch.setattr(charts_checks, "CHECKS", [_ok_check])

    def fsync(fd):
        raise OSError(*err)

    monkeypatch.setattr(tio.os, "fsync", fsync)
    out = tmp_path / "res.json"
    assert cli.main(["-q", "verify", "--only", "charts", "--json", str(out)]) == 2
    cap = capsys.readouterr()
    assert "a quick claim" in cap.out  # the table came first: nothing is lost
    assert cap.err.strip() == f"taylorball: error: cannot write {out}: {err[1]}", cap.err
    assert _files(tmp_path) == []


def test_read_only_folder_is_found_before_any_work(tmp_path, monkeypatch, capsys):
    """A read-only file system (which os.access does not see for root): the probe file
    the check creates is refused, and the command stops before any work."""
    import tempfile

    monkeypatch.setattr(charts_checks, "CHECKS", [_no_study])

    def mkstemp(*a, **k):
        raise OSError(30, "Read-only file system")

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    for argv in (["verify", "--only", "charts", "--json", str(tmp_path / "x.json")],
                 ["reproduce", "--only", "fig2", "--out", str(tmp_path / "out")]):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "not writable (Read-only file system)" in err[0], err
    assert _files(tmp_path) == []


def test_run_names_its_store_on_an_os_error(tmp_path, monkeypatch, capsys):
    """zarr's write on a full disk raises an OSError that names no file: the command names
    the store."""
    import taylorball.study as study_mod

    def full_disk(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(study_mod, "run_study", full_disk)
    (tmp_path / "s.toml").write_text(_STUDY.format(store="st"))
    assert cli.main(["run", str(tmp_path / "s.toml")]) == 2
    assert capsys.readouterr().err.strip() == f"taylorball: error: cannot write {tmp_path / 'st'}: No space left on device"


def _mount_tmpfs(where, options):
    """A small tmpfs at ``where`` (root with mount rights only), or skip."""
    where.mkdir()
    if not (hasattr(os, "geteuid") and os.geteuid() == 0 and shutil.which("mount")):
        pytest.skip("mounting a tmpfs needs root")
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(where)], capture_output=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.decode().strip()}")


@pytest.fixture
def tmpfs(tmp_path):
    mounted = []

    def mount(name, options):
        where = tmp_path / name
        _mount_tmpfs(where, options)
        mounted.append(where)
        return where

    yield mount
    for where in mounted:
        subprocess.run(["umount", str(where)], capture_output=True)


def test_real_full_and_read_only_file_systems(tmpfs, capsys):
    """On a real 64 kB tmpfs a quick figure fills the disk; on a read-only one nothing can
    be written: one line each, exit status 2, no partial file (where a tmpfs can be mounted)."""
    full = tmpfs("full", "size=64k")
    assert cli.main(["-q", "reproduce", "--only", "fig2", "--out", str(full / "out")]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("taylorball")]  # no bars
    assert len(err) == 1 and "No space left on device" in err[0] and str(full / "out") in err[0], err
    assert not [p for p in full.rglob("*") if p.is_file()]  # no half-written data or image
    ro = tmpfs("ro", "ro,size=64k")
    assert cli.main(["-q", "verify", "--only", "measures", "--json", str(ro / "x.json")]) == 2
    assert "Read-only file system" in capsys.readouterr().err
    assert cli.main(["-q", "reproduce", "--only", "fig2", "--out", str(ro / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--out" in err[0] and "Read-only file system" in err[0], err


@pytest.mark.parametrize("argv", [["verify", "--only", "measures"], ["verify", "--only", "measures", "--json"]])
def test_closed_stdout_ends_quietly(argv):
    """``taylorball verify --json | head -1``: the reader went away. The command ends as a
    Unix tool does, without a BrokenPipeError traceback, with status 141 (128 + SIGPIPE).
    The pipe's read end is closed before the command starts, so every write fails."""
    r, w = os.pipe()
    os.close(r)
    try:
        env = dict(os.environ, TQDM_DISABLE="1")
        p = subprocess.run([sys.executable, "-m", "taylorball", *argv], stdout=w, stderr=subprocess.PIPE,
                           text=True, env=env, timeout=600)
    finally:
        os.close(w)
    assert p.returncode == 141, p.stderr
    assert "Traceback" not in p.stderr and "BrokenPipe" not in p.stderr and "Exception ignored" not in p.stderr


# --- the user guide from the command line (a wheel has no docs/ folder) ----------------
def test_help_points_to_pages_the_user_has(capsys):
    """The help named docs/longruns.md, which a wheel does not contain; it names the page
    ``taylorball docs longruns`` prints (from the installed package data; in a checkout from
    docs/ itself; the wheel's copy is checked in tests/test_packaging.py)."""
    for sub in ([], ["run"], ["reproduce"]):
        with pytest.raises(SystemExit):
            cli.main([*sub, "--help"])
        text = capsys.readouterr().out
        assert "docs/" not in text, text
    with pytest.raises(SystemExit):
        cli.main(["run", "--help"])
    assert "taylorball docs longruns" in capsys.readouterr().out.replace("\n", " ")
    assert cli.main(["docs"]) == 0
    listing = capsys.readouterr().out
    assert "longruns" in listing and "getting-started" in listing and " api " not in listing
    assert cli.main(["docs", "longruns"]) == 0
    page = capsys.readouterr().out
    assert page.startswith("# ") and "[output]" in page and "store" in page
    assert cli.main(["docs", "nope"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no page 'nope'" in err[0] and "longruns" in err[0]


def test_run_on_a_full_disk_stops_in_one_line_and_resumes(tmpfs, capsys):
    """``taylorball run`` on a real 24 kB tmpfs: the disk fills while the store is made;
    one line naming the store, exit status 2; with room again (the tmpfs grown), the same
    command completes the run."""
    disk = tmpfs("disk", "size=24k")
    study = disk / "s.toml"
    study.write_text(_STUDY.format(store="st"))
    assert cli.main(["-q", "run", str(study)]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("taylorball")]
    assert err == [f"taylorball: error: cannot write {disk / 'st'}: No space left on device"], err
    subprocess.run(["mount", "-o", "remount,size=20m", str(disk)], check=True)
    assert cli.main(["-q", "run", str(study)]) == 0
    assert "t_end 20" in capsys.readouterr().out


def test_reproduce_workers_report_a_full_disk_in_one_line_each(tmp_path, monkeypatch, capsys):
    """With figures in worker processes, a figure whose files meet a full disk is reported
    in one line (the file and the reason, no exception class) and the command exits with 2
    (the disk, not a figure, failed); another failure keeps exit status 1."""
    import taylorball.ensemble as ens

    def fake_run_many(jobs, *, on_result, **kw):
        on_result(0, ens.MemberFailure(0, OSError(28, "No space left on device", str(tmp_path / "o" / "a.png"))))
        on_result(1, "fig3_symmetric: data ... (fake)")

    monkeypatch.setattr(ens, "run_many", fake_run_many)
    assert cli.main(["-q", "reproduce", "--only", "fig2,fig3", "--workers", "2", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert any(line.endswith(f"FAILED: cannot write {tmp_path / 'o' / 'a.png'}: No space left on device")
               for line in err), err

    def fake_failure(jobs, *, on_result, **kw):
        on_result(0, ens.MemberFailure(0, RuntimeError("a bug")))

    monkeypatch.setattr(ens, "run_many", fake_failure)
    assert cli.main(["-q", "reproduce", "--only", "fig2,fig3", "--workers", "2", "--out", str(tmp_path / "o")]) == 1


def test_reproduce_jobs_is_the_old_name_of_workers(tmp_path, capsys):
    """``--jobs N`` keeps working for one release, with a note naming ``--workers``; both
    together are refused (exit 2)."""
    argv = ["-q", "reproduce", "--only", "fig2", "--out", str(tmp_path)]
    assert cli.main(argv + ["--jobs", "1", "--workers", "1"]) == 2
    assert "give --workers only" in capsys.readouterr().err
    assert cli.main(argv + ["--jobs", "0"]) == 2  # the old name, checked as the new one
    err = capsys.readouterr().err
    assert "--jobs is deprecated: use --workers" in err and "--workers must be a positive integer" in err


def test_quiet_hides_the_figures_progress_bars():
    """``-q`` (the package's log at warnings only) turns the figures' progress bars off:
    every figure module passes its bar through ``_common.bar`` (before, ``reproduce -q``
    with one worker drew the MEGNO and section bars)."""
    import logging
    import re
    from pathlib import Path

    from taylorball.figures import _common as C

    log = logging.getLogger("taylorball")
    old = log.level
    try:
        log.setLevel(logging.WARNING)
        assert C.bar("x") is False and C.bar() is False
        log.setLevel(logging.INFO)
        assert C.bar("x") == "x" and C.bar() is True
    finally:
        log.setLevel(old)
    for f in (Path(__file__).resolve().parents[1] / "taylorball" / "figures").glob("*.py"):
        literal = re.findall(r"progress=(?:True|f?\"[^\"]*\")", f.read_text())
        assert not literal, (f.name, literal)


def test_reproduce_worker_imports_heyoka_without_sympy():
    """A reproduce worker's heyoka import skips heyoka's sympy interop (cli._heyoka_without_sympy:
    ~0.45 CPU s of each worker's start): sympy is not loaded by it, stays importable afterwards,
    heyoka integrates, and only heyoka's sympy conversion says it is off. In a fresh process
    (heyoka is already imported in this one, where the function does nothing)."""
    code = ("import sys\n"
            "from taylorball.cli import _heyoka_without_sympy\n"
            "_heyoka_without_sympy()\n"
            "assert 'heyoka' in sys.modules and 'sympy' not in sys.modules, sorted(sys.modules)[:5]\n"
            "import heyoka as hy, sympy\n"
            "x = hy.make_vars('x')\n"
            "ta = hy.taylor_adaptive([(x, -x)], [1.0]); ta.propagate_until(1.0)\n"
            "assert abs(ta.state[0] - 0.36787944117144233) < 1e-14\n"  # exp(-1); 1e-14 is ~45 eps: the integrator tolerance is eps
            "try:\n    hy.to_sympy(x)\nexcept ImportError as e:\n    print('off:', e)\n")
    r = _run(["-c", code])
    assert r.returncode == 0, r.stderr
    assert "off:" in r.stdout and "sympy" in r.stdout
    # with heyoka already imported (this process), nothing changes
    import heyoka  # noqa: F401

    before = set(sys.modules)
    cli._heyoka_without_sympy()
    assert set(sys.modules) == before
