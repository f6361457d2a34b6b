"""Every ```python snippet of docs/python.md, in order, in one namespace, in a scratch
directory, with its pictures checked."""
import os
import pathlib
import re

import pytest

DOC = pathlib.Path(__file__).parents[2] / "docs" / "python.md"


def snippets():
    return re.findall(r"```python\n(.*?)```", DOC.read_text(encoding="utf-8"), flags=re.S)


def test_the_tutorial_has_snippets():
    assert len(snippets()) >= 6


def test_every_snippet_runs(tmp_path, monkeypatch, data, capsys):
    data("bunny-3k.off")  # fails under CI, skips elsewhere, when the data is missing
    data("aorta-closed-6k.vtp")
    monkeypatch.setenv("MESHPDE_DATA_DIR", str(data("bunny-3k.off").parent.resolve()))
    monkeypatch.chdir(tmp_path)
    namespace = {}
    for k, code in enumerate(snippets()):
        exec(compile(code, f"docs/python.md snippet {k + 1}", "exec"), namespace)
    printed = capsys.readouterr().out.split()
    assert "False" not in printed, f"a snippet printed False: {printed}"
    for png in ["bunny-curvature.png", "bunny-curvature-histogram.png", "aorta-correction.png"]:
        assert (tmp_path / png).stat().st_size > 1000, png
