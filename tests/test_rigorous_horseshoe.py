"""Covering relations of the Fig. 1 M||gamma map (taylorball.rigorous.covering) and their
certificates: the enclosed images contain heyoka's float64 images, the checker proves the
relations it should and says no to tampered sets, graphs and claims; the step memory of the
validated integrator."""

import copy
import math
from fractions import Fraction

import numpy as np
import pytest

pytest.importorskip("flint", reason="taylorball.rigorous needs python-flint (extra 'rigorous')")


def _saddle_hsets():
    """N0 (around the proved saddle at l = 0: the shipped Krawczyk certificate's centre) and
    its mirror image in the stable direction, as in the Fig. 1 chain design (half-width 1.5e-5
    along heyoka's finite-difference eigenvectors); and the saddle's float return time."""
    from taylorball.paper import FIG1_LEVELS, fig1_params
    from taylorball.rigorous.certificates import CERT_DIR, load_certificate
    from taylorball.rigorous.covering import HSet
    from taylorball.rigorous.search import _chart_jacobian

    cert = load_certificate(CERT_DIR / "fig1_saddle_l0_cert.json")
    c = np.array([float.fromhex(v["hex"]) for v in cert["center"]])
    G, tau = float.fromhex(cert["K_guess"]["hex"]), float.fromhex(cert["tau_guess"]["hex"])
    w, V = np.linalg.eig(_chart_jacobian(fig1_params(), FIG1_LEVELS, c, G))
    iu = int(np.argmax(np.abs(w)))
    eu, es = V[:, iu].real / np.linalg.norm(V[:, iu].real), V[:, 1 - iu].real / np.linalg.norm(V[:, 1 - iu].real)
    a = 1.5e-5
    B = ((float(eu[0] * a), float(es[0] * a)), (float(eu[1] * a), float(es[1] * a)))
    return HSet("N0", (float(c[0]), float(c[1])), B, 0.0, G), tau


def test_image_enclosure_contains_heyoka_images():
    """The enclosed coordinates (in N0) of the images of N0's right exit edge contain heyoka's
    float64 images of 5 points of that edge (their chart error, ~1e-15, is ~1e-10 in N0's
    coordinates), and the enclosure is narrow (width < 0.1 in x, |y| < 0.3)."""
    from taylorball.paper import FIG1_LEVELS, fig1_params
    from taylorball.rigorous._balls import exact_arb, interval, working_precision
    from taylorball.rigorous.covering import image_coordinates
    from taylorball.rigorous.search import _mparallel_float_map

    N, tau = _saddle_hsets()
    p = fig1_params()
    with working_precision(53):
        x, y = image_coordinates(p, FIG1_LEVELS, N, N, [exact_arb(1), interval(-1, 1)], tau)
        lo = [float(v.lower().mid()) for v in (x, y)]
        hi = [float(v.upper().mid()) for v in (x, y)]
    B, c = np.array(N.B), np.array(N.center)
    for q2 in np.linspace(-1, 1, 5):
        img, _ = _mparallel_float_map(p, FIG1_LEVELS, c + B @ np.array([1.0, q2]), N.G_guess)
        img[0] -= 2 * math.pi * round((img[0] - c[0]) / (2 * math.pi))
        q = np.linalg.solve(B, img - c)
        assert lo[0] < q[0] < hi[0] and lo[1] < q[1] < hi[1], (q, lo, hi)
    # and it is narrow enough for the covering conditions (|x| > 1, |y| < 1): the linear image
    # is x = 3.566 (the unstable multiplier), |y| <= 0.2804 (the stable one)
    assert 1.5 < lo[0] and hi[0] - lo[0] < 0.1 and max(-lo[1], hi[1]) < 0.3, (lo, hi)


