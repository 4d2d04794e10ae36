"""Multiple-shooting Krawczyk proofs of periodic orbits of the 2D section maps
(taylorball.rigorous.proofs.krawczyk_periodic_orbit), and the refined energy root of the
symmetric ball's section map."""

from __future__ import annotations

import json

import numpy as np
import pytest

flint = pytest.importorskip("flint", reason="python-flint is not installed (optional extra 'rigorous')")

from taylorball.errors import UsageError  # noqa: E402
from taylorball.paper import FIG1_LEVELS, FIG3_BALL, FIG3_LEVELS, fig1_params  # noqa: E402
from taylorball.rigorous._balls import exact_arb, working_precision  # noqa: E402
from taylorball.rigorous.certificates import CERT_DIR  # noqa: E402
from taylorball.rigorous.proofs import _des, _ser, krawczyk_periodic_orbit  # noqa: E402

arb = flint.arb

#: Fig. 1's a, d are unphysical by design (the paper's M||gamma example)
pytestmark = pytest.mark.filterwarnings("ignore::taylorball.params.UnphysicalParametersWarning")


def _fig1_saddle():
    """The Fig. 1 saddle's candidate as stored in its shipped certificate (float64 Newton)."""
    cert = json.loads((CERT_DIR / "fig1_saddle_l0_cert.json").read_text())
    center = [float.fromhex(v["hex"]) for v in cert["center"]]
    return center, float.fromhex(cert["K_guess"]["hex"]), float.fromhex(cert["tau_guess"]["hex"])


def test_ball_serialisation_is_exact():
    """The worker processes' balls: the midpoint survives exactly, the radius rounded up."""
    with working_precision(128):
        for x in (arb(1) / 3, arb(-7) / 3 + arb(0, 1e-20), arb(2) ** 100 / 7, arb(0)):
            y = _des(_ser(x))
            assert y.contains(x) and y.mid() == x.mid()
            assert float(y.rad()) <= 2 * float(x.rad()) + 1e-300


@pytest.mark.slow  # the default run re-proves the same 2-segment orbit with 2 workers (and checks its trace
# against heyoka's multipliers): test_shipped_shooting_certificate_checks_in_a_fresh_process_with_workers
def test_shooting_two_segments_proves_the_fig1_saddle_with_workers():
    """Two segments through the same fixed point (F(p0, p1) = (P(p0) - p1, P(p1) - p0)) in two
    worker processes: proved, hyperbolic, and the trace of D(P^2) encloses heyoka's float64
    multipliers' squares (0.2804^2 + 3.5662^2, tb.periodic_orbit: an independent computation).
    About 25 CPU s at 53 bits."""
    import taylorball as tb
    from taylorball._chart_mparallel import mparallel_states_on_section

    center, G, tau = _fig1_saddle()
    r = krawczyk_periodic_orbit(fig1_params(), FIG1_LEVELS, [center, center], 1e-7, [G, G], [tau, tau], prec=53,
                                kind="mparallel", l_branches=[0.0, 0.0], workers=2)
    assert r.proved and r.kind == "hyperbolic", r.message
    x0 = mparallel_states_on_section(fig1_params(), **FIG1_LEVELS.as_kwargs(), point=(0.0, 0.0))[0]
    mu = np.abs(tb.periodic_orbit("mparallel", fig1_params(), x0, levels=FIG1_LEVELS).multipliers)
    with working_precision(53):
        assert r.trace.contains(exact_arb(float(np.sum(mu ** 2))))
        assert sum(r.taus, exact_arb(0)).contains(exact_arb(2 * tau))  # tau: heyoka's float64 return time


def test_shooting_off_the_orbit_is_not_proved():
    """The box moved by three radii in L/G: K(X) is not inside X, "not proved"; the
    certificate written for it records the failure, claims no box, and never checks."""
    from taylorball.rigorous.certificates import check_certificate, periodic_orbit_certificate

    center, G, tau = _fig1_saddle()
    cert = periodic_orbit_certificate(fig1_params(), FIG1_LEVELS, [[center[0], center[1] + 3e-7]], 1e-7, [G], [tau],
                                      prec=53, kind="mparallel")
    assert cert["proved"] is False and cert["message"].startswith("not proved: K(X) is not inside X")
    assert "periodic_box" not in cert and cert["segments"] == 1 and cert["method"]["order"] == 18
    res = check_certificate(cert)
    assert not res.ok and "failed attempt" in res.message


