"""The asymmetric ball's rigorous 3D section map (``section_map3``, chart ``(l, r1, r2)``),
multiple-shooting Krawczyk for it and the resumable run (docs/rigorous.md, "The Fig. 4a
level: the 3D section map and multiple shooting")."""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest

pytest.importorskip("flint")

import taylorball as tb  # noqa: E402
from taylorball.charts import reduced_state_from_chart  # noqa: E402
from taylorball.errors import UsageError  # noqa: E402
from taylorball.levels import Levels  # noqa: E402
from taylorball.paper import FIG4_BALL, FIG4A_LEVELS  # noqa: E402
from taylorball.rigorous._balls import arb, exact_arb, working_precision  # noqa: E402
from taylorball.rigorous.section import NotProved, chart_start_state, quarter_turns, section_map3  # noqa: E402

#: The first section point of FIG4A_SADDLE_K10 (chart (l, r1, r2), K = M3) and its return
#: time to the next point, from a float64 run of the section integrator (only a start).
_P0 = (5.007492236298971, -5.30212229105745, 0.8065254635269249)
_K0 = -9.603588045239889
_TAU0 = 1.090894701881621


def _float_map(p, K):
    """heyoka's float64 section map from the chart point ``p`` on the level's root nearest
    ``K`` (the float chart's own root finder): the independent reference (``(l', r1', r2')``,
    return time)."""
    from taylorball.charts import reduced_chart, states_on_section

    lv = FIG4A_LEVELS
    xs = states_on_section(FIG4_BALL, C=lv.C, M_gamma=lv.M_gamma, h=lv.h, point=tuple(float(v) for v in p), g0=0.0,
                           direction=1)
    x0 = xs[int(np.argmin(np.abs(np.asarray(reduced_chart(FIG4_BALL, xs)["K"]) - K)))]
    res = tb.poincare_section("reduced", FIG4_BALL, x0, n_points=1)
    return np.asarray(res.points[0], dtype=float), float(res.times[0]), x0


def test_chart_start_state_is_the_float_chart():
    """The ball start state at ``(l, r1, r2)`` contains the float64 chart's state (the
    public omega converted by the model) to float64 rounding (8 eps of |x| ~ 10: the float
    chart's sines, square roots and divisions)."""
    from taylorball.model import get_system

    lv = FIG4A_LEVELS
    x_pub = reduced_state_from_chart(FIG4_BALL, C=lv.C, M_gamma=lv.M_gamma, K=_K0, l=_P0[0], g=0.0, r1=_P0[1],
                                        r2=_P0[2])
    system = get_system("reduced")
    x_int = np.asarray(system.to_internal(system.check_params(FIG4_BALL).pars, tuple(x_pub)), dtype=float)
    with working_precision(128):
        C, Mg = exact_arb(lv.C), exact_arb(lv.M_gamma)
        xb = chart_start_state(C, Mg, exact_arb(_K0), exact_arb(_P0[1]), exact_arb(_P0[2]), exact_arb(_P0[0]))
        tol = 8 * np.finfo(float).eps * 16  # |x| < 16
        assert all((b + arb(0, tol)).contains(exact_arb(float(v))) for b, v in zip(xb, x_int))
        # l = 0 reproduces the symmetric chart (exactly: the same formulas at sin 0 = 0, cos 0 = 1)
        x0 = chart_start_state(C, Mg, exact_arb(_K0), exact_arb(_P0[1]), exact_arb(_P0[2]))
        xl = chart_start_state(C, Mg, exact_arb(_K0), exact_arb(_P0[1]), exact_arb(_P0[2]), exact_arb(0))
        assert all(a.overlaps(b) for a, b in zip(x0, xl))