@pytest.mark.slow
def test_covering_relation_holds_and_fails_when_tampered():
    """N0 => N0 is a covering relation; with N0's columns swapped (the stable direction taken
    as the exit direction) it is not (the message names the exit edge), and neither with the
    target moved by 3 half-widths along its stable direction."""
    from dataclasses import replace

    from taylorball.paper import FIG1_LEVELS, fig1_params
    from taylorball.rigorous.covering import Relation, check_relation

    N, tau = _saddle_hsets()
    p = fig1_params()
    rel = Relation("N0", "N0", tau, n_pieces=2)
    ok = check_relation(p, FIG1_LEVELS, N, N, rel)
    assert ok.proved, ok.message
    swapped = replace(N, B=((N.B[0][1], N.B[0][0]), (N.B[1][1], N.B[1][0])))
    res = check_relation(p, FIG1_LEVELS, swapped, swapped, rel)
    assert not res.proved and "left edge" in res.message and "exit edge" in res.message, res.message
    moved = replace(N, name="N0'", center=(N.center[0] + 3 * N.B[0][1], N.center[1] + 3 * N.B[1][1]))
    res = check_relation(p, FIG1_LEVELS, N, moved, Relation("N0", "N0'", tau, n_pieces=2))
    assert not res.proved and res.message.startswith("not proved: N0 => N0'"), res.message


def _small_cert():
    from taylorball.paper import FIG1_LEVELS, fig1_params
    from taylorball.rigorous.certificates import FORMAT, _hset_json, _levels_json, _params_json
    from taylorball.rigorous.certificates import _exact

    N, tau = _saddle_hsets()
    return {"format": FORMAT, "claim": "covering_relations", "title": "N0 => N0", "statement": "test",
            "kind": "mparallel", "params": _params_json(fig1_params()), "levels": _levels_json("mparallel", FIG1_LEVELS),
            "h_sets": [_hset_json(N)],
            "relations": [{"source": "N0", "target": "N0", "tau_guess": _exact(tau), "n_pieces": 2, "n_edge": 1}],
            "loops": [["N0", "N0"]], "paths": [], "disjoint": [], "method": {"prec": 53, "delta": _exact(1e-3)},
            "proved": True}


@pytest.mark.long
def test_covering_certificate_checks_in_fresh_process_and_tampered_fails(tmp_path, capsys):
    """A covering-relations certificate (N0 => N0) checks through the command line in a fresh
    process (exit 0; its relations in 2 worker processes); through the same command line in
    this process (no second interpreter to start), ``--workers 0`` is a usage error (exit 2)
    and, with N0 moved off the saddle by 3 half-widths along its stable direction (the image,
    pulled towards the saddle, leaves between the entry edges), it exits 1 with "not proved"."""
    import subprocess
    import sys

    from taylorball import cli
    from taylorball.rigorous.certificates import write_certificate

    cert = _small_cert()
    bad = copy.deepcopy(cert)
    hs = bad["h_sets"][0]
    for k in range(2):  # the centre moved by 3 half-widths along the stable direction
        hs["center"][k]["hex"] = (float.fromhex(hs["center"][k]["hex"]) + 3 * float.fromhex(hs["B"][k][1]["hex"])).hex()
    good_f, bad_f = write_certificate(cert, tmp_path / "ok_cert.json"), write_certificate(bad, tmp_path / "bad_cert.json")
    out = subprocess.run([sys.executable, "-m", "taylorball.cli", "prove", "--check", str(good_f), "--workers", "2"],
                         capture_output=True, text=True)
    assert out.returncode == 0 and "proved: N0 => N0 (1 covering relations" in out.stdout, out.stdout + out.stderr
    capsys.readouterr()
    assert cli.main(["prove", "--check", str(good_f), "--workers", "0"]) == 2
    err = capsys.readouterr().err
    assert "--workers must be an integer in [1, 64], got 0" in err, err
    assert cli.main(["prove", "--check", str(bad_f)]) == 1
    got = capsys.readouterr().out
    assert "not proved: N0 => N0" in got and "entry edges" in got, got


