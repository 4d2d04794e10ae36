"""A transversal homoclinic point by a chain of covering relations with cone conditions
(taylorball.rigorous.homoclinic_chain, homoclinic_chain_cert).

The known answer is the area-preserving Henon map f(x, y) = (y, -x + 4 y + y^2), whose
homoclinic point on x = y the one-piece proof also gives: the chain's last h-set must contain
the mpmath point (120 digits, independent of the ball code; tests/test_rigorous_homoclinic.py)
and its cone the mpmath tangent. Tampered chains (a set moved off the orbit, a set too thin, an
end set off the reversor's line, a cone around an eigen-line of R, a start set that is not the
proved one) must fail, and so must tampered certificates.
"""

from __future__ import annotations

import dataclasses
import json
import math
from fractions import Fraction

import pytest

pytest.importorskip("flint")

from taylorball.errors import UsageError  # noqa: E402
from taylorball.rigorous._balls import working_precision  # noqa: E402
from taylorball.rigorous.homoclinic import HenonMap  # noqa: E402
from taylorball.rigorous.homoclinic_chain import (  # noqa: E402
    ChainSet,
    check_end,
    check_relation,
    check_start,
    prove_chain,
)
from taylorball.rigorous.homoclinic_chain_cert import check_chain, run_chain  # noqa: E402
from taylorball.rigorous.homoclinic_chain_design import henon_chain, henon_chain_certificate  # noqa: E402

SWAP = [[0, 1], [1, 0]]
F = HenonMap(Fraction(4))


def _prove(sets, local):
    with working_precision(53):
        return prove_chain(F, sets, SWAP, local=local)


def test_henon_chain_is_proved_and_its_last_set_holds_the_mpmath_point():
    from tests.test_rigorous_homoclinic import _mp_homoclinic_point

    d = henon_chain()
    r = _prove(d["sets"], d["local"])
    assert r.proved, r.message
    assert len(r.relations) == 6 and all(x.ok for x in r.relations)
    assert r.end is not None and r.end.sides == (-1, 1)
    # the mpmath homoclinic point lies in N_n (its coordinates within [-a, a] x [-b, b])
    x, y, dx, dy = _mp_homoclinic_point()
    Nn = d["sets"][-1]
    (t00, t01), (t10, t11) = Nn.T
    det = t00 * t11 - t01 * t10
    px, py = float(x) - Nn.center[0], float(y) - Nn.center[1]
    u, s = (t11 * px - t01 * py) / det, (-t10 * px + t00 * py) / det
    assert abs(u) < Nn.a and abs(s) < Nn.b, (u, s, Nn.a, Nn.b)
    # and the mpmath tangent of W^u there lies in the cone |ds/du| <= b / (g a)
    tu, ts = (t11 * float(dx) - t01 * float(dy)) / det, (-t10 * float(dx) + t00 * float(dy)) / det
    assert abs(ts / tu) <= Nn.b / (Nn.g * Nn.a)


def test_henon_chain_relations_have_the_expected_orientation_and_margins():
    d = henon_chain()
    with working_precision(53):
        recs = [check_relation(F, None if i == 0 else i, d["sets"][i], d["sets"][i + 1]) for i in range(6)]
    assert all(r.ok for r in recs)
    # a positive multiplier (2 + sqrt 3): every relation keeps the exit edges' sides
    assert [r.orientation for r in recs] == [1] * 6
    assert all(r.margins["exit"] > 0 and r.margins["entry"] > 0 and r.margins["m11"] > 0 for r in recs)


def _moved(s: ChainSet, du: float = 0.0, ds: float = 0.0, **kw) -> ChainSet:
    c = (s.center[0] + du * s.T[0][0] + ds * s.T[0][1], s.center[1] + du * s.T[1][0] + ds * s.T[1][1])
    return dataclasses.replace(s, center=c, **kw)


