"""Shared fixtures: the repository's bundled data and the `chronomap` command line.

The command-line comparisons need a built `chronomap` binary: `$CHRONOMAP_BIN`, else
`target/debug/chronomap`, else `target/release/chronomap` (CI builds the first with
`cargo test --workspace`). Without one they are skipped, or fail when
`CHRONOMAP_REQUIRE_CLI=1` (as in CI).
"""

from __future__ import annotations

import json
import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def repo() -> pathlib.Path:
    """The repository root (bundled data under `data/`, test files under `tests/data/`)."""
    return REPO


def _find_cli():
    explicit = os.environ.get("CHRONOMAP_BIN")
    if explicit:
        return pathlib.Path(explicit)
    for profile in ("debug", "release"):
        candidate = REPO / "target" / profile / "chronomap"
        if candidate.exists():
            return candidate
    return None


@pytest.fixture(scope="session")
def cli():
    """Runs the `chronomap` command line: `cli("predict", ..., json=True)` returns the parsed
    JSON output (``--json`` is appended), otherwise the text of stdout."""
    binary = _find_cli()
    if binary is None:
        if os.environ.get("CHRONOMAP_REQUIRE_CLI") == "1":
            pytest.fail("no chronomap binary: build it (cargo build) or set CHRONOMAP_BIN")
        pytest.skip("no chronomap binary (cargo build, or set CHRONOMAP_BIN)")

    def run(*args, json_output=False, check=True):
        argv = [str(binary), *map(str, args)]
        if json_output:
            argv.append("--json")
        done = subprocess.run(argv, capture_output=True, text=True, cwd=REPO, timeout=600)
        if check and done.returncode != 0:
            raise AssertionError(f"{' '.join(argv)} failed ({done.returncode}):\n{done.stderr}")
        return json.loads(done.stdout) if json_output else done

    run.binary = binary
    return run
