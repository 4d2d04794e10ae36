"""The level vocabulary (taylorball.levels) and the paper's data (taylorball.paper)."""

import dataclasses
import math
import subprocess
import sys
import warnings

import numpy as np
import pytest

import taylorball as tb
from taylorball import paper
from taylorball.errors import ParameterError
from taylorball.levels import Levels, MParallelLevels


def test_levels_from_caption_reads_G_H_h_as_C_M_gamma_E():
    lv = Levels.from_caption(G=10, H=2, h=5)
    assert lv == Levels(C=10.0, M_gamma=2.0, h=5.0)
    assert all(type(v) is float for v in (lv.C, lv.M_gamma, lv.h))
    assert lv.as_kwargs() == {"C": 10.0, "M_gamma": 2.0, "h": 5.0}
    assert lv.caption == {"G": 10.0, "H": 2.0, "h": 5.0}
    assert hash(lv) == hash(Levels(10.0, 2.0, 5.0))  # frozen, usable as a key
    with pytest.raises(dataclasses.FrozenInstanceError):
        lv.C = 3.0
    # |M_gamma| = C is the edge of the admissible range (M parallel to gamma), still valid
    assert Levels(C=3.0, M_gamma=-3.0, h=0.0).M_gamma == -3.0
    lv = Levels(C=np.float64(2.0), M_gamma=np.int64(1), h=-1.5)
    assert lv.as_kwargs() == {"C": 2.0, "M_gamma": 1.0, "h": -1.5}


@pytest.mark.parametrize(
    "kw, field, match",
    [
        (dict(C=0.0, M_gamma=0.0, h=5.0), "C", r"C = \|M\| must be > 0, got 0\.0"),
        (dict(C=-1.0, M_gamma=0.0, h=5.0), "C", r"must be > 0, got -1\.0"),
        (dict(C=math.nan, M_gamma=0.0, h=5.0), "C", r"C must be a finite real number, got nan"),
        (dict(C=10.0, M_gamma=math.inf, h=5.0), "M_gamma", r"M_gamma must be a finite real number, got inf"),
        (dict(C=10.0, M_gamma=2.0, h="5"), "h", r"h must be a finite real number, got '5'"),
        (dict(C=10.0, M_gamma=2.0, h=True), "h", r"h must be a finite real number, got True"),
        (dict(C=10.0, M_gamma=2.0, h=1j), "h", r"h must be a finite real number, got 1j"),
        (dict(C=10.0, M_gamma=10.5, h=5.0), "M_gamma", r"\|M_gamma\| <= C = 10\.0 .* got 10\.5"),
        (dict(C=10.0, M_gamma=-11.0, h=5.0), "M_gamma", r"\|M_gamma\| <= C = 10\.0 .* got -11\.0"),
    ],
)
def test_levels_reject_bad_values_naming_field_value_and_form(kw, field, match):
    with pytest.raises(ParameterError, match=match) as e:
        Levels(**kw)
    assert str(e.value).startswith(f"Levels: {field}")
    assert isinstance(e.value, ValueError)


def test_mparallel_levels():
    lv = MParallelLevels(lam=2, h=100)
    assert lv.as_kwargs() == {"lam": 2.0, "h": 100.0} and type(lv.lam) is float
    assert MParallelLevels(lam=-3.5, h=-1.0).lam == -3.5  # any finite reals
    with pytest.raises(ParameterError, match=r"MParallelLevels: lam must be a finite real number, got nan"):
        MParallelLevels(lam=math.nan, h=1.0)
    with pytest.raises(ParameterError, match=r"MParallelLevels: h must be a finite real number, got None"):
        MParallelLevels(lam=1.0, h=None)


