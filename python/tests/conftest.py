"""Shared fixtures: the structgp program of this build and the demo's simulated logs.

ctest runs each file with PYTHONPATH=build/python and STRUCTGP_CLI=<the built structgp>
(python/CMakeLists.txt); by hand:

    PYTHONPATH=build/python STRUCTGP_CLI=build/src/cli/structgp python3 -m pytest python/tests
"""

import os
import subprocess

import pytest


@pytest.fixture(scope="session")
def cli():
    path = os.environ.get("STRUCTGP_CLI")
    if not path:
        pytest.fail("STRUCTGP_CLI must name the structgp program of this build "
                    "(ctest sets it; by hand: STRUCTGP_CLI=build/src/cli/structgp)")
    return path


def run(cli_path, *args, expect=0):
    """Runs the structgp program; returns the completed process (stdout, stderr as text)."""
    result = subprocess.run([cli_path, *map(str, args)], capture_output=True, text=True,
                            check=False)
    assert result.returncode == expect, (args, result.returncode, result.stderr)
    return result


@pytest.fixture(scope="session")
def demo(cli, tmp_path_factory):
    """The demo's files: train.csv (slow log), test.csv (fast log), model_before.json (pol),
    findings.json, written by `structgp demo` (two-link arm, Coulomb friction on joint 2)."""
    out = tmp_path_factory.mktemp("demo")
    run(cli, "demo", "--out", out, "--quiet")
    return out
