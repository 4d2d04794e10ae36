"""The complete results of a few ``poincare_section`` calls, pinned bit for bit.

The values are the code's own output before its per-call overhead was cut (float64, the
Fig. 4 ball, the demo state; 2026-11-28): a paper section with one crossing, with both
directions at another angle, the M||gamma system and a section of the user's choosing.
Every array of the result (times, public states, points, residuals, integrals at the
crossings), the drift, the levels and ``t_end`` are compared exactly (``float.hex``), so a
change of how the result is assembled that moves any bit fails here.
"""

from __future__ import annotations

import numpy as np
import pytest

import taylorball as tb
from taylorball.paper import FIG4_BALL, demo_reduced_state

X0 = demo_reduced_state()
MPAR_X0 = np.concatenate([[0.5, -1.0, 2.0], X0[3:6]])

CALLS = {
    "reduced_1": lambda: tb.poincare_section("reduced", FIG4_BALL, X0, n_points=1),
    "reduced_4_both": lambda: tb.poincare_section("reduced", FIG4_BALL, X0, n_points=4, g0=1.0, direction=0),
    "mparallel_3": lambda: tb.poincare_section("mparallel", FIG4_BALL.to_mparallel(), MPAR_X0, n_points=3),
    "user_gamma3_3": lambda: tb.poincare_section("reduced", FIG4_BALL, X0, n_points=3,
                                                 options=tb.SectionOptions(event="gamma3", chart=("R1", "l"))),
}


def _hexes(r):
    """Every number of a result, by field, as exact ``float.hex`` strings."""
    out = {}
    for name in ("times", "states", "points", "residuals"):
        a = np.asarray(getattr(r, name))
        assert a.dtype == np.float64, (name, a.dtype)
        out[name] = [float(v).hex() for v in a.reshape(-1)]
    for k, v in r.integrals.items():
        out["integrals." + k] = [float(x).hex() for x in np.asarray(v).reshape(-1)]
    for k, v in r.drift.items():
        out["drift." + k] = [float(v).hex()]
    for k, v in r.levels.items():
        out["levels." + k] = [float(v).hex()]
    out["t_end"] = [float(r.t_end).hex()]
    return out


@pytest.mark.parametrize("case", sorted(CALLS))
def test_section_call_bits_pinned(case):
    got = _hexes(CALLS[case]())
    want = PINNED[case]
    assert sorted(got) == sorted(want)
    for name in want:
        assert got[name] == want[name], f"{case}: {name} moved"


def test_section_call_repeats_bitwise():
    """The same call twice in a row (cached problem data reused) gives the same bits."""
    for case in ("reduced_1", "mparallel_3"):
        assert _hexes(CALLS[case]()) == _hexes(CALLS[case]())


