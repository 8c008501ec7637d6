"""Every command against bad output paths and a full disk, each in a subprocess
(:mod:`geoshape.bench.reliability`): exit 0/2/130 only, no traceback, one line for exit 2,
no signal, no partial file."""

from __future__ import annotations

import pytest

from geoshape.bench.reliability import Case, _judge, cases, run_cases


@pytest.mark.slow
def test_every_output_case_is_clean():
    results = run_cases()
    failed = [
        f"{o.case.group} / {o.case.name}: {'; '.join(o.problems)} ({o.message})"
        for o in results
        if o.status == "FAIL"
    ]
    assert not failed, "\n".join(failed)
    assert sum(o.status == "ok" for o in results) >= len(cases()) // 2


def test_judge_catches_tracebacks_signals_and_leftovers(tmp_path):
    import subprocess

    case = Case("g", "n", ("x",), clean=(str(tmp_path),))
    crash = subprocess.CompletedProcess([], -11, "", "")
    assert "killed by signal 11" in _judge(case, crash, []).problems
    trace = subprocess.CompletedProcess(
        [], 1, "", "Traceback (most recent call last):\n  ...\nValueError: x\n"
    )
    problems = _judge(case, trace, []).problems
    assert "traceback" in problems and any("exit 1" in p for p in problems)
    (tmp_path / "half.npy").write_bytes(b"x")
    left = _judge(case, subprocess.CompletedProcess([], 2, "", "geoshape x: error: y\n"), [tmp_path])
    assert left.status == "FAIL" and "left half.npy" in left.problems
