"""Old argument names that keep working for one release.

The package speaks one vocabulary (``docs/design.md``, "Vocabulary"): ``t_end`` for the
end time of a run, ``workers`` for a worker count, ``backend`` for how work is spread.
A public function whose argument was renamed is wrapped with :func:`renamed`, which maps
the old keyword to the new one and warns with a :class:`DeprecationWarning` naming the
new one; giving both is a :class:`~taylorball.errors.UsageError`.
"""

from __future__ import annotations

import functools
import warnings
from typing import Any, Callable, TypeVar, cast

from .errors import UsageError

__all__ = ["renamed"]

F = TypeVar("F", bound=Callable[..., Any])


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
            return fn(*args, **kwargs)

        wrapper.__renamed__ = dict(old_to_new)  # type: ignore[attr-defined]
        return cast(F, wrapper)

    return decorate