@pytest.mark.parametrize("kw,word", [
    (dict(radius=0.0), "radius"), (dict(workers=0), "workers"), (dict(kind="full"), "kind"),
    (dict(l_branches=[1.0]), "l_branches"), (dict(K_guesses=[1.0, 2.0]), "K_guesses"),
])
def test_shooting_bad_arguments_are_refused(kw, word):
    center, G, tau = _fig1_saddle()
    args = dict(centers=[center], radius=1e-7, K_guesses=[G], tau_guesses=[tau], kind="mparallel")
    args.update(kw)
    with pytest.raises(UsageError, match=word):
        krawczyk_periodic_orbit(fig1_params(), FIG1_LEVELS, **args)


def test_refined_energy_root_is_tight_near_the_pole():
    """On the Fig. 3 level at the saddle's section point (-7.0759, -0.5831) the root K = M3 of
    the energy equation is near -C (the chart's pole); a float64 guess 2e-8 off leaves the
    single interval Newton image 1e-14 wide at 128 bits, the refined one below 1e-30."""
    from taylorball.model import get_system
    from taylorball.rigorous.enclosure import ball_pars
    from taylorball.rigorous.section import _newton_root, energy_residual

    p, K_guess = (-7.075896990683475, -0.5831278211157831), -9.999219055821328
    with working_precision(128):
        c = get_system("reduced").constants(ball_pars("reduced", FIG3_BALL))
        C, Mg, h = (exact_arb(v) for v in (FIG3_LEVELS.C, FIG3_LEVELS.M_gamma, FIG3_LEVELS.h))
        F = energy_residual(c, C, Mg, h, exact_arb(p[0]), exact_arb(p[1]))
        one = _newton_root(F, K_guess, (1e-6,), "K")
        ref = _newton_root(F, K_guess, (1e-6,), "K", refine=8)
        assert one.contains(ref) and float(ref.rad()) < 1e-30 < 1e-16 < float(one.rad())
        assert F(ref).contains(exact_arb(0))


# ---------------------------------------------------------------------------------------
# Krawczyk's operator (shared by the fixed-point and the multiple-shooting proofs)
# ---------------------------------------------------------------------------------------
def test_krawczyk_operator_on_a_linear_map_with_a_known_zero():
    """F(y) = A y - A z (exact rationals: the zero z is known exactly). In the box z' +- r
    with z' = z + 0.3 r: K(X) is inside and contains z; with the box moved by 3 r it is not
    inside, and `over` is positive (how far K sticks out)."""
    from fractions import Fraction

    from taylorball.rigorous.proofs import krawczyk_operator

    A = [[Fraction(3), Fraction(1, 2), Fraction(0)], [Fraction(-1), Fraction(2), Fraction(1, 4)],
         [Fraction(1, 8), Fraction(0), Fraction(-5)]]
    z = [Fraction(1, 3), Fraction(-2, 7), Fraction(5, 11)]
    r = 1e-6
    with working_precision(128):
        DF = [[exact_arb(a) for a in row] for row in A]
        mid = np.array([[float(a) for a in row] for row in A])
        zb = [exact_arb(v) for v in z]
        for shift, expect in ((0.3, True), (3.0, False)):
            x = [exact_arb(float(v) + shift * r) for v in z]
            X = [v + arb(0, r) for v in x]
            Fx = [sum((DF[i][j] * (x[j] - zb[j]) for j in range(3)), exact_arb(0)) for i in range(3)]
            K, inside, over = krawczyk_operator(x, X, Fx, DF, mid)
            assert inside is expect and (over <= 0) is expect
            if expect:
                assert all(k.contains(v) for k, v in zip(K, zb))
                assert max(float(k.rad()) for k in K) < 1e-20  # F linear, C exact up to rounding


def test_krawczyk_operator_refuses_mismatched_sizes():
    from taylorball.rigorous.proofs import krawczyk_operator

    with working_precision(53):
        one = exact_arb(1)
        with pytest.raises(UsageError, match="n x n"):
            krawczyk_operator([one, one], [one, one], [one, one], [[one]], np.eye(1))


