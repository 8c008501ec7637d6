"""A crash in native code becomes one line and exit 2 (geoshape.cli.isolation)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from geoshape.cli.isolation import can_isolate

pytestmark = pytest.mark.skipif(not can_isolate(), reason="needs fork (POSIX)")

CRASH = textwrap.dedent('''
    import os, signal, sys
    from pathlib import Path
    from geoshape.cli.isolation import run_isolated
    from geoshape.io.atomic import atomic_path

    out = Path(sys.argv[1])

    def work():
        with atomic_path(out) as tmp:
            tmp.write_text("half")
            os.kill(os.getpid(), signal.SIG{sig})  # dies with the temporary on disk
        return 0

    sys.exit(run_isolated(work, command="demo", inputs=["in.off"], outputs=[out]))
''')


@pytest.mark.parametrize("sig", ["SEGV", "ABRT", "BUS"])
def test_a_native_crash_is_one_line_exit_2_and_leaves_no_temporary(tmp_path, sig):
    out = tmp_path / "result.ply"
    done = subprocess.run([sys.executable, "-c", CRASH.replace("{sig}", sig), str(out)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and f"native code crashed (SIG{sig})" in lines[0] and "in.off" in lines[0]
    assert list(tmp_path.iterdir()) == []


def test_the_childs_exit_status_and_output_pass_through(tmp_path):
    script = textwrap.dedent('''
        import sys
        from geoshape.cli.isolation import run_isolated
        def work():
            print("from the child")
            return 7
        sys.exit(run_isolated(work, command="demo", inputs=[], outputs=[]))
    ''')
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert done.returncode == 7 and done.stdout.strip() == "from the child"


def test_kill_int_of_the_command_alone_reaches_the_child_once(tmp_path):
    """A supervisor's ``kill -INT PID`` (not the whole group) still stops the work: exit 130."""
    import os
    import signal
    import time

    script = textwrap.dedent('''
        import sys, time
        from geoshape.cli.isolation import run_isolated
        def work():
            try:
                print("started", flush=True)
                time.sleep(60)
            except KeyboardInterrupt:
                print("interrupted once", file=sys.stderr)
                return 130
            return 0
        sys.exit(run_isolated(work, command="demo", inputs=[], outputs=[]))
    ''')
    from tests.test_interrupt import default_sigint

    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, preexec_fn=default_sigint)
    assert proc.stdout.readline().strip() == "started"
    time.sleep(0.2)
    os.kill(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130 and err.count("interrupted once") == 1, err


def test_an_ignored_sigint_stays_ignored(tmp_path):
    """Started with SIGINT ignored (``nohup``, ``cmd &``), the command keeps running through a
    SIGINT, as Python itself would: the parent does not forward it, the child ignores it."""
    import os
    import signal

    script = textwrap.dedent('''
        import sys, time
        from geoshape.cli.isolation import run_isolated
        def work():
            print("started", flush=True)
            time.sleep(1.5)
            return 0
        sys.exit(run_isolated(work, command="demo", inputs=[], outputs=[]))
    ''')
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    assert proc.stdout.readline().strip() == "started"
    os.kill(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
