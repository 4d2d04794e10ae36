"""Parameter validation: clear errors naming the argument, the value and the valid form."""

import math
import warnings

import pytest

import taylorball as tb
from taylorball.params import UnphysicalParametersWarning


def test_fig5_ball_is_valid_and_asymmetric():
    p = tb.BallParams(inertia=(2, 3, 4), mass=1, radius=5, plane_rate=2)
    assert p.inertia == (2.0, 3.0, 4.0)
    assert p.d == 25.0
    assert p.pars == (2.0, 3.0, 4.0, 1.0, 5.0, 2.0)
    assert p.symmetry == "asymmetric"
    assert tb.BallParams(inertia=(2, 2, 3), mass=1, radius=5).symmetry == "symmetric"
    assert tb.BallParams(inertia=(3, 3, 3), mass=1, radius=5).symmetry == "homogeneous"


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        (dict(inertia=(2, 3, -4), mass=1, radius=5), "inertia[2] must be > 0"),
        (dict(inertia=(2, 3, 0), mass=1, radius=5), "inertia[2] must be > 0"),
        (dict(inertia=(2, 3), mass=1, radius=5), "exactly three components"),
        (dict(inertia=5.0, mass=1, radius=5), "sequence of three numbers"),
        (dict(inertia=(2, 3, 4), mass=0, radius=5), "mass must be > 0"),
        (dict(inertia=(2, 3, 4), mass=1, radius=-1), "radius must be > 0"),
        (dict(inertia=(2, 3, 4), mass=math.nan, radius=5), "mass must be finite"),
        (dict(inertia=(2, 3, 4), mass=1, radius=5, plane_rate=math.inf), "plane_rate must be finite"),
        (dict(inertia=(1, 1, 3), mass=1, radius=5), "triangle inequality I1 + I2 >= I3"),
        (dict(inertia=(5, 1, 1), mass=1, radius=5), "triangle inequality I2 + I3 >= I1"),
        (dict(inertia=("a", 1, 1), mass=1, radius=5), "must be a real number"),
    ],
)
def test_ball_params_errors(kwargs, needle):
    with pytest.raises(tb.ParameterError, match=__import__("re").escape(needle)):
        tb.BallParams(**kwargs)


def test_parameter_error_is_value_error():
    with pytest.raises(ValueError):
        tb.BallParams(inertia=(1, 1, 3), mass=1, radius=5)


def test_ball_too_heavy_for_its_radius_warns():
    with pytest.warns(UnphysicalParametersWarning, match="2 m a"):
        tb.BallParams(inertia=(2, 3, 4), mass=1, radius=1)


def test_params_are_frozen():
    p = tb.BallParams(inertia=(2, 3, 4), mass=1, radius=5)
    with pytest.raises(AttributeError):
        p.mass = 2.0


def test_to_mparallel_matches_definition():
    p = tb.BallParams(inertia=(2, 3, 4), mass=1, radius=5, plane_rate=2)
    q = p.to_mparallel()
    assert q.d == 25.0
    assert q.a == (1 / 27, 1 / 28, 1 / 29)
    assert q.plane_rate == 2.0
    assert q.physical
    # I_i = 1/a_i - d recovers the moments to rounding (a few ulp of I_i + d = 27..29)
    assert all(abs(i - j) <= 8 * 29 * 2.0**-52 for i, j in zip(q.inertia, p.inertia))


def test_paper_fig1_params_accepted_but_flagged_unphysical():
    with pytest.warns(UnphysicalParametersWarning, match="no rigid body"):
        q = tb.MParallelParams(a=(1, 2, 3), d=4, plane_rate=0.5)
    assert not q.physical
    assert q.inertia == (-3.0, -3.5, 1 / 3 - 4)


def test_mparallel_singular_cone_warns():
    # d a_i = (0.5, 2, 2.5) straddle 1: 1 - d (gamma, A gamma) vanishes on a cone
    with pytest.warns(UnphysicalParametersWarning, match="straddle 1"):
        tb.MParallelParams(a=(0.5, 2, 2.5), d=1)


def test_physical_mparallel_params_do_not_warn():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        q = tb.MParallelParams(a=(1 / 27, 1 / 28, 1 / 29), d=25, plane_rate=2)
    assert q.physical


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        (dict(a=(1, 2, 0), d=4), "a[2] must be > 0"),
        (dict(a=(1, 2, 3), d=0), "d must be > 0"),
        (dict(a=(1, 2, 3), d=4, plane_rate=math.nan), "plane_rate must be finite"),
    ],
)
def test_mparallel_params_errors(kwargs, needle):
    with pytest.raises(tb.ParameterError, match=__import__("re").escape(needle)):
        tb.MParallelParams(**kwargs)