# ---------------------------------------------------------------------------------------
# The periodic_orbit certificate (multiple shooting)
# ---------------------------------------------------------------------------------------
#: The fields of a certificate that say when the proof ran and what it cost.
_COST_KEYS = ("proved_on", "proved_cpu_seconds")


def _shooting_cert():
    from taylorball.rigorous.certificates import FIG1_SHOOTING_CERT_NAME, load_certificate

    return load_certificate(CERT_DIR / FIG1_SHOOTING_CERT_NAME)


@pytest.mark.long
def test_shipped_shooting_certificate_checks_in_a_fresh_process_with_workers(tmp_path):
    """The shipped 2-segment certificate of the Fig. 1 saddle re-checks through the command
    line in a fresh process with two workers, keeping its jobs in a new state file (exit 0;
    ~20 CPU s at 53 bits), is listed by `prove --list`, and its proved boxes contain heyoka's
    float64 fixed point (both points of the period-2 orbit are the fixed point) and its trace
    heyoka's mu1^2 + mu2^2. The check is resumable: called again on its state file it is
    proved without new work; with one job taken out of the state it recomputes that job, to
    the same bits."""
    import subprocess
    import sys

    from taylorball.rigorous.periodic_orbit_run import certificate_from_run, check_periodic_orbit

    import taylorball as tb
    from taylorball.charts import mparallel_chart, mparallel_states_on_section
    from taylorball.rigorous.certificates import FIG1_SHOOTING_CERT_NAME

    cert = _shooting_cert()
    assert cert["claim"] == "periodic_orbit" and cert["segments"] == 2 and cert["orbit_type"] == "hyperbolic"
    state = tmp_path / "check.json"
    out = subprocess.run([sys.executable, "-m", "taylorball.cli", "prove", "--workers", "2", "--check",
                          str(CERT_DIR / FIG1_SHOOTING_CERT_NAME), "--state", str(state)], capture_output=True,
                         text=True)
    assert out.returncode == 0, out.stdout + out.stderr
    assert ": proved: a unique periodic orbit" in out.stdout and "2 segments" in out.stdout
    kept = json.loads(state.read_text())
    assert kept["role"] == "check" and sorted(kept["jobs"]) == ["0", "1", "2", "3"] and kept["proved"] is True
    res = check_periodic_orbit(cert, state)  # every job stored: the verdict alone
    assert res.ok and json.loads(state.read_text())["jobs"] == kept["jobs"], res.message
    part = dict(kept, jobs={k: v for k, v in kept["jobs"].items() if k != "2"})
    state.write_text(json.dumps(part))
    res = check_periodic_orbit(cert, state)  # segment 1's point map again
    again = json.loads(state.read_text())["jobs"]["2"]
    assert res.ok and {k: v for k, v in again.items() if k not in ("cpu", "on")} == \
        {k: v for k, v in kept["jobs"]["2"].items() if k not in ("cpu", "on")}, res.message
    # a run's state file with every job done gives the shipped certificate back (up to its date and cost)
    run_state = tmp_path / "run.json"
    run_state.write_text(json.dumps(dict(kept, role="run")))
    made = certificate_from_run(run_state)
    assert sorted(made) == sorted(cert)
    assert {k: v for k, v in made.items() if k not in _COST_KEYS} == {k: v for k, v in cert.items() if k not in _COST_KEYS}
    with pytest.raises(UsageError, match="made by a check, not a run"):
        certificate_from_run(state)
    lst = subprocess.run([sys.executable, "-m", "taylorball.cli", "prove", "--list"], capture_output=True, text=True)
    assert f"{FIG1_SHOOTING_CERT_NAME}: periodic_orbit:" in lst.stdout
    x0 = mparallel_states_on_section(fig1_params(), **FIG1_LEVELS.as_kwargs(), point=(0.0, 0.0))[0]
    orbit = tb.periodic_orbit("mparallel", fig1_params(), x0, levels=FIG1_LEVELS)
    ch = mparallel_chart(np.asarray(orbit.state, dtype=float))
    lo = [float.fromhex(v["hex"]) for v in cert["periodic_box"]["lower"]]
    hi = [float.fromhex(v["hex"]) for v in cert["periodic_box"]["upper"]]
    for k, v in enumerate([float(ch["l"]), float(ch["L/G"])] * 2):
        assert lo[k] <= v <= hi[k]
    mu = np.abs(orbit.multipliers)
    tr = cert["multiplier_trace"]
    assert float.fromhex(tr["lower"]["hex"]) <= float(np.sum(mu ** 2)) <= float.fromhex(tr["upper"]["hex"])


