"""The bits of the SIMD-lane runs (batch sections and the study runner's ``backend =
"lanes"``) pinned as hashes, so that moving their lane bookkeeping onto the one adapter
(``taylorball.ensemble.orbit_lanes``) is checked to change nothing.

Each orbit's hash covers everything it returns (crossings, states, residuals, integrals,
end time and steps; a study orbit's committed records and its checkpoint's state, double
time, steps and carries). The orbits are run in several packings (all in one call, in
another order, a subset among other companions) and with 1 and 2 worker threads; the
lanes are independent, so every packing gives each orbit its one pinned hash.

The pins were made BEFORE the change, by this file's hashes on the code of 2026-11-28
(heyoka 7.13.2, numpy 2.4.6, 4 float64 lanes, Intel Xeon). A float64 batch integrator's
bits can depend on the SIMD width and the CPU, so on a machine with another lane count
the pins are not comparable and the packing checks alone run.
"""

import hashlib
import json

import numpy as np
import pytest

import taylorball as tb
from taylorball.paper import FIG4_BALL
from taylorball.sections import batch_size

from tests.test_study import store_content, write_study

#: 9 states on the Fig. 4a section (C = 10, M_gamma = 2, h = 5, direction 1): the reprs of
#: ``states_on_section(FIG4_BALL, ..., point=p)[0]`` for the first 9 points of
#: ``section_admissible_sample(FIG4_BALL, n=16, direction=1, seed=0, ...)``.
SECTION_STATES = np.array([
    [3.3568058071497053, -5.244140975225709, 0.12591699591475092, 0.12552655716025565, -0.10514168532696051,
     -0.9865030711833084, 8.031006324798037, -13.818876887107375, 2.494715578298574],
    [1.0357021028987863, -1.671359016361147, -3.71246595007927, 0.3311770691271369, 0.8636277247201447,
     -0.38009064968644724, 2.6063076133151757, -5.1755078108566845, -9.488690977574004],
    [-4.749643637239525, -3.073117136658804, 0.5755770684687489, -0.10196269939968658, -0.3448922562534823,
     -0.9330878519772462, -12.287732644592872, -6.790657707297357, 3.852730094429402],
    [3.08520770846794, 2.5422174825071315, -3.3628811353721413, -0.6981060736562091, -0.31069644732656215,
     -0.6450702500836356, 6.540776999983694, 6.321877068374821, -10.12345693333725],
    [-3.638942628187401, -2.8648420826484964, 0.7324321894562758, -0.641216060528633, 0.049237365704926046,
     -0.7657791101476847, -6.333581356901774, -8.289666213740968, 4.770347886700524],
    [-2.3782022846637023, 1.9624206143496392, -3.8344331775292932, 0.6187510725178336, -0.5696730471113428,
     -0.540943370097932, -5.357958559034415, 4.515919901439234, -10.88439341553694],
    [7.175243633077498, -3.2599201682163397, 1.2854995397611353, 0.41001405108050043, -0.08054249938130895,
     -0.9085160338210705, 16.330085070682774, -8.530000166700562, 8.125989627743728],
    [0.9858265779196098, 2.199385314248982, -1.2159760135808417, 0.3043409042802259, -0.41858943578854546,
     -0.8556631920493726, 2.7744324659558024, 6.00327071604128, -1.9499873687028193],
    [-3.8105970308400385, 1.614217633650954, 0.03239352402449769, -0.4153713481476897, -0.21706350891796816,
     -0.883374256039981, -8.188368895285821, 5.617348085766271, 2.4699526004260997],
])

#: 6 states of the test studies' level (tests/test_study.py BASE: G = 10, H = 2, h = 5):
#: the reprs of the study sampler's draw with ``n = 6, seed = 1``.
STUDY_STATES = [
    [-8.328167014757547, -0.9453674176250991, 0.6777491937241611, -0.28860834414719255, 0.07759172912358961,
     -0.9542980390109932, -20.310730019422927, -3.2318590940349097, 5.879798966946973],
    [6.274247671630193, -4.272092242003301, 1.0055020778345964, 0.3107456977024303, -0.14651740329058496,
     -0.9391324517300069, 14.778713452054633, -10.942585059076672, 6.597259800289055],
    [-6.131158653674147, 3.619549735995837, 1.6963455248363095, -0.31666271730026485, 0.3718645993667346,
     -0.8726061214602099, -14.505763100982774, 7.729294961172373, 8.557911009950814],
    [0.22497677768872681, 0.7203917065144779, -4.200493262311916, -0.743885358512239, -0.6310164370639977,
     -0.22012003440435665, 1.1546366864495894, 2.4812701934067203, -11.015079153738096],
    [2.604948830362717, -5.754606014767375, 0.3769498558069453, 0.07569855075151996, -0.17868324054688314,
     -0.9809903307177825, 6.481353899003431, -14.809905343105555, 3.1976981604555887],
    [5.762425929316628, -2.448398542933968, 1.4547692313684684, 0.2879536455116523, -0.47792062204015484,
     -0.829864191940646, 13.913548191423, -4.125283800421372, 7.203606544020434],
]