def test_tampered_chains_are_not_proved():
    d = henon_chain()
    S, loc = d["sets"], d["local"]
    # a set shifted by twice its half-width along the exit direction: the exit edges' images miss it
    bad = list(S)
    bad[3] = _moved(S[3], du=2 * S[3].a)
    r = _prove(bad, loc)
    assert not r.proved and "relation 2 => 3" in r.message and "exit edges" in r.message
    # a set made too thin across: the image reaches its entry edges
    bad = list(S)
    bad[4] = dataclasses.replace(S[4], b=S[4].b / 10)
    r = _prove(bad, loc)
    assert not r.proved and "relation 3 => 4" in r.message and "|y2| >= 1" in r.message
    # the last set moved off x = y along its exit direction: both exit edges on one side (and
    # the last relation no longer reaches it)
    bad = list(S)
    bad[-1] = _moved(S[-1], du=3 * S[-1].a)
    r = _prove(bad, loc)
    assert not r.proved and "relation 5 => 6" in r.message
    assert r.end is not None and not r.end.ok and "opposite sides of Fix(R)" in r.end.message
    # a cone wide enough to hold an eigen-line of R: transversality not decided
    bad = list(S)
    bad[-1] = dataclasses.replace(S[-1], g=0.05)
    with working_precision(53):
        e = check_end(bad[-1], SWAP)
    assert not e.ok and "eigen-line" in e.message
    # the start set is not the proved one, or its cone is wider than W^u_N0's slope allows
    fr, a, b, c = loc
    ok, msg = check_start(dataclasses.replace(S[0], a=a / 2), fr, a, b, c)
    assert not ok and "not the proved local h-set" in msg
    ok, msg = check_start(dataclasses.replace(S[0], g=c * b / a * 1.01), fr, a, b, c)
    assert not ok and "not a horizontal disc" in msg
    # the wrong reversor's line: x = -y is not crossed by N_n
    with working_precision(53):
        assert not check_end(S[-1], [[0, -1], [-1, 0]]).ok


def test_bad_chain_input_is_refused_before_any_work():
    s = henon_chain()["sets"][1]
    for kw in ({"a": 0.0}, {"b": -1.0}, {"g": math.inf}, {"a": 1}):
        with pytest.raises(UsageError, match="finite float > 0"):
            dataclasses.replace(s, **kw)
    with pytest.raises(UsageError, match="invertible"):
        dataclasses.replace(s, T=((1.0, 2.0), (2.0, 4.0)))
    with pytest.raises(UsageError, match="at least 2 h-sets"):
        _prove([s], henon_chain()["local"])
    with pytest.raises(UsageError, match="float.hex"):
        ChainSet.from_json({"center": ["0x1p0"]})


def test_henon_chain_certificate_checks_and_tampered_ones_fail():
    cert = henon_chain_certificate()
    assert cert["proved"] is True and cert["sides"] == [-1, 1], cert["message"]
    res = check_chain(json.loads(json.dumps(cert)))
    assert res.ok, res.message
    # through the package's checker as well (its claim dispatch)
    from taylorball.rigorous.certificates import check_certificate

    assert check_certificate(json.loads(json.dumps(cert))).ok

    def tampered(edit):
        c = json.loads(json.dumps(cert))
        edit(c)
        return check_chain(c)

    r = tampered(lambda c: c["relations"]["2"].update(orientation=-1))
    assert not r.ok and "orientation" in r.message
    r = tampered(lambda c: c.update(sides=[1, -1]))
    assert not r.ok and "sides" in r.message
    r = tampered(lambda c: c.update(proved=False))
    assert not r.ok and "failed or unfinished" in r.message
    # a set moved by its half-width's double (exact hex edit): a relation fails, named
    def move(c):
        s = ChainSet.from_json(c["sets"][3])
        c["sets"][3] = _moved(s, du=2 * s.a).as_json()
    r = tampered(move)
    assert not r.ok and "relation 2 => 3" in r.message
    # the local h-set's cone constant too small for g_0: the start fails
    r = tampered(lambda c: c["local"].update(c={"hex": (1.0).hex()}))
    assert not r.ok and "start" in r.message
    with pytest.raises(UsageError, match="precisions"):
        tampered(lambda c: c.update(prec=[53]))


