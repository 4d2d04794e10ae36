r"""The Liouville relation rho(x(t)) det Phi(t) = rho(x(0)) along heyoka trajectories.

Tolerance (derived in taylorball/verify/invariant_measures.py): the integration error dPhi of the
fundamental matrix perturbs ln det Phi by tr(Phi^{-1} dPhi), at most
n ||Phi^{-1}|| ||dPhi||; with ||dPhi|| ~ eps sqrt(N) ||Phi|| (N steps, per-step relative
errors ~ eps adding up like a random walk) that is

    BOUND = n * eps * sqrt(N) * cond(Phi),

n the dimension. The measured residual/(eps sqrt(N) cond) is <= 0.04 in every case tried
(float64 and real128, all systems and formulations), i.e. >= 150x below BOUND. The
Lebesgue measure (rho = 1) is held to the opposite: its residual must exceed 100 BOUND (so
the bound discriminates) and the true density's residual by 10^6 (float64; measured 10^7 ..
10^14) or 10^20 (real128).
"""

import math

import heyoka as hy
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import taylorball as tb
from taylorball.verify.invariant_measures import density_mp, liouville, liouville_residual
from taylorball.model import get_system
from taylorball.numbers import resolve_fp_type
from taylorball._propagate import working_state

from .conftest import FIG5, HOMOGENEOUS, SYMMETRIC, ball_params, demo_reduced_state, reduced_states

MP0 = np.array([0.3, -1.2, 0.8, 0.6, 0.0, 0.8])


def _state(kind, params=FIG5):
    if kind == "full":
        return tb.reduced_to_full(params, demo_reduced_state())
    if kind == "reduced":
        return demo_reduced_state()
    return MP0


def _bound(r, n):
    return n * r.eps * math.sqrt(max(r.n_steps, 1)) * r.cond


CASES = [("mparallel", None), ("reduced", "omega"), ("reduced", "momentum"), ("full", "omega"), ("full", "momentum")]


@pytest.mark.parametrize("kind, formulation", CASES)
def test_liouville_float64(kind, formulation):
    """t = 10 on the chaotic Fig. 5 ball: ~200 steps, cond(Phi) up to 2e8."""
    r = liouville(kind, FIG5, _state(kind), 10.0, formulation=formulation)
    n = get_system(kind, formulation).dim
    assert r.residual <= _bound(r, n), (r.residual, _bound(r, n))
    one = liouville(kind, FIG5, _state(kind), 10.0, formulation=formulation, density="one")
    assert one.residual >= 100 * _bound(r, n), (one.residual, _bound(r, n))  # measured >= 5e3
    assert one.residual >= 1e6 * r.residual  # measured 1e7 (full/omega) .. 1e14 (mparallel)
    assert one.det_phi == pytest.approx(r.det_phi, rel=1e-12)  # same run, other density


@pytest.mark.parametrize("kind, formulation", [("mparallel", None), ("reduced", "omega"), ("full", "omega")])
def test_liouville_real128(kind, formulation):
    """Quadruple precision, t = 2 (14 steps): measured 5-9 eps."""
    r = liouville(kind, FIG5, _state(kind), 2.0, formulation=formulation, fp_type=hy.real128)
    n = get_system(kind, formulation).dim
    assert r.eps == 2.0**-112
    assert r.residual <= _bound(r, n)
    # measured 5.5 / 9 / 46 eps with cond(Phi) = 3e2 / 6e2 / 1.2e3; 128 eps is ~1/500 of BOUND
    assert r.residual <= 128 * r.eps
    one = liouville(kind, FIG5, _state(kind), 2.0, formulation=formulation, fp_type=hy.real128, density="one")
    assert one.residual >= 1e20 * r.residual  # the wrong density fails by > 20 orders of magnitude


@pytest.mark.slow
@pytest.mark.parametrize("kind, formulation", [("full", "momentum"), ("reduced", "momentum")])
def test_liouville_real128_slow(kind, formulation):
    r = liouville(kind, FIG5, _state(kind), 2.0, formulation=formulation, fp_type=hy.real128)
    assert r.residual <= _bound(r, get_system(kind, formulation).dim)
    assert r.residual <= 128 * r.eps  # measured 46 eps (full/omega: cond 1.2e3, 14 steps)


@pytest.mark.slow
@pytest.mark.parametrize("params", [HOMOGENEOUS, SYMMETRIC], ids=["homogeneous", "symmetric"])
def test_liouville_long_float64(params):
    r = liouville("reduced", params, _state("reduced", params), 100.0)
    assert r.residual <= _bound(r, 9)


def test_density_mp_matches_package_density():
    """The module's own transcription of the densities equals taylorball.density (float64)."""
    import mpmath

    spec = resolve_fp_type(float)
    for kind, form, coords in [("full", "omega", "public"), ("full", "momentum", "internal"),
                               ("reduced", "omega", "public"), ("reduced", "momentum", "internal"),
                               ("mparallel", None, "internal")]:
        s = _state(kind)
        system, pars, internal = working_state(kind, FIG5, s, spec, formulation=form)
        with mpmath.workdps(30):
            mine = float(density_mp(kind, system.formulation, pars, internal))
        pkg = tb.density(kind, FIG5 if kind != "mparallel" else FIG5.to_mparallel(), s, coords=coords)
        assert abs(mine / pkg - 1) <= 64 * 2.0**-52, (kind, form)  # ~20 roundings + sqrt in the package value


def test_unphysical_fig1_params():
    """The paper's Fig. 1 values (D < 0 everywhere): |D|^{-1/2} is still invariant."""
    with pytest.warns(tb.UnphysicalParametersWarning):
        q = tb.MParallelParams(a=(1, 2, 3), d=4, plane_rate=0.5)
    r = liouville("mparallel", q, MP0, 5.0)
    assert r.residual <= _bound(r, 6)


def test_errors():
    with pytest.raises(tb.UsageError, match="density"):
        liouville_residual("reduced", FIG5, demo_reduced_state(), 1.0, density="wrong")
    with pytest.raises(tb.UsageError, match="t must be > 0"):
        liouville_residual("reduced", FIG5, demo_reduced_state(), 0.0)
    with pytest.raises(tb.UsageError, match="formulation"):
        liouville_residual("reduced", FIG5, demo_reduced_state(), 1.0, formulation="bogus")
    with pytest.raises(tb.ConstraintError):
        liouville_residual("reduced", FIG5, [0.1, 0.2, 0.3, 0, 0, 2.0, 1, 0, 0], 1.0)


@settings(max_examples=6)
@given(data=st.data())
def test_liouville_random_balls_and_states(data):
    """Random physical balls and admissible states (float64, t = 3, omega form)."""
    params = data.draw(ball_params())
    state = data.draw(reduced_states(omega_scale=0.5))
    r = liouville("reduced", params, state, 3.0)
    assert r.residual <= _bound(r, 9), (r.residual, _bound(r, 9))
