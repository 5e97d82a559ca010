"""Scripts that start worker processes must guard their top level: a clear error when one does not.

Worker processes are started with ``spawn`` (:mod:`sweeps.executors`): each is a fresh interpreter
that imports the caller's main script before it can take a task. A script that calls ``run_sweep``
(or starts an :class:`~sweeps.executors.Executor` pool) at its top level, outside ``if __name__ ==
"__main__":``, would run the sweep again inside every worker, which then dies (the results folder is
locked by the parent) and every run is lost. Two checks say so in one line instead:

* ``check_caller_guarded()`` (in the parent, before anything is written): when the main module is a
  Python file and the line of its top level that led here is not inside an ``if __name__ ==
  "__main__":`` block (read from the file's syntax tree), :class:`UnguardedScript`. Interactive
  sessions, notebooks and ``python -c`` have no main file; workers do not import them, and nothing is
  checked.
* ``refuse_in_spawned_import()`` (wherever a worker would re-run the script's sweep): inside a worker
  that is still importing the main script (``multiprocessing``'s ``_inheriting`` flag, the same one
  its own "bootstrapping phase" check reads) it prints :func:`message` on stderr and exits with status
  :data:`UNGUARDED_EXIT`; the executor recognises that status in a dead worker and raises
  :class:`UnguardedScript` in the parent at once (no retries).
"""
from __future__ import annotations

import ast
import multiprocessing
import sys
from pathlib import Path

UNGUARDED_EXIT = 86   # exit status of a worker that found itself importing an unguarded script


class UnguardedScript(RuntimeError):
    """The main script starts worker processes from its top level, outside ``if __name__ == "__main__":``."""


def message() -> str:
    """The one line: which script, and the guard it needs."""
    path = _main_file()
    where = f"{path.name} starts" if path else "your script starts"
    return (f"{where} worker processes from its top level, so each worker re-runs it: guard your script with "
            "if __name__ == '__main__': (put the code that runs the sweep under it)")


def _main_file() -> Path | None:
    """The main script's file (in a worker importing it: ``__mp_main__``, the name it runs under there)."""
    main = sys.modules.get("__mp_main__") or sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    return Path(path) if path and str(path).endswith(".py") and Path(path).is_file() else None


def _is_main_test(node: ast.AST) -> bool:
    """``__name__ == "__main__"`` (either way round)."""
    if not (isinstance(node, ast.Compare) and len(node.ops) == 1 and isinstance(node.ops[0], ast.Eq)):
        return False
    sides = [node.left, node.comparators[0]]
    names = [s for s in sides if isinstance(s, ast.Name) and s.id == "__name__"]
    mains = [s for s in sides if isinstance(s, ast.Constant) and s.value == "__main__"]
    return len(names) == 1 and len(mains) == 1


def guarded_lines(source: str) -> list[tuple[int, int]]:
    """The (first, last) lines of the bodies of the ``if __name__ == "__main__":`` blocks of ``source``."""
    spans = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.If) and _is_main_test(node.test) and node.body:
            spans.append((node.body[0].lineno, node.body[-1].end_lineno or node.body[-1].lineno))
    return spans


def _top_level_line(main_globals: dict) -> int | None:
    """The line of the main module's top level that is running now (None: not called from it)."""
    frame = sys._getframe(1)
    line = None
    while frame is not None:
        if frame.f_globals is main_globals and frame.f_code.co_name == "<module>":
            line = frame.f_lineno
        frame = frame.f_back
    return line


def check_caller_guarded() -> None:
    """:class:`UnguardedScript` when the main script's top level leads here outside a ``__main__`` guard."""
    path = _main_file()
    if path is None:
        return
    line = _top_level_line(vars(sys.modules["__main__"]))
    if line is None:
        return
    try:
        spans = guarded_lines(path.read_text(encoding="utf-8"))
    except (OSError, SyntaxError, UnicodeDecodeError, ValueError):
        return   # the file changed or cannot be read: the workers' own check still catches it
    if not any(first <= line <= last for first, last in spans):
        raise UnguardedScript(message())


def refuse_in_spawned_import() -> None:
    """In a worker still importing the main script: say so in one line and exit with UNGUARDED_EXIT."""
    if getattr(multiprocessing.current_process(), "_inheriting", False):
        print(f"flocksweep: {message()}", file=sys.stderr)
        raise SystemExit(UNGUARDED_EXIT)