def test_paper_constants_are_the_captions():
    """The captions as printed (chaplygin-ball-rotating-plane.tex), typed here once as the
    pin of taylorball.paper."""
    ball = dict(mass=1.0, radius=5.0, plane_rate=2.0)
    assert paper.FIG2_BALL == tb.BallParams(inertia=(3, 3, 3), **ball)
    assert paper.FIG3_BALL == tb.BallParams(inertia=(2, 2, 3), **ball)
    assert paper.FIG4_BALL == tb.BallParams(inertia=(2, 3, 4), **ball)
    assert paper.FIG5_BALL == paper.FIG4_BALL
    assert paper.FIG2_LEVELS == paper.FIG3_LEVELS == paper.FIG4B_LEVELS == Levels.from_caption(G=10, H=6, h=5)
    assert paper.FIG4A_LEVELS == Levels.from_caption(G=10, H=2, h=5)
    assert (paper.FIG5A_LEVELS, paper.FIG5B_LEVELS) == (paper.FIG4A_LEVELS, paper.FIG4B_LEVELS)
    assert paper.FIG1_LEVELS == MParallelLevels(lam=2, h=100)
    with pytest.warns(tb.UnphysicalParametersWarning):
        p1 = paper.fig1_params()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", tb.UnphysicalParametersWarning)
        assert p1 == tb.MParallelParams(a=(1, 2, 3), d=4, plane_rate=0.5)


def test_each_paper_constant_cites_its_caption():
    """Every public constant of taylorball.paper has a docstring line naming its caption."""
    import ast
    import inspect

    body = ast.parse(inspect.getsource(paper)).body
    docs = {}
    for node, nxt in zip(body, body[1:]):
        if isinstance(node, ast.Assign) and isinstance(nxt, ast.Expr) and isinstance(nxt.value, ast.Constant):
            docs[node.targets[0].id] = nxt.value.value
    constants = [n for n in paper.__all__ if not callable(getattr(paper, n))]
    assert constants and all("caption" in docs.get(n, "") for n in constants), (constants, docs)
    assert "caption" in paper.fig1_params.__doc__


def test_importing_paper_does_not_warn():
    code = "import warnings; warnings.simplefilter('error'); import taylorball.paper, taylorball.figures"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr


def test_demo_state_is_on_the_reduced_manifold_and_fresh():
    s = paper.demo_reduced_state()
    res = tb.manifold.constraint_residuals("reduced", s)
    # |gamma|^2 = 0.09 + 0.16 + 0.75 and (R, gamma) = 0 by construction: a few roundings each
    assert all(abs(float(v)) <= 4 * 2.0**-52 for v in res.values()), res
    s[0] = 99.0
    assert paper.demo_reduced_state()[0] == 0.1  # a fresh array on every call


@pytest.mark.parametrize("name", sorted(paper.DEMO_STATES))
def test_demo_state_of_each_figure_lies_on_its_level(name):
    """``paper.demo_state(name)`` lies on the caption's level of that figure: |M| = G,
    (M, gamma) = H, E = h by tb.integrals, |gamma| = 1 and (R, gamma) = 0. Tolerance 2^4 eps
    of each integral's scale (tb.integral_scales: the size of the terms it sums): the state's
    K is a root of the energy equation solved to rounding (measured: E off by up to 2.3e-13
    at a scale of ~1e3, ~1 eps), and the stored digits round-trip exactly."""
    ball, lv = paper.DEMO_LEVELS[name]
    x = paper.demo_state(name)
    assert x.shape == (9,) and paper.demo_state(name) is not x
    I = tb.integrals("reduced", ball, x)
    S = tb.integral_scales("reduced", ball, x)
    eps = np.finfo(float).eps
    for key, want in (("C2", lv.C**2), ("M_gamma", lv.M_gamma), ("E", lv.h), ("gamma2", 1.0), ("R_gamma", 0.0)):
        assert abs(float(I[key]) - want) <= 16 * eps * float(S[key]), (name, key, float(I[key]), want, float(S[key]))


def test_demo_state_refuses_an_unknown_name():
    with pytest.raises(tb.UsageError, match="fig4a"):
        paper.demo_state("fig6")