PINNED = {'mparallel_3': {'drift.E': ['0x1.3aa341fb61837p-50'],
                 'drift.gamma2': ['0x1.ffffffffffffap-52'],
                 'drift.lambda': ['0x1.caf1859534839p-52'],
                 'integrals.E': ['0x1.ef669078ee01ap-3', '0x1.ef669078edfb2p-3', '0x1.ef669078edf9ep-3'],
                 'integrals.gamma2': ['0x1.0000000000003p+0', '0x1.0000000000002p+0', '0x1.0000000000000p+0'],
                 'integrals.lambda': ['0x1.7b67ae8584cb1p+0', '0x1.7b67ae8584ca0p+0', '0x1.7b67ae8584ca5p+0'],
                 'levels.h': ['0x1.ef669078edfeep-3'],
                 'levels.lambda': ['0x1.7b67ae8584cacp+0'],
                 'points': ['0x1.899522f111454p+2', '0x1.ffd23114278b9p-1', '0x1.e5582342046a8p+1',
                            '0x1.fe325e0187ddbp-1', '0x1.5ae8736b94b4ap+2', '0x1.ffeb633987349p-1'],
                 'residuals': ['0x1.bcea27ec6540bp-62', '0x0.0p+0', '0x1.31f6590e23025p-60'],
                 'states': ['-0x1.094a44deb0110p-6', '0x1.ee0058fcba3bcp-4', '0x1.267f5251a005ep+2',
                            '-0x1.043ab09eef223p-3', '0x1.e493d3be17c16p-1', '0x1.2ff2ee68c108cp-2',
                            '-0x1.48df192c19946p-2', '-0x1.b0774be92caa5p-2', '0x1.9385d1698ee8ap+2',
                            '-0x1.32532d56d8d07p-1', '-0x1.92d1384fb70c3p-1', '0x1.370ebb4b27331p-3',
                            '-0x1.71586da4d9470p-4', '0x1.3c3640589161dp-4', '0x1.ac5345d5e12c4p+2',
                            '-0x1.7cbf024c3dedcp-1', '0x1.45f8f81d0c9f9p-1', '0x1.a1f6670b4997bp-3'],
                 't_end': ['0x1.36dcfa1ac62b9p+7'],
                 'times': ['0x1.385690914e0f8p+5', '0x1.023bec91ad0b8p+7', '0x1.36757568eb1e6p+7']},
 'reduced_1': {'drift.C2': ['0x1.0c8a25bc7fcdbp-50'],
               'drift.E': ['0x1.128a30112a263p-53'],
               'drift.M_gamma': ['0x1.4ba737345509cp-56'],
               'drift.R_gamma': ['0x1.3e477beb13c48p-54'],
               'drift.gamma2': ['0x1.ffffffffffff8p-52'],
               'integrals.C2': ['0x1.310eb0d30b131p+7'],
               'integrals.E': ['-0x1.1e39c1f7e9680p+1'],
               'integrals.M_gamma': ['0x1.56d7cf1ce9458p+0'],
               'integrals.R_gamma': ['0x1.02a4202a52b92p-50'],
               'integrals.gamma2': ['0x1.0000000000004p+0'],
               'levels.C': ['0x1.8b3540febd4d2p+3'],
               'levels.M_gamma': ['0x1.56d7cf1ce9459p+0'],
               'levels.h': ['-0x1.1e39c1f7e95cap+1'],
               'points': ['0x1.b3c0a04353812p+1', '0x1.08b5404caa58cp+0', '-0x1.10b7d808ddc97p+1'],
               'residuals': ['0x0.0p+0'],
               'states': ['0x1.bffe9ad5fc332p+1', '-0x1.c3e6a9b0023ccp+1', '0x1.92636596e6910p-5',
                          '-0x1.83ab2766f748dp-5', '-0x1.685e171a82e3ap-3', '-0x1.f76dbb3f3b734p-1',
                          '0x1.3a2c7b2cffa27p+3', '-0x1.1089e34cf18edp+3', '0x1.0d370538b504cp+0'],
               't_end': ['0x1.7615d35616cfep+2'],
               'times': ['0x1.748cf548080cdp+2']},
 'reduced_4_both': {'drift.C2': ['0x1.423f607bcc906p-51'],
                    'drift.E': ['0x1.ef0b8fb18db72p-55'],
                    'drift.M_gamma': ['0x1.4ba737345509bp-52'],
                    'drift.R_gamma': ['0x1.1605a8ebb0483p-53'],
                    'drift.gamma2': ['0x1.ffffffffffffap-53'],
                    'integrals.C2': ['0x1.310eb0d30b137p+7', '0x1.310eb0d30b136p+7', '0x1.310eb0d30b135p+7',
                                     '0x1.310eb0d30b133p+7'],
                    'integrals.E': ['-0x1.1e39c1f7e95d0p+1', '-0x1.1e39c1f7e95c0p+1', '-0x1.1e39c1f7e9600p+1',
                                    '-0x1.1e39c1f7e9600p+1'],
                    'integrals.M_gamma': ['0x1.56d7cf1ce9458p+0', '0x1.56d7cf1ce9459p+0', '0x1.56d7cf1ce9460p+0',
                                          '0x1.56d7cf1ce9469p+0'],
                    'integrals.R_gamma': ['0x1.4ba9846763cb1p-51', '0x1.8423698d133eap-51', '0x1.6ecc9a5026f9ep-50',
                                          '0x1.537663a970482p-50'],
                    'integrals.gamma2': ['0x1.0000000000002p+0', '0x1.0000000000002p+0', '0x1.0000000000003p+0',
                                         '0x1.0000000000003p+0'],
                    'levels.C': ['0x1.8b3540febd4d2p+3'],
                    'levels.M_gamma': ['0x1.56d7cf1ce9459p+0'],
                    'levels.h': ['-0x1.1e39c1f7e95cap+1'],
                    'points': ['0x1.c25624e369b72p+1', '0x1.f2e2a1e5aa200p-8', '0x1.18efa6e8a85acp+2',
                               '0x1.8a96a4d9b800dp+0', '-0x1.1dabf15aa293ep+0', '-0x1.7c9fb61d781c6p+2',
                               '0x1.10c071009be2ap+2', '-0x1.8277d3adb6c25p-1', '0x1.0d69106360ba9p+3',
                               '0x1.561f23856397ap+1', '-0x1.1a0b78445de0dp+1', '-0x1.004a9a22a0cf2p+3'],
                    'residuals': ['-0x1.ada9d5fa6615dp-58', '-0x1.ada9d5fa6615ep-55', '-0x1.ada9d5fa66161p-56',
                                  '-0x1.ada9d5fa66163p-54'],
                    'states': ['0x1.35a7c608f01a0p+0', '0x1.0aaae819c0652p+0', '-0x1.b9f3bce0c9eecp-2',
                               '-0x1.2b071aac96313p-1', '0x1.986dc0ebc3f62p-1', '-0x1.33916a8326406p-3',
                               '0x1.c9f8f38a1d2d1p+1', '0x1.5085b37f8be25p+1', '0x1.9f3d8253eda60p-5',
                               '0x1.3663a16142234p+1', '0x1.ef1f9469cba2cp-1', '-0x1.255f38d18ccbep+0',
                               '0x1.ea2a9e26800adp-2', '-0x1.a543187543823p-1', '-0x1.39caeaf335968p-2',
                               '0x1.33e53045f10eep+2', '0x1.09ede7be867f6p+2', '-0x1.d21dc98a606e9p+1',
                               '0x1.8d7fd09c8bf49p+1', '-0x1.dfbfb59972488p-3', '-0x1.c71b91f696b3ap+0',
                               '0x1.80dcbec778819p-4', '0x1.f311baa144408p-1', '-0x1.9ee9957dc01ecp-3',
                               '0x1.0f7abffa627e7p+3', '-0x1.97984661e7037p+0', '-0x1.dce6588fc3de8p+1',
                               '0x1.be4f4204c8336p+1', '-0x1.674c89d00922ep+0', '-0x1.7cf36e98a6b04p+0',
                               '-0x1.29e1cb62ca820p-1', '-0x1.67c7f37dde2e4p-1', '-0x1.a35ed720f7163p-2',
                               '0x1.09ae00c13a78bp+3', '-0x1.de81dfda44211p+1', '-0x1.585798bf138eep+2'],
                    't_end': ['0x1.2ddc04742a66dp+2'],
                    'times': ['0x1.de682d9685501p+0', '0x1.8b72373fce7d4p+1', '0x1.049fa7b321a52p+2',
                              '0x1.2bc3ab005641cp+2']},
 'user_gamma3_3': {'drift.C2': ['0x1.423f607bcc907p-50'],
                   'drift.E': ['0x1.2fe2dd0b9128bp-55'],
                   'drift.M_gamma': ['0x1.0d77dcda8517ep-52'],
                   'drift.R_gamma': ['0x1.6cb6a3a702776p-54'],
                   'drift.gamma2': ['0x1.ffffffffffff8p-52'],
                   'integrals.C2': ['0x1.310eb0d30b135p+7', '0x1.310eb0d30b131p+7', '0x1.310eb0d30b130p+7'],
                   'integrals.E': ['-0x1.1e39c1f7e95c0p+1', '-0x1.1e39c1f7e95c0p+1', '-0x1.1e39c1f7e9600p+1'],
                   'integrals.M_gamma': ['0x1.56d7cf1ce945bp+0', '0x1.56d7cf1ce9466p+0', '0x1.56d7cf1ce945dp+0'],
                   'integrals.R_gamma': ['0x1.32cc8e2b5f338p-50', '0x1.b25ed3de8fe12p-52', '-0x1.46cbb93ec9940p-51'],
                   'integrals.gamma2': ['0x1.0000000000001p+0', '0x1.0000000000004p+0', '0x1.0000000000004p+0'],
                   'levels.C': ['0x1.8b3540febd4d2p+3'],
                   'levels.M_gamma': ['0x1.56d7cf1ce9459p+0'],
                   'levels.h': ['-0x1.1e39c1f7e95cap+1'],
                   'points': ['0x1.3c25068085b44p+2', '0x1.11d9dd15d32dcp+0', '0x1.0aeeb6bb61d7dp+3',
                              '0x1.1b8137a6d71cap+1', '0x1.31cb41500828cp+3', '0x1.4efc8cf43c144p+1'],
                   'residuals': ['0x1.0000000000000p-107', '0x0.0p+0', '0x1.0000000000000p-105'],
                   'states': ['0x1.55a21b22d20e0p+1', '0x1.9ebb19fb482f7p-1', '-0x1.35e32dbcabdabp+0',
                              '0x1.38eeac92cfedcp-1', '-0x1.953cc73cf0459p-1', '0x1.0000000000000p-107',
                              '0x1.3c25068085b44p+2', '0x1.e84427ca645f9p+1', '-0x1.19723181b09a1p+2',
                              '0x1.b450b66746294p+1', '-0x1.bfcee58a98bc7p+0', '-0x1.87f58ae7bfdc9p+0',
                              '-0x1.eaaf1a0f83283p-2', '-0x1.c163d2286ad3fp-1', '0x0.0p+0', '0x1.0aeeb6bb61d7dp+3',
                              '-0x1.2375ef086fe8bp+2', '-0x1.501c7b08206e1p+2', '0x1.f92e9b5dbd91ep+1',
                              '-0x1.9e4a7b4dc1654p+1', '0x1.76de6f1694d27p-1', '-0x1.6870f559d4ab8p-1',
                              '-0x1.6ba10b90a4e83p-1', '0x1.0000000000000p-105', '0x1.31cb41500828cp+3',
                              '-0x1.2f1cf77d61c8dp+3', '0x1.ff67022e35346p-1'],
                   't_end': ['0x1.8877070111afep+2'],
                   'times': ['0x1.9ac23eafecfe1p+1', '0x1.33035fd5dad57p+2', '0x1.8678ddc03c440p+2']}}


