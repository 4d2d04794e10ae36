"""Transversal homoclinic points by cone conditions (taylorball.rigorous.homoclinic).

The known answer is the area-preserving Henon map f(x, y) = (y, -x + 4 y + y^2) (reversible
with R(x, y) = (y, x)): its saddle's homoclinic point on x = y is computed independently in
mpmath at 120 digits (the unstable eigen-line at distance 1e-40 iterated forwards, bisection
on x - y) and must lie in the proved enclosure, with the same signs of the tangent's
components along R's eigen-lines.
"""

from __future__ import annotations

import json
import subprocess
import sys
from fractions import Fraction

import pytest

pytest.importorskip("flint")

from taylorball.errors import UsageError  # noqa: E402
from taylorball.rigorous._balls import working_precision  # noqa: E402
from taylorball.rigorous.certificates import CERT_DIR, check_certificate, load_certificate  # noqa: E402
from taylorball.rigorous.homoclinic import (  # noqa: E402
    Frame,
    HenonMap,
    local_unstable_manifold,
    prove_homoclinic_point,
    reversor_forms,
)
from taylorball.rigorous.homoclinic_cert import HENON_PROOF, henon_certificate, henon_frame  # noqa: E402

SWAP = [[0, 1], [1, 0]]
HENON_CERT = CERT_DIR / "henon_t4_homoclinic_cert.json"


def _prove(**kw):
    h = dict(HENON_PROOF)
    h.update(kw)
    with working_precision(53):
        return prove_homoclinic_point(HenonMap(Fraction(4)), kw.pop("frame", henon_frame()), h["a"], h["b"], h["c"],
                                      h["us"], h["n"], h.get("R", SWAP), pieces=h["pieces"])


def _mp_homoclinic_point():
    """The Henon map's homoclinic point on x = y near (-2.6365, -2.6365) and W^u's tangent
    there, in mpmath (120 digits), independent of the ball-arithmetic code."""
    import mpmath as mp

    mp.mp.dps = 120
    t = mp.mpf(4)
    lam = (t + mp.sqrt(t * t - 4)) / 2
    eu = mp.matrix([1, lam]) / mp.sqrt(1 + lam * lam)
    eps = mp.mpf(10) ** -40

    def orbit(sig, m):
        x, y = -eps * lam ** sig * eu[0], -eps * lam ** sig * eu[1]
        dx, dy = eu[0], eu[1]  # tangent of the eigen-line, carried by Df
        for _ in range(m):
            x, y, dx, dy = y, -x + t * y + y * y, dy, -dx + (t + 2 * y) * dy
        return x, y, dx, dy

    for m in range(60, 80):
        grid = [mp.mpf(k) / 200 for k in range(201)]
        vals = [orbit(s, m) for s in grid]
        for k in range(200):
            (x0, y0, _, _), (x1, y1, _, _) = vals[k], vals[k + 1]
            if (x0 - y0) * (x1 - y1) < 0 and abs(x0 + 2.6365) < 0.01:
                lo, hi = grid[k], grid[k + 1]
                for _ in range(300):
                    mid = (lo + hi) / 2
                    xm, ym, _, _ = orbit(mid, m)
                    if (xm - ym) * (x0 - y0) > 0:
                        lo = mid
                    else:
                        hi = mid
                return orbit(lo, m)
    raise AssertionError("mpmath found no crossing")


def test_henon_homoclinic_point_is_proved_and_contains_the_mpmath_point():
    r = _prove()
    assert r.proved, r.message
    assert r.sides == [-1, 1]
    crossing = [p for p in r.pieces if not p["off_fix"]]
    assert crossing and all(p["transversal"] for p in crossing)
    x, y, dx, dy = _mp_homoclinic_point()
    assert abs(x - y) < 1e-80
    inside = [p for p in crossing if p["image"][0][0] <= float(x) <= p["image"][0][1]
              and p["image"][1][0] <= float(y) <= p["image"][1][1]]
    assert inside, (float(x), [p["image"] for p in crossing])
    # the tangent's components along R's eigen-lines: (1, 1) -> l+ = (dx + dy)/2, l- = (dx - dy)/2
    lp, lm = float((dx + dy) / 2), float((dx - dy) / 2)
    for p in inside:
        ap, am = (float(v.split("+/-")[0].strip("[ ")) for v in (p["l_plus"], p["l_minus"]))
        assert ap * lp > 0 and am * lm > 0  # the same cone direction (up to the tangent's scale)


def test_henon_local_manifold_alone():
    with working_precision(53):
        m = local_unstable_manifold(HenonMap(Fraction(4)), henon_frame(), 1e-2, 3e-4, 100.0, reversor=SWAP)
    assert m.ok, m.message
    assert 3.7 < float(m.expansion.lower()) < 3.732050808  # lambda = 2 + sqrt 3, less the wrapping


