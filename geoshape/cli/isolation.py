"""Running a command in a forked child, so that a crash inside native code (libigl, PyMeshLab,
robust-laplacian …) becomes one line and exit status 2 instead of a dead interpreter.

Preconditions are checked before native calls wherever they are known (see
:func:`geoshape.io.validate.check_mesh` and the geodesic backends); this is the net under
what cannot be known in advance, e.g. a PyMeshLab filter given out-of-range values by an
``.mlx`` script. The child does the whole command (its outputs are written atomically and,
for all-or-nothing commands, committed only when it succeeds); the parent waits, ignores
Ctrl-C (the child receives it too and exits 130 by itself), and when the child dies by a
signal removes the child's temporary files beside the declared outputs and reports it.
The child exits if the parent dies (Linux ``PR_SET_PDEATHSIG``). Cost: one ``fork``, a few
milliseconds.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
from collections.abc import Callable
from pathlib import Path

from geoshape.parallel import die_with_parent

__all__ = ["can_isolate", "run_isolated"]


def can_isolate() -> bool:
    """True where ``fork`` exists (POSIX)."""
    return hasattr(os, "fork") and sys.platform != "win32"


def _remove_temporaries(outputs: list[Path]) -> list[str]:
    """Remove the ``.NAME.*.tmp*`` files :func:`geoshape.io.atomic.atomic_path` leaves when its
    process dies, beside each output file and inside each output folder."""
    removed = []
    for out in outputs:
        patterns = [(out.parent, f".{out.name}.*.tmp*")]
        if out.is_dir():
            patterns.append((out, ".*.tmp*"))
        for folder, pattern in patterns:
            for tmp in folder.glob(pattern):
                with contextlib.suppress(OSError):
                    tmp.unlink()
                    removed.append(tmp.name)
    return removed


def run_isolated(work: Callable[[], int], *, command: str, inputs: list[str], outputs: list[Path]) -> int:
    """Run ``work()`` (which returns an exit status) in a forked child; return its status.

    If the child is killed by a signal, print ``geoshape COMMAND: error: …`` naming the
    signal and ``inputs`` and return 2.
    """
    sys.stdout.flush()
    sys.stderr.flush()
    parent = os.getpid()
    pid = os.fork()
    if pid == 0:  # the child: do the work, never return into the caller's stack
        code = 1
        try:
            signal.signal(signal.SIGINT, signal.default_int_handler)
            die_with_parent(parent)
            code = int(work() or 0)
        except SystemExit as stop:
            code = stop.code if isinstance(stop.code, int) else 1
        except BaseException:
            import traceback

            traceback.print_exc()
            code = 1
        finally:
            with contextlib.suppress(Exception):
                sys.stdout.flush()
                sys.stderr.flush()
            os._exit(code)
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        while True:
            try:
                _, status = os.waitpid(pid, 0)
                break
            except InterruptedError:
                continue
    finally:
        signal.signal(signal.SIGINT, previous)
    if os.WIFSIGNALED(status):
        sig = os.WTERMSIG(status)
        _remove_temporaries(outputs)
        if sig == signal.SIGINT:
            print(f"geoshape {command}: interrupted", file=sys.stderr)
            return 130
        name = signal.Signals(sig).name if sig in signal.Signals._value2member_map_ else str(sig)
        shown = ", ".join(inputs) if inputs else "its inputs"
        print(f"geoshape {command}: error: native code crashed ({name}) while working on {shown}; "
              f"no output was written", file=sys.stderr)
        return 2
    return os.WEXITSTATUS(status)