def test_section_map3_refuses_bad_arguments_and_says_not_proved_off_the_level():
    """Bad ``l_turns`` or a box of two components: UsageError before any work. A chart box
    off the level (the energy equation has no root near ``K_guess``: the level's ``h``
    moved by 5) and a return-time guess far before the crossing: "not proved" with the
    reason (cheap: the first fails before any flow, the second after 0.05 time units)."""
    with working_precision(53):
        box = [exact_arb(v) for v in _P0]
        with pytest.raises(UsageError, match="l_turns"):
            section_map3(FIG4_BALL, FIG4A_LEVELS, box, _K0, _TAU0, l_turns=1.5, prec=53)  # type: ignore[arg-type]
        with pytest.raises(UsageError, match="three balls"):
            section_map3(FIG4_BALL, FIG4A_LEVELS, box[:2], _K0, _TAU0, l_turns=4, prec=53)
        off = Levels(C=FIG4A_LEVELS.C, M_gamma=FIG4A_LEVELS.M_gamma, h=FIG4A_LEVELS.h + 5.0)
        with pytest.raises(NotProved, match="energy equation's root K is not isolated"):
            section_map3(FIG4_BALL, off, box, _K0, _TAU0, l_turns=4, prec=53, jac=False)
        with pytest.raises(NotProved, match="dg/dt|not isolated|no validated step"):
            section_map3(FIG4_BALL, FIG4A_LEVELS, box, _K0, 0.05, l_turns=4, prec=53, jac=False)


@pytest.mark.slow
def test_section_map3_contains_heyoka_and_c1_box_contains_the_centre_image():
    """The rigorous map at a chart point (80 bits) contains heyoka's float64 image and
    return time up to their float64 error (the float64 section integrator, tolerance eps,
    over one return with expansion ~10: 1e4 eps |x| = 2e-11 with |x| < 10); the wrong branch
    of ``l'`` is "not proved"; the C^1 box's image contains the point image. About 60 + 200
    CPU s (2026-11-29, shared machine)."""
    q, tau, _ = _float_map(_P0, _K0)
    assert quarter_turns(q[0]) == 4
    tol = 1e4 * np.finfo(float).eps * 10
    with working_precision(80):
        pt = [exact_arb(v) for v in _P0]
        se = section_map3(FIG4_BALL, FIG4A_LEVELS, pt, _K0, _TAU0, l_turns=4, prec=80, jac=False)
        assert all((b + arb(0, tol)).contains(exact_arb(float(v))) for b, v in zip(se.P, q))
        assert (se.tau + arb(0, tol)).contains(exact_arb(tau))
        assert max(float(b.rad()) for b in se.P) < 1e-12
        with pytest.raises(NotProved, match="branch|l is not proved"):
            section_map3(FIG4_BALL, FIG4A_LEVELS, pt, _K0, _TAU0, l_turns=2, prec=80, jac=False)
        bx = [v + arb(0, 1e-10) for v in pt]
        sb = section_map3(FIG4_BALL, FIG4A_LEVELS, bx, _K0, _TAU0, l_turns=4, prec=80, jac=True)
        assert all(b.contains(p) for b, p in zip(sb.P, se.P))
        assert len(sb.DP) == 3 and all(len(r) == 3 for r in sb.DP)
        # the Jacobian encloses heyoka's central differences (h = 1e-6: error ~ h^2 |D^3P| +
        # eps/h ~ 1e-8 relative to the entries of size ~10)
        for j in range(3):
            e = np.zeros(3)
            e[j] = 1e-6
            qp = _float_map(np.array(_P0) + e, _K0)[0]
            qm = _float_map(np.array(_P0) - e, _K0)[0]
            d = (qp - qm) / 2e-6
            for i in range(3):
                assert (sb.DP[i][j] + arb(0, 1e-6 * max(1.0, abs(d[i])))).contains(exact_arb(float(d[i])))