def test_run_chain_resumes_and_refuses_another_design(tmp_path):
    from taylorball.rigorous.homoclinic_chain_cert import _design_hash

    full = henon_chain_certificate()
    rec = {k: v for k, v in full.items() if k not in ("relations", "local_result", "proved", "message", "sides",
                                                          "cpu_seconds")}
    rec.update(relations={}, local_result=None, proved=False, message="not run")
    state = tmp_path / "state.json"
    part = run_chain(state, record=rec, only=[0, 1])
    assert sorted(part["relations"]) == ["0", "1"] and part["proved"] is False
    assert "relation 2 => 3: not run" in part["message"] or "local manifold" in part["message"]
    done = run_chain(state)  # resumed from the file alone
    assert done["proved"] is True, done["message"]
    for k in ("0", "1", "5"):
        assert done["relations"][k]["enclosures"] == full["relations"][k]["enclosures"]
    assert done["design_sha256"] == _design_hash(rec)
    other = dict(rec, sets=rec["sets"][:-1], prec=rec["prec"][:-1])
    with pytest.raises(UsageError, match="another design"):
        run_chain(state, record=other)
    edited = json.loads(state.read_text())
    edited["sets"][2]["a"] = (0.5).hex()
    state.write_text(json.dumps(edited))
    with pytest.raises(UsageError, match="changed after it was made"):
        run_chain(state)
    with pytest.raises(UsageError, match="does not exist"):
        run_chain(tmp_path / "missing.json")
    for bad in (0, 1.5, True):  # refused before the state file is made
        with pytest.raises(UsageError, match=r"workers must be an integer in \[1, 64\], got"):
            run_chain(tmp_path / "bad_workers.json", record=rec, workers=bad)
    assert not (tmp_path / "bad_workers.json").exists()
    # a second run on a state file that a live run holds is refused (the lock names its pid)
    import os

    from taylorball.errors import StoreError

    state2 = tmp_path / "state2.json"
    lock = tmp_path / "state2.json.lock"
    from taylorball._store_lock import Lock

    with Lock(lock, "a test"):
        with pytest.raises(StoreError, match=f"pid {os.getpid()}"):
            run_chain(state2, record=rec, only=[0])
    assert not state2.exists()  # refused before anything was written
    assert run_chain(state2, record=rec, only=[0])["relations"]["0"]["ok"] and not lock.exists()


def test_shipped_henon_chain_certificate_checks_in_a_fresh_process(tmp_path):
    import subprocess
    import sys

    from taylorball.rigorous.certificates import CERT_DIR, load_certificate

    path = CERT_DIR / "henon_t4_chain_cert.json"
    ok = subprocess.run([sys.executable, "-m", "taylorball", "prove", "--check", str(path)], capture_output=True,
                        text=True)
    assert ok.returncode == 0, ok.stdout + ok.stderr
    bad = load_certificate(path)
    bad["sides"] = [1, -1]
    p2 = tmp_path / "bad_cert.json"
    p2.write_text(json.dumps(bad))
    no = subprocess.run([sys.executable, "-m", "taylorball", "prove", "--check", str(p2)], capture_output=True, text=True)
    assert no.returncode == 1 and "not proved" in no.stdout


TZ_DESIGN = "tzenoff_d3.5_chain_design.json"


def _tzenoff_record():
    from importlib.resources import files

    from taylorball.rigorous.homoclinic_chain_design import tzenoff_chain_record

    design = json.loads((files("taylorball.rigorous") / "designs" / TZ_DESIGN).read_text())
    return design, tzenoff_chain_record(design)


def test_tzenoff_chain_design_starts_at_the_proved_local_set_and_ends_across_r2_0():
    """The committed float64 design of Tzenoff's chain (30 relations): N_0 is the certified local
    h-set, the last set straddles r2 = 0 with a tangent cone off R's eigen-lines (ball arithmetic,
    no integration); the pseudo-orbit's float64 defects are far below the sets' sizes."""
    from taylorball.rigorous.homoclinic_chain_cert import _end_and_start

    design, rec = _tzenoff_record()
    assert len(rec["sets"]) == 31 and len(rec["prec"]) == 30 and set(rec["prec"]) == {80, 128}
    ends = _end_and_start(rec)
    assert ends["start_ok"], ends["start"]
    assert ends["end_ok"], ends["end"]
    sets = [ChainSet.from_json(s) for s in rec["sets"]]
    assert all(dfc < 0.1 * min(s.a, s.b) for dfc, s in zip(design["defects"], sets[2:]))
    assert 77.0 < design["angle_deg"] < 78.0  # the float64 angle of W^u and W^s at q: 77.40 degrees
    # six short returns before q (1.88, 0.82, 2.07, 2.11, 0.83, 1.88), 24 of the saddle's 4.7065 before them
    assert [round(t, 2) for t in design["returns"][24:]] == [1.88, 0.82, 2.07, 2.11, 0.83, 1.88]
    assert all(abs(t - 4.7065) < 0.03 for t in design["returns"][:24])


