"""Shared fixtures of the Python module's tests.

Run by ctest (python.pytest) with PYTHONPATH at the build's python/ folder, the CLI of
the same build in MESHPDE_CLI and the real meshes in MESHPDE_DATA_DIR.
"""
import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

import meshpde


@pytest.fixture(scope="session")
def cli_path():
    """The command-line tool of this build (ctest sets MESHPDE_CLI)."""
    path = os.environ.get("MESHPDE_CLI")
    if not path or not pathlib.Path(path).exists():
        if os.environ.get("CI") == "true":
            pytest.fail("MESHPDE_CLI is not set to the meshpde tool (ctest sets it)")
        pytest.skip("MESHPDE_CLI not set: run through ctest to compare with the command-line tool")
    return path


@pytest.fixture(scope="session")
def cli(cli_path):
    def run(*args, json_out=False):
        out = subprocess.run([cli_path, *map(str, args)], capture_output=True, text=True, timeout=300)
        if out.returncode != 0:
            raise AssertionError(f"meshpde {' '.join(map(str, args))} failed:\n{out.stderr}")
        return json.loads(out.stdout) if json_out else out.stdout

    return run


@pytest.fixture(scope="session")
def data():
    """The real meshes of ../shared/data: a missing file fails under CI=true, else skips."""
    root = pathlib.Path(os.environ.get("MESHPDE_DATA_DIR", pathlib.Path(__file__).parents[2] / ".." / "shared" / "data"))

    def get(name):
        p = root / name
        if not p.exists():
            if os.environ.get("CI") == "true":
                pytest.fail(f"{p} is missing (CI=true needs ../shared/data)")
            pytest.skip(f"{p} not found")
        return p

    return get


@pytest.fixture(scope="session")
def sphere():
    return meshpde.generate.icosphere(3)


def rel_diff(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return np.abs(a - b).max() / max(np.abs(b).max(), 1e-300)