# ---------------------------------------------------------------------------------------
# Multiple shooting: the verdict from the jobs' results, and the resumable run.
# ---------------------------------------------------------------------------------------
def _linear_outs(A, centers, shift=0.0):
    """The jobs' results of the linear maps ``P_i(p) = A (p - c_i) + c_{i+1}`` (exact
    balls), as :func:`taylorball.rigorous.proofs._shooting_segment` returns them."""
    from taylorball.rigorous.proofs import _ser

    m = len(centers)
    outs = []
    with working_precision(80):
        for i in range(m):
            nxt = centers[(i + 1) % m]
            P = [_ser(exact_arb(v + (shift if (i, a) == (0, 0) else 0.0))) for a, v in enumerate(nxt)]
            outs.append({"ok": True, "P": P, "DP": [], "tau": _ser(exact_arb(1.0)), "steps": 1, "cpu": 0.0})
            DP = [[_ser(exact_arb(float(A[a][b])) + arb(0, 1e-12)) for b in range(3)] for a in range(3)]
            outs.append({"ok": True, "P": [], "DP": DP, "tau": _ser(exact_arb(1.0)), "steps": 1, "cpu": 0.0})
    return outs


def test_shooting_verdict_3d_proves_a_linear_saddle_and_refuses_tampered_results():
    """Krawczyk on the 3D multiple-shooting map assembled from jobs' results: the cycle of a
    linear saddle (multipliers 0.1, 2, 5 per segment) is proved, hyperbolic, with the trace
    of ``D(P^2)`` = 0.01 + 4 + 25; an image moved by 3 radii, a missing job and a failed job
    are "not proved" with the reason."""
    from taylorball.rigorous.proofs import shooting_verdict

    A = np.diag([0.1, 2.0, 5.0])
    cs = [[1.0, 2.0, 3.0], [4.0, -1.0, 0.5]]
    r = shooting_verdict(_linear_outs(A, cs), cs, 1e-6, prec=80, kind="reduced3", cpu=0.0)
    assert r.proved and r.kind == "hyperbolic", r.message
    with working_precision(80):
        assert r.trace.contains(exact_arb(29.01)) and r.trace.rad() < 1e-9
    bad = shooting_verdict(_linear_outs(A, cs, shift=3e-6), cs, 1e-6, prec=80, kind="reduced3", cpu=0.0)
    assert not bad.proved and "K(X) is not inside X" in bad.message
    part = shooting_verdict(_linear_outs(A, cs)[:3], cs, 1e-6, prec=80, kind="reduced3", cpu=0.0)
    assert not part.proved and "3 of the 4" in part.message
    outs = _linear_outs(A, cs)
    outs[1] = {"ok": False, "message": "dg/dt is not proved > 0", "cpu": 0.0}
    fail = shooting_verdict(outs, cs, 1e-6, prec=80, kind="reduced3", cpu=0.0)
    assert not fail.proved and "segment 0 (box): dg/dt" in fail.message


def _design(**kw):
    from taylorball.rigorous.certificates import periodic_orbit_design

    args = dict(params=FIG4_BALL, levels=FIG4A_LEVELS, centers=[list(_P0)], radius=1e-10, K_guesses=[_K0],
                tau_guesses=[_TAU0], prec=80, kind="reduced3")
    args.update(kw)
    return periodic_orbit_design(**args)


def test_periodic_orbit_run_refuses_bad_and_tampered_state_files(tmp_path):
    """The resumable run's state file: a design with centres of the wrong dimension or with
    ``l_branches`` for reduced3 is refused before any work; a state file whose design was
    changed after it was made (a centre moved), or that belongs to another design, is
    refused; a state file recording a failed job is finished without new work, "not
    proved" with that job's reason."""
    from taylorball.rigorous.periodic_orbit_run import _design_hash, run_periodic_orbit

    with pytest.raises(UsageError, match="3 components"):
        _design(centers=[[1.0, 2.0]])
    with pytest.raises(UsageError, match="l_branches"):
        _design(l_branches=[0.0])
    rec = _design()
    assert rec["claim"] == "periodic_orbit" and rec["l_branches"] == ["3"] and rec["proved"] is False
    path = tmp_path / "run.json"
    state = dict(rec, design_sha256=_design_hash(rec), jobs={"0": {"ok": False, "message": "no validated step to the "
                                                                   "crossing", "cpu": 1.0}})
    path.write_text(json.dumps(state))
    out = run_periodic_orbit(path)
    assert out["proved"] is False and "segment 0 (point): no validated step" in out["message"]
    assert json.loads(path.read_text())["message"] == out["message"]
    with pytest.raises(UsageError, match="another design"):
        run_periodic_orbit(path, record=_design(radius=2e-10))
    moved = json.loads(path.read_text())
    moved["centers"][0][0] = {"hex": float.hex(5.0), "decimal": "5.0"}
    path.write_text(json.dumps(moved))
    with pytest.raises(UsageError, match="changed after it was made"):
        run_periodic_orbit(path)
    with pytest.raises(UsageError, match="does not exist"):
        run_periodic_orbit(tmp_path / "none.json")


