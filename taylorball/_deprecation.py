"""Old argument names that keep working for one release.

The package speaks one vocabulary (``docs/design.md``, "Vocabulary"): ``t_end`` for the
end time of a run, ``workers`` for a worker count, ``backend`` for how work is spread.
A public function whose argument was renamed is wrapped with :func:`renamed`, which maps
the old keyword to the new one and warns with a :class:`DeprecationWarning` naming the
new one; giving both is a :class:`~taylorball.errors.UsageError`. A keyword that moved into
an options object (a public function keeps at most 12 parameters) is wrapped with
:func:`moved`, which puts it into the options object and warns naming the new form.
"""

from __future__ import annotations

import dataclasses
import functools
import warnings
from typing import Any, Callable, Dict, Mapping, Optional, Sequence, TypeVar, cast

from .errors import UsageError

__all__ = ["renamed", "moved", "options_of"]

F = TypeVar("F", bound=Callable[..., Any])
O = TypeVar("O")


def renamed(**old_to_new: str) -> Callable[[F], F]:
    """Decorator: accept each old keyword ``old`` as ``old_to_new[old]``, with a
    :class:`DeprecationWarning` (attributed to the caller) naming the new one.

    Examples
    --------
    >>> import warnings
    >>> @renamed(threads="workers")
    ... def f(*, workers=None):
    ...     return workers
    >>> with warnings.catch_warnings(record=True) as w:
    ...     warnings.simplefilter("always")
    ...     f(threads=2), str(w[0].message)
    (2, 'f(threads=...) is deprecated: use workers=... (the old name is accepted for one release)')
    """

    return _deprecating(old_to_new, None, ())


def moved(options: type, *names: str, renamed: Optional[Mapping[str, str]] = None) -> Callable[[F], F]:
    """Decorator: accept each keyword of ``names``, now a field of the dataclass
    ``options`` given as ``options=...``, with a :class:`DeprecationWarning` (attributed
    to the caller) naming the new form; the keyword's value replaces that field of the
    ``options`` passed (default ``options()``). ``renamed`` as for :func:`renamed` (one
    wrapper, so every warning names the caller's line).

    Examples
    --------
    >>> import dataclasses, warnings
    >>> from taylorball._deprecation import moved
    >>> @dataclasses.dataclass
    ... class Opts:
    ...     chunk: float = 1.0
    >>> @moved(Opts, "chunk")
    ... def f(*, options=None):
    ...     return options
    >>> with warnings.catch_warnings(record=True) as w:
    ...     warnings.simplefilter("always")
    ...     f(chunk=2.0), str(w[0].message).split(" (")[0]
    (Opts(chunk=2.0), 'f(chunk=...) is deprecated: use options=tb.Opts(chunk=...)')
    """
    return _deprecating(dict(renamed or {}), options, names)


def _deprecating(old_to_new: Mapping[str, str], options: Optional[type],
                 names: Sequence[str]) -> Callable[[F], F]:
    def decorate(fn: F) -> F:
        name = fn.__name__

        @functools.wraps(fn)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            for old, new in old_to_new.items():
                if old in kwargs:
                    if new in kwargs:
                        raise UsageError(f"{name} got both {old}= (its old name) and {new}=: pass only {new}=")
                    warnings.warn(f"{name}({old}=...) is deprecated: use {new}=... (the old name is accepted "
                                  "for one release)", DeprecationWarning, stacklevel=2)
                    kwargs[new] = kwargs.pop(old)
            given: Dict[str, Any] = {k: kwargs.pop(k) for k in names if k in kwargs}
            if given and options is not None:
                for k in given:
                    warnings.warn(f"{name}({k}=...) is deprecated: use options=tb.{options.__name__}({k}=...) "
                                  "(the old form is accepted for one release)", DeprecationWarning,
                                  stacklevel=2)
                base: Any = options_of(kwargs.get("options"), options, name)
                kwargs["options"] = dataclasses.replace(base, **given)
            return fn(*args, **kwargs)

        wrapper.__renamed__ = dict(old_to_new)  # type: ignore[attr-defined]
        wrapper.__moved__ = tuple(names)  # type: ignore[attr-defined]
        return cast(F, wrapper)

    return decorate


def options_of(options: Any, kind: Callable[[], O], where: str) -> O:
    """``options`` if it is a ``kind`` (an options dataclass), ``kind()`` for ``None``;
    otherwise a :class:`~taylorball.errors.UsageError` naming ``where`` and the valid form."""
    if options is None:
        return kind()
    if not isinstance(options, kind):  # type: ignore[arg-type]
        name = getattr(kind, "__name__", repr(kind))
        raise UsageError(f"{where}: options must be a taylorball.{name}(...), got {options!r}")
    return options
