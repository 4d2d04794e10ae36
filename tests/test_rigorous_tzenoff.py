"""The proved relative periodic orbit of the dynamically symmetric ball (Tzenoff's case) on the
scouted level (taylorball.rigorous.certificates.tzenoff_saddle_certificate, docs/rigorous.md)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

flint = pytest.importorskip("flint", reason="python-flint is not installed (optional extra 'rigorous')")

from taylorball.rigorous.certificates import (  # noqa: E402
    CERT_DIR, TZENOFF_SADDLE_CERT_NAME, load_certificate, tzenoff_ball, tzenoff_levels,
)


def _cert():
    return load_certificate(CERT_DIR / TZENOFF_SADDLE_CERT_NAME)


def _box(cert):
    lo = [float.fromhex(v["hex"]) for v in cert["periodic_box"]["lower"]]
    hi = [float.fromhex(v["hex"]) for v in cert["periodic_box"]["upper"]]
    return np.array(lo), np.array(hi)


def test_tzenoff_certificate_is_the_symmetric_physical_ball_and_heyoka_agrees():
    """The certificate is for I1 = I2 (Tzenoff's case) with moments a body inside the sphere
    can have (no UnphysicalParametersWarning), claims a hyperbolic orbit of one segment at
    128 bits, and heyoka's float64 map (an independent integrator) sends the certificate's
    centre back into the proved box, with a return time in the proved period's range."""
    from taylorball.rigorous.certificates import _params_from_json
    from taylorball.rigorous.search import float_map

    cert = _cert()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        P = _params_from_json(cert["params"])
    assert P == tzenoff_ball() and P.inertia[0] == P.inertia[1] != P.inertia[2]
    assert cert["claim"] == "periodic_orbit" and cert["kind"] == "reduced" and cert["proved"] is True
    assert cert["orbit_type"] == "hyperbolic" and cert["segments"] == 1 and cert["method"]["prec"] == 128
    c = np.array([float.fromhex(v["hex"]) for v in cert["centers"][0]])
    K = float.fromhex(cert["K_guesses"][0]["hex"])
    Pc, tau, _ = float_map(P, tzenoff_levels(), c, K_near=K)
    lo, hi = _box(cert)
    assert np.all(lo <= c) and np.all(c <= hi)  # the float64 Newton candidate is in the proved box
    # heyoka's float64 map (tolerance eps, ~80 steps of a state of size ~10) carries a rounding
    # error of some tens of eps (6.9e-15 = 31 eps measured at the candidate); 256 eps of margin
    tol = 256 * np.finfo(float).eps
    assert np.all(lo - tol <= Pc) and np.all(Pc <= hi + tol), (lo, Pc, hi)
    assert np.all(hi - lo < 1e-13)  # the box is the proof's K(X) (widened by its width), not X
    assert abs(tau - float.fromhex(cert["tau_guesses"][0]["hex"])) < 1e-12


@pytest.mark.slow
def test_tzenoff_certificate_checks_in_a_fresh_process():
    """`taylorball prove --check` re-proves it from scratch with two workers (exit 0; the
    CPU cost is in docs/rigorous.md), and the proved trace of DP contains heyoka's float64
    multipliers' sum (tb.periodic_orbit)."""
    import subprocess
    import sys

    import taylorball as tb

    cert = _cert()
    out = subprocess.run([sys.executable, "-m", "taylorball.cli", "prove", "--workers", "2", "--check",
                          str(CERT_DIR / TZENOFF_SADDLE_CERT_NAME)], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
    assert ": proved: a unique periodic orbit" in out.stdout and "hyperbolic" in out.stdout
    orbs = tb.periodic_orbits("reduced", tzenoff_ball(), tzenoff_levels(), k_max=1, n_points=60)
    o = max((q for q in orbs if q.stability == "hyperbolic"), key=lambda q: max(abs(q.multipliers)))
    tr = float(np.sum(o.multipliers.real))
    t = cert["multiplier_trace"]
    assert float.fromhex(t["lower"]["hex"]) <= tr <= float.fromhex(t["upper"]["hex"])
