"""The first run after an install compiles the loop's kernels (about a minute on 2
cores): `kernels.in_cache` tells a compiled kernel from one never compiled or whose
source changed, and `platoon-sumo run` says why that first run is slow."""

from __future__ import annotations

import contextlib
import importlib
import io
import sys
from pathlib import Path

import pytest

from platoon_sumo import cli
from platoon_sumo.kernels import in_cache
from tests.test_results_folders import scenario, write

SOURCE = """
from numba import njit


@njit(cache=True)
def scaled(x):
    return {body}
"""
NOTE = "compiles the loop's kernels once"


def test_in_cache_tells_a_compiled_kernel_from_a_new_or_edited_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    module = tmp_path / "fresh_kernel_for_cache_test.py"
    module.write_text(SOURCE.format(body="2.0 * x"))
    monkeypatch.syspath_prepend(str(tmp_path))
    fresh = importlib.import_module(module.stem)
    try:
        assert in_cache(fresh.scaled) is False  # never compiled
        assert fresh.scaled(1.5) == 3.0
        assert in_cache(fresh.scaled) is True  # compiled and saved by that call
        module.write_text(SOURCE.format(body="3.0 * x + 0.0"))  # another size, stamp
        edited = importlib.reload(fresh)
        assert in_cache(edited.scaled) is False
        assert edited.scaled(1.5) == 4.5
        assert in_cache(edited.scaled) is True
    finally:
        sys.modules.pop(module.stem, None)


def test_in_cache_has_no_answer_for_what_is_not_a_cached_kernel() -> None:
    assert in_cache(len) is None


@pytest.mark.parametrize("compiled", [False, True])
def test_run_says_why_the_first_run_is_slow(
    compiled: bool, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(cli, "_kernels_compiled", lambda: compiled)
    path = write(tmp_path, scenario(simulation={"step_s": 0.1, "end_s": 0.5, "seed": 1}))
    stderr = io.StringIO()
    with contextlib.redirect_stderr(stderr), contextlib.redirect_stdout(io.StringIO()):
        assert cli.main(["run", str(path), "--out", str(tmp_path / "out")]) == 0
    assert (NOTE in stderr.getvalue()) is not compiled