def test_graph_and_disjointness_claims_are_checked_without_integration():
    """A chain through a relation that is not listed, a pair claimed disjoint that overlaps,
    and a certificate recording a failed attempt are not proved (before any integration)."""
    from dataclasses import replace

    from taylorball.rigorous.certificates import _hset_json, check_certificate, hsets_disjoint

    N, _ = _saddle_hsets()
    far = replace(N, name="far", center=(N.center[0] + 1e-3, N.center[1]))
    pi_side = replace(N, name="pi", center=(N.center[0] + math.pi, N.center[1]), l_branch=math.pi)
    near = replace(N, name="near", center=(N.center[0] + N.B[0][0], N.center[1] + N.B[1][0]))
    assert hsets_disjoint(N, far) and hsets_disjoint(N, pi_side) and not hsets_disjoint(N, near)
    cert = _small_cert()
    cert["h_sets"] += [_hset_json(far), _hset_json(near)]
    gap = copy.deepcopy(cert)
    gap["paths"] = [["N0", "far"]]
    res = check_certificate(gap)
    assert not res.ok and "N0 => far" in res.message and "not a listed relation" in res.message, res.message
    over = copy.deepcopy(cert)
    over["disjoint"] = [["N0", "far"], ["N0", "near"]]
    res = check_certificate(over)
    assert not res.ok and "N0 and near are not proved disjoint" in res.message, res.message
    failed = copy.deepcopy(cert)
    failed["proved"] = False
    assert not check_certificate(failed).ok


def test_bad_hset_input_is_refused():
    from taylorball.errors import UsageError
    from taylorball.rigorous.covering import HSet

    with pytest.raises(UsageError, match="B must be an invertible"):
        HSet("x", (0.0, 0.0), ((1.0, 2.0), (2.0, 4.0)), 0.0, 10.0)
    with pytest.raises(UsageError, match="l_branch must be one of"):
        HSet("x", (0.0, 0.0), ((1.0, 0.0), (0.0, 1.0)), 1.0, 10.0)
    with pytest.raises(UsageError, match="not in l_branch"):
        HSet("x", (3.0, 0.0), ((1.0, 0.0), (0.0, 1.0)), 0.0, 10.0)


def test_step_memory_fewer_attempts_and_still_contains_the_truth(monkeypatch):
    """The step memory of integrate_set (default) attempts fewer steps than the former step
    control (step_memory=False) on the reduced system, and its enclosure still contains the
    256-bit heyoka MPFR solution."""
    import heyoka as hy

    import taylorball as tb
    from taylorball.paper import FIG4_BALL, demo_reduced_state
    from taylorball.rigorous import enclosure
    from taylorball.rigorous._balls import arb, exact_arb, working_precision
    from taylorball.rigorous._taylor import LohnerSet, default_order
    from taylorball.rigorous.enclosure import _to_ball, ball_pars, ball_rhs, integrate_set, internal_system

    calls = {"n": 0}
    orig = enclosure.lohner_step

    def counted(*a, **k):
        calls["n"] += 1
        return orig(*a, **k)

    monkeypatch.setattr(enclosure, "lohner_step", counted)
    x = tb.propagate("reduced", FIG4_BALL, demo_reduced_state(), 0.0, project=True)
    t = 0.1
    ref = tb.propagate("reduced", FIG4_BALL, x, t, fp_type=hy.real, prec=256)
    attempts = {}
    system = internal_system("reduced")
    with working_precision(53):
        pars = ball_pars("reduced", FIG4_BALL)
        # heyoka snaps the float state onto the constraints at 256 bits: start from a box of
        # radius 2e-15 (about 10 float64 ulps of |x| ~ 1) that contains the snapped state
        X0 = list(system.to_internal(pars, [exact_arb(float(v)) + arb(0, 2e-15) for v in x]))
        for mem in (False, True):
            calls["n"] = 0
            _, _, steps, box = integrate_set(ball_rhs("reduced", pars), LohnerSet.from_box(X0), Fraction(t), prec=53,
                                             order=default_order(53), tol=2.0 ** -53, step_memory=mem)
            attempts[mem] = calls["n"] / steps
            pub = system.to_public(pars, box)
            assert all(b.contains(_to_ball(v)) for b, v in zip(pub, ref))
    assert attempts[True] < attempts[False], attempts
