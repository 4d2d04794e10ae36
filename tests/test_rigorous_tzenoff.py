"""The proved relative periodic orbits of the dynamically symmetric ball (Tzenoff's case) on
the scouted levels (taylorball.rigorous.certificates.tzenoff_certificate, docs/rigorous.md)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

flint = pytest.importorskip("flint", reason="python-flint is not installed (optional extra 'rigorous')")

from taylorball.rigorous.certificates import (  # noqa: E402
    CERT_DIR, TZENOFF_ORBITS, load_certificate, tzenoff_ball, tzenoff_levels,
)

#: the orbit type each certificate claims
TYPES = {"saddle": "hyperbolic", "elliptic": "elliptic"}


def _cert(which):
    return load_certificate(CERT_DIR / TZENOFF_ORBITS[which][0])


def _box(cert):
    lo = [float.fromhex(v["hex"]) for v in cert["periodic_box"]["lower"]]
    hi = [float.fromhex(v["hex"]) for v in cert["periodic_box"]["upper"]]
    return np.array(lo), np.array(hi)


@pytest.mark.parametrize("which", sorted(TZENOFF_ORBITS))
def test_tzenoff_certificate_is_the_symmetric_physical_ball_and_heyoka_agrees(which):
    """The certificate is for I1 = I2 (Tzenoff's case) with moments a body inside the sphere
    can have (no UnphysicalParametersWarning), claims the orbit type at 128 bits with one
    segment, and heyoka's float64 map (an independent integrator) sends the certificate's
    centre back into the proved box, with the candidate's return time."""
    from taylorball.rigorous.certificates import _params_from_json
    from taylorball.rigorous.search import float_map

    cert = _cert(which)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        P = _params_from_json(cert["params"])
    assert P == tzenoff_ball() and P.inertia[0] == P.inertia[1] != P.inertia[2]
    assert cert["claim"] == "periodic_orbit" and cert["kind"] == "reduced" and cert["proved"] is True
    assert cert["orbit_type"] == TYPES[which] and cert["segments"] == 1 and cert["method"]["prec"] == 128
    assert float.fromhex(cert["levels"]["h"]["hex"]) == TZENOFF_ORBITS[which][1]
    c = np.array([float.fromhex(v["hex"]) for v in cert["centers"][0]])
    K = float.fromhex(cert["K_guesses"][0]["hex"])
    Pc, tau, _ = float_map(P, tzenoff_levels(TZENOFF_ORBITS[which][1]), c, K_near=K)
    lo, hi = _box(cert)
    assert np.all(lo <= c) and np.all(c <= hi)  # the float64 Newton candidate is in the proved box
    # heyoka's float64 map (tolerance eps, ~80 steps of a state of size ~10) carries a rounding
    # error of some tens of eps (6.9e-15 = 31 eps measured at the saddle); 256 eps of margin
    tol = 256 * np.finfo(float).eps
    assert np.all(lo - tol <= Pc) and np.all(Pc <= hi + tol), (lo, Pc, hi)
    assert np.all(hi - lo < 1e-13)  # the box is the proof's K(X) (widened by its width), not X
    assert abs(tau - float.fromhex(cert["tau_guesses"][0]["hex"])) < 1e-12


@pytest.mark.slow
@pytest.mark.parametrize("which", sorted(TZENOFF_ORBITS))
def test_tzenoff_certificate_checks_in_a_fresh_process(which):
    """`taylorball prove --check` re-proves it from scratch with two workers (exit 0; about
    350 CPU s each at 128 bits, docs/rigorous.md), and the proved trace of DP contains
    heyoka's float64 multipliers' sum (tb.periodic_orbits, an independent search)."""
    import subprocess
    import sys

    import taylorball as tb

    cert = _cert(which)
    out = subprocess.run([sys.executable, "-m", "taylorball.cli", "prove", "--workers", "2", "--check",
                          str(CERT_DIR / TZENOFF_ORBITS[which][0])], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
    assert ": proved: a unique periodic orbit" in out.stdout and TYPES[which] in out.stdout
    orbs = tb.periodic_orbits("reduced", tzenoff_ball(), tzenoff_levels(TZENOFF_ORBITS[which][1]), k_max=1,
                              n_points=60)
    c = np.array([float.fromhex(v["hex"]) for v in cert["centers"][0]])
    near = [o for o in orbs if np.max(np.abs(np.asarray(o.points[0])[-2:] - c)) < 1e-6]
    assert near, [o.points for o in orbs]
    tr = float(np.sum(near[0].multipliers.real))
    t = cert["multiplier_trace"]
    assert float.fromhex(t["lower"]["hex"]) <= tr <= float.fromhex(t["upper"]["hex"])
