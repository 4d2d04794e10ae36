"""The docstring examples of the main public functions run, and say what they show.

Each listed object's own docstring (not its methods': those are listed on their own) is
collected with :class:`doctest.DocTestFinder` and run with :class:`doctest.DocTestRunner`
(ELLIPSIS | NORMALIZE_WHITESPACE) in empty globals, so every example imports what it uses
and can be pasted as it is. Every listed object must have at least one example, so the
list cannot shrink without this test failing.
"""

import doctest
import io

import pytest

import taylorball as tb

OBJECTS = {
    "problem": tb.problem,
    "propagate": tb.propagate,
    "make_integrator": tb.make_integrator,
    "integrals": tb.integrals,
    "integral_scales": tb.integral_scales,
    "reduced_to_full": tb.reduced_to_full,
    "project": tb.project,
    "BallParams": tb.BallParams,
    "MParallelParams": tb.MParallelParams,
    "Levels": tb.Levels,
    "Levels.from_caption": tb.Levels.from_caption,
    "states_on_section": tb.states_on_section,
    "section_admissible_sample": tb.section_admissible_sample,
    "reduced_chart": tb.reduced_chart,
    "section_sheet": tb.section_sheet,
    "poincare_section": tb.poincare_section,
    "Section": tb.Section,
    "poincare_sections": tb.poincare_sections,
    "megno": tb.megno,
    "megno_many": tb.megno_many,
    "megno_map": tb.megno_map,
    "lyapunov_spectrum": tb.lyapunov_spectrum,
    "chaotic_fraction": tb.chaotic_fraction,
    "run_many": tb.run_many,
    "StudyConfig.from_problem": tb.StudyConfig.from_problem,
    "run_study": tb.run_study,
    "transport.msd": tb.transport.msd,
    "transport.diffusion_exponent": tb.transport.diffusion_exponent,
    "transport.occupation": tb.transport.occupation,
    "section_sigma": tb.section_sigma,
}

FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


@pytest.mark.parametrize("name", sorted(OBJECTS))
def test_docstring_examples(name):
    obj = OBJECTS[name]
    finder = doctest.DocTestFinder(recurse=False)
    tests = [t for t in finder.find(obj, f"taylorball.{name}", globs={}) if t.examples]
    assert tests, f"taylorball.{name} has no docstring example (an Examples section with >>> lines)"
    out = io.StringIO()
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    for test in tests:
        runner.run(test, out=out.write)
    failed, attempted = runner.failures, runner.tries
    assert attempted > 0
    assert failed == 0, f"{failed} of {attempted} examples of taylorball.{name} failed:\n{out.getvalue()}"