def test_shooting_certificate_with_a_wrong_segment_count_or_record_is_not_proved():
    """No computation needed to say no: the claimed segment count disagrees with the lists
    (3 claimed, 2 listed; or a segment's data dropped), the certificate records a failed
    attempt, or it has no periodic_box."""
    import copy

    from taylorball.rigorous.certificates import check_certificate

    cert = _shooting_cert()
    three = copy.deepcopy(cert)
    three["segments"] = 3
    res = check_certificate(three)
    assert not res.ok and "claims 3 segments" in res.message, res.message
    dropped = copy.deepcopy(cert)
    dropped["tau_guesses"] = dropped["tau_guesses"][:1]
    res = check_certificate(dropped)
    assert not res.ok and "claims 2 segments" in res.message, res.message
    failed = copy.deepcopy(cert)
    failed["proved"] = False
    assert not check_certificate(failed).ok
    nobox = copy.deepcopy(cert)
    del nobox["periodic_box"]
    assert not check_certificate(nobox).ok


@pytest.mark.slow
def test_shooting_certificate_tampered_box_or_parameter_is_not_proved():
    """The second box moved by 3 radii in L/G: K(X) sticks out; a changed parameter
    (Omega = 1/2 -> 513/1024): not proved; a narrowed periodic_box: the recomputed K(X) is not
    inside it (about 60 CPU s at 53 bits)."""
    import copy

    from taylorball.rigorous.certificates import check_certificate

    cert = _shooting_cert()
    moved = copy.deepcopy(cert)
    r = float.fromhex(cert["radius"]["hex"])
    moved["centers"][1][1]["hex"] = (float.fromhex(cert["centers"][1][1]["hex"]) + 3 * r).hex()
    res = check_certificate(moved, workers=2)
    assert not res.ok and res.message.startswith("not proved: K(X) is not inside X"), res.message
    other = copy.deepcopy(cert)
    other["params"]["plane_rate"] = "513/1024"
    assert not check_certificate(other, workers=2).ok
    narrow = copy.deepcopy(cert)
    lo = float.fromhex(cert["periodic_box"]["lower"][3]["hex"])
    hi = float.fromhex(cert["periodic_box"]["upper"][3]["hex"])
    narrow["periodic_box"]["lower"][3]["hex"] = (lo + 0.49 * (hi - lo)).hex()
    res = check_certificate(narrow, workers=2)
    assert not res.ok and "periodic_box" in res.message, res.message


def test_check_state_file_is_refused_where_it_cannot_be_the_check_s_own(tmp_path, capsys):
    """``prove --check CERT --state FILE``: refused before any work for two certificates, for
    FILE the certificate itself, for a certificate of another claim, and for a state file
    that a proof run made (a check must not adopt a run's stored results)."""
    import shutil

    from taylorball import cli
    from taylorball.rigorous.certificates import FIG1_SHOOTING_CERT_NAME, load_certificate
    from taylorball.rigorous.periodic_orbit_run import _design_hash, check_periodic_orbit

    cert = CERT_DIR / FIG1_SHOOTING_CERT_NAME
    assert cli.main(["prove", "--check", str(cert), str(cert), "--state", str(tmp_path / "s.json")]) == 2
    assert "--state keeps the check of one certificate, got 2" in capsys.readouterr().err
    copy = tmp_path / "c.json"
    shutil.copy(cert, copy)
    assert cli.main(["prove", "--check", str(copy), "--state", str(copy)]) == 2
    assert "not the certificate itself" in capsys.readouterr().err
    with pytest.raises(UsageError, match="only a periodic_orbit certificate"):
        check_periodic_orbit(load_certificate(CERT_DIR / "fig1_saddle_l0_cert.json"), tmp_path / "s.json")
    rec = load_certificate(cert)
    run_state = tmp_path / "run.json"
    run_state.write_text(json.dumps(dict(rec, design_sha256=_design_hash(rec), jobs={})))
    with pytest.raises(UsageError, match="made by a run, not a check"):
        check_periodic_orbit(rec, run_state)
    assert not (tmp_path / "s.json").exists()