def test_henon_tampered_inputs_are_not_proved():
    u1, u2 = HENON_PROOF["us"]
    shifted = _prove(us=(u1 + 1e-4, u2 + 1e-4))  # both endpoints on one side of x = y
    assert not shifted.proved and "sign change" in shifted.message
    wide = _prove(c=1.0)  # the cone of tangents too wide to decide the angle
    assert not wide.proved and "transversality" in wide.message
    big = _prove(a=0.5, b=0.2)  # the h-set too large: no cone condition / covering
    assert not big.proved and big.message.startswith("local manifold: not proved")
    T = henon_frame().T
    swapped = Frame((0.0, 0.0), ((T[0][1], T[0][0]), (T[1][1], T[1][0])))  # stable column as the exit one
    with working_precision(53):
        m = local_unstable_manifold(HenonMap(Fraction(4)), swapped, 1e-2, 3e-4, 100.0)
    assert not m.ok and "exit edges" in m.message


def test_bad_input_is_refused_before_any_work():
    with pytest.raises(UsageError, match="us must be"):
        _prove(us=(1e-3, -1e-3))
    with pytest.raises(UsageError, match="n \\(the number of iterates\\)"):
        _prove(n=0)
    with pytest.raises(UsageError, match="involution"):
        reversor_forms([[1, 1], [0, 1]])
    with pytest.raises(UsageError, match="a must be a float > 0"):
        with working_precision(53):
            local_unstable_manifold(HenonMap(Fraction(4)), henon_frame(), -1.0, 1e-3, 1.0)


def test_henon_certificate_checks_and_tampered_ones_fail(tmp_path):
    shipped = load_certificate(HENON_CERT)
    fresh = henon_certificate()
    for k in ("map", "frame", "a", "b", "c", "us", "n", "sides", "proved"):
        assert shipped[k] == fresh[k], k
    assert check_certificate(shipped).ok
    bad = json.loads(json.dumps(shipped))
    bad["sides"] = [1, -1]
    res = check_certificate(bad)
    assert not res.ok and "claims [1, -1]" in res.message
    bad = json.loads(json.dumps(shipped))
    bad["c"] = {"hex": (1.0).hex()}
    assert not check_certificate(bad).ok
    bad = json.loads(json.dumps(shipped))
    bad["us"] = [{"hex": (u + 1e-4).hex()} for u in HENON_PROOF["us"]]  # both endpoints on one side
    assert not check_certificate(bad).ok
    bad = json.loads(json.dumps(shipped))
    bad["proved"] = False
    assert "failed attempt" in check_certificate(bad).message
    # through the command line, in a fresh process: exit 0, and 1 for the tampered one
    p = tmp_path / "tampered_cert.json"
    bad = json.loads(json.dumps(shipped))
    bad["sides"] = [1, -1]
    p.write_text(json.dumps(bad))
    ok = subprocess.run([sys.executable, "-m", "taylorball", "prove", "--check", str(HENON_CERT)],
                        capture_output=True, text=True)
    assert ok.returncode == 0, ok.stdout + ok.stderr
    no = subprocess.run([sys.executable, "-m", "taylorball", "prove", "--check", str(p)], capture_output=True, text=True)
    assert no.returncode == 1 and "not proved" in no.stdout
    listed = subprocess.run([sys.executable, "-m", "taylorball", "prove", "--list"], capture_output=True, text=True)
    assert "henon_t4_homoclinic_cert.json: homoclinic_point: " in listed.stdout


def test_the_reversor_of_the_symmetric_balls_section_map_symbolically():
    """The lemma the Tzenoff chain uses (exact, sympy): for I1 = I2 the reflection sigma_1 of
    the body axis 1 (x = (M, gamma, R) -> (-M1, M2, M3, -gamma1, ...)) reverses the reduced
    field, f(sigma x) = -sigma f(x), keeps the energy and the levels, maps the section's event
    function e to -e (so g = 0 with g increasing, time reversed, to itself), keeps K = M3 and
    maps the chart's (r1, r2) to (r1, -r2): sigma (r1, r2) = (r1, -r2) reverses the 2D map."""
    import sympy as sp

    from taylorball.charts import section_event_function
    from taylorball.model import REDUCED, get_system
    from taylorball.rigorous.section import chart_r

    system = get_system("reduced")
    I1, I3, m, a, om = sp.symbols("I1 I3 m a Omega", positive=True)
    pars = (I1, I1, I3, m, a, om)
    x = sp.symbols("M1 M2 M3 g1 g2 g3 R1 R2 R3", real=True)
    S = [-1, 1, 1] * 3
    xs = tuple(s * v for s, v in zip(S, x))
    f, fs = system.rhs(pars, x), system.rhs(pars, xs)
    assert all(sp.simplify(fs[i] + S[i] * f[i]) == 0 for i in range(9))
    c = system.constants(pars)
    E, Es = (REDUCED.integrals(c, system.vectors(c, v))["E"] for v in (x, xs))
    assert sp.simplify(E - Es) == 0
    assert sp.simplify(section_event_function(xs[0:3], xs[3:6], 0.0) + section_event_function(x[0:3], x[3:6], 0.0)) == 0
    (r1, r2), (r1s, r2s) = chart_r(x), chart_r(xs)
    assert sp.simplify(r1 - r1s) == 0 and sp.simplify(r2 + r2s) == 0
    # a sign matrix that is not a reversor (M1 reflected alone) is told apart: the check can say no
    S3 = [-1, 1, 1] + [1, 1, 1] * 2
    f3 = system.rhs(pars, tuple(s * v for s, v in zip(S3, x)))
    assert any(sp.simplify(f3[i] + S3[i] * f[i]) != 0 for i in range(9))