@pytest.mark.slow
def test_tzenoff_chain_last_relation_is_proved():
    """The last relation of Tzenoff's chain (N_29 => N_30, a short return of 1.88 time units to
    the set straddling r2 = 0) at 80 bits: ~100-200 CPU s."""
    from taylorball.rigorous.homoclinic_chain_cert import _relation_job

    _, rec = _tzenoff_record()
    r = _relation_job((rec, 29))
    assert r["ok"], r["message"]


def test_a_section_map_that_does_not_close_is_a_failed_relation_not_a_crash(monkeypatch):
    """A relation whose section map raises NotProved (an interval Newton inclusion failed) is
    recorded as not proved with the reason; the run goes on with the other relations."""
    import taylorball.rigorous.homoclinic_chain as hc
    from taylorball.rigorous.homoclinic_chain_cert import _relation_job
    from taylorball.rigorous.section import NotProved

    cert = henon_chain_certificate()

    def boom(*args, **kw):
        raise NotProved("the crossing time is not isolated (a test)")

    monkeypatch.setattr(hc, "check_relation", boom)
    r = _relation_job((cert, 2))
    assert r["ok"] is False and "the section map: the crossing time is not isolated" in r["message"]


TZ_CERT = "tzenoff_d3.5_homoclinic_chain_cert.json"


def test_shipped_tzenoff_chain_certificate_is_the_committed_design_and_says_what_it_proves():
    """The shipped headline certificate is the committed design's record (the same maps, sets,
    precisions, local set and reversor: the design hash), with every relation's claimed
    orientation recorded; its statement is about the flow (the section maps are local, not proved
    to be first returns). No integration."""
    from taylorball.rigorous.certificates import CERT_DIR, load_certificate
    from taylorball.rigorous.homoclinic_chain_cert import _RECORD_KEYS, _design_hash

    cert = load_certificate(CERT_DIR / TZ_CERT)
    _, rec = _tzenoff_record()
    assert {k: cert[k] for k in _RECORD_KEYS} == {k: rec[k] for k in _RECORD_KEYS}
    assert cert["design_sha256"] == _design_hash(rec)
    assert cert["claim"] == "transversal_homoclinic_point" and cert["proved"] is True
    assert sorted(int(k) for k in cert["relations"]) == list(range(30))
    assert [cert["relations"][str(i)]["orientation"] for i in range(30)] == [-1] + [1] * 29
    assert "reduced flow has a transversal homoclinic orbit" in cert["title"]
    assert "not proved to be a first return" in cert["statement"]


def test_tampered_tzenoff_chain_certificates_fail_before_any_integration():
    """The checker says no, cheaply, to a headline certificate whose last set is moved off the
    reversor's line, whose local set is not the certified one, or that records an unfinished
    run (the full re-check is the slow test below)."""
    import copy

    from taylorball.rigorous.certificates import CERT_DIR, load_certificate

    cert = load_certificate(CERT_DIR / TZ_CERT)
    moved = copy.deepcopy(cert)
    last = ChainSet.from_json(moved["sets"][-1])
    c = list(last.center)
    c[1] = c[1] + 4 * max(last.a, last.b)  # r2 moved by 4 half-widths: N_30 no longer straddles r2 = 0
    moved["sets"][-1] = ChainSet(tuple(c), last.T, last.a, last.b, last.g).as_json()
    res = check_chain(moved)
    assert not res.ok and "end" in res.message and res.cpu_seconds < 30
    loose = copy.deepcopy(cert)
    loose["local"]["c"] = {"hex": (1.0).hex(), "decimal": "1.0"}  # the local graph's Lipschitz constant 1, not 1/10
    res = check_chain(loose)
    assert not res.ok and "start" in res.message and res.cpu_seconds < 30
    unfinished = dict(cert, proved=False)
    res = check_chain(unfinished)
    assert not res.ok and "failed or unfinished" in res.message


@pytest.mark.slow
def test_shipped_tzenoff_chain_certificate_checks_from_scratch():
    """The headline: `taylorball prove --workers 2 --check` re-proves Tzenoff's transversal
    homoclinic orbit from scratch in a fresh process (30 relations, the local manifold and the
    end): about 7100 CPU s, an hour on two cores."""
    import subprocess
    import sys

    from taylorball.rigorous.certificates import CERT_DIR

    ok = subprocess.run([sys.executable, "-m", "taylorball", "prove", "--workers", "2", "--check",
                         str(CERT_DIR / TZ_CERT)], capture_output=True, text=True)
    assert ok.returncode == 0, ok.stdout + ok.stderr
