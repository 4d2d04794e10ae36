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


# --- scales the float64 equations cannot carry: refused, naming the field and the range ----
# Each of these went through before: plane_rate = 1e300 ended in an OverflowError traceback
# (Omega**2 in the energy), I_i or m = 1e200 gave C2 = |M|^2 = inf, I_i = m = 1e-300 gave
# C2 = 0 (no digit left).
@pytest.mark.parametrize("kwargs, needle", [
    (dict(plane_rate=1e300), "plane_rate=1e+300 is out of range"),
    (dict(plane_rate=-1e160), "plane_rate=-1e+160 is out of range"),
    (dict(plane_rate=1e150), "|plane_rate| <= 3.45e+148"),  # 1e150 / (4 + 25)
    (dict(inertia=(1e300, 1e300, 1e300)), "I1 + m a^2 (a momentum per unit rate) = 1e+300"),
    (dict(inertia=(1e200, 1e200, 1e200)), "must be in 1e-150 .. 1e+150"),
    (dict(mass=1e300), "mass=1e+300"),
    (dict(mass=1e-300, inertia=(1e-300, 1e-300, 1e-300), radius=1.0), "I1 + m a^2"),
    (dict(radius=1e-160, mass=1e300), "radius=1e-160"),
])
def test_ball_params_out_of_float64_scale(kwargs, needle):
    base = dict(inertia=(2, 3, 4), mass=1, radius=5, plane_rate=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnphysicalParametersWarning)
        with pytest.raises(tb.ParameterError, match=__import__("re").escape(needle)) as e:
            tb.BallParams(**{**base, **kwargs})
    assert "rescale the units" in str(e.value)


def test_ball_params_scales_at_the_bound_work():
    """Just inside the bounds the integrals are finite and a short propagation runs."""
    import numpy as np

    for kw in (dict(plane_rate=1e148), dict(plane_rate=-3.4e148), dict(plane_rate=1e-300),
               dict(inertia=(2e149, 3e149, 4e149), plane_rate=0.5), dict(mass=1e-300)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UnphysicalParametersWarning)
            ball = tb.BallParams(**{**dict(inertia=(2, 3, 4), mass=1, radius=5, plane_rate=2), **kw})
        x = np.array([0.3, 0.2, 0.1, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0])  # (omega, gamma, R), (R, gamma) = 0
        assert all(np.isfinite(v) for v in tb.integrals("reduced", ball, x).values()), kw


@pytest.mark.parametrize("kwargs, needle", [
    (dict(a=(1, 2, 3), d=4, plane_rate=1e300), "plane_rate=1e+300 is out of range"),
    (dict(a=(1e-300, 2, 3), d=4), "a1 = 1/(I1 + m a^2) = 1e-300"),
    (dict(a=(1e200, 2, 3), d=4), "a1 = 1/(I1 + m a^2) = 1e+200"),
    (dict(a=(1, 2, 3), d=1e300), "d = m a^2 = 1e+300"),
])
def test_mparallel_params_out_of_float64_scale(kwargs, needle):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnphysicalParametersWarning)
        with pytest.raises(tb.ParameterError, match=__import__("re").escape(needle)):
            tb.MParallelParams(**kwargs)