def test_classify3_saddle_and_undecided():
    """``classify3``: three real multipliers off the unit circle are "hyperbolic"; a complex
    pair, or a multiplier at 1, is "undecided"."""
    from taylorball.rigorous.proofs import classify3

    def balls(M):
        return [[exact_arb(float(v)) for v in row] for row in M]

    with working_precision(80):
        R = np.array([[1.0, 0.3, 0.0], [0.2, 1.0, 0.1], [0.0, 0.4, 1.0]])
        A = R @ np.diag([0.0155, 7.17, 8.98]) @ np.linalg.inv(R)
        assert classify3(balls(A))[0] == "hyperbolic"
        c, s = math.cos(1.0), math.sin(1.0)
        assert classify3(balls([[2 * c, -2 * s, 0], [2 * s, 2 * c, 0], [0, 0, 0.25]]))[0] == "undecided"
        assert classify3(balls(np.diag([1.0, 0.5, 2.0])))[0] == "undecided"


@pytest.mark.parametrize("workers", [1, 2])
def test_proof_job_pool_hands_every_result_with_its_index(workers):
    """The pool of the resumable proof runs and the checkers (`_run_state.run_jobs`): each
    result reaches `keep` with its job's index; one worker stops at the first result `keep`
    rejects (a failed inclusion decides a proof), two workers run every job."""
    from taylorball.rigorous._run_state import run_jobs

    got = []
    run_jobs(abs, [-1, -2, -3], workers, lambda k, r: got.append((k, r)) or r != 2)
    assert sorted(got) == ([(0, 1), (1, 2)] if workers == 1 else [(0, 1), (1, 2), (2, 3)])


def test_periodic_orbit_run_refuses_bad_workers(tmp_path):
    from taylorball.rigorous.periodic_orbit_run import run_periodic_orbit

    for bad in (0, True, 2.0):
        with pytest.raises(UsageError, match=r"workers must be an integer in \[1, 64\], got"):
            run_periodic_orbit(tmp_path / "run.json", record=_design(), workers=bad)
    assert not (tmp_path / "run.json").exists()


def test_fig4a_design_refuses_unknown_centres():
    from taylorball.rigorous.periodic_orbit_run import fig4a_saddle_design

    with pytest.raises(UsageError, match="centers must be 'float64' or 'real128', got 'quad'"):
        fig4a_saddle_design(centers="quad")


#: The Fig. 4a saddle's 160-bit proof run, kept in the package (docs/rigorous.md, "The Fig. 4a
#: saddle: the 160-bit run"), the certificate made from it, and the state of its check.
_FIG4A_RUN = "fig4a_saddle_k10_run.json"
_FIG4A_CERT = "fig4a_saddle_k10_cert.json"
_FIG4A_CHECK = "fig4a_saddle_k10_check.json"


def _fig4a_run_state():
    from importlib.resources import files

    return json.loads((files("taylorball.rigorous") / "designs" / _FIG4A_RUN).read_text())


def _fig4a_cert():
    from taylorball.rigorous.certificates import CERT_DIR, load_certificate

    return load_certificate(CERT_DIR / _FIG4A_CERT)


