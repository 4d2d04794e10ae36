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
