"""Multiple-shooting Krawczyk proofs of periodic orbits of the 2D section maps
(taylorball.rigorous.proofs.krawczyk_periodic_orbit), and the refined energy root of the
symmetric ball's section map."""

from __future__ import annotations

import json

import numpy as np
import pytest

flint = pytest.importorskip("flint", reason="python-flint is not installed (optional extra 'rigorous')")

from taylorball.errors import UsageError  # noqa: E402
from taylorball.paper import FIG1_LEVELS, FIG3_BALL, FIG3_LEVELS, fig1_params  # noqa: E402
from taylorball.rigorous._balls import exact_arb, working_precision  # noqa: E402
from taylorball.rigorous.certificates import CERT_DIR  # noqa: E402
from taylorball.rigorous.proofs import _des, _ser, krawczyk_periodic_orbit  # noqa: E402

arb = flint.arb

#: Fig. 1's a, d are unphysical by design (the paper's M||gamma example)
pytestmark = pytest.mark.filterwarnings("ignore::taylorball.params.UnphysicalParametersWarning")


def _fig1_saddle():
    """The Fig. 1 saddle's candidate as stored in its shipped certificate (float64 Newton)."""
    cert = json.loads((CERT_DIR / "fig1_saddle_l0_cert.json").read_text())
    center = [float.fromhex(v["hex"]) for v in cert["center"]]
    return center, float.fromhex(cert["K_guess"]["hex"]), float.fromhex(cert["tau_guess"]["hex"])


def test_ball_serialisation_is_exact():
    """The worker processes' balls: the midpoint survives exactly, the radius rounded up."""
    with working_precision(128):
        for x in (arb(1) / 3, arb(-7) / 3 + arb(0, 1e-20), arb(2) ** 100 / 7, arb(0)):
            y = _des(_ser(x))
            assert y.contains(x) and y.mid() == x.mid()
            assert float(y.rad()) <= 2 * float(x.rad()) + 1e-300


def test_shooting_two_segments_proves_the_fig1_saddle_with_workers():
    """Two segments through the same fixed point (F(p0, p1) = (P(p0) - p1, P(p1) - p0)) in two
    worker processes: proved, hyperbolic, and the trace of D(P^2) encloses heyoka's float64
    multipliers' squares (0.2804^2 + 3.5662^2, tb.periodic_orbit: an independent computation).
    About 25 CPU s at 53 bits."""
    import taylorball as tb
    from taylorball._chart_mparallel import mparallel_states_on_section

    center, G, tau = _fig1_saddle()
    r = krawczyk_periodic_orbit(fig1_params(), FIG1_LEVELS, [center, center], 1e-7, [G, G], [tau, tau], prec=53,
                                kind="mparallel", l_branches=[0.0, 0.0], workers=2)
    assert r.proved and r.kind == "hyperbolic", r.message
    x0 = mparallel_states_on_section(fig1_params(), **FIG1_LEVELS.as_kwargs(), point=(0.0, 0.0))[0]
    mu = np.abs(tb.periodic_orbit("mparallel", fig1_params(), x0, levels=FIG1_LEVELS).multipliers)
    with working_precision(53):
        assert r.trace.contains(exact_arb(float(np.sum(mu ** 2))))
        assert sum(r.taus, exact_arb(0)).contains(exact_arb(2 * tau))  # tau: heyoka's float64 return time


def test_shooting_off_the_orbit_is_not_proved():
    """The box moved by three radii in L/G: K(X) is not inside X, "not proved"."""
    center, G, tau = _fig1_saddle()
    r = krawczyk_periodic_orbit(fig1_params(), FIG1_LEVELS, [[center[0], center[1] + 3e-7]], 1e-7, [G], [tau],
                                prec=53, kind="mparallel")
    assert not r.proved and r.message.startswith("not proved: K(X) is not inside X")


@pytest.mark.parametrize("kw,word", [
    (dict(radius=0.0), "radius"), (dict(workers=0), "workers"), (dict(kind="full"), "kind"),
    (dict(l_branches=[1.0]), "l_branches"), (dict(K_guesses=[1.0, 2.0]), "K_guesses"),
])
def test_shooting_bad_arguments_are_refused(kw, word):
    center, G, tau = _fig1_saddle()
    args = dict(centers=[center], radius=1e-7, K_guesses=[G], tau_guesses=[tau], kind="mparallel")
    args.update(kw)
    with pytest.raises(UsageError, match=word):
        krawczyk_periodic_orbit(fig1_params(), FIG1_LEVELS, **args)


def test_refined_energy_root_is_tight_near_the_pole():
    """On the Fig. 3 level at the saddle's section point (-7.0759, -0.5831) the root K = M3 of
    the energy equation is near -C (the chart's pole); a float64 guess 2e-8 off leaves the
    single interval Newton image 1e-14 wide at 128 bits, the refined one below 1e-30."""
    from taylorball.model import get_system
    from taylorball.rigorous.enclosure import ball_pars
    from taylorball.rigorous.section import _newton_root, energy_residual

    p, K_guess = (-7.075896990683475, -0.5831278211157831), -9.999219055821328
    with working_precision(128):
        c = get_system("reduced").constants(ball_pars("reduced", FIG3_BALL))
        C, Mg, h = (exact_arb(v) for v in (FIG3_LEVELS.C, FIG3_LEVELS.M_gamma, FIG3_LEVELS.h))
        F = energy_residual(c, C, Mg, h, exact_arb(p[0]), exact_arb(p[1]))
        one = _newton_root(F, K_guess, (1e-6,), "K")
        ref = _newton_root(F, K_guess, (1e-6,), "K", refine=8)
        assert one.contains(ref) and float(ref.rad()) < 1e-30 < 1e-16 < float(one.rad())
        assert F(ref).contains(exact_arb(0))