# ---------------------------------------------------------------------------------------
# The float64 shortcuts against the general numpy paths they replace (same bits).
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["reduced", "mparallel"])
def test_few_rows_same_bits_as_columns(kind, monkeypatch):
    """Up to ``_FEW_ROWS`` crossings are converted row by row on Python floats; forcing the
    whole-column numpy path for the same run gives the same bits in every field."""
    from taylorball import sections

    n = sections._FEW_ROWS
    if kind == "reduced":
        call = lambda: tb.poincare_section("reduced", FIG4_BALL, X0, n_points=n, direction=0)  # noqa: E731
    else:
        call = lambda: tb.poincare_section("mparallel", FIG4_BALL.to_mparallel(), MPAR_X0, n_points=n)  # noqa: E731
    rows = _hexes(call())
    monkeypatch.setattr(sections, "_FEW_ROWS", 0)
    cols = _hexes(call())
    assert rows == cols


def test_drift_floats_same_as_numpy_reduction():
    """The drift on Python floats equals the numpy reduction (exact maxima of exact
    differences), and declines (numpy decides) when a value is not finite."""
    from taylorball.sections import _drift_floats

    rng = np.random.default_rng(7)
    for n in (2, 3, 9):
        A = rng.normal(size=(3, n)) * 10.0 ** rng.integers(-3, 4, size=(3, 1))
        B = np.abs(rng.normal(size=(3, n)))
        B[2] = 0.0  # a zero scale: drift 0
        names = ("a", "b", "c")
        drift = {}
        assert _drift_floats({k: list(map(float, A[i])) for i, k in enumerate(names)},
                             {k: list(map(float, B[i])) for i, k in enumerate(names)}, names, drift)
        dev = np.abs(A[:, 1:] - A[:, :1]).max(axis=1)
        sc = np.maximum(np.abs(B[:, 1:]).max(axis=1), np.abs(B[:, 0]))
        want = {k: (float(dv) / float(s) if s > 0 else 0.0) for k, dv, s in zip(names, dev, sc)}
        assert drift == want
    drift = {}
    assert not _drift_floats({"a": [1.0, float("nan"), 2.0]}, {"a": [1.0, 1.0, 1.0]}, ("a",), drift)
    assert drift == {}