def test_fig4a_proof_run_state_resumes_from_a_copy(tmp_path):
    """The committed state of the Fig. 4a proof run: its design is intact (its sha256), all 20
    jobs succeeded, and a copy resumes: a run asked for no job does no work, keeps every
    stored result to the bit and draws the verdict from them (proved); the certificate made
    from it is the shipped one (up to the date it was drawn). The package's own file is never
    written (the copy is)."""
    from taylorball.rigorous.periodic_orbit_run import _design_hash, certificate_from_run, run_periodic_orbit

    rec = _fig4a_run_state()
    assert rec["design_sha256"] == _design_hash(rec) and rec["segments"] == 10
    assert rec["method"]["prec"] == 160 and rec["radius"]["hex"] == (1e-20).hex()
    assert sorted(int(k) for k in rec["jobs"]) == list(range(20)) and all(o["ok"] for o in rec["jobs"].values())
    state = tmp_path / "run.json"
    state.write_text(json.dumps(rec))
    out = run_periodic_orbit(state, only=[])
    assert out["jobs"] == rec["jobs"] and out["proved"] is True, out["message"]
    made = certificate_from_run(state)
    shipped = _fig4a_cert()
    assert sorted(made) == sorted(shipped)
    assert {k: v for k, v in made.items() if k != "proved_on"} == {k: v for k, v in shipped.items() if k != "proved_on"}


def test_shipped_fig4a_certificate_contains_heyoka_s_orbit():
    """The proved Fig. 4a saddle is the orbit heyoka found: the float64 section points of
    ``FIG4A_SADDLE_K10`` (the design's ``centers="float64"``, a fresh float64 section run) lie
    in the proved boxes up to their own error, and the catalogue's period and trace of the map's
    Jacobian (heyoka's variational equations) lie in the proved intervals. No integration in
    ball arithmetic."""
    import re

    from taylorball.periodic_catalog import FIG4A_SADDLE_K10 as E
    from taylorball.rigorous.periodic_orbit_run import fig4a_saddle_design

    cert = _fig4a_cert()
    assert cert["claim"] == "periodic_orbit" and cert["proved"] is True and cert["orbit_type"] == "hyperbolic"
    assert cert["segments"] == 10 and cert["method"]["prec"] == 160
    lo = np.array([float.fromhex(v["hex"]) for v in cert["periodic_box"]["lower"]])
    hi = np.array([float.fromhex(v["hex"]) for v in cert["periodic_box"]["upper"]])
    pts = np.array([float.fromhex(v["hex"]) for c in fig4a_saddle_design()["centers"] for v in c])
    # the float64 orbit closes to ~1e-12 (Newton's stop in multiple shooting) and the map
    # expands by up to |mu| ~ 9: its points are within ~1e-11 = 5e4 eps of the true ones
    tol = 5e4 * np.finfo(float).eps
    assert np.all(lo - tol <= pts) and np.all(pts <= hi + tol), np.max(np.maximum(lo - pts, pts - hi))
    tr = cert["multiplier_trace"]
    assert float.fromhex(tr["lower"]["hex"]) <= E.trace <= float.fromhex(tr["upper"]["hex"])
    m = re.search(r"period \[([0-9.]+) \+/- ([0-9.e-]+)\]", cert["message"])
    assert m and abs(E.period - float(m.group(1))) <= float(m.group(2)), cert["message"]


def test_tampered_fig4a_certificate_is_not_proved_without_integration():
    """The checker says no before any section map to the shipped Fig. 4a certificate with a
    segment count that disagrees with its lists, a record of a failed attempt, or no proved
    box (the full re-check is the slow test below)."""
    import copy

    from taylorball.rigorous.certificates import check_certificate

    cert = _fig4a_cert()
    nine = dict(cert, segments=9)
    res = check_certificate(nine)
    assert not res.ok and "claims 9 segments" in res.message and res.cpu_seconds < 5, res.message
    short = copy.deepcopy(cert)
    short["centers"] = short["centers"][:9]
    res = check_certificate(short)
    assert not res.ok and "claims 10 segments" in res.message and res.cpu_seconds < 5, res.message
    res = check_certificate(dict(cert, proved=False))
    assert not res.ok and res.cpu_seconds < 5, res.message
    nobox = {k: v for k, v in cert.items() if k != "periodic_box"}
    res = check_certificate(nobox)
    assert not res.ok and res.cpu_seconds < 5, res.message


