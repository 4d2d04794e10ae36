"""Fill heyoka's disk cache with the compiled systems the default test run needs, in a
background process at the lowest CPU priority (started by ``tests/conftest.py`` in the
controller of an xdist run; ``TAYLORBALL_TEST_WARMUP=0`` turns it off).

On an empty compile cache the test workers compile each system the first time a test needs
it, on the run's critical path. Started at nice 19, this process compiles the same systems
(the same ``taylorball`` code paths, so the same LLVM modules and cache entries) while the
workers leave a core idle (tests waiting on child processes, browsers, kills) and takes
almost nothing from them otherwise; a worker that then needs a system loads it from the
disk cache in a fraction of a second. It builds only, runs nothing, and cannot change a
result: heyoka's disk cache is keyed by the compiled code itself. It also fills mypy's
cache for ``test_typing`` (see :func:`_mypy_cache`).

The list is the costly systems compiled in a cold default run (the ``taylorball.compile``
log of each worker). First come the costliest of those a run needs only after its first
minutes, in the order of the modules that need them (``test_verify``'s tangent systems,
the long double sections of ``test_periodic``, the M||gamma MEGNO system without compact
mode of ``test_paper``, the tutorials' long double integrator, the sections at the ``g0``
of the skeleton and the continuation, the user's sections of ``test_user_sections``, those
of ``test_sections``): in a cold run on the shared 2-core Xeon (load ~14), 2026-11-28, the
workers compiled them all themselves, ~370 s of their wall time at that load, the warm-up
not having reached them in the run's order. Then the others in the order the run first
needed them (those of the first minute the workers mostly compile themselves). A system
missing here is compiled by the worker as before.
"""

from __future__ import annotations

import os
import sys


def _recipes():
    import heyoka as hy
    import numpy as np

    import taylorball as tb
    from taylorball import _propagate
    from taylorball.paper import FIG5_BALL
    from taylorball.sections import Section
    from taylorball.tangent import TangentSystem

    ld, q = np.longdouble, hy.real128

    def prob(kind, fp=float, **kw):
        return tb.problem(kind, FIG5_BALL, fp_type=fp, **kw)

    def plain(kind, fp=float):
        return lambda: _propagate.integrator(prob(kind, fp))

    def section(kind, fp=float, g0=0.0, tol=None):
        return lambda: Section(prob(kind, fp, tol=tol), g0, 1).integrator()

    def batch_section(kind, **event):
        from taylorball._section_batch import _batch_template, batch_size

        return lambda: _batch_template(Section(prob(kind), 0.0, 1, **event).event_def, None, 1, batch_size())

    def tangent(kind, vectors, indicators, norm="full", jacobian="symbolic", fp=float, batch=False, compact_mode=True,
                formulation=None):
        def build():
            p = prob(kind, fp, formulation=formulation)
            ts = TangentSystem.of(p, vectors, indicators, norm, jacobian)
            return (ts.batch_template(compact_mode=compact_mode) if batch
                    else ts.template(p, compact_mode=compact_mode))

        return build

    def user_section(expr, kind="reduced", direction=0):
        return lambda: Section(prob(kind), event=expr(), direction=direction).integrator()


    def r1_minus_half_omega2():
        r1, w2 = hy.make_vars("R1", "omega2")
        return r1 - 0.5 * w2

    return [
        tangent("full", "all", False, formulation="omega"),  # test_verify's chaos rows
        tangent("full", "all", False),
        tangent("reduced", "all", False, formulation="omega"),
        section("mparallel", ld),  # test_periodic
        section("reduced", ld),
        tangent("mparallel", "one", True, compact_mode=False),  # test_paper
        plain("reduced", ld),  # test_tutorials
        section("reduced", g0=3.83),  # test_periodic_skeleton
        section("reduced", g0=0.55),
        section("reduced", g0=1.0),
        user_section(r1_minus_half_omega2),  # test_explore
        section("reduced", g0=3.15),  # test_periodic_continuation
        section("reduced", g0=6.11),
        _mypy_cache,  # test_typing's mypy run
        user_section(lambda: "gamma3", "full", 1),  # test_user_sections
        user_section(lambda: hy.make_vars("gamma3") - 2.0, direction=1),
        user_section(lambda: 1e10 * hy.make_vars("gamma3"), direction=1),
        user_section(lambda: "gamma2", "mparallel", 1),
        batch_section("reduced", event="gamma3"),
        section("reduced", g0=4.0),  # test_sections
        section("mparallel", g0=1.0),
        section("mparallel", g0=4.0),
        # then the others, in the order a cold run first needed them
        plain("reduced"),
        tangent("mparallel", "all", False, fp=q),
        plain("mparallel"),
        plain("mparallel", ld),
        tangent("reduced", "one", True, "compact"),
        section("mparallel"),
        tangent("mparallel", "all", False),
        tangent("reduced", "one", True, "compact", batch=True),
        batch_section("mparallel"),
        tangent("mparallel", "one", True, jacobian="forward", batch=True),
        batch_section("reduced"),
        tangent("reduced", "one", True, jacobian="forward", batch=True),
        tangent("reduced", "one", True, "compact", fp=ld),
        tangent("reduced", "one", True),
        tangent("reduced", "one", True, batch=True),
        tangent("reduced", "one", True, "compact", jacobian="forward", batch=True),
        tangent("reduced", "all", False),
        tangent("full", "one", True, "compact"),
        tangent("full", "one", True),
        tangent("full", "one", True, "compact", fp=ld),
        tangent("full", "one", True, "compact", batch=True),
        section("reduced"),
        tangent("reduced", "all", False, fp=ld),
        tangent("mparallel", "all", False, fp=ld),
        tangent("mparallel", "one", True, batch=True),
        tangent("reduced", "all", False, formulation="omega", fp=q),
        tangent("full", "all", False, formulation="omega", fp=q),
        section("reduced", tol=1e-12),
        section("reduced", tol=1e-10),
        plain("full"),
    ]


def _mypy_cache() -> None:
    """``test_typing.test_mypy_clean``'s ``mypy taylorball`` (pyproject's configuration) in
    this process, from the checkout's root: it fills the checkout's ``.mypy_cache``, cold in
    a fresh clone (13.7 CPU s of a worker in a cold run on the shared 2-core Xeon,
    2026-11-28; ~0.3 s warm). The test still runs mypy over the whole package and reports
    its errors; mypy writes each cache file atomically (a temporary file, then a rename), so
    a test running at the same time reads whole files or none. Nothing without mypy."""
    try:
        from mypy import api
    except ImportError:
        return
    here = os.getcwd()
    os.chdir(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    try:
        api.run(["taylorball"])
    finally:
        os.chdir(here)


def main() -> int:
    try:
        os.nice(19)
    except OSError:
        pass
    from taylorball import _cache

    for build in _recipes():
        try:
            build()
        except Exception as e:  # a recipe that no longer matches the package: the worker compiles it
            print(f"compile warm-up: {type(e).__name__}: {e}", file=sys.stderr)
        _cache.clear()  # the machine code is on disk now; this process keeps none of it
    return 0


if __name__ == "__main__":
    sys.exit(main())