TZENOFF_WU_CERT = CERT_DIR / "tzenoff_d3.5_saddle_wu_cert.json"


def test_tzenoff_local_manifold_certificate_structure_and_cheap_refusals():
    """The shipped certificate of the Tzenoff saddle's local unstable manifold: its h-set's
    box hull lies in the saddle certificate's box, and records that cannot check are refused
    before any integration."""
    from taylorball.rigorous.homoclinic_cert import SIGMA1, TZENOFF_FRAME, TZENOFF_HSET

    cert = load_certificate(TZENOFF_WU_CERT)
    assert cert["claim"] == "local_unstable_manifold" and cert["proved"] is True
    assert cert["reversor"] == SIGMA1 and cert["prec"] == 128
    a, b = (float.fromhex(cert[k]["hex"]) for k in ("a", "b"))
    assert (a, b) == (TZENOFF_HSET["a"], TZENOFF_HSET["b"])
    T = TZENOFF_FRAME[1]
    assert all(abs(T[i][0]) * a + abs(T[i][1]) * b < 1e-13 for i in range(2))
    bad = json.loads(json.dumps(cert))
    bad["proved"] = False
    assert "failed attempt" in check_certificate(bad).message
    bad = json.loads(json.dumps(cert))
    bad.update(claim="homoclinic_point", us=[{"hex": (-a / 2).hex()}, {"hex": (a / 2).hex()}], n=3, pieces=1,
               sides=[-1, 1])
    res = check_certificate(bad)  # three iterates, no return-time guesses for them: refused at once
    assert not res.ok and "only 0 return-time guesses" in res.message and res.cpu_seconds < 5


@pytest.mark.slow
def test_tzenoff_local_manifold_certificate_checks_in_a_fresh_process():
    """~400 CPU s at 128 bits (the point map at the centre and the C^1 map on the h-set)."""
    ok = subprocess.run([sys.executable, "-m", "taylorball", "prove", "--check", str(TZENOFF_WU_CERT)],
                        capture_output=True, text=True)
    assert ok.returncode == 0, ok.stdout + ok.stderr
    assert "proved: Tzenoff's case" in ok.stdout


@pytest.mark.slow
def test_section_map_doubleton_start_contains_the_float_images_and_is_narrower():
    """section_map(start="doubleton") on the Tzenoff saddle's map (53 bits, a box of radius
    1e-10): the enclosure contains heyoka's float64 images of the box's corners and centre;
    from the 9D box start the same map is wider or not enclosed at all (measured 2026-11-28:
    no validated step at t = 4.09 of the 4.71, the box grown to radius 0.45). ~100 CPU s."""
    import numpy as np

    from taylorball.errors import IntegrationError
    from taylorball.rigorous._balls import arb, exact_arb
    from taylorball.rigorous.certificates import tzenoff_ball, tzenoff_levels
    from taylorball.rigorous.homoclinic_cert import TZENOFF_FRAME
    from taylorball.rigorous.search import float_map
    from taylorball.rigorous.section import NotProved, section_map

    P, L = tzenoff_ball(), tzenoff_levels(-20.0)
    c, rad, K, tau = TZENOFF_FRAME[0], 1e-10, 6.7765456340679915, 4.706483237165501
    with working_precision(53):
        box = [exact_arb(v) + arb(0, rad) for v in c]
        dbl = section_map(P, L, box, K, tau, prec=53, order=12, jac=False, start="doubleton").P
        for dx in (-rad, 0.0, rad):
            for dy in (-rad, 0.0, rad):
                img, _, _ = float_map(P, L, np.array(c) + (dx, dy), K_near=K)
                # float64 image: its own error (~1e-13 here) is far below the enclosure's radius
                assert all(dbl[i].contains(exact_arb(float(img[i]))) for i in range(2)), (img, dx, dy)
        try:
            wide = max(float(v.rad()) for v in section_map(P, L, box, K, tau, prec=53, order=12, jac=False,
                                                           start="box").P)
        except (IntegrationError, NotProved):
            wide = float("inf")
        assert max(float(v.rad()) for v in dbl) < wide
        with pytest.raises(UsageError, match="start must be"):
            section_map(P, L, box, K, tau, prec=53, jac=False, start="boxes")
