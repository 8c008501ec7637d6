"""Running a command in a forked child, so that a crash inside native code (libigl, PyMeshLab,
robust-laplacian …) becomes one line and exit status 2 instead of a dead interpreter.

Preconditions are checked before native calls wherever they are known (see
:func:`geoshape.io.validate.check_mesh` and the geodesic backends); this is the net under
what cannot be known in advance, e.g. a PyMeshLab filter given out-of-range values by an
``.mlx`` script. The child does the whole command (its outputs are written atomically and,
for all-or-nothing commands, committed only when it succeeds) in its own process group; the
parent waits and passes SIGINT, SIGTERM and SIGHUP on to it (so Ctrl-C, or ``kill -INT`` of
the command, reaches the child exactly once and it exits 130 by itself), and when the child
dies by a signal removes the child's temporary files beside the declared outputs and reports it.
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

#: Signals the parent passes on to the child (which runs in its own process group).
_FORWARDED = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def can_isolate() -> bool:
    """True where ``fork`` exists (POSIX)."""
    return hasattr(os, "fork") and sys.platform != "win32"


def _remove_temporaries(outputs: list[Path]) -> None:
    """Remove what a dead child's :func:`~geoshape.io.atomic.atomic_path` left beside each output."""
    from geoshape.io.atomic import leftover_temporaries

    for out in outputs:
        for tmp in leftover_temporaries(out):
            with contextlib.suppress(OSError):
                tmp.unlink()


def run_isolated(work: Callable[[], int], *, command: str, inputs: list[str], outputs: list[Path]) -> int:
    """Run ``work()`` (which returns an exit status) in a forked child; return its status.

    If the child is killed by a signal, print ``geoshape COMMAND: error: …`` naming the
    signal and ``inputs`` and return 2.
    """
    sys.stdout.flush()
    sys.stderr.flush()
    inherited = {sig: signal.getsignal(sig) for sig in _FORWARDED}
    signal.pthread_sigmask(signal.SIG_BLOCK, _FORWARDED)  # no signal lost between fork and handlers
    parent = os.getpid()
    pid = os.fork()
    if pid == 0:  # the child: do the work, never return into the caller's stack
        code = 1
        try:
            # its own process group: a terminal's Ctrl-C reaches it once, forwarded by the parent
            with contextlib.suppress(OSError):
                os.setpgid(0, 0)
            # a background group must still write to the terminal (progress bars), even
            # where the terminal stops background writers (stty tostop)
            signal.signal(signal.SIGTTOU, signal.SIG_IGN)
            for sig, handler in inherited.items():
                if sig == signal.SIGINT and handler is not signal.SIG_IGN:
                    handler = signal.default_int_handler
                signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
            signal.pthread_sigmask(signal.SIG_UNBLOCK, _FORWARDED)
            die_with_parent(parent)
            # worker pools killed by Ctrl-C leave semaphores that multiprocessing's resource
            # tracker (a process started with these -W options) frees and then warns about,
            # after our one "interrupted" line; the freeing is what matters, not the warning
            # (the filter also hides the tracker's other UserWarnings: -W cannot match on a
            # longer prefix, the message continues with a colon)
            sys.warnoptions.append("ignore:resource_tracker:UserWarning")
            code = int(work() or 0)
        except SystemExit as stop:  # as sys.exit: None is success, a message is printed
            if stop.code is None or isinstance(stop.code, int):
                code = stop.code or 0
            else:
                print(stop.code, file=sys.stderr)
                code = 1
        except BaseException:
            import traceback

            traceback.print_exc()
            code = 1
        finally:
            with contextlib.suppress(Exception):
                sys.stdout.flush()
                sys.stderr.flush()
            os._exit(code)

    def forward(sig, _frame):
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, sig)

    for sig, handler in inherited.items():
        if handler is not signal.SIG_IGN:  # e.g. nohup: an ignored signal stays ignored
            signal.signal(sig, forward)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, _FORWARDED)
    try:
        while True:
            try:
                _, status = os.waitpid(pid, 0)
                break
            except InterruptedError:
                continue
    finally:
        for sig, handler in inherited.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
    if os.WIFSIGNALED(status):
        sig = os.WTERMSIG(status)
        _remove_temporaries(outputs)
        if sig == signal.SIGINT:
            print(f"geoshape {command}: interrupted", file=sys.stderr)
            return 130
        if sig in (signal.SIGTERM, signal.SIGHUP):
            print(f"geoshape {command}: terminated", file=sys.stderr)
            return 128 + sig
        name = signal.Signals(sig).name if sig in signal.Signals._value2member_map_ else str(sig)
        shown = ", ".join(inputs) if inputs else "its inputs"
        print(f"geoshape {command}: error: native code crashed ({name}) while working on {shown}; "
              f"no output was written", file=sys.stderr)
        return 2
    return os.WEXITSTATUS(status)
