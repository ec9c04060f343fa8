"""Python warnings raised while a sequence renders become cmlt warnings.

Python prints a warning as two raw lines on stderr (``file:line: UserWarning:
text`` and the source line), past ``--quiet`` and ``--log-json``. While
:func:`render_sequence` runs (decorated with :func:`routes_python_warnings`)
every warning that the filters in force would show goes to the sequence's
warnings instead: kept until the frame loop's reporter exists, then shown
through it (``cmlt: warning: ...`` or a ``warning`` event), once per text, and
kept in the result. cmlt's own warnings (:class:`UserWarning` raised in the
``cmlt`` package) already name their prim or file and go in as they are; any
other warning (a library's) is prefixed with its category and the place that
raised it, since its text names neither.
"""
from __future__ import annotations

import contextlib
import contextvars
import functools
import os
import warnings
from typing import Callable, List, Optional

__all__ = ["WarningRouter", "routes_python_warnings", "current_router", "warnings_to_stderr"]

_PACKAGE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
_CURRENT: contextvars.ContextVar = contextvars.ContextVar("cmlt_warning_router", default=None)


def warning_text(message, category, filename: str, lineno: int) -> str:
    """One line for a Python warning (module rules)."""
    text = " ".join(str(message).split())
    own = os.path.abspath(str(filename)).startswith(_PACKAGE + os.sep)
    if own and issubclass(category, UserWarning):
        return text
    return f"{category.__name__} from {os.path.basename(str(filename))}:{lineno}: {text}"


class WarningRouter:
    """Collects warnings until :meth:`attach` names where they go."""

    def __init__(self):
        self.pending: List[str] = []
        self._sink: Optional[Callable[[List[str]], None]] = None

    def attach(self, sink: Callable[[List[str]], None]) -> List[str]:
        """From now on send warnings to ``sink``; returns those collected so far."""
        self._sink = sink
        out, self.pending = self.pending, []
        return out

    def show(self, message, category, filename, lineno, file=None, line=None) -> None:
        text = warning_text(message, category, filename, lineno)
        if self._sink is not None:
            self._sink([text])
        elif text not in self.pending:
            self.pending.append(text)

    @contextlib.contextmanager
    def routing(self):
        with warnings.catch_warnings():
            warnings.showwarning = self.show
            yield self


@contextlib.contextmanager
def warnings_to_stderr():
    """For commands without a reporter (``cmlt inspect``): each distinct Python
    warning as one ``cmlt: warning: ...`` line on stderr."""
    import sys
    seen: List[str] = []

    def sink(texts):
        for t in texts:
            if t not in seen:
                seen.append(t)
                sys.stderr.write(f"cmlt: warning: {t}\n")
    router = WarningRouter()
    router.attach(sink)
    with router.routing():
        yield


def current_router() -> Optional[WarningRouter]:
    """The router of the sequence being rendered in this context, or None."""
    return _CURRENT.get()


def routes_python_warnings(fn):
    """Run ``fn`` with a :class:`WarningRouter` installed (see the module doc)."""
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        router = WarningRouter()
        token = _CURRENT.set(router)
        try:
            with router.routing():
                return fn(*args, **kwargs)
        finally:
            _CURRENT.reset(token)
    return wrapper
