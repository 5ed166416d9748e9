"""The README's Python example runs as written (the fenced python block of its Python section),
and the example script writes its figure."""

import os
import pathlib
import re
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


def readme_example():
    text = (ROOT / "README.md").read_text()
    section = text.split("\n## Python", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, re.S)
    assert len(blocks) == 1, "the README's Python section has one python block"
    return blocks[0]


def test_the_readme_example_runs_as_written(tmp_path, monkeypatch, capsys):
    code = readme_example()
    assert len(code.strip().splitlines()) <= 10
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "README.md", "exec"), {})
    out = capsys.readouterr().out
    assert "Suggestion('coulomb@2'" in out
    assert "'coulomb@2': (0.150" in out
    assert (tmp_path / "after.json").exists()


def test_the_example_script_writes_its_figure(tmp_path):
    pytest.importorskip("matplotlib")
    figure = tmp_path / "figure.png"
    result = subprocess.run([sys.executable, str(ROOT / "examples/python/diagnose_and_plot.py"),
                             "--out", str(figure)], capture_output=True, text=True,
                            env=dict(os.environ), check=False)
    assert result.returncode == 0, result.stderr
    assert "missing Coulomb friction" in result.stdout
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
