"""No public function or method of the package takes more than 12 parameters: a call that
grows puts its rarer options in an options object (:class:`taylorball.MegnoMapOptions`,
:class:`taylorball.MegnoOptions`, :class:`taylorball.SectionOptions`).

Counted: every parameter of the signature a user sees (``inspect.signature``, which follows
the deprecation wrappers to the function itself), ``*args`` and ``**kwargs`` each as one,
``self`` and ``cls`` not. Public: every name of ``taylorball.__all__`` that is a function or
a class (its ``__init__`` and its public methods, static and class methods included,
properties excluded). A record's constructor that ``dataclasses`` writes from its fields
(``SectionResult``, ``PeriodicOrbit``, ...) is not counted: its fields are the data the
record holds, not options of a call; a constructor written by hand is."""

import inspect

import taylorball as tb

MAX_PARAMETERS = 12


def _count(fn) -> int:
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):  # a builtin without a signature
        return 0
    return sum(1 for name in sig.parameters if name not in ("self", "cls"))


def _generated(fn) -> bool:
    """Whether ``fn`` was written by ``dataclasses`` (compiled from a string)."""
    return fn.__code__.co_filename == "<string>"


def _public_callables():
    for name in tb.__all__:
        obj = getattr(tb, name)
        if inspect.isclass(obj):
            init = vars(obj).get("__init__")
            if inspect.isfunction(init) and not _generated(init):
                yield f"{name}.__init__", init
            for mname, member in vars(obj).items():
                if mname.startswith("_"):
                    continue
                if isinstance(member, (staticmethod, classmethod)):
                    member = member.__func__
                if inspect.isfunction(member):
                    yield f"{name}.{mname}", member
        elif inspect.isfunction(obj):
            yield name, obj


def test_public_callables_are_found():
    names = {n for n, _ in _public_callables()}
    assert {"megno_many", "poincare_sections", "chaotic_fraction", "Section.run", "Section.__init__",
            "Levels.from_caption"} <= names
    assert "SectionResult.__init__" not in names  # written by dataclasses


def test_no_public_function_over_twelve_parameters():
    over = {n: _count(f) for n, f in _public_callables() if _count(f) > MAX_PARAMETERS}
    assert not over, f"more than {MAX_PARAMETERS} parameters (put the rarer ones in an options object): {over}"