def test_branch_test_of_few_rows_same_as_columns():
    """The branch test of a few float64 roots row by row gives the decisions of the
    whole-column test, at every section angle."""
    from taylorball._problem import problem
    from taylorball.sections import Section, _branch_mask

    prob = problem("reduced", FIG4_BALL)
    rng = np.random.default_rng(3)
    states = [rng.normal(size=9) for _ in range(6)]
    states.append(np.array([1.0, 0.0, 0.5, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0]))  # num = -1, den = 0.5
    for g0 in (0.0, 1.0, 3.0, 5.5):
        sec = Section(prob, g0=g0, direction=0)
        assert np.array_equal(sec.on_branch(states), _branch_mask(states, g0, prob.spec))
        assert np.array_equal(sec.on_branch(states[:1]), _branch_mask(states[:1], g0, prob.spec))


@pytest.mark.parametrize("kind", ["reduced", "mparallel", "full"])
def test_start_state_same_bits_as_array_path(kind):
    """A float64 start state projected and converted on Python floats equals the numpy
    path on the array's columns (``_project_array`` then ``to_internal``), bit for bit,
    for states slightly off the manifold too."""
    from taylorball._problem import problem
    from taylorball._propagate import _arr, start_state
    from taylorball.model import _project_array

    params = FIG4_BALL.to_mparallel() if kind == "mparallel" else FIG4_BALL
    base = {"reduced": X0, "mparallel": MPAR_X0, "full": None}[kind]
    if base is None:
        base = tb.reduced_to_full(FIG4_BALL, X0)
    prob = problem(kind, params)
    rng = np.random.default_rng(11)
    for _ in range(5):
        x = np.array(base, dtype=float) * (1 + 1e-10 * rng.normal(size=len(base)))
        got = start_state(prob, x, project_state=True)
        ref = _arr(prob.system.to_internal(tuple(prob.pars), tuple(_project_array(prob.system.info, x))), prob.spec)
        assert got.dtype == np.float64
        assert [v.hex() for v in got.tolist()] == [v.hex() for v in ref.tolist()]
