"""docs/pipeline.md run as written: its ```sh blocks with bash and its ```python blocks
in one namespace, in order, in a scratch folder, with `meshpde` the tool of this build;
then what the doc claims about the result is checked on the files it wrote."""
import os
import pathlib
import re
import subprocess

import numpy as np
import pytest

import meshpde

ROOT = pathlib.Path(__file__).parents[2]
DOC = ROOT / "docs" / "pipeline.md"

if not meshpde.has_medical:
    pytest.skip("built without meshpde::medical", allow_module_level=True)


def blocks():
    return re.findall(r"```(sh|python)\n(.*?)```", DOC.read_text(encoding="utf-8"), flags=re.S)


def test_the_doc_runs_and_corrects_the_segmentation(tmp_path, cli_path, monkeypatch):
    pytest.importorskip("pydicom")
    pytest.importorskip("matplotlib")
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "meshpde").symlink_to(pathlib.Path(cli_path).resolve())
    # The module this test imports, for the doc's python3 too.
    module_dir = str(pathlib.Path(meshpde.__file__).resolve().parents[1])
    python_path = os.pathsep.join(filter(None, [module_dir, os.environ.get("PYTHONPATH")]))
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}", MESHPDE_SRC=str(ROOT),
               PYTHONPATH=python_path)
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    namespace = {}
    found = blocks()
    assert sum(kind == "sh" for kind, _ in found) >= 4 and any(kind == "python" for kind, _ in found)
    for k, (kind, code) in enumerate(found):
        if kind == "sh":
            r = subprocess.run(["bash", "-euo", "pipefail", "-c", code], cwd=work, env=env, capture_output=True,
                               encoding="utf-8", timeout=600)
            assert r.returncode == 0, f"docs/pipeline.md block {k + 1} failed:\n{code}\n{r.stdout}\n{r.stderr}"
        else:
            exec(compile(code, f"docs/pipeline.md block {k + 1}", "exec"), namespace)

    # The corrected segmentation: beside the input, the spine bit for bit, only voxels
    # near the handle changed, and the artery closer to the vessel the scan shows.
    before, A, segments = meshpde.read_segmentation(work / "case" / "vessels.seg.nrrd")
    after, B, table = meshpde.read_segmentation(work / "case" / "vessels-corrected.seg.nrrd")
    assert np.array_equal(A, B) and [s["name"] for s in table] == ["artery", "spine"]
    assert np.array_equal(before == 2, after == 2)
    changed = np.argwhere(before != after)
    assert len(changed) > 10
    handle, radius = np.array([2.5, 0.0, -10.0]), 8.0
    voxel = np.linalg.norm(A[:3, :3], axis=0).max()
    assert np.linalg.norm(changed @ A[:3, :3].T + A[:3, 3] - handle, axis=1).max() <= radius + 2 * voxel
    V, F = meshpde.generate.bifurcation()  # the vessel the synthetic scan was made from
    truth = meshpde.voxelize(V, F, work / "case" / "vessels.seg.nrrd", "artery", full=True)[0] == 1
    wrong_before = ((before == 1) ^ truth).sum()
    wrong_after = ((after == 1) ^ truth).sum()
    assert wrong_after < 0.5 * wrong_before, (wrong_before, wrong_after)
    for png in ["before.png", "after.png", "slice.png"]:
        assert (work / png).stat().st_size > 5000, png