def test_fig4a_check_state_holds_the_run_s_results_to_the_bit():
    """The committed state of the Fig. 4a certificate's check (``prove --check CERT --state``,
    resumable: docs/rigorous.md): made by a check of the run's design, and every job it holds
    recomputed in a fresh process equals the run's result for that job to the bit (the
    computation is deterministic); while jobs are missing it is "not proved yet"."""
    from importlib.resources import files

    from taylorball.rigorous.periodic_orbit_run import _design_hash

    path = files("taylorball.rigorous") / "designs" / _FIG4A_CHECK
    if not path.is_file():
        pytest.skip("no check state committed")
    chk = json.loads(path.read_text())
    run = _fig4a_run_state()
    assert chk["role"] == "check" and chk["design_sha256"] == run["design_sha256"] == _design_hash(chk)
    assert chk["jobs"]
    for k, o in chk["jobs"].items():
        assert {a: v for a, v in o.items() if a not in ("cpu", "on")} == \
            {a: v for a, v in run["jobs"][k].items() if a not in ("cpu", "on")}, k
    if len(chk["jobs"]) < 20:
        assert chk["proved"] is False and "20" in chk["message"]
    else:  # the check from scratch is complete: its verdict is the certificate's
        cert = _fig4a_cert()
        assert chk["proved"] is True and chk["message"] == cert["message"], chk["message"]


def test_fig4a_completed_check_draws_the_certificate_s_verdict_from_its_own_jobs(tmp_path):
    """Resumed on a copy of the committed, complete check state, ``check_periodic_orbit``
    has no enclosure left to compute: it draws the verdict (the Krawczyk step) from the
    check's own 20 jobs and compares it with the certificate's claims, in seconds."""
    import shutil
    from importlib.resources import files

    from taylorball.rigorous.periodic_orbit_run import check_periodic_orbit

    path = files("taylorball.rigorous") / "designs" / _FIG4A_CHECK
    chk = json.loads(path.read_text())
    if len(chk.get("jobs", {})) < 20:
        pytest.skip("the committed check state is not complete")
    state = tmp_path / "check.json"
    shutil.copyfile(str(path), state)
    t0 = time.process_time()
    res = check_periodic_orbit(_fig4a_cert(), state, workers=1)
    spent = time.process_time() - t0
    assert res.ok, res.message
    # the verdict counts the jobs' CPU (about 16000 s); this call ran no section map
    assert res.cpu_seconds > 1e4 and spent < 60, (res.cpu_seconds, spent)
    assert json.loads(state.read_text())["jobs"] == chk["jobs"]


@pytest.mark.slow  # about 17000 CPU s: 2 h 30 min on two idle cores
def test_shipped_fig4a_certificate_checks_from_scratch(tmp_path):
    """``taylorball prove --workers 2 --check fig4a_saddle_k10_cert.json --state FILE`` re-proves
    the Fig. 4a saddle from its design alone in a fresh process (20 section-map enclosures at
    160 bits and the Krawczyk step): exit 0."""
    import subprocess
    import sys

    from taylorball.rigorous.certificates import CERT_DIR

    out = subprocess.run([sys.executable, "-m", "taylorball.cli", "prove", "--workers", "2", "--check",
                          str(CERT_DIR / _FIG4A_CERT), "--state", str(tmp_path / "check.json")], capture_output=True,
                         text=True)
    assert out.returncode == 0 and ": proved: a unique periodic orbit" in out.stdout, out.stdout + out.stderr


@pytest.mark.slow  # ~60 CPU s: the real128 refinement and section run of the design
def test_fig4a_real128_design_is_the_committed_run_s_design():
    """``fig4a_saddle_design(prec=160, radius=1e-20, centers="real128")`` reproduces, bit for
    bit (its sha256), the design of the committed proof run, so the run can be resumed from
    the package's function as well as from its file."""
    from taylorball.rigorous.periodic_orbit_run import _design_hash, fig4a_saddle_design

    rec = fig4a_saddle_design(prec=160, radius=1e-20, centers="real128")
    assert _design_hash(rec) == _fig4a_run_state()["design_sha256"]