PINNED_LANES = 4  # the lane count the pins were made with
PINNED_SECTIONS = {
    "n20": ["cdf3d4a4703b1424", "f490f8b7ef41336c", "aef5bf4f248e55aa", "b782ff5dc9af4429", "9967aaf0079b0f93",
           "74a024411d71e5ad", "778b1c296063d29e", "c45c5780ec2e49f2", "fd09a83d1dc13d33"],
    "t_end": ["44e504c61335403d", "eaae96498577cb71", "40456322a8104990", "085dbad0a427eebd", "f552d3669812e472",
             "00bf24818b682b1c", "af5ee5cebced93e3", "ec724c1865687e63", "c7a45309612d29dd"],
    "dir0": ["dfb4208e47032507", "7fc4db1ac6dabb69", "358eb9be7b869947", "cabe0adc20778dd8", "e170e9ae68341502",
            "a48e359965b19115", "942dfff22f41f294", "c05c8fa89473e6ad", "85cfc57cb71897c3"],
}
PINNED_STUDY = {
    "grid": ["38b2bf1bcfff98e1", "48b79a85acefc57b", "eaeed3cf62889e02", "101b31c3b58b202c", "3d8ece4da2780832",
            "3e7d85ab7f7661ec"],
    "ends": ["0f09f748452a97f3", "2d928d8828c50b8d", "91a83eb6c250c929", "34e8f4718645a88c", "4a206b706fd4e026",
            "4b913ee4c29fe3f7"],
}


def _pins_apply() -> bool:
    return batch_size() == PINNED_LANES


def _section_digest(r) -> str:
    h = hashlib.sha256()
    for a in (r.points, r.times, r.states, r.residuals, *(r.integrals[k] for k in sorted(r.integrals))):
        h.update(np.ascontiguousarray(a).tobytes())
    h.update(repr((float(r.t_end), int(r.n_steps), str(r.outcome))).encode())
    return h.hexdigest()[:16]


def _study_digest(ck, arrays) -> str:
    """An orbit's committed records (not the index, whose digests hold the study's
    fingerprint) and its checkpoint's state, time, steps and carries."""
    h = hashlib.sha256()
    for k in sorted(arrays):
        if not k.startswith("_index"):
            dtype, shape, data, _ = arrays[k]
            h.update(repr((k, dtype, shape)).encode())
            h.update(data)
    h.update(json.dumps({k: ck[k] for k in ("state", "dtime", "n_steps", "carries", "lengths", "chunks", "t")},
                        sort_keys=True, default=repr).encode())
    return h.hexdigest()[:16]


#: (name, kwargs of poincare_sections): crossings reached in some chunk (orbits refilled
#: at different times), a run cut by t_end, and the both-directions section
SECTION_CASES = [
    ("n20", dict(n_points=20)),
    ("t_end", dict(n_points=400, t_end=60.0)),
    ("dir0", dict(n_points=15, direction=0)),
]
#: (states' indices, workers): all in order, reversed, a subset among others
PACKINGS = [(list(range(9)), 1), (list(range(9)), 2), (list(range(8, -1, -1)), 2), ([4, 0, 7], 1),
            ([2], 1)]


@pytest.mark.parametrize("name, kw", SECTION_CASES)
def test_batch_sections_bits(name, kw):
    got: dict = {}
    for idx, workers in PACKINGS:
        out = tb.poincare_sections("reduced", FIG4_BALL, SECTION_STATES[idx], batch=True, workers=workers, **kw)
        for i, r in zip(idx, out):
            got.setdefault(i, set()).add(_section_digest(r))
    assert all(len(v) == 1 for v in got.values()), got  # one hash per orbit, whatever the packing
    digests = [next(iter(got[i])) for i in range(9)]
    if _pins_apply():
        assert digests == PINNED_SECTIONS[name], digests


STUDY_CASES = [
    ("grid", {"samples_every": 0.25, "angles_every": 0.25, "sections": "all", "histogram": True}),
    ("ends", {"angles_every": 0.0, "samples_every": 0.0, "sections": "all"}),
]


@pytest.mark.parametrize("name, obs", STUDY_CASES)
def test_lanes_study_bits(tmp_path, name, obs):
    level = {"G": None, "H": None, "h": None}
    got: dict = {}
    for k, (idx, workers) in enumerate([(list(range(6)), 1), (list(range(6)), 2), ([5, 1, 3], 2)]):
        f = write_study(tmp_path / str(k), run={"backend": "lanes", "workers": workers, "t_end": 50.0},
                        observables=obs, level=level,
                        orbits={"n": None, "seed": None, "states": [STUDY_STATES[i] for i in idx]})
        tb.run_study(f)
        for j, (ck, arrays) in store_content(tmp_path / str(k) / "store").items():
            got.setdefault(idx[j], set()).add(_study_digest(ck, arrays))
    assert all(len(v) == 1 for v in got.values()), got
    digests = [next(iter(got[i])) for i in range(6)]
    if _pins_apply():
        assert digests == PINNED_STUDY[name], digests
